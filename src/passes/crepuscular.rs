//! The crepuscular-ray pass (`shaders/box/crepuscular.comp`): single scattering in
//! homogeneous box media under collimated light, direct lighting of the shapes, the
//! environment's light on both (`shaders/box/environment.glsl`), and the background,
//! accumulated per pixel. With the ME estimator in a scene with shapes, a
//! moment-map stage (`shaders/box/moments.comp`) renders each directional light's
//! moment shadow map once, before the first frame.

use anyhow::{bail, Result};
use glam::Vec3;
use nimbus_gpu::{
    compute_barrier, vk, BindingDesc, Buffer, BufferDesc, ComputePipeline, Context, DescriptorSet,
    DescriptorWrite, GpuObjects, Handle, Profiler, SpecValue,
};
use nimbus_scene::{Scene, Shape};

use super::{
    compute_pipeline, upload_env_map, upload_records, FrameConstants, ImagePass, Pass, Targets,
};
use crate::plan::{estimator_id, moment_levels, moment_texels_per_light, CrepuscularPlan};
use crate::shader_data::features::*;
use crate::shader_data::{
    bindings, non_empty, BoxMediumGpu, FrameUniforms, GpuEnvMap, GpuScene, MeshBuffers,
    MomentFrameGpu, MomentPush, PassPush, RecordCounts,
};
use crate::shaders;

/// The specialization constants of `crepuscular.comp` for a plan.
pub fn specialization(plan: &CrepuscularPlan) -> [(u32, SpecValue); 11] {
    let f = plan.features;
    [
        (SC_ID_HAS_ENV_MAP, SpecValue::Bool(f.has_env_map)),
        (SC_ID_HAS_MESHES, SpecValue::Bool(f.has_meshes)),
        (SC_ID_HAS_SHAPES, SpecValue::Bool(f.has_shapes)),
        (SC_ID_HAS_GOBOS, SpecValue::Bool(f.has_gobos)),
        (SC_ID_HAS_ENV, SpecValue::Bool(f.has_env)),
        (
            SC_ID_ESTIMATOR,
            SpecValue::U32(estimator_id(plan.estimator)),
        ),
        (SC_ID_HAS_MEDIA, SpecValue::Bool(f.has_media)),
        (SC_ID_MAX_BOUNCES, SpecValue::U32(plan.max_bounces)),
        (SC_ID_PIXEL_JITTER, SpecValue::Bool(f.pixel_jitter)),
        (SC_ID_HAS_CONVEX, SpecValue::Bool(f.has_convex)),
        (SC_ID_MAX_PIECES, SpecValue::U32(f.max_pieces)),
    ]
}

/// The storage buffers of `crepuscular.comp` beside the film's, in the order `create`
/// uploads them.
const CREPUSCULAR_BUFFERS: [u32; 11] = [
    bindings::BOX_MEDIA,
    bindings::MEDIUM_PLANES,
    bindings::SHAPES,
    bindings::BVH_NODES,
    bindings::MESH_TRIANGLES,
    bindings::LIGHTS,
    bindings::GOBO_PLANES,
    bindings::MOMENT_MAP,
    bindings::MOMENT_FRAMES,
    bindings::ENV_TEXELS,
    bindings::ENV_CDF,
];

/// The storage buffers of `moments.comp` beside the film's, in the order `create` gives
/// them.
const MOMENT_BUFFERS: [u32; 5] = [
    bindings::SHAPES,
    bindings::BVH_NODES,
    bindings::MESH_TRIANGLES,
    bindings::MOMENT_MAP,
    bindings::MOMENT_FRAMES,
];

/// The specialization constants of `moments.comp` for a plan.
fn moment_specialization(plan: &CrepuscularPlan) -> [(u32, SpecValue); 2] {
    [
        (SC_ID_HAS_SHAPES, SpecValue::Bool(plan.features.has_shapes)),
        (SC_ID_HAS_MESHES, SpecValue::Bool(plan.features.has_meshes)),
    ]
}

/// The layout of a pipeline made by `storage_pipeline` with `buffers`.
fn storage_layout(buffers: &[u32]) -> Vec<BindingDesc> {
    let mut layout = Vec::from(Targets::layout());
    layout.extend(buffers.iter().map(|&b| BindingDesc::storage_buffer(b)));
    layout
}

/// The pass's pipelines for `plan` as it creates them (without a device; see
/// [`super::PipelineContract`]): the moment-map stage's too where the plan runs it.
pub fn pipeline_contracts(plan: &CrepuscularPlan) -> Vec<super::PipelineContract> {
    let mut contracts = vec![super::PipelineContract::of::<PassPush>(
        "crepuscular",
        shaders::BOX_CREPUSCULAR,
        storage_layout(&CREPUSCULAR_BUFFERS),
        &specialization(plan),
    )];
    if plan.needs_moment_maps() {
        contracts.push(super::PipelineContract::of::<MomentPush>(
            "moment maps",
            shaders::BOX_MOMENTS,
            storage_layout(&MOMENT_BUFFERS),
            &moment_specialization(plan),
        ));
    }
    contracts
}

/// Corners of box medium `m` (of its bounding box for a convex medium) in world space.
fn medium_corners(m: &BoxMediumGpu) -> impl Iterator<Item = Vec3> + '_ {
    let axes = m.world_to_local.map(|r| Vec3::new(r[0], r[1], r[2]));
    let h = Vec3::from(m.half_size);
    (0..8).map(move |i| {
        let s = |bit: u32| if i & (1 << bit) != 0 { 1.0 } else { -1.0 };
        Vec3::from(m.center) + s(0) * h.x * axes[0] + s(1) * h.y * axes[1] + s(2) * h.z * axes[2]
    })
}

/// The least depth `omega · x` over shape `s` (a bound: spheres of boxes).
fn shape_min_depth(s: &Shape, omega: Vec3) -> f32 {
    match s {
        Shape::Quad {
            corner,
            edge_u,
            edge_v,
            ..
        } => [
            *corner,
            *corner + *edge_u,
            *corner + *edge_v,
            *corner + *edge_u + *edge_v,
        ]
        .iter()
        .map(|c| c.dot(omega))
        .fold(f32::INFINITY, f32::min),
        Shape::Box { center, size, .. } => center.dot(omega) - 0.5 * size.length(),
        Shape::Sphere { center, radius, .. } => center.dot(omega) - radius,
        Shape::Mesh { mesh, .. } => {
            let (lo, hi) = mesh.bounds();
            (lo + hi).dot(omega) * 0.5 - 0.5 * (hi - lo).length()
        }
    }
}

/// Where each directional light's moment map lies: perpendicular to the light over the
/// media's footprint (grown by 1 % and one texel so bilinear lookups at the edge stay
/// inside), its rays starting upstream of every shape.
pub fn moment_frames(records: &GpuScene, scene: &Scene, size: u32) -> Vec<MomentFrameGpu> {
    let per_light = moment_texels_per_light(u64::from(size)) as u32;
    let corners: Vec<Vec3> = records.media.iter().flat_map(medium_corners).collect();
    records
        .lights
        .iter()
        .enumerate()
        .map(|(l, light)| {
            let omega = Vec3::from(light.direction_or_position).normalize();
            let (u_axis, v_axis) = omega.any_orthonormal_pair();
            let range = |axis: Vec3| {
                corners
                    .iter()
                    .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), c| {
                        (lo.min(c.dot(axis)), hi.max(c.dot(axis)))
                    })
            };
            let (u_lo, u_hi) = range(u_axis);
            let (v_lo, v_hi) = range(v_axis);
            let (z_lo, z_hi) = range(omega);
            // A margin that survives f32 rounding at the media's distance from the origin.
            let scale = corners
                .iter()
                .map(|c| c.abs().max_element())
                .fold(1e-3, f32::max);
            let grow = |lo: f32, hi: f32| {
                let pad = 0.01 * (hi - lo) + 1e-5 * scale;
                let (lo, hi) = (lo - pad, hi + pad);
                // One more texel on each side.
                let texel = (hi - lo) / size as f32;
                (lo - texel, hi + texel)
            };
            let (u_lo, u_hi) = grow(u_lo, u_hi);
            let (v_lo, v_hi) = grow(v_lo, v_hi);
            let depth_far = z_hi.max(z_lo + 1e-6 * scale);
            let shapes_lo = scene
                .shapes
                .iter()
                .map(|s| shape_min_depth(s, omega))
                .fold(z_lo, f32::min);
            let trace_start = shapes_lo - 1e-3 * (depth_far - shapes_lo) - 1e-5 * scale;
            MomentFrameGpu {
                u_axis: u_axis.into(),
                u_min: u_lo,
                v_axis: v_axis.into(),
                v_min: v_lo,
                omega: omega.into(),
                trace_start,
                texels_u: size as f32 / (u_hi - u_lo),
                texels_v: size as f32 / (v_hi - v_lo),
                depth_near: z_lo,
                depth_far,
                size,
                levels: moment_levels(size),
                first: l as u32 * per_light,
                _pad0: 0,
            }
        })
        .collect()
}

/// A pipeline of push constants `P` whose set holds the film targets and the storage
/// buffers `buffers` (binding, buffer), and that set.
fn storage_pipeline<P>(
    ctx: &Context,
    o: &mut GpuObjects,
    targets: &Targets,
    buffers: &[(u32, Handle<Buffer>)],
    spirv: &[u8],
    specialization: &[(u32, SpecValue)],
    (name, counter_slot): (&str, u32),
) -> Result<(Handle<ComputePipeline>, Handle<DescriptorSet>)> {
    let layout = storage_layout(&buffers.iter().map(|&(b, _)| b).collect::<Vec<_>>());
    let pipeline = compute_pipeline::<P>(
        ctx,
        o,
        spirv,
        &layout,
        specialization,
        targets.film_spec(counter_slot),
        name,
    )?;
    let mut writes = Vec::from(targets.writes());
    writes.extend(
        buffers
            .iter()
            .map(|&(binding, buffer)| DescriptorWrite::StorageBuffer {
                binding,
                buffer: &o[buffer],
            }),
    );
    let set = ctx.create_descriptor_set(&o[pipeline], &writes, &format!("{name} set"))?;
    Ok((pipeline, o.add(set)))
}

/// The moment-map stage: its pipeline, set and the dispatches of one frame.
struct MomentStage {
    pipeline: Handle<ComputePipeline>,
    set: Handle<DescriptorSet>,
    frames: Vec<MomentFrameGpu>,
}

/// The crepuscular pass: the per-pixel dispatch, after the moment maps where ME needs
/// them. Lights and shapes do not change during a crepuscular render, so the maps are
/// rendered once, before the first frame (profile scope `moments` in that frame only),
/// as a real-time renderer caches the shadow maps of static lights.
pub struct CrepuscularPass {
    image: ImagePass,
    moments: Option<MomentStage>,
    moments_ready: bool,
    /// The light records, gobo half-planes and moment-map frames, re-uploaded per scene
    /// frame when the lights are animated (light keyframes).
    lights: Handle<Buffer>,
    gobo_planes: Handle<Buffer>,
    moment_frames: Handle<Buffer>,
    moment_map_size: u32,
    /// The scene frame whose lights are uploaded (`None`: the scene's un-keyed lights).
    lights_frame: Option<u32>,
    /// The AOVs of the render (the light records' groups).
    aov: crate::plan::AovPlan,
}

/// Creates the pass of `plan`.
pub fn create(
    ctx: &Context,
    plan: &CrepuscularPlan,
    scene: &Scene,
    targets: &Targets,
) -> Result<CrepuscularPass> {
    let records = GpuScene::build(scene)?;
    let env_map = if plan.features.has_env_map {
        GpuEnvMap::load(scene)?
    } else {
        None
    };
    let meshes = MeshBuffers::build(scene);
    let constants = FrameConstants {
        env_radiance: records.env_radiance,
        env_size: env_map.as_ref().map_or([1, 1], |m| m.size),
        counts: RecordCounts {
            box_media: records.media.len() as u32,
            shapes: records.shapes.len() as u32,
            lights: records.lights.len() as u32,
            ray_samples: plan.samples_along_ray,
        },
    };
    let with_moments = plan.needs_moment_maps();
    let frames = if with_moments {
        moment_frames(&records, scene, plan.moment_map_size)
    } else {
        Vec::new()
    };
    let map_texels = if with_moments {
        moment_texels_per_light(u64::from(plan.moment_map_size)) * frames.len() as u64
    } else {
        1
    };
    if map_texels > u64::from(u32::MAX) {
        bail!(
            "{}: [integrator] moment_map_size = {}: {} lights' moment maps take {map_texels} \
             texels, more than a shader can index",
            scene.source.display(),
            plan.moment_map_size,
            frames.len()
        );
    }
    let (objects, (pipeline, set, moment_stage, light_buffers)) = GpuObjects::build(ctx, |o| {
        let media = upload_records(ctx, o, &non_empty(&records.media), "box media")?;
        let planes = upload_records(ctx, o, &non_empty(&records.medium_planes), "medium planes")?;
        let shapes = upload_records(ctx, o, &non_empty(&records.shapes), "shapes")?;
        let bvh_nodes = upload_records(ctx, o, &meshes.nodes, "mesh BVH nodes")?;
        let mesh_triangles = upload_records(ctx, o, &meshes.triangles, "mesh triangles")?;
        let mut light_records = records.lights.clone();
        targets.aov.assign_groups(scene, &mut light_records);
        let lights = upload_records(ctx, o, &non_empty(&light_records), "lights")?;
        let gobo_planes = upload_records(ctx, o, &non_empty(&records.gobo_planes), "gobo planes")?;
        let moment_map = o.add(ctx.create_buffer(
            &BufferDesc::gpu_only(map_texels * 16, vk::BufferUsageFlags::STORAGE_BUFFER),
            "moment maps",
        )?);
        let moment_frames = upload_records(ctx, o, &non_empty(&frames), "moment frames")?;
        let (env_texels, env_tables) = upload_env_map(ctx, o, env_map.as_ref())?;
        let buffers = [
            media,
            planes,
            shapes,
            bvh_nodes,
            mesh_triangles,
            lights,
            gobo_planes,
            moment_map,
            moment_frames,
            env_texels,
            env_tables,
        ];
        let (pipeline, set) = storage_pipeline::<PassPush>(
            ctx,
            o,
            targets,
            &CREPUSCULAR_BUFFERS
                .into_iter()
                .zip(buffers)
                .collect::<Vec<_>>(),
            shaders::BOX_CREPUSCULAR,
            &specialization(plan),
            ("crepuscular", 0),
        )?;
        let stage = if with_moments {
            Some(storage_pipeline::<MomentPush>(
                ctx,
                o,
                targets,
                &MOMENT_BUFFERS
                    .into_iter()
                    .zip([shapes, bvh_nodes, mesh_triangles, moment_map, moment_frames])
                    .collect::<Vec<_>>(),
                shaders::BOX_MOMENTS,
                &moment_specialization(plan),
                ("moment maps", 1),
            )?)
        } else {
            None
        };
        Ok((pipeline, set, stage, (lights, gobo_planes, moment_frames)))
    })?;
    let c = constants.counts;
    // Per segment: the media (and their planes) and shapes it crosses, and per light its
    // shadow and estimator loops (ray-marching samples, gobo and media crossings, and the
    // trapezoid-piece tables: pieces x planes per medium; ME adds its mip-level walk).
    let planes = records.medium_planes.len() as u32;
    let tables = c.box_media * plan.features.max_pieces.max(3) * (planes.max(6) + 4);
    let per_sample = if with_moments { 14 } else { 1 };
    // The environment: per sample along the segment and at its surface, a shadow ray
    // (media, planes, shapes) and, for a map, its two binary searches (a constant
    // environment has none: counting them split the default scene's 4 spp into 4
    // dispatches per frame on lavapipe).
    let searches = if plan.features.has_env_map { 2 * 32 } else { 0 };
    let env = if plan.features.has_env {
        2 * c.ray_samples * (c.box_media + planes + c.shapes + searches)
    } else {
        0
    };
    // A mesh costs a BVH traversal per ray: the segment's, and each shadow ray's.
    let mesh = super::mesh_ray_cost(scene);
    let env_mesh = if plan.features.has_env {
        2 * c.ray_samples * mesh
    } else {
        0
    };
    let per_segment = c.box_media
        + planes
        + c.shapes
        + mesh
        + env
        + env_mesh
        + c.lights
            * (c.ray_samples * (per_sample + mesh)
                + c.box_media
                + planes
                + c.shapes
                + mesh
                + tables
                + 16);
    let sample_cost = per_segment.saturating_mul(plan.max_bounces + 1);
    Ok(CrepuscularPass {
        image: ImagePass::new(
            ctx,
            "crepuscular",
            objects,
            pipeline,
            set,
            constants,
            sample_cost,
        ),
        moments: moment_stage.map(|(pipeline, set)| MomentStage {
            pipeline,
            set,
            frames,
        }),
        moments_ready: false,
        lights: light_buffers.0,
        gobo_planes: light_buffers.1,
        moment_frames: light_buffers.2,
        moment_map_size: plan.moment_map_size,
        lights_frame: None,
        aov: targets.aov.clone(),
    })
}

impl CrepuscularPass {
    /// Records the moment maps of every light: level 0 traced, then each coarser level
    /// averaged from the one before, a barrier between levels.
    fn record_moments(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        stage: &MomentStage,
    ) -> Result<()> {
        let objects = &self.image.objects;
        let Some(first) = stage.frames.first() else {
            return Ok(());
        };
        let (size, levels) = (first.size, first.levels);
        for level in 0..levels {
            let level_size = size >> level;
            for (light, frame) in stage.frames.iter().enumerate() {
                let offset = |k: u32| -> u32 {
                    frame.first + (0..k).map(|i| (size >> i) * (size >> i)).sum::<u32>()
                };
                let push = MomentPush {
                    light: light as u32,
                    level,
                    size: level_size,
                    dst: offset(level),
                    src: if level > 0 { offset(level - 1) } else { 0 },
                    ..Default::default()
                };
                objects[stage.pipeline].dispatch(
                    ctx,
                    cmd,
                    &objects[stage.set],
                    bytemuck::bytes_of(&push),
                    [
                        level_size.div_ceil(super::GROUP_SIZE[0]),
                        level_size.div_ceil(super::GROUP_SIZE[1]),
                        1,
                    ],
                )?;
            }
            compute_barrier(ctx, cmd);
        }
        Ok(())
    }
}

impl Pass for CrepuscularPass {
    fn label(&self) -> &'static str {
        self.image.label()
    }

    fn counter_labels(&self) -> Vec<&'static str> {
        vec!["crepuscular", "crepuscular/moments"]
    }

    fn frame_uniforms(&self, scene: &Scene, frame: u32) -> FrameUniforms {
        self.image.frame_uniforms(scene, frame)
    }

    /// Light keyframes: the records of `scene_frame`'s lights (direction, irradiance, their
    /// gobo prisms and moment-map frames), uploaded when they differ from the ones the
    /// pass holds; the moment maps are then traced again.
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
        let mut keyed = scene.clone();
        keyed.lights = scene.lights_at(scene_frame);
        let records = GpuScene::build(&keyed)?;
        let objects = &self.image.objects;
        let mut lights = non_empty(&records.lights);
        self.aov.assign_groups(scene, &mut lights);
        ctx.upload_buffer(&objects[self.lights], 0, bytemuck::cast_slice(&lights))?;
        let planes = non_empty(&records.gobo_planes);
        ctx.upload_buffer(&objects[self.gobo_planes], 0, bytemuck::cast_slice(&planes))?;
        if let Some(stage) = self.moments.as_mut() {
            let frames = moment_frames(&records, &keyed, self.moment_map_size);
            ctx.upload_buffer(
                &objects[self.moment_frames],
                0,
                bytemuck::cast_slice(&non_empty(&frames)),
            )?;
            stage.frames = frames;
            self.moments_ready = false;
        }
        self.lights_frame = Some(scene_frame);
        Ok(())
    }

    fn record(
        &mut self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        uniforms: &FrameUniforms,
        dispatch_index: u32,
        mut profiler: Option<&mut Profiler>,
    ) -> Result<()> {
        if let (Some(stage), false) = (&self.moments, self.moments_ready) {
            self.moments_ready = true;
            if let Some(p) = profiler.as_deref_mut() {
                p.begin_scope(ctx, cmd, "moments")?;
            }
            self.record_moments(ctx, cmd, stage)?;
            if let Some(p) = profiler.as_deref_mut() {
                p.end_scope(ctx, cmd)?;
                p.begin_scope(ctx, cmd, "scatter")?;
            }
            self.image
                .record(ctx, cmd, uniforms, dispatch_index, profiler.as_deref_mut())?;
            if let Some(p) = profiler {
                p.end_scope(ctx, cmd)?;
            }
            return Ok(());
        }
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
