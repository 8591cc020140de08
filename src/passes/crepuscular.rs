//! The crepuscular-ray pass (`shaders/box/crepuscular.comp`): single scattering in
//! homogeneous box media under collimated light, direct lighting of the shapes, and the
//! background, accumulated per pixel.

use anyhow::{bail, Result};
use nimbus_gpu::{
    vk, BindingDesc, Buffer, BufferDesc, ComputePipeline, ComputePipelineDesc, Context,
    DescriptorSet, DescriptorWrite, SpecValue,
};

use crate::bindings;
use crate::gpu_scene::{non_empty, FrameUniforms, GpuScene, PassPush};
use crate::plan::{estimator_id, CrepuscularPlan};
use crate::shaders;

/// Workgroup size of the shader (`local_size_x`, `local_size_y`).
pub const GROUP_SIZE: [u32; 2] = [8, 8];

/// Workgroups covering the frame's image, one invocation per pixel.
pub fn image_groups(uniforms: &FrameUniforms) -> [u32; 3] {
    [
        uniforms.image[0].div_ceil(GROUP_SIZE[0]),
        uniforms.image[1].div_ceil(GROUP_SIZE[1]),
        1,
    ]
}

/// The pass's pipeline and the scene buffers it reads.
pub struct CrepuscularPass {
    pipeline: ComputePipeline,
    set: DescriptorSet,
    scene_buffers: Vec<Buffer>,
}

/// Buffers shared with the renderer: written by the pass, read back by the renderer.
pub struct Targets<'a> {
    pub uniforms: &'a Buffer,
    pub accum: &'a Buffer,
    pub accum_sq: &'a Buffer,
    pub stats: &'a Buffer,
}

impl<'a> Targets<'a> {
    /// The descriptor writes of the frame uniforms and the three outputs, which every
    /// pass binds at the same binding numbers.
    pub fn writes(&self) -> [DescriptorWrite<'a>; 4] {
        [
            DescriptorWrite::UniformBuffer {
                binding: bindings::FRAME_UNIFORMS,
                buffer: self.uniforms,
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::ACCUM,
                buffer: self.accum,
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::ACCUM_SQ,
                buffer: self.accum_sq,
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::STATS,
                buffer: self.stats,
            },
        ]
    }
}

/// The specialization constants of `crepuscular.comp` for a plan.
pub fn specialization(plan: &CrepuscularPlan) -> [(u32, SpecValue); 7] {
    let f = plan.features;
    [
        (0, SpecValue::Bool(f.has_shapes)),
        (1, SpecValue::Bool(f.has_gobos)),
        (2, SpecValue::Bool(f.has_env)),
        (3, SpecValue::U32(estimator_id(plan.estimator))),
        (4, SpecValue::Bool(f.has_media)),
        (5, SpecValue::U32(plan.max_bounces)),
        (6, SpecValue::Bool(f.pixel_jitter)),
    ]
}

pub fn upload_records<T: bytemuck::Pod>(
    ctx: &Context,
    records: &[T],
    name: &str,
) -> Result<Buffer> {
    let bytes: &[u8] = bytemuck::cast_slice(records);
    let buffer = ctx.create_buffer(
        &BufferDesc::gpu_only(bytes.len() as u64, vk::BufferUsageFlags::STORAGE_BUFFER),
        name,
    )?;
    if let Err(e) = ctx.upload_buffer(&buffer, 0, bytes) {
        ctx.destroy_buffer(buffer);
        return Err(e);
    }
    Ok(buffer)
}

impl CrepuscularPass {
    pub fn new(
        ctx: &Context,
        plan: &CrepuscularPlan,
        scene: &GpuScene,
        targets: &Targets,
    ) -> Result<Self> {
        let spirv = spirv_words(shaders::BOX_CREPUSCULAR)?;
        let layout = [
            BindingDesc::uniform_buffer(bindings::FRAME_UNIFORMS),
            BindingDesc::storage_buffer(bindings::ACCUM),
            BindingDesc::storage_buffer(bindings::ACCUM_SQ),
            BindingDesc::storage_buffer(bindings::STATS),
            BindingDesc::storage_buffer(bindings::BOX_MEDIA),
            BindingDesc::storage_buffer(bindings::SHAPES),
            BindingDesc::storage_buffer(bindings::LIGHTS),
            BindingDesc::storage_buffer(bindings::GOBO_PLANES),
        ];
        let spec = specialization(plan);
        let pipeline = ctx.create_compute_pipeline(
            &ComputePipelineDesc {
                spirv: &spirv,
                entry: "main",
                bindings: &layout,
                push_constant_size: std::mem::size_of::<PassPush>() as u32,
                specialization: &spec,
            },
            "crepuscular",
        )?;

        let mut scene_buffers = Vec::new();
        let result = (|| -> Result<DescriptorSet> {
            scene_buffers.push(upload_records(ctx, &non_empty(&scene.media), "box media")?);
            scene_buffers.push(upload_records(ctx, &non_empty(&scene.shapes), "shapes")?);
            scene_buffers.push(upload_records(ctx, &non_empty(&scene.lights), "lights")?);
            scene_buffers.push(upload_records(
                ctx,
                &non_empty(&scene.gobo_planes),
                "gobo planes",
            )?);
            let mut writes = Vec::from(targets.writes());
            writes.extend([
                DescriptorWrite::StorageBuffer {
                    binding: bindings::BOX_MEDIA,
                    buffer: &scene_buffers[0],
                },
                DescriptorWrite::StorageBuffer {
                    binding: bindings::SHAPES,
                    buffer: &scene_buffers[1],
                },
                DescriptorWrite::StorageBuffer {
                    binding: bindings::LIGHTS,
                    buffer: &scene_buffers[2],
                },
                DescriptorWrite::StorageBuffer {
                    binding: bindings::GOBO_PLANES,
                    buffer: &scene_buffers[3],
                },
            ]);
            ctx.create_descriptor_set(&pipeline, &writes, "crepuscular set")
        })();
        match result {
            Ok(set) => Ok(Self {
                pipeline,
                set,
                scene_buffers,
            }),
            Err(e) => {
                for b in scene_buffers {
                    ctx.destroy_buffer(b);
                }
                ctx.destroy_compute_pipeline(pipeline);
                Err(e)
            }
        }
    }

    /// Record one dispatch over a `width` x `height` image.
    pub fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        uniforms: &FrameUniforms,
        push: &PassPush,
    ) -> Result<()> {
        let groups = image_groups(uniforms);
        self.pipeline
            .dispatch(ctx, cmd, &self.set, bytemuck::bytes_of(push), groups)
    }

    pub fn destroy(self, ctx: &Context) {
        ctx.destroy_descriptor_set(self.set);
        for b in self.scene_buffers {
            ctx.destroy_buffer(b);
        }
        ctx.destroy_compute_pipeline(self.pipeline);
    }
}

/// SPIR-V bytes as words (the embedded bytes carry no alignment guarantee).
pub fn spirv_words(bytes: &[u8]) -> Result<Vec<u32>> {
    if !bytes.len().is_multiple_of(4) {
        bail!(
            "embedded SPIR-V of {} bytes is not a whole number of words",
            bytes.len()
        );
    }
    Ok(bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}
