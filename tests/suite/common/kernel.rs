//! The one scaffold of the GPU unit tests: a test compute kernel (a shader from
//! `shaders/tests/`) run over buffers and images the test hands it, with the outputs
//! read back. Every object a run creates lives in one [`GpuObjects`] bag and is freed
//! when the run ends, whatever happened; the pipeline lives as long as the [`Kernel`].

use nimbus_gpu::{
    vk, BindingDesc, BufferDesc, ComputePipeline, ComputePipelineDesc, Context, DescriptorWrite,
    GpuObjects, ImageDesc, SamplerDesc, SpecValue,
};

/// One binding of a run.
pub enum Arg<'a> {
    /// A storage buffer holding these bytes; read back after the run.
    Storage(u32, &'a [u8]),
    /// A zero-filled storage buffer of this many bytes (at least 16); read back.
    Zeroed(u32, usize),
    /// A sampled 3D image (`sampler3D`) of `dims` texels of `format`.
    Image3d {
        binding: u32,
        dims: [u32; 3],
        format: vk::Format,
        data: &'a [u8],
        sampler: SamplerDesc,
    },
}

impl Arg<'_> {
    fn binding(&self) -> BindingDesc {
        match self {
            Arg::Storage(b, _) | Arg::Zeroed(b, _) => BindingDesc::storage_buffer(*b),
            Arg::Image3d { binding, .. } => BindingDesc::sampled_image(*binding),
        }
    }
}

/// A validated context and one test pipeline.
pub struct Kernel {
    ctx: Context,
    /// Always `Some` until dropped.
    pipeline: Option<ComputePipeline>,
    name: String,
}

impl Kernel {
    /// A kernel from embedded SPIR-V (`nimbus::shaders::TESTS_*`) whose set 0 has
    /// `layout`, with `push_constant_size` bytes of push constants.
    pub fn new(
        spirv: &[u8],
        layout: &[BindingDesc],
        push_constant_size: u32,
        specialization: &[(u32, SpecValue)],
        name: &str,
    ) -> Kernel {
        let ctx = super::gpu::context();
        let words = super::gpu::spirv(spirv);
        let pipeline = ctx
            .create_compute_pipeline(
                &ComputePipelineDesc {
                    spirv: &words,
                    entry: "main",
                    bindings: layout,
                    push_constant_size,
                    specialization,
                },
                name,
            )
            .unwrap_or_else(|e| panic!("{name}: pipeline: {e:#}"));
        Kernel {
            ctx,
            pipeline: Some(pipeline),
            name: name.to_owned(),
        }
    }

    /// A kernel whose layout is the bindings of `args` (in the order given).
    pub fn for_args(spirv: &[u8], args: &[Arg], push_constant_size: u32, name: &str) -> Kernel {
        let layout: Vec<BindingDesc> = args.iter().map(Arg::binding).collect();
        Kernel::new(spirv, &layout, push_constant_size, &[], name)
    }

    pub fn ctx(&self) -> &Context {
        &self.ctx
    }

    fn pipeline(&self) -> &ComputePipeline {
        self.pipeline
            .as_ref()
            .expect("the pipeline lives until drop")
    }

    /// Dispatches `groups` with `push` over `args` and returns the contents of every
    /// storage buffer, in the order of `args` (empty for images). No dispatch when a
    /// group count is 0.
    pub fn run(&self, args: &[Arg], push: &[u8], groups: [u32; 3]) -> Vec<Vec<u8>> {
        let ctx = &self.ctx;
        let name = &self.name;
        let max = ctx.info().max_compute_work_group_count;
        assert!(
            groups.iter().zip(max).all(|(g, m)| *g <= m),
            "{name}: {groups:?} workgroups exceed the device's {max:?}"
        );
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let run = GpuObjects::build(ctx, |o| {
            enum Made {
                Buffer(nimbus_gpu::Handle<nimbus_gpu::Buffer>),
                Image(nimbus_gpu::Handle<nimbus_gpu::Image>, vk::Sampler),
            }
            let mut made = Vec::with_capacity(args.len());
            for (i, arg) in args.iter().enumerate() {
                match arg {
                    Arg::Storage(_, bytes) => {
                        let size = (bytes.len() as u64).max(16);
                        let b = o.add(ctx.create_buffer(
                            &BufferDesc::gpu_only(size, storage),
                            &format!("{name} arg {i}"),
                        )?);
                        ctx.fill_buffer(&o[b], 0)?;
                        if !bytes.is_empty() {
                            ctx.upload_buffer(&o[b], 0, bytes)?;
                        }
                        made.push(Made::Buffer(b));
                    }
                    Arg::Zeroed(_, size) => {
                        let b = o.add(ctx.create_buffer(
                            &BufferDesc::gpu_only((*size as u64).max(16), storage),
                            &format!("{name} arg {i}"),
                        )?);
                        ctx.fill_buffer(&o[b], 0)?;
                        made.push(Made::Buffer(b));
                    }
                    Arg::Image3d {
                        dims,
                        format,
                        data,
                        sampler,
                        ..
                    } => {
                        let image = o.add(ctx.create_image(
                            &ImageDesc::sampled_3d(dims[0], dims[1], dims[2], *format),
                            &format!("{name} image {i}"),
                        )?);
                        ctx.upload_image(&o[image], data)?;
                        let s = ctx.create_sampler(sampler, &format!("{name} sampler {i}"))?;
                        o.add(s);
                        made.push(Made::Image(image, s));
                    }
                }
            }
            let set = {
                let writes: Vec<DescriptorWrite> = args
                    .iter()
                    .zip(&made)
                    .map(|(arg, m)| match (arg.binding(), m) {
                        (b, Made::Buffer(h)) => DescriptorWrite::StorageBuffer {
                            binding: b.binding,
                            buffer: &o[*h],
                        },
                        (b, Made::Image(h, s)) => DescriptorWrite::SampledImage {
                            binding: b.binding,
                            image: &o[*h],
                            sampler: *s,
                        },
                    })
                    .collect();
                ctx.create_descriptor_set(self.pipeline(), &writes, &format!("{name} set"))?
            };
            let set = o.add(set);
            if groups.iter().all(|g| *g > 0) {
                ctx.submit_one_shot(&format!("{name} dispatch"), |cmd| {
                    self.pipeline().dispatch(ctx, cmd, &o[set], push, groups)
                })?;
            }
            made.iter()
                .map(|m| match m {
                    Made::Buffer(h) => ctx.readback_buffer(&o[*h]),
                    Made::Image(..) => Ok(Vec::new()),
                })
                .collect::<anyhow::Result<Vec<Vec<u8>>>>()
        });
        match run {
            Ok((objects, outputs)) => {
                objects.destroy(ctx);
                outputs
            }
            Err(e) => panic!("{name}: {e:#}"),
        }
    }

    /// Fails on any validation error so far.
    pub fn finish(self) {
        super::gpu::assert_no_validation_errors(&self.ctx);
    }
}

impl Drop for Kernel {
    fn drop(&mut self) {
        if let Some(pipeline) = self.pipeline.take() {
            self.ctx.destroy_compute_pipeline(pipeline);
        }
    }
}

/// The first `count` records of type `T` in `bytes` (a read-back buffer may be longer).
pub fn records<T: bytemuck::Pod>(bytes: &[u8], count: usize) -> Vec<T> {
    bytemuck::pod_collect_to_vec(&bytes[..count * std::mem::size_of::<T>()])
}
