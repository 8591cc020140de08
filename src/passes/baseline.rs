//! The baseline path tracer for grid media (`shaders/baseline/pathtrace.comp`): the
//! equal-time reference of Volumetric ReSTIR, with decomposition tracking and residual
//! ratio tracking on 8x super-voxels.

use anyhow::Result;
use nimbus_gpu::{
    vk, BindingDesc, Buffer, BufferDesc, ComputePipeline, ComputePipelineDesc, Context,
    DescriptorSet, DescriptorWrite, Image, ImageDesc, SamplerDesc, SpecValue,
};

use crate::bindings;
use crate::gpu_scene::{non_empty, BoxMediumGpu, FrameUniforms, GpuGrid, PassPush, ShapeGpu};
use crate::passes::crepuscular::{image_groups, spirv_words, upload_records, Targets};
use crate::plan::BaselinePlan;
use crate::shaders;

/// The pipeline, the grid's density texture and the buffers the pass reads.
pub struct BaselinePass {
    pipeline: ComputePipeline,
    set: DescriptorSet,
    buffers: Vec<Buffer>,
    density: Image,
    emission: Option<Image>,
    sampler: vk::Sampler,
}

/// The specialization constants of `pathtrace.comp` for a plan.
pub fn specialization(plan: &BaselinePlan) -> [(u32, SpecValue); 7] {
    [
        (8, SpecValue::Bool(plan.has_env_map)),
        (4, SpecValue::Bool(plan.has_boxes)),
        (0, SpecValue::Bool(plan.has_shapes)),
        (2, SpecValue::Bool(plan.has_env)),
        (5, SpecValue::U32(plan.max_bounces)),
        (6, SpecValue::Bool(plan.pixel_jitter)),
        (7, SpecValue::Bool(plan.has_emission)),
    ]
}

/// GPU objects made so far, freed together if creation fails half-way.
#[derive(Default)]
struct Partial {
    buffers: Vec<Buffer>,
    density: Option<Image>,
    emission: Option<Image>,
    sampler: Option<vk::Sampler>,
}

impl Partial {
    fn destroy(self, ctx: &Context) {
        for b in self.buffers {
            ctx.destroy_buffer(b);
        }
        for image in [self.density, self.emission].into_iter().flatten() {
            ctx.destroy_image(image);
        }
        if let Some(sampler) = self.sampler {
            ctx.destroy_sampler(sampler);
        }
    }
}

impl BaselinePass {
    pub fn new(
        ctx: &Context,
        plan: &BaselinePlan,
        grid: &GpuGrid,
        boxes: &[BoxMediumGpu],
        shapes: &[ShapeGpu],
        targets: &Targets,
    ) -> Result<Self> {
        let spirv = spirv_words(shaders::BASELINE_PATHTRACE)?;
        let layout = [
            BindingDesc::uniform_buffer(bindings::FRAME_UNIFORMS),
            BindingDesc::storage_buffer(bindings::ACCUM),
            BindingDesc::storage_buffer(bindings::ACCUM_SQ),
            BindingDesc::storage_buffer(bindings::STATS),
            BindingDesc::storage_buffer(bindings::SHAPES),
            BindingDesc::storage_buffer(bindings::LIGHTS),
            BindingDesc::uniform_buffer(bindings::BASELINE_UNIFORMS),
            BindingDesc::sampled_image(bindings::GRID_DENSITY),
            BindingDesc::storage_buffer(bindings::SUPER_VOXELS),
            BindingDesc::sampled_image(bindings::GRID_EMISSION),
            BindingDesc::storage_buffer(bindings::BOX_MEDIA),
            BindingDesc::storage_buffer(bindings::ENV_TEXELS),
            BindingDesc::storage_buffer(bindings::ENV_CDF),
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
            "baseline path tracer",
        )?;

        let mut partial = Partial::default();
        let result = (|| -> Result<DescriptorSet> {
            partial
                .buffers
                .push(upload_records(ctx, &non_empty(shapes), "shapes")?);
            partial
                .buffers
                .push(upload_records(ctx, &non_empty(&grid.lights), "lights")?);
            partial
                .buffers
                .push(upload_records(ctx, &grid.super_voxels, "super-voxels")?);
            partial
                .buffers
                .push(upload_records(ctx, &non_empty(boxes), "box media")?);
            // Without a map the (compiled-out) environment bindings get one zero record.
            let (texels, tables) = grid
                .env_map
                .clone()
                .unwrap_or_else(|| (vec![[0.0; 4]], vec![0.0]));
            partial
                .buffers
                .push(upload_records(ctx, &texels, "environment texels")?);
            partial
                .buffers
                .push(upload_records(ctx, &tables, "environment tables")?);
            let uniforms = ctx.create_buffer(
                &BufferDesc::gpu_only(
                    std::mem::size_of_val(&grid.uniforms) as u64,
                    vk::BufferUsageFlags::UNIFORM_BUFFER,
                ),
                "baseline uniforms",
            )?;
            let uploaded = ctx.upload_buffer(&uniforms, 0, bytemuck::bytes_of(&grid.uniforms));
            partial.buffers.push(uniforms);
            uploaded?;

            let [nx, ny, nz] = grid.density.dims;
            let image = ctx.create_image(
                &ImageDesc::sampled_3d(nx, ny, nz, vk::Format::R32_SFLOAT),
                "grid density",
            )?;
            let uploaded = ctx.upload_image(&image, bytemuck::cast_slice(&grid.density.data));
            partial.density = Some(image);
            uploaded?;
            if let Some(emission) = &grid.emission {
                let [ex, ey, ez] = emission.dims;
                let image = ctx.create_image(
                    &ImageDesc::sampled_3d(ex, ey, ez, vk::Format::R32_SFLOAT),
                    "grid emission",
                )?;
                let uploaded = ctx.upload_image(&image, bytemuck::cast_slice(&emission.data));
                partial.emission = Some(image);
                uploaded?;
            }
            partial.sampler = Some(ctx.create_sampler(&SamplerDesc::nearest(), "grid density")?);
            let density = partial
                .density
                .as_ref()
                .expect("density image was just created");
            let sampler = partial.sampler.expect("sampler was just created");
            // Without emission the (compiled-out) emission binding sees the density.
            let emission = partial.emission.as_ref().unwrap_or(density);

            let b = &partial.buffers;
            let mut writes = Vec::from(targets.writes());
            writes.extend([
                DescriptorWrite::StorageBuffer {
                    binding: bindings::SHAPES,
                    buffer: &b[0],
                },
                DescriptorWrite::StorageBuffer {
                    binding: bindings::LIGHTS,
                    buffer: &b[1],
                },
                DescriptorWrite::StorageBuffer {
                    binding: bindings::SUPER_VOXELS,
                    buffer: &b[2],
                },
                DescriptorWrite::UniformBuffer {
                    binding: bindings::BASELINE_UNIFORMS,
                    buffer: &b[6],
                },
                DescriptorWrite::StorageBuffer {
                    binding: bindings::BOX_MEDIA,
                    buffer: &b[3],
                },
                DescriptorWrite::StorageBuffer {
                    binding: bindings::ENV_TEXELS,
                    buffer: &b[4],
                },
                DescriptorWrite::StorageBuffer {
                    binding: bindings::ENV_CDF,
                    buffer: &b[5],
                },
                DescriptorWrite::SampledImage {
                    binding: bindings::GRID_DENSITY,
                    image: density,
                    sampler,
                },
                DescriptorWrite::SampledImage {
                    binding: bindings::GRID_EMISSION,
                    image: emission,
                    sampler,
                },
            ]);
            ctx.create_descriptor_set(&pipeline, &writes, "baseline set")
        })();
        match result {
            Ok(set) => Ok(Self {
                pipeline,
                set,
                buffers: partial.buffers,
                density: partial
                    .density
                    .expect("density image exists when the set does"),
                emission: partial.emission,
                sampler: partial.sampler.expect("sampler exists when the set does"),
            }),
            Err(e) => {
                partial.destroy(ctx);
                ctx.destroy_compute_pipeline(pipeline);
                Err(e)
            }
        }
    }

    /// Record one dispatch over the image.
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
        Partial {
            buffers: self.buffers,
            density: Some(self.density),
            emission: self.emission,
            sampler: Some(self.sampler),
        }
        .destroy(ctx);
        ctx.destroy_compute_pipeline(self.pipeline);
    }
}
