//! Volumetric ReSTIR (`shaders/restir/*.comp`): initial candidates, temporal reuse,
//! spatial reuse and final shading, with reservoirs that persist across frames.
//!
//! - [`schedule`]: which stages a frame dispatches on which of the two or three reservoir slots
//!   (pure, unit-tested);
//! - [`volumes`]: the piecewise-constant levels and ray-march mips derived, brick by
//!   brick, from every density grid of the animation, and their atlas layouts;
//! - [`resources`]: the GPU objects, by name.
//!
//! Reservoirs live in one storage buffer of two or three slots (`reservoir_slots`) of `pixels × stride` u32 each
//! (`stride = 8 + 2K`: a 32-byte header and 8 bytes per path vertex, see
//! `shaders/include/reservoir.glsl`).

pub mod history;
pub mod resources;
pub mod schedule;
pub mod volumes;

use anyhow::Result;

use nimbus_gpu::{compute_barrier, vk, Context, GpuObjects, Profiler, SpecValue};
use nimbus_scene::{GridMedium, GridSource, Scene};

use self::resources::{Inputs, Resources};
use self::schedule::{schedule, ScheduleSettings, Stage};
use self::volumes::{grid_level, march_step, DerivedVolume, Volumes};
use super::{image_groups, scene_grid, FrameConstants, Pass, Targets};
use crate::budget::{brick_bytes, grid_bytes, Binding, Footprint};
use crate::gpu::features::*;
use crate::gpu::sparse::{atlas_bytes, atlas_dims, atlas_slots, layer_bytes, slot_bound};
use crate::gpu::sparse::{upload_atlas, Indirection, TexelFormat};
use crate::gpu::{
    non_empty, shape_records, BaselineUniformsGpu, FrameUniforms, GpuGrid, LightGpu, LightSet,
    MeshBuffers, RecordCounts, RestirPush, RestirUniformsGpu,
};
use crate::plan::RestirPlan;
use glam::IVec3;
use nimbus_scene::bricks::shr;
use nimbus_scene::BrickTopology;
use std::collections::HashSet;

pub use crate::gpu::reservoir_bytes;

/// The residual majorant's multiple in final ratio tracking
/// (`FINAL_RATIO_MAJORANT_SCALE` of `shaders/restir/transmittance.glsl`).
pub const FINAL_RATIO_MAJORANT_SCALE: f32 = 4.0;

/// The specialization constants of the ReSTIR shaders for a plan; `exact_spans`: some
/// super-voxel of some density frame is hot for final ratio tracking
/// ([`crate::gpu::scene::needs_exact_spans`]).
/// `two_level`: some brick indirection section is two-level.
pub fn specialization(
    plan: &RestirPlan,
    exact_spans: bool,
    two_level: bool,
) -> [(u32, SpecValue); 23] {
    [
        (SC_ID_TWO_LEVEL_BRICKS, SpecValue::Bool(two_level)),
        (
            SC_ID_EXACT_SPANS,
            SpecValue::Bool(plan.final_ratio_tracking && exact_spans),
        ),
        (SC_ID_HAS_AREA_LIGHTS, SpecValue::Bool(plan.has_area_lights)),
        (SC_ID_HAS_GOBOS, SpecValue::Bool(plan.has_gobos)),
        (SC_ID_HAS_MEDIA, SpecValue::Bool(plan.has_boxes)),
        (SC_ID_HAS_SHAPES, SpecValue::Bool(plan.has_shapes)),
        (SC_ID_HAS_MESHES, SpecValue::Bool(plan.has_meshes)),
        (SC_ID_HAS_ENV, SpecValue::Bool(plan.has_env)),
        (SC_ID_MAX_BOUNCES, SpecValue::U32(plan.max_bounces)),
        (SC_ID_PIXEL_JITTER, SpecValue::Bool(plan.pixel_jitter)),
        (SC_ID_HAS_EMISSION, SpecValue::Bool(plan.has_emission)),
        (SC_ID_HAS_CONVEX, SpecValue::Bool(plan.has_convex)),
        (SC_ID_HAS_BLACKBODY, SpecValue::Bool(plan.has_blackbody)),
        (SC_ID_HAS_ALBEDO_GRID, SpecValue::Bool(plan.has_albedo_grid)),
        (SC_ID_HAS_ENV_MAP, SpecValue::Bool(plan.has_env_map)),
        (SC_ID_REUSE_VERTEX, SpecValue::Bool(plan.vertex_reuse)),
        (
            SC_ID_FINAL_RATIO_TRACKING,
            SpecValue::Bool(plan.final_ratio_tracking),
        ),
        (SC_ID_HAS_VELOCITY, SpecValue::Bool(plan.has_velocity)),
        (SC_ID_MIS_PAIRWISE, SpecValue::Bool(plan.pairwise_mis)),
        (
            SC_ID_SPATIAL_TAU_SHIFT,
            SpecValue::Bool(plan.spatial_tau_shift),
        ),
        (SC_ID_FOLD_EMISSION, SpecValue::Bool(plan.fold_emission)),
        (SC_ID_NEE_SPLIT, SpecValue::Bool(plan.nee_split)),
        (
            SC_ID_DIRECT_EACH_WALK,
            SpecValue::Bool(plan.direct_each_walk),
        ),
    ]
}

/// Loop iterations one candidate walk costs, per segment: the blocks of the
/// piecewise-constant level it tracks through (camera segment, then scattered ones), the
/// NEE ray march, and the loops over the lights (nearest emitter, selection, shadow).
pub struct CandidateCost {
    pub pc_blocks: [u32; 2],
    pub march_steps: u32,
    pub lights: u32,
    /// Loop iterations of one ray through the meshes ([`crate::passes::mesh_ray_cost`]).
    pub mesh_rays: u32,
    /// Box media beside the grid (each segment loops over them a few times).
    pub boxes: u32,
    /// Primitives in the emitter table (an area-light sample binary-searches it).
    pub emitters: u32,
}

/// The reservoir slots `plan`'s schedule uses (2, or 3 when the history is taken before
/// two or more spatial rounds; [`schedule::slots`]).
pub fn reservoir_slots(plan: &RestirPlan) -> u32 {
    schedule::slots(&schedule_settings(plan, 1))
}

fn schedule_settings(plan: &RestirPlan, candidates_per_dispatch: u32) -> ScheduleSettings {
    ScheduleSettings {
        temporal: plan.temporal,
        spatial_neighbors: plan.spatial_neighbors,
        spatial_rounds: plan.spatial_rounds,
        candidates: plan.candidates,
        candidates_per_dispatch,
        history_before_spatial: plan.history_before_spatial,
    }
}

/// How many candidates one initial dispatch may draw so that an invocation stays within
/// the device's loop budget (half of it: the other loops of the invocation and a margin),
/// or all M where the device has none. At least 1: one candidate's walk is far below the
/// budget for every grid the loader admits (dims ≤ 4096 per axis).
pub fn candidates_per_dispatch(
    budget: Option<u32>,
    plan: &RestirPlan,
    cost: &CandidateCost,
) -> u32 {
    let Some(budget) = budget else {
        return plan.candidates;
    };
    // A segment's nearest-shape ray and its NEE shadow ray cross the meshes.
    let segment = |blocks: u32| {
        let search = u32::BITS - cost.emitters.leading_zeros();
        u64::from(blocks + cost.march_steps + 3 * cost.lights + 4 * cost.boxes + search + 64)
            + 2 * u64::from(cost.mesh_rays)
    };
    let k = u64::from(plan.max_bounces.max(1));
    // With the direct candidate of every walk the camera segment is walked twice: to its
    // end for T*, then by tracking.
    let direct = if plan.direct_each_walk {
        u64::from(cost.pc_blocks[0])
    } else {
        0
    };
    let per_candidate =
        segment(cost.pc_blocks[0]) + direct + (k - 1) * segment(cost.pc_blocks[1]) + k;
    let fit = (u64::from(budget / 2) / per_candidate.max(1)).max(1);
    u32::try_from(fit).unwrap_or(u32::MAX).min(plan.candidates)
}

/// Where each grid's indirection section starts in the `grid_bricks[]` buffer. Without
/// density frames the previous frame's sections are this frame's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sections {
    pub density: u32,
    pub emission: u32,
    pub temperature: u32,
    pub albedo: u32,
    pub density_prev: u32,
    pub pc_primary: u32,
    pub pc_indirect: u32,
    pub march_reuse: u32,
    pub march_reuse_prev: u32,
    pub march_nee: u32,
}

/// The indirection buffer of frame `cur` with previous frame `prev`, and its sections.
fn indirection(
    cur: &DerivedVolume,
    prev: &DerivedVolume,
    statics: &[nimbus_scene::bricks::Indirection; 3],
    animated: bool,
) -> Result<(Vec<u32>, Sections)> {
    let mut ind = Indirection::default();
    let density = ind.push(&cur.density_layout.indirection)?;
    let emission = ind.push(&statics[0])?;
    let temperature = ind.push(&statics[1])?;
    let albedo = ind.push(&statics[2])?;
    let density_prev = if animated {
        ind.push(&prev.density_layout.indirection)?
    } else {
        density
    };
    let pc_primary = ind.push(&cur.pc_primary_layout.indirection)?;
    let pc_indirect = ind.push(&cur.pc_indirect_layout.indirection)?;
    let march_reuse = ind.push(&cur.march_reuse_layout.indirection)?;
    let march_reuse_prev = if animated {
        ind.push(&prev.march_reuse_layout.indirection)?
    } else {
        march_reuse
    };
    let march_nee = ind.push(&cur.march_nee_layout.indirection)?;
    Ok((
        ind.finish(),
        Sections {
            density,
            emission,
            temperature,
            albedo,
            density_prev,
            pc_primary,
            pc_indirect,
            march_reuse,
            march_reuse_prev,
            march_nee,
        },
    ))
}

/// Voxels a velocity may move a point per frame before Nimbus says so: more is what a
/// file of units per second read as metres per frame looks like (a Houdini `vel` at 24
/// fps moves 24 times too far), and it smears a still scene into streaks.
pub const VELOCITY_NOTE_VOXELS: f32 = 4.0;

/// The velocity grid as dense RGBA16F texels over the medium's box (an OpenVDB one over
/// its dense window, as the loader cuts it), in metres per frame (times
/// `velocity_scale`), and a note when it moves a point more than
/// [`VELOCITY_NOTE_VOXELS`] density voxels per frame.
#[allow(clippy::type_complexity)]
fn velocity_texels(
    grid: &GridMedium,
    label: &str,
    density_dims: [u32; 3],
) -> Result<Option<([u32; 3], Vec<u16>, Option<String>)>> {
    let Some(source) = &grid.velocity else {
        return Ok(None);
    };
    let v = nimbus_scene::load_grid(source, 3, &format!("{label} > velocity"))?;
    let scale = grid.velocity_scale;
    let texels = v
        .data
        .chunks_exact(3)
        .flat_map(|c| [c[0], c[1], c[2], 0.0].map(|x| half::f16::from_f32(x * scale).to_bits()))
        .collect();
    let speed = v
        .data
        .chunks_exact(3)
        .map(|c| glam::Vec3::new(c[0], c[1], c[2]).length() * scale)
        .fold(0.0f32, f32::max);
    let size = grid.bounds_max - grid.bounds_min;
    let voxel = (0..3)
        .map(|a| size[a] / density_dims[a].max(1) as f32)
        .fold(f32::INFINITY, f32::min);
    let voxels = speed / voxel;
    let note = (voxels > VELOCITY_NOTE_VOXELS).then(|| {
        format!(
            "{label} > velocity moves points up to {voxels:.1} voxels per frame (|v| up to \
             {speed:.3} m/frame after velocity_scale = {scale}): velocities are metres per \
             frame; if the file holds units per second (Houdini, EmberGen), set \
             velocity_scale = 1/fps (times metres per unit)"
        )
    });
    Ok(Some((v.dims, texels, note)))
}

/// Rows of the affine map from a world point to the velocity texture's coordinates: the
/// medium's box for `type = "grid"`; for `type = "vdb"` the index space of the velocity's
/// dense window (voxel `d` holds lattice point `origin + d`, or `origin + dims - 1 - d`
/// along a flipped axis) through the inverse of the medium's index-to-world transform.
fn velocity_uvw(grid: &GridMedium) -> [[f32; 4]; 3] {
    use glam::{DMat4, DVec3};
    let to_uvw = match (&grid.vdb, &grid.velocity) {
        (Some(placement), Some(nimbus_scene::GridSource::Vdb { window, .. })) => {
            let dims = DVec3::from_array(window.dims.map(f64::from));
            // Lattice point l -> (l - origin + 0.5) / dims, mirrored where flipped.
            let mut scale = dims.recip();
            let mut offset = (DVec3::splat(0.5) - window.origin.as_dvec3()) / dims;
            for a in 0..3 {
                if window.flip[a] {
                    scale[a] = -scale[a];
                    offset[a] = 1.0 - offset[a];
                }
            }
            DMat4::from_translation(offset)
                * DMat4::from_scale(scale)
                * placement.index_to_world.inverse()
        }
        _ => {
            let (lo, hi) = (grid.bounds_min.as_dvec3(), grid.bounds_max.as_dvec3());
            DMat4::from_scale((hi - lo).recip()) * DMat4::from_translation(-lo)
        }
    };
    let row = |r: usize| -> [f32; 4] { to_uvw.row(r).as_vec4().to_array() };
    [row(0), row(1), row(2)]
}

/// The four stages, what they read, and the state carried from frame to frame.
pub struct RestirPass {
    objects: GpuObjects,
    res: Resources,
    settings: ScheduleSettings,
    /// `spatial_when = "camera_moves"`, and whether this frame's camera moved (set by
    /// `prepare`): the frame's spatial rounds run only then.
    spatial_camera_moves: bool,
    spatial_now: bool,
    constants: FrameConstants,
    grid: GridMedium,
    volumes: Volumes,
    /// The emission's and the temperature's indirection sections (the same for every
    /// frame; [`GpuGrid::static_sections`]).
    static_sections: [nimbus_scene::bricks::Indirection; 3],
    scene_lights_radius: f32,
    env_map_luminance: Option<f32>,
    /// The environment map's luminance for the history confidence of a turning map (only
    /// when the lights are animated and the environment has a map).
    env_change: Option<history::EnvLuminance>,
    /// The emitting shapes' total power (their LIGHT_AREA record's selection weight).
    area_power: f64,
    base_uniforms: BaselineUniformsGpu,
    /// Density indices loaded into the current / previous atlases.
    loaded: (usize, usize),
    /// The slot holding the previous frame's final reservoirs.
    prev_slot: Option<u32>,
    /// The previous-frame uniforms last uploaded.
    prev_uploaded: Option<FrameUniforms>,
    /// The ReSTIR uniforms as uploaded (`history_static` changes per frame).
    restir_uniforms: RestirUniformsGpu,
    /// The levels the plan asked for, `None` for `auto` (the volumes hold those used).
    plan_levels: (u32, Option<u32>, Option<u32>),
    /// What the velocity grid's magnitude suggests about its unit, if anything.
    velocity_note: Option<String>,
}

impl RestirPass {
    pub fn new(
        ctx: &Context,
        plan: &RestirPlan,
        scene: &Scene,
        mut grid_gpu: GpuGrid,
        targets: &Targets,
    ) -> Result<Self> {
        let (index, grid) = scene_grid(scene)?;
        let grid_label = format!("{}: [[medium]] #{}", scene.source.display(), index + 1);
        let r = &scene.render;
        let pixels = u64::from(r.width) * u64::from(r.height);
        let stride_bytes = reservoir_bytes(plan.max_bounces);
        let reservoir_total = u64::from(reservoir_slots(plan)) * pixels * stride_bytes;
        let (velocity, velocity_note) = if plan.has_velocity {
            match velocity_texels(grid, &grid_label, grid.density.dims()?)? {
                Some((dims, texels, note)) => (Some((dims, texels)), note),
                None => (None, None),
            }
        } else {
            (None, None)
        };
        let velocity_uvw = velocity_uvw(grid);
        // The density moves into `volumes`; the rest of the grid records are uploaded.
        let density = std::mem::take(&mut grid_gpu.density);
        let bricks = std::mem::take(&mut grid_gpu.density_layout.bricks);
        let records = std::mem::take(&mut grid_gpu.super_voxels);
        let volumes = Volumes::load(
            (density, bricks, records),
            grid,
            plan,
            &scene.position_scale(),
            &grid_label,
        )?;
        let first = volumes.base()?;
        let levels = volumes.levels;
        let animated = !grid.frames.is_empty();
        let static_sections = grid_gpu.static_sections()?;
        let (mut bricks, sections) = indirection(first, first, &static_sections, animated)?;
        // An animated grid's frames share their sections' offsets, not their lengths
        // where a section is two-level (its leaf tables follow the occupied nodes): the
        // buffer holds the longest pair of frames (at most twice the longest frame).
        if animated && first.density_layout.indirection.two_level {
            let mut longest = bricks.len();
            for i in 0..=grid.frames.len() {
                let v = volumes.get(i)?;
                longest = longest.max(indirection(v, v, &static_sections, true)?.0.len());
            }
            bricks.resize(2 * longest, nimbus_scene::bricks::NO_BRICK);
        }
        let mut base_uniforms = grid_gpu.uniforms;
        base_uniforms.grid.space.bricks_offset = sections.density;
        base_uniforms.grid.space.slots_x = volumes.sizes.density[0];
        base_uniforms.grid.space.slots_y = volumes.sizes.density[1];
        base_uniforms.grid.sigma_t_max = volumes.sigma_t_max;
        base_uniforms.emission.bricks_offset = sections.emission;
        base_uniforms.temperature.bricks_offset = sections.temperature;
        base_uniforms.albedo_grid.bricks_offset = sections.albedo;
        let g = &first.grids;
        let density = &g.density;
        let size = grid.bounds_max - grid.bounds_min;
        let shapes = shape_records(scene);
        let crate::gpu::scene::MediumRecords {
            media: boxes,
            planes: medium_planes,
        } = crate::gpu::scene::medium_records(scene);
        let candidates_per_dispatch = candidates_per_dispatch(
            ctx.info().loop_budget(),
            plan,
            &CandidateCost {
                pc_blocks: [&g.pc_primary, &g.pc_indirect]
                    .map(|l| (l.lattice_max - l.lattice_min + 1).max(glam::IVec3::ONE))
                    .map(|d| (d.x + d.y + d.z) as u32 + 3),
                // Split NEE marches towards the environment sample and every delta light.
                march_steps: (size.length() / march_step(grid, density, levels.indirect))
                    .ceil()
                    .min(crate::gpu::features::MARCH_MAX_STEPS as f32)
                    as u32
                    * if plan.nee_split {
                        1 + grid_gpu.lights.len() as u32
                    } else {
                        1
                    },
                lights: grid_gpu.lights.len() as u32,
                mesh_rays: crate::passes::mesh_ray_cost(scene),
                boxes: boxes.len() as u32,
                emitters: grid_gpu.emitters.len() as u32,
            },
        );
        let restir_uniforms = RestirUniformsGpu {
            pc_primary: grid_level(
                density,
                &g.pc_primary,
                &first.pc_primary_layout,
                levels.candidates,
                sections.pc_primary,
            ),
            pc_indirect: grid_level(
                density,
                &g.pc_indirect,
                &first.pc_indirect_layout,
                levels.indirect,
                sections.pc_indirect,
            ),
            march_reuse: grid_level(
                density,
                &g.march_reuse,
                &first.march_reuse_layout,
                levels.reuse,
                sections.march_reuse,
            ),
            march_nee: grid_level(
                density,
                &g.march_nee,
                &first.march_nee_layout,
                levels.indirect,
                sections.march_nee,
            ),
            march_reuse_prev_offset: sections.march_reuse_prev,
            density_prev_offset: sections.density_prev,
            candidates: plan.candidates,
            temporal_limit: plan.temporal_limit,
            spatial_neighbors: plan.spatial_neighbors,
            reservoir_stride: (stride_bytes / 4) as u32,
            candidates_per_dispatch,
            spatial_radius: plan.spatial_radius_px,
            spatial_max_m: plan.spatial_max_history * plan.candidates as f32,
            march_reuse_step: march_step(grid, density, levels.reuse),
            march_nee_step: march_step(grid, density, levels.indirect),
            velocity_dims: velocity.as_ref().map_or([1, 1, 1], |v| v.0),
            velocity_uvw_x: velocity_uvw[0],
            velocity_uvw_y: velocity_uvw[1],
            velocity_uvw_z: velocity_uvw[2],
            history_confidence: 1.0,
            ..RestirUniformsGpu::default()
        };
        let meshes = MeshBuffers::build(scene);
        let inputs = Inputs {
            grid: &grid_gpu,
            shapes: &shapes,
            meshes: &meshes,
            boxes: &boxes,
            planes: &medium_planes,
            first,
            base_uniforms: &base_uniforms,
            velocity: velocity.as_ref(),
            uniforms: &restir_uniforms,
            indirection: &bricks,
            reservoir_bytes: reservoir_total,
            march_format: volumes.format,
            sizes: volumes.sizes,
            animated,
        };
        let exact_spans =
            volumes.needs_exact_spans(&grid_gpu.p_to_world, FINAL_RATIO_MAJORANT_SCALE);
        // The density is the finest grid: its section is two-level if any is.
        let two_level =
            first.density_layout.indirection.two_level || grid_gpu.two_level_bricks()?;
        let spec = specialization(plan, exact_spans, two_level);
        let (objects, res) =
            GpuObjects::build(ctx, |o| Resources::create(ctx, o, &spec, &inputs, targets))?;
        Ok(RestirPass {
            objects,
            res,
            settings: schedule_settings(plan, candidates_per_dispatch),
            spatial_camera_moves: plan.spatial_camera_moves,
            spatial_now: true,
            constants: FrameConstants {
                env_radiance: grid_gpu.env_radiance,
                env_size: grid_gpu.uniforms.env_size,
                counts: RecordCounts {
                    lights: grid_gpu.lights.len() as u32,
                    shapes: shapes.len() as u32,
                    box_media: boxes.len() as u32,
                    ..RecordCounts::default()
                },
            },
            grid: grid.clone(),
            volumes,
            static_sections,
            scene_lights_radius: grid_gpu.light_radius,
            env_map_luminance: grid_gpu.env_map_luminance,
            env_change: grid_gpu
                .env_map
                .as_ref()
                .filter(|_| scene.lights_animated())
                .map(|m| {
                    history::EnvLuminance::from_texels(m.size[0], m.size[1], |i| {
                        let t = m.texels[i];
                        nimbus_scene::luminance([t[0], t[1], t[2]])
                    })
                }),
            area_power: grid_gpu.emitters.total_power,
            base_uniforms,
            loaded: (0, 0),
            prev_slot: None,
            prev_uploaded: None,
            restir_uniforms,
            plan_levels: (plan.mip_candidates, plan.mip_indirect, plan.mip_reuse),
            velocity_note,
        })
    }

    /// The environment's irradiance (luminance, pi times its mean radiance) for the
    /// lights' history confidence.
    fn env_irradiance(&self, scene: &Scene) -> f32 {
        let constant: glam::Vec3 = scene
            .lights
            .iter()
            .filter_map(|l| match l {
                nimbus_scene::Light::Environment {
                    radiance,
                    scale,
                    file: None,
                    ..
                } => Some(*radiance * *scale),
                _ => None,
            })
            .sum();
        let luminance = self
            .env_map_luminance
            .unwrap_or_else(|| constant.dot(glam::Vec3::new(0.2126, 0.7152, 0.0722)));
        std::f32::consts::PI * luminance
    }

    /// Uploads the lights of this frame and of the previous one (only when lights are
    /// animated: otherwise the creation-time upload holds).
    fn upload_lights(&self, ctx: &Context, scene: &Scene, frame: u32, prev: u32) -> Result<()> {
        if !scene.lights_animated() {
            return Ok(());
        }
        let set = |f| {
            LightSet::build(
                &scene.lights_at(f),
                self.scene_lights_radius,
                self.env_map_luminance,
                self.area_power,
            )
        };
        let (cur, prev) = (set(frame), set(prev));
        let records: Vec<LightGpu> = non_empty(&[cur.lights, prev.lights].concat());
        ctx.upload_buffer(
            &self.objects[self.res.lights],
            0,
            bytemuck::cast_slice(&records),
        )?;
        let mut base = self.base_uniforms;
        base.env_select = cur.env_select;
        ctx.upload_buffer(
            &self.objects[self.res.base_uniforms],
            0,
            bytemuck::bytes_of(&base),
        )
    }

    /// Uploads the density of this frame and of the previous one when they change: their
    /// atlases, super-voxel records and indirection sections (offsets stay: every frame
    /// has the same lattice).
    fn upload_density(&mut self, ctx: &Context, frame: u32, prev: u32) -> Result<()> {
        let want = (
            self.grid.density_index_at(frame),
            self.grid.density_index_at(prev),
        );
        if want == self.loaded {
            return Ok(());
        }
        let cur = self.volumes.get(want.0)?;
        let prev = self.volumes.get(want.1)?;
        let o = &self.objects;
        let r = &self.res;
        let sizes = self.volumes.sizes;
        let format = self.volumes.format;
        let scale = self.grid.density_scale;
        let r32 = TexelFormat::R32;
        let (c, p) = (&cur.grids, &prev.grids);
        upload_atlas(
            ctx,
            &o[r.density],
            sizes.density,
            &[(&cur.density_layout, &c.density, 1.0)],
            r32,
        )?;
        upload_atlas(
            ctx,
            &o[r.pc],
            sizes.pc,
            &[
                (&cur.pc_primary_layout, &c.pc_primary, scale),
                (&cur.pc_indirect_layout, &c.pc_indirect, scale),
            ],
            r32,
        )?;
        upload_atlas(
            ctx,
            &o[r.march_reuse],
            sizes.march_reuse,
            &[(&cur.march_reuse_layout, &c.march_reuse, 1.0)],
            format,
        )?;
        upload_atlas(
            ctx,
            &o[r.march_nee],
            sizes.march_nee,
            &[(&cur.march_nee_layout, &c.march_nee, 1.0)],
            format,
        )?;
        upload_atlas(
            ctx,
            &o[r.density_prev],
            sizes.density,
            &[(&prev.density_layout, &p.density, 1.0)],
            r32,
        )?;
        upload_atlas(
            ctx,
            &o[r.march_reuse_prev],
            sizes.march_reuse,
            &[(&prev.march_reuse_layout, &p.march_reuse, 1.0)],
            format,
        )?;
        let mut records = c.super_voxels.clone();
        records.resize(
            records.len().max(resources::slot_count(sizes.density)),
            [0.0; 4],
        );
        ctx.upload_buffer(&o[r.super_voxels], 0, bytemuck::cast_slice(&records))?;
        let animated = !self.grid.frames.is_empty();
        let (entries, _) = indirection(cur, prev, &self.static_sections, animated)?;
        ctx.upload_buffer(&o[r.bricks], 0, bytemuck::cast_slice(&entries))?;
        self.loaded = want;
        Ok(())
    }
}

impl Pass for RestirPass {
    fn label(&self) -> &'static str {
        "restir"
    }

    fn counter_labels(&self) -> Vec<&'static str> {
        vec![
            "restir/initial",
            "restir/temporal",
            "restir/spatial",
            "restir/shade",
        ]
    }

    fn frame_uniforms(&self, scene: &Scene, frame: u32) -> FrameUniforms {
        self.constants.uniforms(scene, frame)
    }

    /// Uploads what changes per frame: the lights of this frame and the previous one,
    /// the previous camera, and the density grids of both frames when they change.
    fn prepare(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        scene_frame: u32,
        prev_frame: u32,
    ) -> Result<()> {
        self.upload_lights(ctx, scene, scene_frame, prev_frame)?;
        // The previous frame's camera and environment map turn (the first frame's own
        // on frame 0).
        let camera = scene.camera.frame_at(prev_frame);
        let prev = self.constants.uniforms(scene, prev_frame);
        if self.prev_uploaded.map(|u| bytemuck::bytes_of(&u).to_vec())
            != Some(bytemuck::bytes_of(&prev).to_vec())
        {
            ctx.upload_buffer(
                &self.objects[self.res.prev_frame],
                0,
                bytemuck::bytes_of(&prev),
            )?;
            self.prev_uploaded = Some(prev);
        }
        self.upload_density(ctx, scene_frame, prev_frame)?;
        // spatial_when = "camera_moves": spatial reuse on frames whose camera moved (a
        // choice made per frame from the cameras alone, never from the samples).
        self.spatial_now =
            !self.spatial_camera_moves || scene.camera.frame_at(scene_frame) != camera;
        // Whether the previous frame's target function is this frame's: the same camera,
        // light set and density (a static scene, or a held frame of an animation).
        let same = scene.camera.frame_at(scene_frame) == camera
            && (!scene.lights_animated()
                || scene.lights_at(scene_frame) == scene.lights_at(prev_frame))
            && self.grid.density_index_at(scene_frame) == self.grid.density_index_at(prev_frame);
        let flag = u32::from(same);
        // The lights' confidence in the previous frame (1 when they did not change).
        let confidence = if scene.lights_animated() {
            history::light_confidence(
                &scene.lights_at(prev_frame),
                &scene.lights_at(scene_frame),
                (self.grid.bounds_min + self.grid.bounds_max) * 0.5,
                self.env_irradiance(scene),
                self.env_change.as_ref(),
            )
        } else {
            1.0
        };
        if flag != self.restir_uniforms.history_static
            || confidence != self.restir_uniforms.history_confidence
        {
            self.restir_uniforms.history_static = flag;
            self.restir_uniforms.history_confidence = confidence;
            ctx.upload_buffer(
                &self.objects[self.res.restir_uniforms],
                0,
                bytemuck::bytes_of(&self.restir_uniforms),
            )?;
        }
        Ok(())
    }

    /// Records the frame's stages, each in its own profiler scope (spatial rounds share
    /// one), with a barrier between consecutive dispatches; the last output becomes the
    /// next frame's previous slot.
    fn record(
        &mut self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        uniforms: &FrameUniforms,
        dispatch_index: u32,
        mut profiler: Option<&mut Profiler>,
    ) -> Result<()> {
        let settings = ScheduleSettings {
            spatial_neighbors: if self.spatial_now {
                self.settings.spatial_neighbors
            } else {
                0
            },
            ..self.settings
        };
        let (dispatches, last) = schedule(dispatch_index, self.prev_slot, &settings);
        let mut open: Option<Stage> = None;
        for (n, d) in dispatches.iter().enumerate() {
            if n > 0 {
                compute_barrier(ctx, cmd);
            }
            if open != Some(d.stage) {
                if let (Some(p), Some(_)) = (profiler.as_deref_mut(), open) {
                    p.end_scope(ctx, cmd)?;
                }
                if let Some(p) = profiler.as_deref_mut() {
                    p.begin_scope(ctx, cmd, d.stage.name())?;
                }
                open = Some(d.stage);
            }
            let stage = d.stage as usize;
            let push: RestirPush = d.push;
            self.objects[self.res.pipelines[stage]].dispatch(
                ctx,
                cmd,
                &self.objects[self.res.sets[stage]],
                bytemuck::bytes_of(&push),
                image_groups(uniforms),
            )?;
        }
        if let (Some(p), Some(_)) = (profiler, open) {
            p.end_scope(ctx, cmd)?;
        }
        self.prev_slot = Some(last);
        Ok(())
    }

    fn device_bytes(&self) -> u64 {
        self.objects.bytes()
    }

    fn notes(&self) -> Vec<String> {
        let l = self.volumes.levels;
        let mut notes: Vec<String> = self.velocity_note.iter().cloned().collect();
        if let Some(errors) = &self.volumes.march_errors {
            let list: Vec<String> = errors.iter().map(|e| format!("{e:.3}")).collect();
            notes.push(format!(
                "ReSTIR chose mip {} (scattered segments) and {} (reuse targets) from the \
                 volume's content: marched optical depth errors {} at mips 0..{} \
                 (transmittance-weighted RMS), the coarsest within {}",
                l.indirect,
                l.reuse,
                list.join(" / "),
                errors.len().saturating_sub(1),
                volumes::MAX_MARCH_ERROR
            ));
        }
        let (candidates, indirect, reuse) = self.plan_levels;
        let asked = (
            candidates,
            indirect.unwrap_or(l.indirect),
            reuse.unwrap_or(l.reuse),
        );
        if (l.candidates, l.indirect, l.reuse) == asked {
            return notes;
        }
        notes.push(format!(
            "ReSTIR used mip levels {}/{}/{} (candidates/indirect/reuse) instead of {}/{}/{}: \
             coarser levels would spread the grid's sharpest density steps over more than \
             {} optical depths and stop sampling paths that contribute",
            l.candidates,
            l.indirect,
            l.reuse,
            asked.0,
            asked.1,
            asked.2,
            volumes::MAX_LEVEL_EXCESS_TAU
        ));
        notes
    }

    fn destroy(self: Box<Self>, ctx: &Context) {
        self.objects.destroy(ctx);
    }
}

/// The bricks of mip `level` of a grid of topology `t` (each brick's parent at that
/// level), after growing `t` by its 26 neighbours when `dilate` (the conservative grid's
/// zeros next to density become positive).
fn level_topology(t: &BrickTopology, level: u32, dilate: bool) -> BrickTopology {
    let dims = IVec3::from_array(t.brick_dims().map(|d| d as i32));
    let mut set = HashSet::new();
    for b in &t.bricks {
        let range = if dilate { -1..=1 } else { 0..=0 };
        for z in range.clone() {
            for y in range.clone() {
                for x in range.clone() {
                    let n = *b + IVec3::new(x, y, z);
                    if n.cmpge(IVec3::ZERO).all() && n.cmplt(dims).all() {
                        set.insert(shr(n, level));
                    }
                }
            }
        }
    }
    BrickTopology {
        lattice_min: shr(t.lattice_min, level),
        lattice_max: shr(t.lattice_max, level),
        bricks: set.into_iter().collect(),
        ..t.clone()
    }
}

/// What the ReSTIR passes allocate (see [`crate::budget`]): the grid's atlases (density,
/// piecewise-constant levels, ray-march mips, and the previous frame's where density
/// frames change), sized for the largest frame at the plan's mip levels (`auto` ones at
/// the finest they can be; a level refined by content, see
/// [`volumes::MAX_LEVEL_EXCESS_TAU`], is finer and larger), the indirection sections,
/// reservoirs and velocity.
pub fn footprint(scene: &Scene, p: &RestirPlan, f: &mut Footprint) -> Result<()> {
    f.add_meshes(scene);
    f.add_emitters(scene);
    f.add_env_map(scene)?;
    let Some(gf) = f.add_grid(scene)? else {
        return Ok(());
    };
    let (g, table) = (gf.medium, gf.table.clone());
    let file = scene.source.display();
    let r = &scene.render;
    let pixels = u64::from(r.width) * u64::from(r.height);
    let reservoirs = u64::from(reservoir_slots(p)) * pixels * reservoir_bytes(p.max_bounces);
    f.add(
        format!("{file}: [render] `width` x `height` with [integrator] `max_bounces` = {} (ReSTIR reservoirs)", p.max_bounces),
        Binding::Storage,
        reservoirs,
    );
    let mut frames = vec![gf.density.clone()];
    let mut frame_slots = vec![gf.density_slots];
    for (i, frame) in g.frames.iter().enumerate() {
        let what = format!(
            "{table} > [[medium.frame]] #{} (frame {})",
            i + 1,
            frame.frame
        );
        let topo = BrickTopology::of(&frame.density, 1, &what)?;
        frame_slots.push(crate::budget::density_slot_bound(&frame.density, &topo));
        frames.push(topo);
    }
    let animated = frames.len() > 1;
    let brick = 512 * 4;
    let mut density_slots = gf.density_slots;
    let (mut pc, mut reuse, mut nee) = (0u64, 0u64, 0u64);
    let (mut kept, mut building) = (0u64, 0u64);
    let mut cells = 0u64;
    // A level chosen from the content when the grid loads: counted at the finest it can
    // be.
    let mip_indirect = p.mip_indirect.unwrap_or(volumes::MIN_AUTO_INDIRECT);
    let mip_reuse = p.mip_reuse.unwrap_or(0);
    for (n, t) in frames.iter().enumerate() {
        let primary = level_topology(t, p.mip_candidates, true);
        let indirect = level_topology(t, mip_indirect, true);
        let march_reuse = level_topology(t, mip_reuse, false);
        let march_nee = level_topology(t, mip_indirect, false);
        let slots = frame_slots[n];
        if n > 0 {
            density_slots = density_slots.max(slots);
        }
        let pc_n = (primary.bricks.len() + indirect.bricks.len()) as u64;
        pc = pc.max(pc_n);
        reuse = reuse.max(slot_bound(&march_reuse, false));
        nee = nee.max(slot_bound(&march_nee, false));
        let level_cells =
            primary.cells() + indirect.cells() + march_reuse.cells() + march_nee.cells();
        if n == 0 {
            cells = level_cells;
        }
        // Kept for the whole render: the grid, its records and every level (f32 values,
        // coordinates, indirection and layout indirection). The base density's bricks
        // are those `add_grid` counted (the pass moves them into its levels, no copy).
        kept += if n == 0 { 0 } else { brick_bytes(t) }
            + slots * (12 + 16)
            + (pc_n + (march_reuse.bricks.len() + march_nee.bricks.len()) as u64) * (brick + 12)
            + 2 * (t.cells() + level_cells) * 4;
        // While a frame is derived: its conservative copy (the bricks and neighbours).
        let conservative = level_topology(t, 0, true);
        building = building
            .max(conservative.bricks.len() as u64 * (brick + 12) + conservative.cells() * 4);
    }
    let r32 = TexelFormat::R32;
    // The march mips as f32 (what a density beyond f16's range needs), or f16 where every
    // density is the procedural cloud, whose values lie in [0, 1].
    let procedural = |s: &GridSource| matches!(s, GridSource::ProceduralCloud { .. });
    let march = if procedural(&g.density) && g.frames.iter().all(|fr| procedural(&fr.density)) {
        TexelFormat::R16
    } else {
        TexelFormat::R32
    };
    let mut atlas = |name: &str, slots: u64, format: TexelFormat| -> Result<()> {
        f.add(
            format!("{table} ({name}, atlas of {slots} bricks)"),
            Binding::Image3d(atlas_dims(atlas_slots(slots)?)),
            atlas_bytes(slots, format)?,
        );
        Ok(())
    };
    atlas("piecewise-constant levels", pc, r32)?;
    atlas("ray-march mip, reuse", reuse, march)?;
    atlas("ray-march mip, NEE", nee, march)?;
    if animated {
        atlas("previous density", density_slots, r32)?;
        atlas("ray-march mip, reuse, previous", reuse, march)?;
        // The base density's atlas (counted by `add_grid`) grows to the largest frame's.
        let base = gf.density_slots;
        if density_slots > base {
            f.add(
                format!("{table} (density atlas for the largest frame)"),
                Binding::Image3d(atlas_dims(atlas_slots(density_slots)?)),
                atlas_bytes(density_slots, r32)? - atlas_bytes(base, r32)?,
            );
        }
        cells += gf.density.cells() + level_topology(&gf.density, mip_reuse, false).cells();
    }
    f.add(
        format!("{table} (brick indirection of the derived levels)"),
        Binding::Storage,
        cells * 4,
    );
    if let Some(v) = &g.velocity {
        // Dense over the medium's box (an OpenVDB velocity over its dense window).
        let vd = v.dims()?;
        f.add(
            format!("{table} field `velocity`"),
            Binding::Image3d(vd),
            grid_bytes(vd, 8),
        );
        f.host_peak += grid_bytes(vd, 12 + 8);
    }
    f.host_peak += kept + building + cells * 4 + 2 * layer_bytes(pc.max(reuse).max(nee), r32)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use glam::{DVec3, Vec4};
    use nimbus_scene::{GridSource, Medium};

    use super::{candidates_per_dispatch, velocity_uvw, CandidateCost};

    /// Every walk's direct candidate walks the camera segment a second time, which the
    /// split of M over dispatches must count: lavapipe silently ends the loops of an
    /// invocation past its budget, which would drop candidates and darken the image.
    #[test]
    fn the_direct_candidates_walk_counts_against_the_loop_budget() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/assets/scenes/cloud-restir.toml"
        );
        let scene = crate::load_scene(Some(std::path::Path::new(path)), &[]).unwrap();
        let plan = crate::plan::build(&scene, None).unwrap();
        let mut p = plan.restir().unwrap().clone();
        p.candidates = 4096;
        p.max_bounces = 3;
        let cost = CandidateCost {
            pc_blocks: [2000, 100],
            march_steps: 300,
            lights: 2,
            mesh_rays: 0,
            boxes: 0,
            emitters: 0,
        };
        let budget = 65_535;
        p.direct_each_walk = false;
        let escape = candidates_per_dispatch(Some(budget), &p, &cost);
        p.direct_each_walk = true;
        let each = candidates_per_dispatch(Some(budget), &p, &cost);
        assert!(each < escape, "{each} vs {escape}");
        // The loops of `each` candidates with the second walk stay within half the budget.
        let segment = |blocks: u64| blocks + 300 + 6 + 64;
        let per = segment(2000) + 2000 + 2 * segment(100) + 3;
        assert!(
            u64::from(each) * per <= u64::from(budget / 2),
            "{each} x {per}"
        );
        assert_eq!(candidates_per_dispatch(None, &p, &cost), 4096);
    }

    /// The map from world points to the velocity texture puts each dense voxel's centre
    /// at its texel centre: for an axis-aligned window with a flipped axis (the box
    /// formula the shader used before) and for a rotated grid (through the inverse
    /// index-to-world transform).
    #[test]
    fn velocity_texel_centres_map_to_their_voxels() {
        let file = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/test-vdb/multi.vdb");
        for to_world in [
            "{ scale = [2, -1, 0.5], translate = [1, 2, -3] }",
            "{ scale = [2, -1, 0.5], rotate_deg = [20, 35, -10], translate = [1, 2, -3] }",
        ] {
            let text = format!(
                "[render]\nwidth = 4\nheight = 4\n[camera]\nposition = [0, 0, 40]\n\
                 look_at = [0, 0, 0]\n[[light]]\ntype = \"environment\"\nradiance = 1\n\
                 [[medium]]\ntype = \"vdb\"\ndensity = {{ file = \"{file}\" }}\n\
                 velocity = {{ file = \"{file}\", grid = \"vel\" }}\nto_world = {to_world}\n"
            );
            let scene = nimbus_scene::parse_str(&text, std::path::Path::new("t.toml"))
                .unwrap_or_else(|e| panic!("{e:#}"));
            let Some(Medium::Grid(g)) = scene.media.first() else {
                panic!("a grid medium")
            };
            let Some(GridSource::Vdb { window, .. }) = &g.velocity else {
                panic!("a vdb velocity")
            };
            let rows = velocity_uvw(g).map(Vec4::from_array).map(|r| r.as_dvec4());
            let uvw = |x: DVec3| {
                let h = x.extend(1.0);
                DVec3::new(rows[0].dot(h), rows[1].dot(h), rows[2].dot(h))
            };
            let placement = g.vdb.as_ref().unwrap();
            let dims = DVec3::from_array(window.dims.map(f64::from));
            let (lo, hi) = (g.bounds_min.as_dvec3(), g.bounds_max.as_dvec3());
            for d in [
                [0, 0, 0],
                [1, 2, 3],
                [window.dims[0] - 1, 0, window.dims[2] - 1],
            ] {
                let d = DVec3::from_array(d.map(f64::from));
                let texel = (d + 0.5) / dims;
                // Dense voxel d holds lattice point origin + d, mirrored where flipped.
                let l = DVec3::from_array([0, 1, 2].map(|a| {
                    let o = f64::from(window.origin[a]);
                    if window.flip[a] {
                        o + dims[a] - 1.0 - d[a]
                    } else {
                        o + d[a]
                    }
                }));
                let x = (placement.index_to_world * l.extend(1.0)).truncate();
                assert!(
                    uvw(x).abs_diff_eq(texel, 1e-5),
                    "{to_world}: {d} {}",
                    uvw(x)
                );
                if !to_world.contains("rotate") {
                    assert_eq!(window.flip, [false, true, false]);
                    let centre = lo + texel * (hi - lo);
                    assert!(uvw(centre).abs_diff_eq(texel, 1e-5), "{to_world}: box {d}");
                }
            }
        }
    }
}
