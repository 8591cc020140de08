//! The GPU timing report of `nimbus profile`: per-pass milliseconds from timestamp
//! queries (median, min, max over the measured frames) as a table and as JSON.

use std::fmt::Write as _;

use anyhow::Result;
use nimbus_gpu::{summarize, Context, PassStats};
use nimbus_scene::Scene;

use crate::renderer::RenderResult;

/// What was measured, on which device, for which scene.
pub struct Report {
    pub device: String,
    pub scene: String,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub frames: usize,
    pub passes: Vec<PassStats>,
    /// Each measured frame's GPU milliseconds (its top-level scopes), in order: a median
    /// hides a frame that alternates between two costs, which this shows.
    pub frame_ms: Vec<f64>,
    /// The work counters, when the render counted them.
    pub work: Option<crate::shader_data::counters::WorkCounts>,
    /// Measured with `--coherent-lanes` (a diagnostic: not the scene's image).
    pub coherent_lanes: bool,
}

impl Report {
    pub fn new(ctx: &Context, scene: &Scene, result: &RenderResult) -> Self {
        Self {
            device: ctx.info().name.clone(),
            scene: scene.source.display().to_string(),
            width: scene.render.width,
            height: scene.render.height,
            spp: scene.render.spp,
            frames: result.frame_timings.len(),
            passes: summarize(&result.frame_timings),
            frame_ms: result
                .frame_timings
                .iter()
                .map(|f| f.iter().map(|s| s.duration_ms()).sum())
                .collect(),
            work: result.work.clone(),
            coherent_lanes: false,
        }
    }

    /// A fixed-width table, one row per pass.
    pub fn table(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{} on {} ({}x{}, {} spp), {} measured frames",
            self.scene, self.device, self.width, self.height, self.spp, self.frames
        );
        if self.coherent_lanes {
            let _ = writeln!(
                out,
                "coherent lanes: every 8x8 workgroup of the baseline and crepuscular passes \
                 traced its first pixel's samples (ReSTIR's passes as usual); divide a plain \
                 profile's ms by these for the cost of divergence"
            );
        }
        let _ = writeln!(
            out,
            "{:<32} {:>10} {:>10} {:>10} {:>10}",
            "pass", "median ms", "min ms", "max ms", "mean ms"
        );
        for p in &self.passes {
            let _ = writeln!(
                out,
                "{:<32} {:>10.3} {:>10.3} {:>10.3} {:>10.3}",
                p.label, p.median_ms, p.min_ms, p.max_ms, p.mean_ms
            );
        }
        let _ = write!(out, "frame ms in order:");
        for ms in &self.frame_ms {
            let _ = write!(out, " {ms:.3}");
        }
        let _ = writeln!(out);
        out
    }

    pub fn json(&self) -> Result<String> {
        let passes: Vec<serde_json::Value> = self
            .passes
            .iter()
            .map(|p| {
                serde_json::json!({
                    "pass": p.label,
                    "median_ms": p.median_ms,
                    "min_ms": p.min_ms,
                    "max_ms": p.max_ms,
                    "mean_ms": p.mean_ms,
                    "frames": p.samples,
                })
            })
            .collect();
        let doc = serde_json::json!({
            "device": self.device,
            "scene": self.scene,
            "width": self.width,
            "height": self.height,
            "spp": self.spp,
            "frames": self.frames,
            "coherent_lanes": self.coherent_lanes,
            "passes": passes,
            "frame_ms": self.frame_ms,
            "work": self.work.as_ref().map(|w| w.json()),
        });
        Ok(serde_json::to_string_pretty(&doc)?)
    }
}
