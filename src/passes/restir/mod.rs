//! Volumetric ReSTIR (`shaders/restir/*.comp`): initial candidates, temporal reuse,
//! spatial reuse and final shading, with reservoirs that persist across frames.
//!
//! - [`mod@schedule`]: which stages a frame dispatches on which of the two or three reservoir slots
//!   (pure, unit-tested);
//! - [`volumes`]: the piecewise-constant levels and ray-march mips derived, brick by
//!   brick, from every density grid of the animation, and their atlas layouts;
//! - [`resources`]: the GPU objects, by name.
//!
//! Reservoirs live in one storage buffer of two or three slots ([`RestirPlan::reservoir_slots`]) of `pixels × stride` u32 each
//! (`stride = 8 + 2K`: a 32-byte header and 8 bytes per path vertex, see
//! `shaders/include/reservoir.glsl`).

pub mod dispatch;
pub mod history;
pub mod indirection;
pub mod resources;
pub mod schedule;
pub mod velocity;
pub mod volumes;

use anyhow::Result;

use nimbus_gpu::{compute_barrier, vk, Context, GpuObjects, Profiler};
use nimbus_scene::{GridMedium, Scene};

use self::dispatch::{candidates_per_dispatch, schedule_settings, specialization, CandidateCost};
use self::indirection::indirection;
use self::resources::{Inputs, Resources};
use self::schedule::{schedule, ScheduleSettings, Stage};
use self::velocity::{velocity_texels, velocity_uvw};
use self::volumes::{grid_level, march_step, Volumes};
use super::{image_groups, scene_grid, FrameConstants, Pass, Targets};
use crate::plan::RestirPlan;
use crate::shader_data::sparse::{
    upload_atlas, upload_march_quads, upload_slot_major, TexelFormat,
};
use crate::shader_data::{
    non_empty, shape_records, BaselineUniformsGpu, FrameUniforms, GpuGrid, LightGpu, LightSet,
    MeshBuffers, RecordCounts, RestirPush, RestirUniformsGpu,
};

pub use crate::shader_data::reservoir_bytes;

/// The residual majorant's multiple in final ratio tracking
/// (`FINAL_RATIO_MAJORANT_SCALE` of `shaders/restir/transmittance.glsl`).
pub const FINAL_RATIO_MAJORANT_SCALE: f32 = 4.0;

/// Values of `RestirUniforms::history_static` (restir/temporal.comp): the previous
/// frame's camera, lights and density are this frame's; only its lights differ.
const HISTORY_STATIC: u32 = 1;
const HISTORY_CAMERA_STILL: u32 = 2;

/// The four stages, what they read, and the state carried from frame to frame.
pub struct RestirPass {
    objects: GpuObjects,
    res: Resources,
    settings: ScheduleSettings,
    /// `spatial_when`, and whether its trigger fired on this frame (set by `prepare`):
    /// the frame's spatial rounds run only then.
    spatial_when: nimbus_scene::SpatialWhen,
    spatial_now: bool,
    /// The medium has a velocity field (its points move between frames even where the
    /// density does not change).
    has_velocity: bool,
    /// Q on frames whose camera, density and (under map reuse) environment map did not
    /// move, and on frames where one did (`temporal_limit`, `temporal_limit_moving`):
    /// `prepare` uploads the frame's.
    temporal_limits: [u32; 2],
    /// This frame's Q from `temporal_limits` (set by `prepare`).
    frame_temporal_limit: u32,
    /// M on frames whose history is full (`candidates_settled`, fewer than M), and how
    /// many frames in a row up to the last one recorded kept the previous frame's target
    /// (`history_static`): from `temporal_limits[0]` of them on, a frame draws the
    /// settled M, the cap of Q·M candidates kept (`record`).
    candidates_settled: Option<u32>,
    still_run: u32,
    /// The pass keeps the shade cache
    /// ([`crate::plan::RestirPlan::keeps_shade_cache`]), and whether the last frame
    /// recorded shaded the reservoirs it left as the history: then a still frame whose
    /// temporal stage keeps a pixel's path (and runs no spatial round) reuses the F
    /// cached for it (the shade dispatch's `aux` = 1).
    shade_cache: bool,
    shaded_history: bool,
    /// `restir_uniforms` changed since its last upload (`prepare` sets the history's
    /// flags, `record` the frame's M and Q and uploads them together).
    uniforms_stale: bool,
    /// `env_reuse = "map"` with a map: a turn of the map is a moving frame's.
    env_reuse_map: bool,
    /// Tracking reads the piecewise-constant levels from `res.pc_texels` (SC_PC_BUFFER).
    pc_buffer: bool,
    /// The passes read this frame's density from `res.density_texels` (SC_DENSITY_BUFFER).
    density_buffer: bool,
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
    /// What the velocity grid's magnitude suggests about its unit, if anything.
    velocity_note: Option<String>,
    /// Why the candidates' tracking differs from the plan's, if it does.
    tracking_note: Option<String>,
    /// The render's AOVs: the light groups written into animated light records.
    aov: crate::plan::AovPlan,
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
        let slots_bytes = u64::from(plan.reservoir_slots()) * pixels * stride_bytes;
        // The shade cache follows the slots in the same buffer (its first u32 in the
        // uniforms; 0 when there is none).
        let shade_cache = plan.keeps_shade_cache(targets.aov);
        let reservoir_total = slots_bytes
            + if shade_cache {
                pixels * crate::plan::SHADE_CACHE_BYTES_PER_PIXEL
            } else {
                0
            };
        let shade_cache_base = if shade_cache {
            u32::try_from(slots_bytes / 4).map_err(|_| {
                anyhow::anyhow!(
                    "{}: the ReSTIR reservoirs ({slots_bytes} bytes) exceed the 16 GiB a \
                     32-bit index reaches: lower [render] width x height or [integrator] \
                     max_bounces",
                    scene.source.display()
                )
            })?
        } else {
            0
        };
        let (velocity, velocity_note) = if plan.has_velocity {
            match velocity_texels(grid, &grid_label, grid.density.dims()?)? {
                Some((dims, texels, note)) => (Some((dims, texels)), note),
                None => (None, None),
            }
        } else {
            (None, None)
        };
        let velocity_uvw = velocity_uvw(grid);
        // Light records carry their light group (both sets copy these).
        targets.aov.assign_groups(scene, &mut grid_gpu.lights);
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
        let pc_buffer = resources::pc_in_buffer(
            ctx.info(),
            plan.settings.pc_fetch,
            volumes.sizes.pc,
            &scene.source,
        )?;
        // Where the marches find each mip in the buffer of quads (read only where it is
        // bound: SC_MARCH_BUFFER).
        let march_quads = resources::MarchQuads::of(volumes.sizes, animated);
        let density_buffer = resources::density_in_buffer(
            ctx.info(),
            plan.settings.density_fetch,
            volumes.sizes,
            march_quads,
            &scene.source,
        )?;
        // Where this frame's density is read from its buffer, `candidate_tracking = "auto"`
        // takes delta tracking (RestirPlan::with_density_buffer).
        let buffered_plan = density_buffer.then(|| plan.with_density_buffer()).flatten();
        let tracking_note = buffered_plan.as_ref().map(|_| {
            "[integrator.restir] candidate_tracking = \"auto\": delta tracking, because this \
             device reads the density from its buffer of quads (density_fetch), where an exact \
             lookup costs as little as regular tracking's"
                .to_string()
        });
        let plan = buffered_plan.as_ref().unwrap_or(plan);
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
        let crate::shader_data::scene::MediumRecords {
            media: boxes,
            planes: medium_planes,
        } = crate::shader_data::scene::medium_records(scene);
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
                    .min(crate::shader_data::features::MARCH_MAX_STEPS as f32)
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
                super_voxels: density.brick_dims.iter().sum::<u32>() + 3,
                dual_cells: {
                    let d = (density.lattice_max - density.lattice_min + 1).max(glam::IVec3::ONE);
                    (d.x + d.y + d.z) as u32 + 3
                },
            },
        );
        let mut restir_uniforms = RestirUniformsGpu {
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
            candidates: plan.settings.candidates,
            temporal_limit: plan.temporal_limit,
            spatial_neighbors: plan.spatial_neighbors,
            reservoir_stride: (stride_bytes / 4) as u32,
            candidates_per_dispatch,
            spatial_radius: plan.spatial_radius_px,
            spatial_max_m: plan.spatial_max_history * plan.settings.candidates as f32,
            march_reuse_step: march_step(grid, density, levels.reuse),
            march_nee_step: march_step(grid, density, levels.indirect),
            velocity_dims: velocity.as_ref().map_or([1, 1, 1], |v| v.0),
            velocity_uvw_x: velocity_uvw[0],
            velocity_uvw_y: velocity_uvw[1],
            velocity_uvw_z: velocity_uvw[2],
            history_confidence: 1.0,
            spatial_feature_tolerance: plan.settings.spatial_feature_tolerance,
            spatial_anchor: u32::from(plan.settings.spatial_anchor),
            shade_cache_base,
            ..RestirUniformsGpu::default()
        };
        let meshes = MeshBuffers::build(scene);
        restir_uniforms.march_reuse.quad_base = march_quads.reuse as u32;
        restir_uniforms.march_nee.quad_base = march_quads.nee as u32;
        restir_uniforms.march_reuse_prev_quad_base = march_quads.reuse_prev as u32;
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
            pc_buffer,
            density_buffer,
            march_quads,
            still_temporal: resources::builds_still_temporal(plan),
        };
        let exact_spans =
            volumes.needs_exact_spans(&grid_gpu.p_to_world, FINAL_RATIO_MAJORANT_SCALE);
        // The density is the finest grid: its section is two-level if any is.
        let two_level =
            first.density_layout.indirection.two_level || grid_gpu.two_level_bricks()?;
        let spec = specialization(plan, exact_spans, two_level, pc_buffer, density_buffer);
        let (objects, res) =
            GpuObjects::build(ctx, |o| Resources::create(ctx, o, &spec, &inputs, targets))?;
        Ok(RestirPass {
            objects,
            res,
            settings: schedule_settings(plan, candidates_per_dispatch),
            spatial_when: plan.spatial_when,
            spatial_now: true,
            has_velocity: plan.has_velocity,
            temporal_limits: [plan.temporal_limit, plan.temporal_limit_moving],
            frame_temporal_limit: plan.temporal_limit,
            candidates_settled: plan.candidates_settled(),
            still_run: 0,
            shade_cache,
            shaded_history: false,
            uniforms_stale: false,
            env_reuse_map: plan.env_reuse_map,
            pc_buffer,
            density_buffer,
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
                // With env_reuse = "map" the reused samples turn with the map, so its turn
                // counts as a light's turn (history::light_confidence without the table).
                .filter(|_| scene.lights_animated() && !plan.env_reuse_map)
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
            velocity_note,
            tracking_note,
            aov: targets.aov.clone(),
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
            let mut set = LightSet::build(
                &scene.lights_at(f),
                self.scene_lights_radius,
                self.env_map_luminance,
                self.area_power,
            );
            self.aov.assign_groups(scene, &mut set.lights);
            set
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
        if self.density_buffer {
            // The passes read this frame's density and every march mip from the buffers
            // (their atlases are unread placeholders); the previous density's atlas below.
            crate::passes::upload_density_quads(
                ctx,
                &o[r.density_texels],
                &cur.density_layout,
                &c.density,
            )?;
            let at = r.march_quads_at;
            for (base, layout, level) in [
                (at.reuse, &cur.march_reuse_layout, &c.march_reuse),
                (at.nee, &cur.march_nee_layout, &c.march_nee),
                (at.reuse_prev, &prev.march_reuse_layout, &p.march_reuse),
            ] {
                upload_march_quads(ctx, &o[r.march_quads], base, layout, level, format)?;
            }
        } else {
            upload_atlas(
                ctx,
                &o[r.density],
                sizes.density,
                &[(&cur.density_layout, &c.density, 1.0)],
                r32,
            )?;
            for (atlas, slots, layout, level) in [
                (
                    r.march_reuse,
                    sizes.march_reuse,
                    &cur.march_reuse_layout,
                    &c.march_reuse,
                ),
                (
                    r.march_nee,
                    sizes.march_nee,
                    &cur.march_nee_layout,
                    &c.march_nee,
                ),
                (
                    r.march_reuse_prev,
                    sizes.march_reuse,
                    &prev.march_reuse_layout,
                    &p.march_reuse,
                ),
            ] {
                upload_atlas(ctx, &o[atlas], slots, &[(layout, level, 1.0)], format)?;
            }
        }
        let levels = [
            (&cur.pc_primary_layout, &c.pc_primary, scale),
            (&cur.pc_indirect_layout, &c.pc_indirect, scale),
        ];
        if self.pc_buffer {
            upload_slot_major(ctx, &o[r.pc_texels], &levels)?;
        } else {
            upload_atlas(ctx, &o[r.pc], sizes.pc, &levels, r32)?;
        }
        upload_atlas(
            ctx,
            &o[r.density_prev],
            sizes.density,
            &[(&prev.density_layout, &p.density, 1.0)],
            r32,
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
        // spatial_when = "camera_moves": spatial reuse on frames whose camera moved; and
        // Q = temporal_limit_moving where the camera, the density or (under map reuse) the
        // environment map moved (choices made per frame from the two frames alone, never
        // from the samples, so the estimator stays unbiased).
        let camera_moved = scene.camera.frame_at(scene_frame) != camera;
        let density_moved =
            self.grid.density_index_at(scene_frame) != self.grid.density_index_at(prev_frame);
        // The two frames' lights where they are animated (else every frame's are the
        // scene's own).
        let lights = scene
            .lights_animated()
            .then(|| (scene.lights_at(prev_frame), scene.lights_at(scene_frame)));
        // With env_reuse = "map" a turning map turns every reused environment sample: the
        // history's paths are shifted paths whose targets drift frame after frame, as
        // under a moving camera (docs/restir.md, "A turning sky under map reuse").
        let map_turned = self.env_reuse_map
            && lights.as_ref().is_some_and(|(prev, cur)| {
                crate::plan::env_map_rotation(prev) != crate::plan::env_map_rotation(cur)
            });
        self.spatial_now = match self.spatial_when {
            nimbus_scene::SpatialWhen::Always => true,
            nimbus_scene::SpatialWhen::CameraMoves => camera_moved,
            nimbus_scene::SpatialWhen::CameraOrDensity => camera_moved || density_moved,
        };
        let temporal_limit =
            self.temporal_limits[usize::from(camera_moved || density_moved || map_turned)];
        // Whether the previous frame's target function is this frame's: the same camera,
        // light set and density (a static scene, or a held frame of an animation).
        let same = !camera_moved
            && !density_moved
            && lights.as_ref().is_none_or(|(prev, cur)| prev == cur);
        // 2: only the lights changed, and no velocity field moves the medium's points, so
        // the aligned neighbour is the pixel itself at the camera's full confidence.
        let flag = match (same, !camera_moved && !density_moved && !self.has_velocity) {
            (true, _) => HISTORY_STATIC,
            (false, true) => HISTORY_CAMERA_STILL,
            (false, false) => 0,
        };
        // The lights' confidence in the previous frame (1 when they did not change).
        let confidence = lights.as_ref().map_or(1.0, |(prev, cur)| {
            history::light_confidence(
                prev,
                cur,
                (self.grid.bounds_min + self.grid.bounds_max) * 0.5,
                self.env_irradiance(scene),
                self.env_change.as_ref(),
            )
        });
        self.frame_temporal_limit = temporal_limit;
        // Uploaded by `record` with the frame's M and Q, once.
        let same_density = u32::from(!density_moved);
        if flag != self.restir_uniforms.history_static
            || confidence != self.restir_uniforms.history_confidence
            || same_density != self.restir_uniforms.history_same_density
        {
            self.restir_uniforms.history_static = flag;
            self.restir_uniforms.history_confidence = confidence;
            self.restir_uniforms.history_same_density = same_density;
            self.uniforms_stale = true;
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
        // Frames in a row whose previous frame had this frame's target (none before the
        // first frame): once Q of them have filled the history, the settled M.
        self.still_run = match dispatch_index {
            0 => 0,
            _ if self.restir_uniforms.history_static == HISTORY_STATIC => {
                self.still_run.saturating_add(1)
            }
            _ => 0,
        };
        let (candidates, temporal_limit) = crate::plan::settled_candidates(
            self.settings.candidates,
            self.frame_temporal_limit,
            self.candidates_settled
                .filter(|_| self.still_run >= self.temporal_limits[0]),
        );
        if candidates != self.restir_uniforms.candidates
            || temporal_limit != self.restir_uniforms.temporal_limit
        {
            self.restir_uniforms.candidates = candidates;
            self.restir_uniforms.temporal_limit = temporal_limit;
            self.uniforms_stale = true;
        }
        if std::mem::take(&mut self.uniforms_stale) {
            ctx.upload_buffer(
                &self.objects[self.res.restir_uniforms],
                0,
                bytemuck::bytes_of(&self.restir_uniforms),
            )?;
        }
        let settings = ScheduleSettings {
            spatial_neighbors: if self.spatial_now {
                self.settings.spatial_neighbors
            } else {
                0
            },
            candidates,
            ..self.settings
        };
        let (dispatches, last) = schedule(dispatch_index, self.prev_slot, &settings);
        // Shading may reuse the cached F where the temporal stage kept the history's path:
        // on a still frame (its still pipeline, which clears the cache's flag where the
        // path changed) after a frame that shaded its history, with no spatial round
        // between the temporal stage and shading. Decided from the two frames alone.
        let temporal_still = self.res.temporal_still.is_some()
            && self.restir_uniforms.history_static == HISTORY_STATIC
            && dispatches.iter().any(|d| d.stage == Stage::Temporal);
        let spatial = dispatches.iter().any(|d| d.stage == Stage::Spatial);
        let shade_reuse = self.shade_cache
            && std::mem::take(&mut self.shaded_history)
            && temporal_still
            && !spatial;
        self.shaded_history = self.shade_cache
            && dispatches
                .last()
                .is_some_and(|d| d.stage == Stage::Shade && d.push.src == last);
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
            let mut push: RestirPush = d.push;
            if d.stage == Stage::Shade {
                push.aux = u32::from(shade_reuse);
            }
            // A still frame's temporal stage: the pipeline without the motion code.
            let (pipeline, set) = match self.res.temporal_still {
                Some(still)
                    if d.stage == Stage::Temporal
                        && self.restir_uniforms.history_static == HISTORY_STATIC =>
                {
                    still
                }
                _ => (self.res.pipelines[stage], self.res.sets[stage]),
            };
            self.objects[pipeline].dispatch(
                ctx,
                cmd,
                &self.objects[set],
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
        self.velocity_note
            .iter()
            .chain(&self.tracking_note)
            .cloned()
            .collect()
    }

    fn destroy(self: Box<Self>, ctx: &Context) {
        self.objects.destroy(ctx);
    }
}
