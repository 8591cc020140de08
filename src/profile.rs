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
    /// The settling load before the measured frames, where it applied (not on a CPU
    /// device): `renderer::settle`.
    pub settled: Option<std::time::Duration>,
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
            settled: None,
        }
    }

    /// A warning when the measured frames fall into two costs: the median of the slowest
    /// quarter over 1.5x the fastest quarter's (at least 8 frames, so that one slow first
    /// frame is not a quarter). Either the work
    /// changed between frames (an animation whose frames differ) or the device's state
    /// did: an H200's first frames of a freshly built pipeline ran at 12.2 ms and then
    /// 2.67 ms, with the same work (docs/gpu/h200-2026-11-28-6fe5952).
    pub fn timing_warning(&self) -> Option<String> {
        let mut ms: Vec<f64> = self
            .frame_ms
            .iter()
            .copied()
            .filter(|t| t.is_finite())
            .collect();
        if ms.len() < 8 {
            return None;
        }
        ms.sort_by(f64::total_cmp);
        let q = ms.len() / 4;
        let fast = ms[q / 2];
        let slow = ms[ms.len() - 1 - q / 2];
        (fast > 0.0 && slow > 1.5 * fast).then(|| {
            format!(
                "warning: the measured frames fall into two costs ({fast:.3} ms for the \
                 fastest quarter, {slow:.3} ms for the slowest, {:.1}x; 'frame ms in order' \
                 shows when): either their work differs (an animation's frames) or the \
                 device changed state during the measurement (its clocks, or a pipeline its \
                 driver was still optimising), and then neither median nor mean is the \
                 cost of one state: raise --warmup or --settle-ms and profile again",
                slow / fast
            )
        })
    }

    /// A fixed-width table, one row per pass.
    pub fn table(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{} on {} ({}x{}, {} spp), {} measured frames",
            self.scene, self.device, self.width, self.height, self.spp, self.frames
        );
        if let Some(settled) = self.settled.filter(|d| !d.is_zero()) {
            let _ = writeln!(
                out,
                "settled: {} ms of arithmetic load before the first measured frame",
                settled.as_millis()
            );
        }
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
            "settle_ms": self.settled.map(|d| d.as_millis() as u64),
            "passes": passes,
            "frame_ms": self.frame_ms,
            "work": self.work.as_ref().map(|w| w.json()),
        });
        Ok(serde_json::to_string_pretty(&doc)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(frame_ms: &[f64]) -> Report {
        Report {
            device: "gpu".into(),
            scene: "s.toml".into(),
            width: 8,
            height: 8,
            spp: 1,
            frames: frame_ms.len(),
            passes: Vec::new(),
            frame_ms: frame_ms.to_vec(),
            work: None,
            coherent_lanes: false,
            settled: None,
        }
    }

    #[test]
    fn frames_of_two_costs_are_flagged() {
        // The H200's first profile of the baseline (2026-11-28): 11 frames of a slow
        // state, then 5 at the pipeline's real cost.
        let mut two = vec![12.2; 11];
        two.extend([2.67; 5]);
        let w = report(&two).timing_warning().expect("a warning");
        assert!(
            w.contains("2.670 ms for the fastest quarter, 12.200 ms"),
            "{w}"
        );
        // One state, with noise and one slow first frame: no warning.
        let mut one = vec![2.68, 2.66, 2.71, 2.69, 2.70, 2.65, 2.67, 2.68];
        one[0] = 4.5;
        assert_eq!(report(&one).timing_warning(), None);
        // Too few frames to tell.
        assert_eq!(report(&[29.3, 18.0, 13.1, 14.2]).timing_warning(), None);
    }
}
