//! The GPU objects of the ReSTIR passes, by name: four pipelines sharing one layout (and
//! a fifth, the temporal stage's for still frames, where temporal reuse is aligned),
//! their descriptor sets, the scene buffers, the reservoir slots and the atlases of the
//! density and its derived levels for the current and the previous frame.

use anyhow::Result;
use nimbus_gpu::{
    vk, BindingDesc, Buffer, BufferDesc, ComputePipeline, Context, DescriptorSet, DescriptorWrite,
    GpuObjects, Handle, Image, ImageDesc, SamplerDesc,
};

use super::schedule::Stage;
use super::volumes::{AtlasSizes, DerivedVolume};
use crate::passes::{
    compute_pipelines, image_3d, upload_env_map, upload_params, upload_records, PipelineJob,
    StaticGrids, Targets,
};
use crate::shader_data::sparse::{
    atlas_dims, slot_major_bytes, upload_atlas, upload_march_quads, upload_slot_major, TexelFormat,
};
use crate::shader_data::{
    bindings, non_empty, BaselineUniformsGpu, BoxMediumGpu, FrameUniforms, GpuGrid, MeshBuffers,
    RestirPush, RestirUniformsGpu, ShapeGpu,
};
use crate::shaders;

/// Handles of every object in the pass's [`GpuObjects`] bag.
pub struct Resources {
    /// One pipeline and one descriptor set per [`Stage`], in `Stage::ALL` order.
    pub pipelines: [Handle<ComputePipeline>; 4],
    pub sets: [Handle<DescriptorSet>; 4],
    /// The temporal stage's pipeline for still frames (`SC_TEMPORAL_STILL`) and its set,
    /// where [`Inputs::still_temporal`] asks for one.
    pub temporal_still: Option<(Handle<ComputePipeline>, Handle<DescriptorSet>)>,
    /// The analytic lights of this frame, then those of the previous frame.
    pub lights: Handle<Buffer>,
    pub base_uniforms: Handle<Buffer>,
    pub restir_uniforms: Handle<Buffer>,
    pub prev_frame: Handle<Buffer>,
    /// Every grid's indirection section ([`super::indirection::Sections`] says where each starts).
    pub bricks: Handle<Buffer>,
    /// Super-voxel records of this frame's density slots.
    pub super_voxels: Handle<Buffer>,
    /// Atlases: this frame's density, its piecewise-constant levels, its ray-march mips
    /// for reuse and NEE.
    pub density: Handle<Image>,
    pub pc: Handle<Image>,
    pub march_reuse: Handle<Image>,
    pub march_nee: Handle<Image>,
    /// The previous frame's density and reuse mip (the temporal stage evaluates the
    /// previous reservoirs with them); the same images as this frame's when the density
    /// does not change.
    pub density_prev: Handle<Image>,
    pub march_reuse_prev: Handle<Image>,
    /// The piecewise-constant levels slot-major, where tracking reads them from a buffer
    /// (`Inputs::pc_buffer`); else one texel.
    pub pc_texels: Handle<Buffer>,
    /// This frame's density as slots of quads, where the passes read it from a buffer
    /// (`Inputs::density_buffer`); else one quad.
    pub density_texels: Handle<Buffer>,
    /// The ray-march mips as slots of quads (where `density_texels` is a buffer; else
    /// one quad), each level from its first slot in `march_quads_at`.
    pub march_quads: Handle<Buffer>,
    pub march_quads_at: MarchQuads,
}

/// Where each ray-march mip's slots start in the buffer of march quads (`GridLevel`'s
/// `quad_base`, restir/transmittance.glsl), each section its atlas's slots: this frame's
/// reuse mip, the previous frame's (where the density changes; else the same section),
/// the NEE mip.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MarchQuads {
    pub reuse: u64,
    pub reuse_prev: u64,
    pub nee: u64,
    /// Slots in all.
    pub slots: u64,
}

impl MarchQuads {
    pub fn of(sizes: AtlasSizes, animated: bool) -> MarchQuads {
        let reuse = slot_count(sizes.march_reuse) as u64;
        let nee = slot_count(sizes.march_nee) as u64;
        let prev = if animated { reuse } else { 0 };
        MarchQuads {
            reuse: 0,
            reuse_prev: prev,
            nee: reuse + prev,
            slots: reuse + prev + nee,
        }
    }

    /// The buffer's bytes (at least one quad).
    pub fn bytes(&self) -> u64 {
        (self.slots * crate::shader_data::sparse::MARCH_QUAD_SLOT_BYTES).max(16)
    }
}

/// What [`Resources::create`] uploads.
pub struct Inputs<'a> {
    pub grid: &'a GpuGrid,
    /// The scene's shapes and its meshes' BVHs (surface vertices).
    pub shapes: &'a [ShapeGpu],
    pub meshes: &'a MeshBuffers,
    /// The box and convex media beside the grid, and the convex media's planes.
    pub boxes: &'a [BoxMediumGpu],
    pub planes: &'a [[f32; 4]],
    pub first: &'a DerivedVolume,
    pub base_uniforms: &'a BaselineUniformsGpu,
    /// The velocity grid as dense RGBA16F texels over the medium's world box.
    pub velocity: Option<&'a ([u32; 3], Vec<u16>)>,
    pub uniforms: &'a RestirUniformsGpu,
    pub indirection: &'a [u32],
    pub reservoir_bytes: u64,
    pub march_format: TexelFormat,
    pub sizes: AtlasSizes,
    /// Density frames change: the previous frame gets atlases of its own.
    pub animated: bool,
    /// Regular tracking reads the piecewise-constant levels from a storage buffer
    /// (SC_PC_BUFFER, [`pc_in_buffer`]).
    pub pc_buffer: bool,
    /// The passes read this frame's density from a storage buffer of quads
    /// (SC_DENSITY_BUFFER, [`density_in_buffer`]).
    pub density_buffer: bool,
    /// Where each march mip starts in the buffer of quads (the uniforms' `quad_base`s).
    pub march_quads: MarchQuads,
    /// The plan runs temporal reuse with the aligned reprojection, whose still frames
    /// (camera, lights and density as in the previous frame) the pass dispatches with
    /// [`Resources::temporal_still`].
    pub still_temporal: bool,
}

/// Whether regular tracking reads the piecewise-constant levels from a slot-major
/// storage buffer the size of their atlas instead of the atlas image (`[integrator.restir]
/// pc_fetch`, [`crate::passes::volume_in_buffer`]).
pub fn pc_in_buffer(
    info: &nimbus_gpu::DeviceInfo,
    fetch: nimbus_scene::DensityFetch,
    pc_slots: [u32; 3],
    source: &std::path::Path,
) -> Result<bool> {
    crate::passes::volume_in_buffer(
        info,
        fetch,
        slot_major_bytes(slot_count(pc_slots) as u64),
        source,
        "[integrator.restir] field `pc_fetch`",
        "the piecewise-constant levels",
    )
}

/// Whether the passes read this frame's full-resolution density from a storage buffer of
/// its slots' quads (the baseline's layout: [`crate::passes::upload_density_quads`])
/// instead of its atlas image, and the ray marches their mips from one buffer of quads
/// ([`MarchQuads`]) instead of their linearly filtered atlases (`[integrator.restir]
/// density_fetch`, [`crate::passes::volume_in_buffer`], judged by the larger buffer): on
/// lavapipe a trilinear lookup from a buffer is two 16-byte loads, from an atlas eight
/// texelFetch calls or one filtered textureLod. The previous frame's density (read where
/// it differs) stays in its atlas.
pub fn density_in_buffer(
    info: &nimbus_gpu::DeviceInfo,
    fetch: nimbus_scene::DensityFetch,
    sizes: AtlasSizes,
    march: MarchQuads,
    source: &std::path::Path,
) -> Result<bool> {
    let slots = slot_count(sizes.density) as u64;
    let density = crate::shader_data::sparse::density_buffer_bytes(slots);
    let (bytes, what) = if density >= march.bytes() {
        (density, format!("the density's {slots} slots"))
    } else {
        (
            march.bytes(),
            format!("the ray-march mips' {} slots", march.slots),
        )
    };
    crate::passes::volume_in_buffer(
        info,
        fetch,
        bytes,
        source,
        "[integrator.restir] field `density_fetch`",
        &what,
    )
}

/// The descriptor layout all four stages share.
fn layout() -> Vec<BindingDesc> {
    let mut layout = Vec::from(Targets::layout());
    layout.extend([
        BindingDesc::storage_buffer(bindings::PREV_FRAME_UNIFORMS),
        BindingDesc::storage_buffer(bindings::LIGHTS),
        BindingDesc::storage_buffer(bindings::GOBO_PLANES),
        BindingDesc::storage_buffer(bindings::BASELINE_UNIFORMS),
        BindingDesc::storage_buffer(bindings::RESTIR_UNIFORMS),
        BindingDesc::sampled_image(bindings::GRID_DENSITY),
        BindingDesc::storage_buffer(bindings::GRID_DENSITY_TEXELS),
        BindingDesc::sampled_image(bindings::GRID_DENSITY_PREV),
        BindingDesc::sampled_image(bindings::GRID_EMISSION),
        BindingDesc::sampled_image(bindings::GRID_TEMPERATURE),
        BindingDesc::storage_buffer(bindings::BLACKBODY),
        BindingDesc::sampled_image(bindings::GRID_ALBEDO),
        BindingDesc::sampled_image(bindings::MARCH_REUSE),
        BindingDesc::sampled_image(bindings::MARCH_REUSE_PREV),
        BindingDesc::sampled_image(bindings::MARCH_NEE),
        BindingDesc::sampled_image(bindings::VELOCITY),
        BindingDesc::sampled_image(bindings::PC_GRID),
        BindingDesc::storage_buffer(bindings::PC_TEXELS),
        BindingDesc::storage_buffer(bindings::MARCH_QUADS),
        BindingDesc::storage_buffer(bindings::SUPER_VOXELS),
        BindingDesc::storage_buffer(bindings::GRID_BRICKS),
        BindingDesc::storage_buffer(bindings::RESERVOIRS),
        BindingDesc::storage_buffer(bindings::ENV_TEXELS),
        BindingDesc::storage_buffer(bindings::ENV_CDF),
        BindingDesc::storage_buffer(bindings::SHAPES),
        BindingDesc::storage_buffer(bindings::BVH_NODES),
        BindingDesc::storage_buffer(bindings::MESH_TRIANGLES),
        BindingDesc::storage_buffer(bindings::BOX_MEDIA),
        BindingDesc::storage_buffer(bindings::MEDIUM_PLANES),
        BindingDesc::storage_buffer(bindings::EMITTERS),
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

/// The specialization of the temporal stage's still pipeline: the plan's, with
/// `SC_TEMPORAL_STILL` set.
fn still_specialization(
    specialization: &[(u32, nimbus_gpu::SpecValue)],
) -> Vec<(u32, nimbus_gpu::SpecValue)> {
    let still = crate::shader_data::features::SC_ID_TEMPORAL_STILL;
    specialization
        .iter()
        .map(|&(id, value)| match id == still {
            true => (id, nimbus_gpu::SpecValue::Bool(true)),
            false => (id, value),
        })
        .collect()
}

/// Whether a plan's pass builds the temporal stage's still pipeline: temporal reuse with
/// the aligned reprojection (the paper's reprojection keeps its own walk on still frames).
pub fn builds_still_temporal(plan: &crate::plan::RestirPlan) -> bool {
    plan.builds_still_temporal()
}

/// The stages' pipelines as the pass creates them (without a device; see
/// [`crate::passes::PipelineContract`]): the four stages, and the temporal stage's still
/// pipeline where the plan builds it.
pub fn pipeline_contracts(plan: &crate::plan::RestirPlan) -> Vec<crate::passes::PipelineContract> {
    let specialization = super::specialization(plan, false, false, false, false);
    let contract = |name: &str, stage: Stage, specialization: &[(u32, nimbus_gpu::SpecValue)]| {
        crate::passes::PipelineContract::of::<RestirPush>(
            name,
            spirv_of(stage),
            layout(),
            specialization,
        )
    };
    let mut contracts: Vec<_> = Stage::ALL
        .into_iter()
        .map(|stage| contract(&format!("restir {}", stage.name()), stage, &specialization))
        .collect();
    if builds_still_temporal(plan) {
        contracts.push(contract(
            "restir temporal (still)",
            Stage::Temporal,
            &still_specialization(&specialization),
        ));
    }
    contracts
}

/// A 3D image for an atlas of `slots` per axis in `format`.
fn atlas(
    ctx: &Context,
    o: &mut GpuObjects,
    slots: [u32; 3],
    format: TexelFormat,
    name: &str,
) -> Result<Handle<Image>> {
    let [w, h, d] = atlas_dims(slots);
    Ok(o.add(ctx.create_image(&ImageDesc::sampled_3d(w, h, d, format.vk()), name)?))
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
            shapes,
            meshes,
            boxes,
            planes: medium_planes,
            first,
            base_uniforms,
            velocity,
            uniforms,
            indirection,
            reservoir_bytes,
            march_format,
            sizes,
            animated,
            pc_buffer,
            density_buffer,
            march_quads: march_quads_at,
            still_temporal,
        } = *inputs;
        let layout = layout();
        // The four passes' pipelines are built at once (about 4 s on lavapipe one after
        // the other).
        let still_specialization = still_specialization(specialization);
        let mut jobs: Vec<PipelineJob<'_>> = Stage::ALL
            .into_iter()
            .enumerate()
            .map(|(slot, stage)| PipelineJob {
                spirv: spirv_of(stage),
                specialization,
                film: targets.film_spec(slot as u32),
                name: format!("restir {}", stage.name()),
            })
            .collect();
        if still_temporal {
            // Counted in the temporal stage's slot.
            jobs.push(PipelineJob {
                spirv: spirv_of(Stage::Temporal),
                specialization: &still_specialization,
                film: targets.film_spec(Stage::Temporal as u32),
                name: "restir temporal (still)".to_string(),
            });
        }
        let pipelines = compute_pipelines::<RestirPush>(ctx, o, &layout, &jobs)?;

        // Scene buffers. The light buffer holds this frame's and the previous frame's
        // records (the same until lights animate).
        let light_records = non_empty(&[grid.lights.clone(), grid.lights.clone()].concat());
        let lights = upload_records(ctx, o, &light_records, "restir lights")?;
        // Both sets index the same half-planes (gobo polygons do not animate); without
        // gobos the (compiled-out) planes are one zeroed record.
        let gobo_planes = upload_records(ctx, o, &grid.gobo_planes, "gobo planes")?;
        let shapes = upload_records(ctx, o, &non_empty(shapes), "shapes")?;
        let bvh_nodes = upload_records(ctx, o, &meshes.nodes, "mesh BVH nodes")?;
        let mesh_triangles = upload_records(ctx, o, &meshes.triangles, "mesh triangles")?;
        let boxes = upload_records(ctx, o, &non_empty(boxes), "box media")?;
        // The convex media's planes (one zeroed record without any: compiled out).
        let planes = upload_records(ctx, o, &non_empty(medium_planes), "medium planes")?;
        let records = &first.grids.super_voxels;
        let mut padded = records.clone();
        padded.resize(padded.len().max(slot_count(sizes.density)), [0.0; 4]);
        let super_voxels = upload_records(ctx, o, &padded, "super-voxels")?;
        let bricks = upload_records(ctx, o, indirection, "grid bricks")?;
        let (env_texels, env_cdf) = upload_env_map(ctx, o, grid.env_map.as_ref())?;
        // The emitting shapes' primitives (one zeroed record without area lights, when
        // lights.glsl compiles the table out).
        let emitters = upload_records(ctx, o, &non_empty(&grid.emitters.records), "emitters")?;
        let base_uniforms = upload_params(ctx, o, base_uniforms, "grid uniforms")?;
        let restir_uniforms = upload_params(ctx, o, uniforms, "restir uniforms")?;
        let prev_frame = o.add(ctx.create_buffer(
            &BufferDesc::gpu_only(
                std::mem::size_of::<FrameUniforms>() as u64,
                vk::BufferUsageFlags::STORAGE_BUFFER,
            ),
            "previous frame uniforms",
        )?);
        let reservoirs = o.add(ctx.create_buffer(
            &BufferDesc::gpu_only(reservoir_bytes, vk::BufferUsageFlags::STORAGE_BUFFER),
            "reservoirs",
        )?);
        ctx.fill_buffer(&o[reservoirs], 0)?;

        // Atlases, each sized for the largest frame.
        let g = &first.grids;
        let r32 = TexelFormat::R32;
        let density = atlas(ctx, o, sizes.density, r32, "density")?;
        upload_atlas(
            ctx,
            &o[density],
            sizes.density,
            &[(&first.density_layout, &g.density, 1.0)],
            r32,
        )?;
        let density_texels = if density_buffer {
            let b = crate::passes::density_quads_buffer(ctx, o, slot_count(sizes.density) as u64)?;
            crate::passes::upload_density_quads(ctx, &o[b], &first.density_layout, &g.density)?;
            b
        } else {
            upload_records(ctx, o, &[[0f32; 4]], "grid density texels (unused)")?
        };
        let scale = grid.uniforms.grid.density_scale;
        // Where tracking reads the levels' buffer (SC_PC_BUFFER), nothing reads their
        // atlas: a one-slot placeholder.
        let pc = if pc_buffer {
            atlas(ctx, o, [1, 1, 1], r32, "piecewise-constant levels, unused")?
        } else {
            let pc = atlas(ctx, o, sizes.pc, r32, "piecewise-constant levels")?;
            upload_atlas(
                ctx,
                &o[pc],
                sizes.pc,
                &[
                    (&first.pc_primary_layout, &g.pc_primary, scale),
                    (&first.pc_indirect_layout, &g.pc_indirect, scale),
                ],
                r32,
            )?;
            pc
        };
        let pc_texels = o.add(ctx.create_buffer(
            &BufferDesc::gpu_only(
                if pc_buffer {
                    slot_major_bytes(slot_count(sizes.pc) as u64)
                } else {
                    4
                },
                vk::BufferUsageFlags::STORAGE_BUFFER,
            ),
            "piecewise-constant levels (slot-major)",
        )?);
        if pc_buffer {
            ctx.fill_buffer(&o[pc_texels], 0)?;
            upload_slot_major(
                ctx,
                &o[pc_texels],
                &[
                    (&first.pc_primary_layout, &g.pc_primary, scale),
                    (&first.pc_indirect_layout, &g.pc_indirect, scale),
                ],
            )?;
        }
        // The marches' atlases, or where they read the buffer of quads below
        // (SC_MARCH_BUFFER) one-slot placeholders: nothing reads them then.
        let march_atlas = |o: &mut GpuObjects,
                           slots: [u32; 3],
                           layout: &crate::shader_data::sparse::SparseLayout,
                           level: &nimbus_scene::BrickGrid,
                           name: &str|
         -> Result<Handle<Image>> {
            if density_buffer {
                return atlas(ctx, o, [1, 1, 1], march_format, &format!("{name}, unused"));
            }
            let a = atlas(ctx, o, slots, march_format, name)?;
            upload_atlas(ctx, &o[a], slots, &[(layout, level, 1.0)], march_format)?;
            Ok(a)
        };
        let march_reuse = march_atlas(
            o,
            sizes.march_reuse,
            &first.march_reuse_layout,
            &g.march_reuse,
            "march (reuse)",
        )?;
        let march_nee = march_atlas(
            o,
            sizes.march_nee,
            &first.march_nee_layout,
            &g.march_nee,
            "march (NEE)",
        )?;
        // The march mips' quads: the previous frame's section starts as a copy of the
        // first frame's.
        let march_quads = if density_buffer {
            let b = o.add(ctx.create_buffer(
                &BufferDesc::gpu_only(march_quads_at.bytes(), vk::BufferUsageFlags::STORAGE_BUFFER),
                "ray-march mips (quads)",
            )?);
            ctx.fill_buffer(&o[b], 0)?;
            let mut sections = vec![
                (
                    march_quads_at.reuse,
                    &first.march_reuse_layout,
                    &g.march_reuse,
                ),
                (march_quads_at.nee, &first.march_nee_layout, &g.march_nee),
            ];
            if animated {
                sections.push((
                    march_quads_at.reuse_prev,
                    &first.march_reuse_layout,
                    &g.march_reuse,
                ));
            }
            for (base, layout, level) in sections {
                upload_march_quads(ctx, &o[b], base, layout, level, march_format)?;
            }
            b
        } else {
            upload_records(ctx, o, &[[0f32; 4]], "ray-march mips (quads, unused)")?
        };
        // The previous frame starts as a copy of the first.
        let (density_prev, march_reuse_prev) = if animated {
            let d = atlas(ctx, o, sizes.density, r32, "previous density")?;
            upload_atlas(
                ctx,
                &o[d],
                sizes.density,
                &[(&first.density_layout, &g.density, 1.0)],
                r32,
            )?;
            let m = march_atlas(
                o,
                sizes.march_reuse,
                &first.march_reuse_layout,
                &g.march_reuse,
                "previous march (reuse)",
            )?;
            (d, m)
        } else {
            (density, march_reuse)
        };
        let StaticGrids {
            emission,
            temperature,
            blackbody,
            albedo,
        } = StaticGrids::upload(ctx, o, grid, density, super_voxels)?;
        let rgba16 = vk::Format::R16G16B16A16_SFLOAT;
        let velocity = match velocity {
            Some((dims, texels)) => image_3d(
                ctx,
                o,
                *dims,
                rgba16,
                bytemuck::cast_slice(texels),
                "velocity",
            )?,
            None => image_3d(ctx, o, [1, 1, 1], rgba16, &[0u8; 8], "no velocity")?,
        };
        let nearest = ctx.create_sampler(&SamplerDesc::nearest(), "restir nearest")?;
        o.add(nearest);
        let linear = ctx.create_sampler(&SamplerDesc::linear(), "restir linear")?;
        o.add(linear);

        let mut sets = Vec::with_capacity(pipelines.len());
        for (job, pipeline) in jobs.iter().zip(&pipelines) {
            let set = {
                let buffer = |binding, handle: Handle<Buffer>| DescriptorWrite::StorageBuffer {
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
                    buffer(bindings::PREV_FRAME_UNIFORMS, prev_frame),
                    buffer(bindings::LIGHTS, lights),
                    buffer(bindings::GOBO_PLANES, gobo_planes),
                    buffer(bindings::BASELINE_UNIFORMS, base_uniforms),
                    buffer(bindings::RESTIR_UNIFORMS, restir_uniforms),
                    image(bindings::GRID_DENSITY, density, nearest),
                    buffer(bindings::GRID_DENSITY_TEXELS, density_texels),
                    image(bindings::GRID_DENSITY_PREV, density_prev, nearest),
                    image(bindings::GRID_EMISSION, emission, nearest),
                    image(bindings::GRID_TEMPERATURE, temperature, nearest),
                    buffer(bindings::BLACKBODY, blackbody),
                    image(bindings::GRID_ALBEDO, albedo, nearest),
                    image(bindings::MARCH_REUSE, march_reuse, linear),
                    image(bindings::MARCH_REUSE_PREV, march_reuse_prev, linear),
                    image(bindings::MARCH_NEE, march_nee, linear),
                    image(bindings::VELOCITY, velocity, linear),
                    image(bindings::PC_GRID, pc, nearest),
                    buffer(bindings::PC_TEXELS, pc_texels),
                    buffer(bindings::MARCH_QUADS, march_quads),
                    buffer(bindings::SUPER_VOXELS, super_voxels),
                    buffer(bindings::GRID_BRICKS, bricks),
                    buffer(bindings::RESERVOIRS, reservoirs),
                    buffer(bindings::ENV_TEXELS, env_texels),
                    buffer(bindings::ENV_CDF, env_cdf),
                    buffer(bindings::SHAPES, shapes),
                    buffer(bindings::BVH_NODES, bvh_nodes),
                    buffer(bindings::MESH_TRIANGLES, mesh_triangles),
                    buffer(bindings::BOX_MEDIA, boxes),
                    buffer(bindings::MEDIUM_PLANES, planes),
                    buffer(bindings::EMITTERS, emitters),
                ]);
                ctx.create_descriptor_set(&o[*pipeline], &writes, &format!("{} set", job.name))?
            };
            sets.push(o.add(set));
        }
        Ok(Resources {
            pipelines: [pipelines[0], pipelines[1], pipelines[2], pipelines[3]],
            temporal_still: pipelines.get(4).copied().zip(sets.get(4).copied()),
            sets: [sets[0], sets[1], sets[2], sets[3]],
            lights,
            base_uniforms,
            restir_uniforms,
            prev_frame,
            bricks,
            super_voxels,
            density,
            pc,
            march_reuse,
            march_nee,
            density_prev,
            march_reuse_prev,
            pc_texels,
            density_texels,
            march_quads,
            march_quads_at,
        })
    }
}

/// Slots of an atlas of `slots` per axis.
pub fn slot_count(slots: [u32; 3]) -> usize {
    slots.iter().map(|&s| s as usize).product()
}
