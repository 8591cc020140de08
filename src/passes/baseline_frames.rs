//! The baseline path tracer over animated density (`[[medium.frame]]`): one baseline
//! pass per density grid of the animation, each built as the static scene of that grid,
//! and the frame's grid picks the pass that dispatches (issue 26: the baseline refused
//! animated density, so ReSTIR's motion scenes had no equal-time reference).
//!
//! Every grid is resident at once (the memory guard counts each, `footprint`): simple and
//! exact, fit for the short animations of the studies; a sequence of hundreds of large
//! frames is refused by the guard before anything is allocated.

use anyhow::Result;
use nimbus_gpu::{vk, Context, Profiler};
use nimbus_scene::{GridMedium, Medium, Scene};

use super::baseline::{self, BaselinePass};
use super::{FrameUniforms, Pass, Targets};
use crate::budget::Footprint;
use crate::gpu::GpuGrid;
use crate::plan::BaselinePlan;

/// The grid medium of `scene` and its index among the media.
fn animated_grid(scene: &Scene) -> Option<(usize, &GridMedium)> {
    scene.media.iter().enumerate().find_map(|(i, m)| match m {
        Medium::Grid(g) if !g.frames.is_empty() => Some((i, g)),
        _ => None,
    })
}

/// Whether `scene`'s grid medium has density frames.
pub fn has_density_frames(scene: &Scene) -> bool {
    animated_grid(scene).is_some()
}

/// The static scene of density grid `index` (0: the base `density`, i: the i-th
/// `[[medium.frame]]`'s): the grid's density replaced, its frames dropped.
fn scene_of_grid(scene: &Scene, index: usize) -> Scene {
    let mut s = scene.clone();
    if let Some((m, grid)) = animated_grid(scene) {
        let density = grid
            .density_sources()
            .nth(index)
            .cloned()
            .unwrap_or_else(|| grid.density.clone());
        if let Medium::Grid(g) = &mut s.media[m] {
            g.density = density;
            g.frames.clear();
        }
    }
    s
}

/// One baseline pass per density grid; `active` dispatches.
pub struct BaselineFrames {
    passes: Vec<BaselinePass>,
    grid: GridMedium,
    active: usize,
}

/// Creates the passes of `plan` for every density grid of `scene`'s animation.
pub fn create(
    ctx: &Context,
    plan: &BaselinePlan,
    scene: &Scene,
    targets: &Targets,
) -> Result<BaselineFrames> {
    let Some((_, grid)) = animated_grid(scene) else {
        anyhow::bail!("internal: the animated baseline for a scene without density frames");
    };
    let mut passes = Vec::new();
    for index in 0..=grid.frames.len() {
        let s = scene_of_grid(scene, index);
        let made = GpuGrid::build(&s).and_then(|g| baseline::create(ctx, plan, &s, g, targets));
        match made {
            Ok(pass) => passes.push(pass),
            Err(e) => {
                for pass in passes {
                    Box::new(pass).destroy(ctx);
                }
                return Err(e);
            }
        }
    }
    Ok(BaselineFrames {
        passes,
        grid: grid.clone(),
        active: 0,
    })
}

/// What the passes allocate: every density grid's resources (see [`crate::budget`]).
pub fn footprint(scene: &Scene, f: &mut Footprint) -> Result<()> {
    let count = animated_grid(scene).map_or(0, |(_, g)| g.frames.len());
    for index in 0..=count {
        baseline::footprint(&scene_of_grid(scene, index), f)?;
    }
    Ok(())
}

impl Pass for BaselineFrames {
    fn label(&self) -> &'static str {
        self.passes[self.active].label()
    }

    fn frame_uniforms(&self, scene: &Scene, frame: u32) -> FrameUniforms {
        self.passes[self.active].frame_uniforms(scene, frame)
    }

    /// Picks the pass of the frame's density grid and lets it follow the lights.
    fn prepare(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        scene_frame: u32,
        previous_frame: u32,
    ) -> Result<()> {
        self.active = self.grid.density_index_at(scene_frame);
        self.passes[self.active].prepare(ctx, scene, scene_frame, previous_frame)
    }

    fn record(
        &mut self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        uniforms: &FrameUniforms,
        dispatch_index: u32,
        profiler: Option<&mut Profiler>,
    ) -> Result<()> {
        self.passes[self.active].record(ctx, cmd, uniforms, dispatch_index, profiler)
    }

    fn device_bytes(&self) -> u64 {
        self.passes.iter().map(Pass::device_bytes).sum()
    }

    fn destroy(self: Box<Self>, ctx: &Context) {
        for pass in self.passes {
            Box::new(pass).destroy(ctx);
        }
    }
}
