//! The baseline path tracer for grid media (`shaders/baseline/pathtrace.comp`): the
//! equal-time reference of Volumetric ReSTIR, with decomposition tracking and residual
//! ratio tracking on 8x super-voxels.

use anyhow::Result;
use nimbus_gpu::{
    vk, BindingDesc, Buffer, Context, DescriptorWrite, GpuObjects, Handle, Profiler, SamplerDesc,
    SpecValue,
};
use nimbus_scene::Scene;

use super::{
    atlas_image, compute_pipeline, upload_env_map, upload_params, upload_records, FrameConstants,
    ImagePass, Pass, StaticGrids, Targets,
};
use crate::plan::BaselinePlan;
use crate::shader_data::features::*;
use crate::shader_data::scene::{medium_records, MediumRecords};
use crate::shader_data::sparse::TexelFormat;
use crate::shader_data::{
    bindings, non_empty, shape_records, BaselineUniformsGpu, FrameUniforms, GpuGrid, LightGpu,
    LightSet, MeshBuffers, PassPush, RecordCounts, LIGHT_DIRECTIONAL, LIGHT_POINT,
};
use crate::shaders;

/// The specialization constants of `pathtrace.comp` for a plan; `two_level`: some
/// brick indirection section of the grid is two-level.
pub fn specialization(
    plan: &BaselinePlan,
    exact_spans: bool,
    two_level: bool,
    density_buffer: bool,
) -> [(u32, SpecValue); 19] {
    [
        (
            SC_ID_HAS_SPHERE_LIGHTS,
            SpecValue::Bool(plan.has_sphere_lights),
        ),
        (SC_ID_SKY_ALONG_PATH, SpecValue::Bool(plan.sky_along_path)),
        (SC_ID_DENSITY_BUFFER, SpecValue::Bool(density_buffer)),
        (SC_ID_EXACT_SPANS, SpecValue::Bool(exact_spans)),
        (SC_ID_TWO_LEVEL_BRICKS, SpecValue::Bool(two_level)),
        (SC_ID_HAS_AREA_LIGHTS, SpecValue::Bool(plan.has_area_lights)),
        (SC_ID_HAS_GOBOS, SpecValue::Bool(plan.has_gobos)),
        (SC_ID_HAS_MESHES, SpecValue::Bool(plan.has_meshes)),
        (SC_ID_HAS_ENV_MAP, SpecValue::Bool(plan.has_env_map)),
        (SC_ID_HAS_MEDIA, SpecValue::Bool(plan.has_boxes)),
        (SC_ID_HAS_SHAPES, SpecValue::Bool(plan.has_shapes)),
        (SC_ID_HAS_ENV, SpecValue::Bool(plan.has_env)),
        (SC_ID_MAX_BOUNCES, SpecValue::U32(plan.max_bounces)),
        (SC_ID_PIXEL_JITTER, SpecValue::Bool(plan.pixel_jitter)),
        (SC_ID_HAS_EMISSION, SpecValue::Bool(plan.has_emission)),
        (SC_ID_HAS_CONVEX, SpecValue::Bool(plan.has_convex)),
        (SC_ID_HAS_BLACKBODY, SpecValue::Bool(plan.has_blackbody)),
        (SC_ID_HAS_ALBEDO_GRID, SpecValue::Bool(plan.has_albedo_grid)),
        (SC_ID_NEE_SPLIT, SpecValue::Bool(plan.nee_split)),
    ]
}

/// The descriptor layout of `pathtrace.comp`.
fn layout() -> Vec<BindingDesc> {
    let mut layout = Vec::from(Targets::layout());
    layout.extend([
        BindingDesc::storage_buffer(bindings::SHAPES),
        BindingDesc::storage_buffer(bindings::LIGHTS),
        BindingDesc::storage_buffer(bindings::GOBO_PLANES),
        BindingDesc::storage_buffer(bindings::BASELINE_UNIFORMS),
        BindingDesc::sampled_image(bindings::GRID_DENSITY),
        BindingDesc::storage_buffer(bindings::GRID_DENSITY_TEXELS),
        BindingDesc::storage_buffer(bindings::SUPER_VOXELS),
        BindingDesc::sampled_image(bindings::GRID_EMISSION),
        BindingDesc::sampled_image(bindings::GRID_TEMPERATURE),
        BindingDesc::storage_buffer(bindings::BLACKBODY),
        BindingDesc::sampled_image(bindings::GRID_ALBEDO),
        BindingDesc::storage_buffer(bindings::BOX_MEDIA),
        BindingDesc::storage_buffer(bindings::MEDIUM_PLANES),
        BindingDesc::storage_buffer(bindings::ENV_TEXELS),
        BindingDesc::storage_buffer(bindings::ENV_CDF),
        BindingDesc::storage_buffer(bindings::GRID_BRICKS),
        BindingDesc::storage_buffer(bindings::BVH_NODES),
        BindingDesc::storage_buffer(bindings::MESH_TRIANGLES),
        BindingDesc::storage_buffer(bindings::EMITTERS),
    ]);
    layout
}

/// The pipeline of `plan` as the pass creates it (without a device; see
/// [`super::PipelineContract`]).
pub fn pipeline_contract(plan: &BaselinePlan) -> super::PipelineContract {
    super::PipelineContract::of::<PassPush>(
        "baseline path tracer",
        shaders::BASELINE_PATHTRACE,
        layout(),
        &specialization(plan, false, false, false),
    )
}

/// The baseline pass: one image pass, and what it needs to follow animated lights.
pub struct BaselinePass {
    image: ImagePass,
    /// The analytic lights' records and the grid uniforms (whose `env_select` follows the
    /// lights' powers), re-uploaded per scene frame when the lights are animated.
    lights: Handle<Buffer>,
    uniforms: Handle<Buffer>,
    base: BaselineUniformsGpu,
    light_radius: f32,
    env_map_luminance: Option<f32>,
    area_power: f64,
    /// The scene frame whose lights are uploaded (`None`: the scene's un-keyed lights).
    lights_frame: Option<u32>,
    /// The AOVs of the render (the light records' groups).
    aov: crate::plan::AovPlan,
}

/// Creates the pass of `plan`.
pub fn create(
    ctx: &Context,
    plan: &BaselinePlan,
    scene: &Scene,
    grid: GpuGrid,
    targets: &Targets,
) -> Result<BaselinePass> {
    let shapes = shape_records(scene);
    let meshes = MeshBuffers::build(scene);
    let MediumRecords {
        media: boxes,
        planes: medium_planes,
    } = medium_records(scene);
    let constants = FrameConstants {
        env_radiance: grid.env_radiance,
        env_size: grid.uniforms.env_size,
        counts: RecordCounts {
            box_media: boxes.len() as u32,
            shapes: shapes.len() as u32,
            lights: grid.lights.len() as u32,
            ray_samples: 0,
        },
    };
    let density_buffer = density_in_buffer(ctx, plan, &grid, scene)?;
    let (objects, (pipeline, set, lights_buffer, uniforms_buffer)) = GpuObjects::build(ctx, |o| {
        let layout = layout();
        let pipeline = compute_pipeline::<PassPush>(
            ctx,
            o,
            shaders::BASELINE_PATHTRACE,
            &layout,
            &specialization(
                plan,
                grid.needs_exact_spans(),
                grid.two_level_bricks()?,
                density_buffer,
            ),
            targets.film_spec(0),
            "baseline path tracer",
        )?;
        let shapes = upload_records(ctx, o, &non_empty(&shapes), "shapes")?;
        let bvh_nodes = upload_records(ctx, o, &meshes.nodes, "mesh BVH nodes")?;
        let mesh_triangles = upload_records(ctx, o, &meshes.triangles, "mesh triangles")?;
        let mut light_records = grid.lights.clone();
        targets.aov.assign_groups(scene, &mut light_records);
        let lights = upload_records(ctx, o, &non_empty(&light_records), "lights")?;
        // Without gobos the (compiled-out) planes are one zeroed record.
        let gobo_planes = upload_records(ctx, o, &grid.gobo_planes, "gobo planes")?;
        // Without area lights the (compiled-out) table is one zeroed record.
        let emitters = upload_records(ctx, o, &non_empty(&grid.emitters.records), "emitters")?;
        let super_voxels = upload_records(ctx, o, &grid.super_voxels, "super-voxels")?;
        let boxes = upload_records(ctx, o, &non_empty(&boxes), "box media")?;
        // The convex media's planes (one zeroed record without any: compiled out).
        let planes = upload_records(ctx, o, &non_empty(&medium_planes), "medium planes")?;
        let (env_texels, env_tables) = upload_env_map(ctx, o, grid.env_map.as_ref())?;
        let uniforms = upload_params(ctx, o, &grid.uniforms, "baseline uniforms")?;
        let bricks = upload_records(ctx, o, &grid.indirection()?, "grid bricks")?;
        let (density, density_texels) = if density_buffer {
            let layout = &grid.density_layout;
            let slots = layout.first_slot as u64 + layout.bricks.len() as u64;
            let buffer = super::density_quads_buffer(ctx, o, slots)?;
            super::upload_density_quads(ctx, &o[buffer], layout, &grid.density)?;
            let image = placeholder_atlas(ctx, o)?;
            (image, buffer)
        } else {
            let image = atlas_image(
                ctx,
                o,
                &grid.density_layout,
                &grid.density,
                1.0,
                TexelFormat::R32,
                "grid density",
            )?;
            (
                image,
                upload_records(ctx, o, &[0f32], "grid density texels (unused)")?,
            )
        };
        let StaticGrids {
            emission,
            temperature,
            blackbody,
            albedo,
        } = StaticGrids::upload(ctx, o, &grid, density, super_voxels)?;
        let sampler = ctx.create_sampler(&SamplerDesc::nearest(), "grid density")?;
        o.add(sampler);

        let mut writes = Vec::from(targets.writes());
        writes.extend([
            DescriptorWrite::StorageBuffer {
                binding: bindings::SHAPES,
                buffer: &o[shapes],
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::BVH_NODES,
                buffer: &o[bvh_nodes],
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::MESH_TRIANGLES,
                buffer: &o[mesh_triangles],
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::LIGHTS,
                buffer: &o[lights],
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::GOBO_PLANES,
                buffer: &o[gobo_planes],
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::EMITTERS,
                buffer: &o[emitters],
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::SUPER_VOXELS,
                buffer: &o[super_voxels],
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::BASELINE_UNIFORMS,
                buffer: &o[uniforms],
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::BOX_MEDIA,
                buffer: &o[boxes],
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::MEDIUM_PLANES,
                buffer: &o[planes],
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::ENV_TEXELS,
                buffer: &o[env_texels],
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::ENV_CDF,
                buffer: &o[env_tables],
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::GRID_BRICKS,
                buffer: &o[bricks],
            },
            DescriptorWrite::SampledImage {
                binding: bindings::GRID_DENSITY,
                image: &o[density],
                sampler,
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::GRID_DENSITY_TEXELS,
                buffer: &o[density_texels],
            },
            DescriptorWrite::SampledImage {
                binding: bindings::GRID_EMISSION,
                image: &o[emission],
                sampler,
            },
            DescriptorWrite::SampledImage {
                binding: bindings::GRID_TEMPERATURE,
                image: &o[temperature],
                sampler,
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::BLACKBODY,
                buffer: &o[blackbody],
            },
            DescriptorWrite::SampledImage {
                binding: bindings::GRID_ALBEDO,
                image: &o[albedo],
                sampler,
            },
        ]);
        let set = ctx.create_descriptor_set(&o[pipeline], &writes, "baseline set")?;
        Ok((pipeline, o.add(set), lights, uniforms))
    })?;
    Ok(BaselinePass {
        image: ImagePass::new(
            ctx,
            "baseline",
            objects,
            pipeline,
            set,
            constants,
            sample_cost(plan, &grid, scene),
        ),
        lights: lights_buffer,
        uniforms: uniforms_buffer,
        base: grid.uniforms,
        light_radius: grid.light_radius,
        env_map_luminance: grid.env_map_luminance,
        area_power: grid.emitters.total_power,
        lights_frame: None,
        aov: targets.aov.clone(),
    })
}

impl Pass for BaselinePass {
    fn label(&self) -> &'static str {
        self.image.label()
    }

    fn frame_uniforms(&self, scene: &Scene, frame: u32) -> FrameUniforms {
        self.image.frame_uniforms(scene, frame)
    }

    /// Light keyframes: the lights of `scene_frame` (their records and the environment's
    /// selection probability), uploaded when they differ from the ones the pass holds.
    fn prepare(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        scene_frame: u32,
        _previous_frame: u32,
    ) -> Result<()> {
        if !super::lights_change(scene, self.lights_frame, scene_frame) {
            return Ok(());
        }
        let set = LightSet::build(
            &scene.lights_at(scene_frame),
            self.light_radius,
            self.env_map_luminance,
            self.area_power,
        );
        let mut records: Vec<LightGpu> = non_empty(&set.lights);
        self.aov.assign_groups(scene, &mut records);
        let objects = &self.image.objects;
        ctx.upload_buffer(&objects[self.lights], 0, bytemuck::cast_slice(&records))?;
        let base = BaselineUniformsGpu {
            env_select: set.env_select,
            ..self.base
        };
        ctx.upload_buffer(&objects[self.uniforms], 0, bytemuck::bytes_of(&base))?;
        self.lights_frame = Some(scene_frame);
        Ok(())
    }

    fn record(
        &mut self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        uniforms: &FrameUniforms,
        dispatch_index: u32,
        profiler: Option<&mut Profiler>,
    ) -> Result<()> {
        self.image
            .record(ctx, cmd, uniforms, dispatch_index, profiler)
    }

    fn device_bytes(&self) -> u64 {
        self.image.device_bytes()
    }

    fn destroy(self: Box<Self>, ctx: &Context) {
        Box::new(self.image).destroy(ctx);
    }
}

/// Whether the pass reads the density from a storage buffer of its slots instead of the
/// atlas image (`[integrator.baseline] density_fetch`, [`super::volume_in_buffer`]): on
/// lavapipe a trilinear lookup from it is two 16-byte loads, from the atlas a texelFetch.
fn density_in_buffer(
    ctx: &Context,
    plan: &BaselinePlan,
    grid: &GpuGrid,
    scene: &Scene,
) -> Result<bool> {
    let layout = &grid.density_layout;
    let slots = u64::from(layout.first_slot) + layout.bricks.len() as u64;
    super::volume_in_buffer(
        ctx.info(),
        plan.density_fetch,
        crate::shader_data::sparse::density_buffer_bytes(slots),
        &scene.source,
        "[integrator.baseline] field `density_fetch`",
        &format!("the density's {slots} slots"),
    )
}

/// A 1-texel atlas bound where the density is read from its buffer.
fn placeholder_atlas(ctx: &Context, o: &mut GpuObjects) -> Result<Handle<nimbus_gpu::Image>> {
    super::image_3d(
        ctx,
        o,
        [1, 1, 1],
        vk::Format::R32_SFLOAT,
        &0f32.to_le_bytes(),
        "grid density (read from its buffer)",
    )
}

/// Loop iterations one camera sample may typically run (see
/// [`super::samples_per_dispatch`]): K + 1 segments, each with its shadow rays, each
/// crossing the super-voxel grid (blocks, an exact span of up to `GRID_EXACT_SPAN_STEPS`),
/// looping over the lights and traversing the meshes. Collisions are random; the loop
/// sentinel refuses an image a rare long walk would cut.
fn sample_cost(plan: &BaselinePlan, grid: &GpuGrid, scene: &Scene) -> u32 {
    let blocks: u32 = grid.uniforms.grid.space.brick_dims.iter().sum::<u32>() + 3;
    // A segment's closest-hit ray and each light's shadow ray through the meshes.
    let mesh_rays = (1 + grid.lights.len() as u32) * super::mesh_ray_cost(scene);
    // An area-light sample's binary search in the emitter table.
    let emitter_search = usize::BITS - grid.emitters.len().leading_zeros();
    let segment =
        blocks + GRID_EXACT_SPAN_STEPS + 3 * grid.lights.len() as u32 + mesh_rays + emitter_search;
    // Each vertex's walks: the next segment and its shadow rays (with split NEE one per
    // delta light besides the sampled one).
    let shadow_rays = if plan.nee_split {
        1 + grid
            .lights
            .iter()
            .filter(|l| l.r#type == LIGHT_DIRECTIONAL || l.r#type == LIGHT_POINT)
            .count() as u32
    } else {
        1
    };
    let segments = (1 + shadow_rays) * (plan.max_bounces + 1);
    segment.saturating_mul(segments)
}
