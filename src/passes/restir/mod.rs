//! Volumetric ReSTIR (`shaders/restir/*.comp`): initial candidates, temporal reuse,
//! spatial reuse and final shading, with reservoirs that persist across frames.
//!
//! - [`schedule`]: which stages a frame dispatches on which of the three reservoir slots
//!   (pure, unit-tested);
//! - [`volumes`]: the piecewise-constant levels and ray-march mips derived from every
//!   density grid of the animation;
//! - [`resources`]: the GPU objects, by name.
//!
//! Reservoirs live in one storage buffer of three slots of `pixels × stride` u32 each
//! (`stride = 8 + 2K`: a 32-byte header and 8 bytes per path vertex, see
//! `shaders/include/reservoir.glsl`).

pub mod resources;
pub mod schedule;
pub mod volumes;

use anyhow::Result;
use nimbus_gpu::{compute_barrier, vk, Context, GpuObjects, Profiler, SpecValue};
use nimbus_scene::{CameraFrame, GridMedium, Scene};

use self::resources::{Inputs, Resources};
use self::schedule::{schedule, ScheduleSettings, Stage, SLOTS};
use self::volumes::{last_level, march_step, Volumes};
use super::{image_groups, scene_grid, FrameConstants, Pass, Targets};
use crate::budget::{grid_bytes, level_dims, Binding, Footprint};
use crate::gpu::features::*;
use crate::gpu::{
    frame_uniforms, non_empty, BaselineUniformsGpu, FrameUniforms, GpuGrid, LightGpu, LightSet,
    RecordCounts, RestirPush, RestirUniformsGpu,
};
use crate::plan::RestirPlan;

pub use crate::gpu::reservoir_bytes;

/// The specialization constants of the ReSTIR shaders for a plan.
pub fn specialization(plan: &RestirPlan) -> [(u32, SpecValue); 9] {
    [
        (SC_ID_HAS_ENV, SpecValue::Bool(plan.has_env)),
        (SC_ID_MAX_BOUNCES, SpecValue::U32(plan.max_bounces)),
        (SC_ID_PIXEL_JITTER, SpecValue::Bool(plan.pixel_jitter)),
        (SC_ID_HAS_EMISSION, SpecValue::Bool(plan.has_emission)),
        (SC_ID_HAS_ENV_MAP, SpecValue::Bool(plan.has_env_map)),
        (SC_ID_REUSE_VERTEX, SpecValue::Bool(plan.vertex_reuse)),
        (
            SC_ID_FINAL_RATIO_TRACKING,
            SpecValue::Bool(plan.final_ratio_tracking),
        ),
        (SC_ID_HAS_VELOCITY, SpecValue::Bool(plan.has_velocity)),
        (SC_ID_MIS_PAIRWISE, SpecValue::Bool(plan.pairwise_mis)),
    ]
}

/// Loop iterations one candidate walk costs, per segment: the blocks of the
/// piecewise-constant level it tracks through (camera segment, then scattered ones), the
/// NEE ray march, and the loops over the lights (nearest emitter, selection, shadow).
pub struct CandidateCost {
    pub pc_blocks: [u32; 2],
    pub march_steps: u32,
    pub lights: u32,
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
    let segment = |blocks: u32| u64::from(blocks + cost.march_steps + 3 * cost.lights + 64);
    let k = u64::from(plan.max_bounces.max(1));
    let per_candidate = segment(cost.pc_blocks[0]) + (k - 1) * segment(cost.pc_blocks[1]) + k;
    let fit = (u64::from(budget / 2) / per_candidate.max(1)).max(1);
    u32::try_from(fit).unwrap_or(u32::MAX).min(plan.candidates)
}

/// The four stages, what they read, and the state carried from frame to frame.
pub struct RestirPass {
    objects: GpuObjects,
    res: Resources,
    settings: ScheduleSettings,
    constants: FrameConstants,
    grid: GridMedium,
    volumes: Volumes,
    scene_lights_radius: f32,
    env_map_luminance: Option<f32>,
    base_uniforms: BaselineUniformsGpu,
    /// Density indices loaded into the current / previous images.
    loaded: (usize, usize),
    /// The slot holding the previous frame's final reservoirs.
    prev_slot: Option<u32>,
    /// The previous-frame uniforms last uploaded.
    prev_uploaded: Option<FrameUniforms>,
    /// The levels the plan asked for (the volumes hold those used).
    plan_levels: volumes::Levels,
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
        let reservoir_total = u64::from(SLOTS) * pixels * stride_bytes;
        let velocity = match &grid.velocity {
            Some(source) if plan.has_velocity => Some(nimbus_scene::load_grid(
                source,
                3,
                &format!("{grid_label} > velocity"),
            )?),
            _ => None,
        };
        // The density moves into `volumes`; the rest of the grid records are uploaded.
        let density = std::mem::take(&mut grid_gpu.density);
        let dims = density.dims;
        let size = grid.bounds_max - grid.bounds_min;
        let volumes = Volumes::load(density, grid, plan, &scene.position_scale(), &grid_label)?;
        let first = volumes.base()?;
        let levels = volumes.levels;
        // Voxels per block edge of a mip level.
        let factor = |level: u32| 1 << level.min(last_level(dims));
        let candidates_per_dispatch = candidates_per_dispatch(
            ctx.info().loop_budget(),
            plan,
            &CandidateCost {
                pc_blocks: [first.pc_primary_dims, first.pc_indirect_dims]
                    .map(|d| d.iter().sum::<u32>() + 3),
                march_steps: (size.length() / march_step(grid, dims, levels.indirect))
                    .ceil()
                    .min(crate::gpu::features::MARCH_MAX_STEPS as f32)
                    as u32,
                lights: grid_gpu.lights.len() as u32,
            },
        );
        let restir_uniforms = RestirUniformsGpu {
            pc_primary_dims: first.pc_primary_dims,
            pc_primary_offset: 0,
            pc_indirect_dims: first.pc_indirect_dims,
            pc_indirect_offset: first.pc_indirect_offset,
            pc_primary_factor: factor(levels.candidates),
            pc_indirect_factor: factor(levels.indirect),
            march_reuse_factor: factor(levels.reuse),
            march_nee_factor: factor(levels.indirect),
            march_reuse_dims: first.march_reuse.dims,
            march_nee_dims: first.march_nee.dims,
            candidates: plan.candidates,
            temporal_limit: plan.temporal_limit,
            spatial_neighbors: plan.spatial_neighbors,
            reservoir_stride: (stride_bytes / 4) as u32,
            candidates_per_dispatch,
            spatial_radius: plan.spatial_radius_px,
            march_reuse_step: march_step(grid, dims, levels.reuse),
            march_nee_step: march_step(grid, dims, levels.indirect),
            velocity_dims: velocity.as_ref().map_or([1, 1, 1], |v| v.dims),
            ..RestirUniformsGpu::default()
        };
        let inputs = Inputs {
            grid: &grid_gpu,
            first,
            velocity: velocity.as_ref(),
            uniforms: &restir_uniforms,
            reservoir_bytes: reservoir_total,
            march_format: volumes.format,
        };
        let spec = specialization(plan);
        let (objects, res) =
            GpuObjects::build(ctx, |o| Resources::create(ctx, o, &spec, &inputs, targets))?;
        Ok(RestirPass {
            objects,
            res,
            settings: ScheduleSettings {
                temporal: plan.temporal,
                spatial_neighbors: plan.spatial_neighbors,
                spatial_rounds: plan.spatial_rounds,
                candidates: plan.candidates,
                candidates_per_dispatch,
                history_before_spatial: plan.history_before_spatial,
            },
            constants: FrameConstants {
                env_radiance: grid_gpu.env_radiance,
                counts: RecordCounts {
                    lights: grid_gpu.lights.len() as u32,
                    ..RecordCounts::default()
                },
            },
            grid: grid.clone(),
            volumes,
            scene_lights_radius: grid_gpu.light_radius,
            env_map_luminance: grid_gpu.env_map_luminance,
            base_uniforms: grid_gpu.uniforms,
            loaded: (0, 0),
            prev_slot: None,
            prev_uploaded: None,
            plan_levels: volumes::Levels {
                candidates: plan.mip_candidates,
                indirect: plan.mip_indirect,
                reuse: plan.mip_reuse,
            },
        })
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

    /// Uploads the density of this frame and of the previous one when they change.
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
        ctx.upload_image(&o[r.density], bytemuck::cast_slice(&cur.density.data))?;
        ctx.upload_image(&o[r.march_reuse], &cur.march_reuse.texels)?;
        ctx.upload_image(&o[r.march_nee], &cur.march_nee.texels)?;
        ctx.upload_buffer(&o[r.pc_grid], 0, bytemuck::cast_slice(&cur.pc))?;
        ctx.upload_image(&o[r.density_prev], bytemuck::cast_slice(&prev.density.data))?;
        ctx.upload_image(&o[r.march_reuse_prev], &prev.march_reuse.texels)?;
        self.loaded = want;
        Ok(())
    }
}

impl Pass for RestirPass {
    fn label(&self) -> &'static str {
        "restir"
    }

    fn frame_uniforms(&self, scene: &Scene, camera: &CameraFrame) -> FrameUniforms {
        self.constants.uniforms(scene, camera)
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
        // The previous frame's camera (the first frame's own camera on frame 0).
        let camera = scene.camera.frame_at(prev_frame);
        let prev = frame_uniforms(
            scene,
            &camera,
            self.constants.env_radiance,
            self.constants.counts,
        );
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
        self.upload_density(ctx, scene_frame, prev_frame)
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
        let (dispatches, last) = schedule(dispatch_index, self.prev_slot, &self.settings);
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
        let asked = (
            self.plan_levels.candidates,
            self.plan_levels.indirect,
            self.plan_levels.reuse,
        );
        if (l.candidates, l.indirect, l.reuse) == asked {
            return Vec::new();
        }
        vec![format!(
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
        )]
    }

    fn destroy(self: Box<Self>, ctx: &Context) {
        self.objects.destroy(ctx);
    }
}

/// What the ReSTIR passes allocate (see [`crate::budget`]).
pub fn footprint(scene: &Scene, p: &RestirPlan, f: &mut Footprint) -> Result<()> {
    f.add_env_map(scene)?;
    let Some((g, table, dims)) = f.add_grid(scene)? else {
        return Ok(());
    };
    let file = scene.source.display();
    let r = &scene.render;
    let pixels = u64::from(r.width) * u64::from(r.height);
    let voxels = grid_bytes(dims, 1);
    let reservoirs = 3 * pixels * reservoir_bytes(p.max_bounces);
    f.add(
        format!("{file}: [render] `width` x `height` with [integrator] `max_bounces` = {} (ReSTIR reservoirs)", p.max_bounces),
        Binding::Storage,
        reservoirs,
    );
    let primary = level_dims(dims, p.mip_candidates);
    let indirect = level_dims(dims, p.mip_indirect);
    let reuse = level_dims(dims, p.mip_reuse);
    f.add(
        format!("{table} (piecewise-constant levels)"),
        Binding::Storage,
        grid_bytes(primary, 4) + grid_bytes(indirect, 4),
    );
    // Previous-frame density and the ray-march mips (f16, or f32 for densities f16
    // cannot hold: counted as f32).
    f.add(
        format!("{table} (previous density)"),
        Binding::Image3d(dims),
        voxels * 4,
    );
    for (name, d) in [
        ("reuse", reuse),
        ("reuse, previous", reuse),
        ("NEE", indirect),
    ] {
        f.add(
            format!("{table} (ray-march mip, {name})"),
            Binding::Image3d(d),
            grid_bytes(d, 4),
        );
    }
    if let Some(v) = &g.velocity {
        let vd = v.dims()?;
        f.add(
            format!("{table} field `velocity`"),
            Binding::Image3d(vd),
            grid_bytes(vd, 8),
        );
        f.host_peak += grid_bytes(vd, 12 + 8);
    }
    // Every density frame is derived and kept: the grid, its levels and mips; while
    // one is built, its conservative copy and one mip level are alive too.
    let derived = |d: [u32; 3]| {
        grid_bytes(d, 4)
            + grid_bytes(primary, 4)
            + grid_bytes(indirect, 4)
            + grid_bytes(reuse, 4)
            + grid_bytes(indirect, 4)
    };
    let frames: Vec<&nimbus_scene::GridSource> = g.density_sources().collect();
    let kept: u64 = frames
        .iter()
        .map(|s| s.dims().map(derived))
        .sum::<Result<u64>>()?;
    let building = grid_bytes(dims, 4) + grid_bytes(level_dims(dims, 1), 4);
    f.host_peak += kept + building;
    Ok(())
}
