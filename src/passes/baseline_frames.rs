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
use nimbus_scene::{GridMedium, Scene};

use super::baseline::{self, BaselinePass};
use super::{FrameUniforms, Pass, Targets};
use crate::plan::{animated_grid, scene_of_grid, BaselinePlan};
use crate::shader_data::GpuGrid;

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
