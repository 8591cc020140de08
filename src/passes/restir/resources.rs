//! The GPU objects of the ReSTIR passes, by name: four pipelines sharing one layout,
//! their descriptor sets, the scene buffers, the reservoir slots and the density images
//! of the current and the previous frame.

use anyhow::Result;
use nimbus_gpu::{
    vk, BindingDesc, Buffer, BufferDesc, ComputePipeline, Context, DescriptorSet, DescriptorWrite,
    GpuObjects, Handle, Image, SamplerDesc,
};
use nimbus_scene::VoxelGrid;

use super::schedule::Stage;
use super::volumes::DerivedVolume;
use crate::gpu::{bindings, non_empty, FrameUniforms, GpuGrid, RestirPush, RestirUniformsGpu};
use crate::passes::{
    compute_pipeline, image_3d, upload_env_map, upload_records, upload_uniform, Targets,
};
use crate::shaders;

/// Handles of every object in the pass's [`GpuObjects`] bag.
pub struct Resources {
    /// One pipeline and one descriptor set per [`Stage`], in `Stage::ALL` order.
    pub pipelines: [Handle<ComputePipeline>; 4],
    pub sets: [Handle<DescriptorSet>; 4],
    /// The analytic lights of this frame, then those of the previous frame.
    pub lights: Handle<Buffer>,
    pub base_uniforms: Handle<Buffer>,
    pub prev_frame: Handle<Buffer>,
    pub pc_grid: Handle<Buffer>,
    /// This frame's density (full resolution) and its ray-march mips for reuse and NEE.
    pub density: Handle<Image>,
    pub march_reuse: Handle<Image>,
    pub march_nee: Handle<Image>,
    /// The previous frame's density and reuse mip (the temporal stage evaluates the
    /// previous reservoirs with them).
    pub density_prev: Handle<Image>,
    pub march_reuse_prev: Handle<Image>,
}

/// What [`Resources::create`] uploads.
pub struct Inputs<'a> {
    pub grid: &'a GpuGrid,
    pub first: &'a DerivedVolume,
    pub velocity: Option<&'a VoxelGrid>,
    pub uniforms: &'a RestirUniformsGpu,
    pub reservoir_bytes: u64,
    pub march_format: super::volumes::MarchFormat,
}

/// The descriptor layout all four stages share.
fn layout() -> Vec<BindingDesc> {
    let mut layout = Vec::from(Targets::layout());
    layout.extend([
        BindingDesc::uniform_buffer(bindings::PREV_FRAME_UNIFORMS),
        BindingDesc::storage_buffer(bindings::LIGHTS),
        BindingDesc::uniform_buffer(bindings::BASELINE_UNIFORMS),
        BindingDesc::uniform_buffer(bindings::RESTIR_UNIFORMS),
        BindingDesc::sampled_image(bindings::GRID_DENSITY),
        BindingDesc::sampled_image(bindings::GRID_DENSITY_PREV),
        BindingDesc::sampled_image(bindings::GRID_EMISSION),
        BindingDesc::sampled_image(bindings::MARCH_REUSE),
        BindingDesc::sampled_image(bindings::MARCH_REUSE_PREV),
        BindingDesc::sampled_image(bindings::MARCH_NEE),
        BindingDesc::sampled_image(bindings::VELOCITY),
        BindingDesc::storage_buffer(bindings::SUPER_VOXELS),
        BindingDesc::storage_buffer(bindings::PC_GRID),
        BindingDesc::storage_buffer(bindings::RESERVOIRS),
        BindingDesc::storage_buffer(bindings::ENV_TEXELS),
        BindingDesc::storage_buffer(bindings::ENV_CDF),
    ]);
    layout
}

fn spirv_of(stage: Stage) -> &'static [u8] {
    match stage {
        Stage::Initial => shaders::RESTIR_INITIAL,
        Stage::Temporal => shaders::RESTIR_TEMPORAL,
        Stage::Spatial => shaders::RESTIR_SPATIAL,
        Stage::Shade => shaders::RESTIR_SHADE,
    }
}

impl Resources {
    /// Creates every object of the pass in `o` (which frees them if this fails).
    pub fn create(
        ctx: &Context,
        o: &mut GpuObjects,
        specialization: &[(u32, nimbus_gpu::SpecValue)],
        inputs: &Inputs,
        targets: &Targets,
    ) -> Result<Resources> {
        let Inputs {
            grid,
            first,
            velocity,
            uniforms,
            reservoir_bytes,
            march_format,
        } = *inputs;
        let layout = layout();
        let mut pipelines = Vec::with_capacity(4);
        for stage in Stage::ALL {
            pipelines.push(compute_pipeline::<RestirPush>(
                ctx,
                o,
                spirv_of(stage),
                &layout,
                specialization,
                &format!("restir {}", stage.name()),
            )?);
        }

        // Scene buffers. The light buffer holds this frame's and the previous frame's
        // records (the same until lights animate).
        let light_records = non_empty(&[grid.lights.clone(), grid.lights.clone()].concat());
        let lights = upload_records(ctx, o, &light_records, "restir lights")?;
        let super_voxels = upload_records(ctx, o, &grid.super_voxels, "super-voxels")?;
        let (env_texels, env_cdf) = upload_env_map(ctx, o, grid)?;
        let base_uniforms = upload_uniform(ctx, o, &grid.uniforms, "grid uniforms")?;
        let restir_uniforms = upload_uniform(ctx, o, uniforms, "restir uniforms")?;
        let prev_frame = o.add(ctx.create_buffer(
            &BufferDesc::gpu_only(
                std::mem::size_of::<FrameUniforms>() as u64,
                vk::BufferUsageFlags::UNIFORM_BUFFER,
            ),
            "previous frame uniforms",
        )?);
        let pc_grid = upload_records(ctx, o, &first.pc, "piecewise-constant levels")?;
        let reservoirs = o.add(ctx.create_buffer(
            &BufferDesc::gpu_only(reservoir_bytes, vk::BufferUsageFlags::STORAGE_BUFFER),
            "reservoirs",
        )?);
        ctx.fill_buffer(&o[reservoirs], 0)?;

        // Density images: the previous frame starts as a copy of the first.
        let density: &[u8] = bytemuck::cast_slice(&first.density.data);
        let reuse: &[u8] = &first.march_reuse.texels;
        let nee: &[u8] = &first.march_nee.texels;
        let (r32, march) = (vk::Format::R32_SFLOAT, march_format.vk());
        let density_image = image_3d(ctx, o, first.density.dims, r32, density, "density")?;
        let march_reuse = image_3d(
            ctx,
            o,
            first.march_reuse.dims,
            march,
            reuse,
            "march (reuse)",
        )?;
        let march_nee = image_3d(ctx, o, first.march_nee.dims, march, nee, "march (NEE)")?;
        let density_prev = image_3d(ctx, o, first.density.dims, r32, density, "previous density")?;
        let march_reuse_prev = image_3d(
            ctx,
            o,
            first.march_reuse.dims,
            march,
            reuse,
            "previous march (reuse)",
        )?;
        let emission = match &grid.emission {
            Some(e) => image_3d(
                ctx,
                o,
                e.dims,
                r32,
                bytemuck::cast_slice(&e.data),
                "grid emission",
            )?,
            // Without emission the (compiled-out) binding gets a 1-texel image.
            None => image_3d(
                ctx,
                o,
                [1, 1, 1],
                r32,
                bytemuck::bytes_of(&0.0f32),
                "no emission",
            )?,
        };
        let rgba16 = vk::Format::R16G16B16A16_SFLOAT;
        let velocity = match velocity {
            Some(v) => {
                let texels: Vec<u16> = v
                    .data
                    .chunks_exact(3)
                    .flat_map(|c| [c[0], c[1], c[2], 0.0])
                    .map(|x| half::f16::from_f32(x).to_bits())
                    .collect();
                image_3d(
                    ctx,
                    o,
                    v.dims,
                    rgba16,
                    bytemuck::cast_slice(&texels),
                    "velocity",
                )?
            }
            None => image_3d(ctx, o, [1, 1, 1], rgba16, &[0u8; 8], "no velocity")?,
        };
        let nearest = ctx.create_sampler(&SamplerDesc::nearest(), "restir nearest")?;
        o.add(nearest);
        let linear = ctx.create_sampler(&SamplerDesc::linear(), "restir linear")?;
        o.add(linear);

        let mut sets = Vec::with_capacity(4);
        for (stage, pipeline) in Stage::ALL.into_iter().zip(&pipelines) {
            let set = {
                let buffer = |binding, handle: Handle<Buffer>| DescriptorWrite::StorageBuffer {
                    binding,
                    buffer: &o[handle],
                };
                let uniform = |binding, handle: Handle<Buffer>| DescriptorWrite::UniformBuffer {
                    binding,
                    buffer: &o[handle],
                };
                let image =
                    |binding, handle: Handle<Image>, sampler| DescriptorWrite::SampledImage {
                        binding,
                        image: &o[handle],
                        sampler,
                    };
                let mut writes = Vec::from(targets.writes());
                writes.extend([
                    uniform(bindings::PREV_FRAME_UNIFORMS, prev_frame),
                    buffer(bindings::LIGHTS, lights),
                    uniform(bindings::BASELINE_UNIFORMS, base_uniforms),
                    uniform(bindings::RESTIR_UNIFORMS, restir_uniforms),
                    image(bindings::GRID_DENSITY, density_image, nearest),
                    image(bindings::GRID_DENSITY_PREV, density_prev, nearest),
                    image(bindings::GRID_EMISSION, emission, nearest),
                    image(bindings::MARCH_REUSE, march_reuse, linear),
                    image(bindings::MARCH_REUSE_PREV, march_reuse_prev, linear),
                    image(bindings::MARCH_NEE, march_nee, linear),
                    image(bindings::VELOCITY, velocity, linear),
                    buffer(bindings::SUPER_VOXELS, super_voxels),
                    buffer(bindings::PC_GRID, pc_grid),
                    buffer(bindings::RESERVOIRS, reservoirs),
                    buffer(bindings::ENV_TEXELS, env_texels),
                    buffer(bindings::ENV_CDF, env_cdf),
                ]);
                ctx.create_descriptor_set(
                    &o[*pipeline],
                    &writes,
                    &format!("restir {} set", stage.name()),
                )?
            };
            sets.push(o.add(set));
        }
        Ok(Resources {
            pipelines: [pipelines[0], pipelines[1], pipelines[2], pipelines[3]],
            sets: [sets[0], sets[1], sets[2], sets[3]],
            lights,
            base_uniforms,
            prev_frame,
            pc_grid,
            density: density_image,
            march_reuse,
            march_nee,
            density_prev,
            march_reuse_prev,
        })
    }
}
