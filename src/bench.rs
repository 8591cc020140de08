//! `nimbus bench`: the cost of a sample, measured and compared with a stored baseline.
//!
//! Every case renders one small benchmark scene (embedded in the binary, so the command
//! needs no repository) with the work counters on ([`crate::shader_data::counters`]) and the
//! timestamp profiler, and reports per pass the median GPU milliseconds per frame and per
//! camera sample, every counter per camera sample and the dispatches per frame. The
//! baseline file (`assets/bench/baseline.json`, written by `nimbus bench --update`) holds
//! the same numbers from an earlier run; each is shown with its ratio to it.
//!
//! Counts are deterministic for a scene, seed and device, so a counter that moves past
//! [`COUNTER_MARGIN`] is a change of the work itself, not noise: `nimbus bench` exits 1
//! and `tests/suite/contracts/counters.rs` fails. Timings compare only on the baseline's device and
//! are shown, never judged (machines are shared; compare binaries in one run with
//! `--compare`). `docs/performance.md` says how to read the report and holds its history.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _, Result};
use nimbus_gpu::{summarize, Context};
use nimbus_scene::{FieldOverride, Scene};
use serde::{Deserialize, Serialize};

use crate::renderer::{self, RenderOptions};
use crate::shader_data::counters::NAMES;

/// A counter per sample may move by this factor (either way) before it counts as a
/// regression (or an unexplained drop): far outside the few per cent that a change of
/// random numbers moves them, well inside the 2x of a real cost regression.
pub const COUNTER_MARGIN: f64 = 1.4;

/// Counters per sample below this are too rare to judge by ratio (a few events).
pub const COUNTER_FLOOR: f64 = 0.05;

/// One benchmark case: an embedded scene with overrides.
pub struct Case {
    pub name: &'static str,
    /// What it measures.
    pub what: &'static str,
    source: &'static str,
    text: &'static str,
    overrides: &'static [&'static str],
    warmup: u32,
}

const PERF_CLOUD: &str = include_str!("../assets/bench/perf-cloud.toml");
const WINDOW: &str = include_str!("../assets/scenes/window.toml");
const BOX_SPHERE: &str = include_str!("../assets/scenes/box-sphere.toml");

/// The benchmark cloud under a camera that orbits about 0.9 px per frame at 48 px wide
/// (issue 26's motion passes: temporal reuse re-evaluated on a new camera, spatial reuse).
const PERF_CLOUD_MOVING: &str = concat!(
    include_str!("../assets/bench/perf-cloud.toml"),
    "\n[[camera.keyframe]]\nframe = 0\nposition = [0.0, 0.2, 2.4]\nlook_at = [0.0, 0.0, 0.0]\n\n\
     [[camera.keyframe]]\nframe = 8\nposition = [0.3, 0.2, 2.3]\nlook_at = [0.0, 0.0, 0.0]\n"
);

/// The benchmark cases, small enough for lavapipe in CI (a few seconds each).
pub const CASES: [Case; 6] = [
    Case {
        name: "baseline-k3",
        what: "64³ cloud, sigma_t <= 20/m, K = 3: decomposition + residual ratio tracking",
        source: "assets/bench/perf-cloud.toml",
        text: PERF_CLOUD,
        overrides: &[
            "render.width=48",
            "render.height=48",
            "render.spp=4",
            "render.frames=2",
        ],
        warmup: 1,
    },
    Case {
        name: "baseline-k1",
        what: "the same cloud, single scattering",
        source: "assets/bench/perf-cloud.toml",
        text: PERF_CLOUD,
        overrides: &[
            "render.width=48",
            "render.height=48",
            "render.spp=4",
            "render.frames=2",
            "integrator.max_bounces=1",
        ],
        warmup: 1,
    },
    Case {
        name: "restir-k3",
        what: "the same cloud by Volumetric ReSTIR (its defaults), K = 3",
        source: "assets/bench/perf-cloud.toml",
        text: PERF_CLOUD,
        overrides: &[
            "render.width=48",
            "render.height=48",
            "render.spp=1",
            "render.frames=3",
            "integrator.volume=\"restir\"",
        ],
        warmup: 2,
    },
    Case {
        name: "restir-motion-k3",
        what: "the same cloud by ReSTIR under an orbiting camera: temporal reuse aligned on the \
               new camera, spatial reuse on the moving frames",
        source: "assets/bench/perf-cloud.toml",
        text: PERF_CLOUD_MOVING,
        overrides: &[
            "render.width=48",
            "render.height=48",
            "render.spp=1",
            "render.frames=4",
            "integrator.volume=\"restir\"",
        ],
        warmup: 2,
    },
    Case {
        name: "crepuscular-window",
        what: "the default scene: box medium, window, MCWVDS",
        source: "assets/scenes/window.toml",
        text: WINDOW,
        overrides: &["render.width=48", "render.height=36", "render.frames=2"],
        warmup: 1,
    },
    Case {
        name: "crepuscular-box-sphere",
        what: "box medium with a sphere occluder, MCWVDS, K = 1",
        source: "assets/scenes/box-sphere.toml",
        text: BOX_SPHERE,
        overrides: &["render.width=48", "render.height=36", "render.frames=2"],
        warmup: 1,
    },
];

impl Case {
    /// The case's scene with its overrides.
    pub fn scene(&self) -> Result<Scene> {
        let overrides = self
            .overrides
            .iter()
            .map(|o| FieldOverride::parse(o))
            .collect::<Result<Vec<_>>>()?;
        nimbus_scene::parse_str_with(self.text, &PathBuf::from(self.source), &overrides)
            .with_context(|| format!("bench case {}", self.name))
    }
}

/// What one case measured.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CaseResult {
    /// Camera samples per frame (pixels x spp).
    pub samples_per_frame: u64,
    /// Median GPU milliseconds per frame, per profiler scope (`frame/...`).
    pub ms_per_frame: BTreeMap<String, f64>,
    /// Per stage, each counter per camera sample.
    pub counters: BTreeMap<String, BTreeMap<String, f64>>,
    pub dispatches_per_frame: f64,
}

impl CaseResult {
    /// GPU nanoseconds per camera sample of the whole frame.
    pub fn ns_per_sample(&self) -> f64 {
        let ms = self.ms_per_frame.get("frame").copied().unwrap_or(0.0);
        ms * 1e6 / self.samples_per_frame.max(1) as f64
    }
}

/// A whole benchmark run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BenchReport {
    pub device: String,
    /// `nimbus --version` of the binary that measured it.
    pub version: String,
    pub cases: BTreeMap<String, CaseResult>,
}

/// Renders `case` with counters and timestamps on `ctx`.
pub fn run_case(ctx: &Context, case: &Case) -> Result<CaseResult> {
    let scene = case.scene()?;
    let plan = crate::plan::build(&scene, None)?;
    let opts = RenderOptions {
        warmup_frames: case.warmup,
        // The moving case's warm-up renders its first scene frames and the measured
        // frames follow them (all of them moving frames).
        first_frame: case.warmup,
        counters: true,
        skip_alpha: true,
        // A GPU at its working clocks (renderer::settle); nothing on lavapipe.
        settle: renderer::settle::DEFAULT_SETTLE,
        ..Default::default()
    };
    let result = renderer::render(ctx, &scene, &plan, &opts)
        .with_context(|| format!("bench case {}", case.name))?;
    let work = result
        .work
        .context("internal: a counting render returned no counts")?;
    let ms_per_frame = summarize(&result.frame_timings)
        .into_iter()
        .map(|p| (p.label, p.median_ms))
        .collect();
    let counters = work
        .slots
        .iter()
        .filter(|s| s.get("samples") > 0)
        .map(|s| {
            let per = NAMES
                .iter()
                .skip(1)
                .map(|(name, _)| ((*name).to_string(), s.per_sample(name)))
                .collect();
            (s.label.clone(), per)
        })
        .collect();
    let r = &scene.render;
    Ok(CaseResult {
        samples_per_frame: u64::from(r.width) * u64::from(r.height) * u64::from(r.spp.max(1)),
        ms_per_frame,
        counters,
        dispatches_per_frame: work.dispatches_per_frame(),
    })
}

/// Runs every case whose name contains `filter` (all without one).
pub fn run(ctx: &Context, filter: Option<&str>) -> Result<BenchReport> {
    let mut cases = BTreeMap::new();
    for case in CASES
        .iter()
        .filter(|c| filter.is_none_or(|f| c.name.contains(f)))
    {
        cases.insert(case.name.to_string(), run_case(ctx, case)?);
    }
    if cases.is_empty() {
        bail!(
            "no bench case matches {:?} (cases: {})",
            filter.unwrap_or(""),
            CASES.iter().map(|c| c.name).collect::<Vec<_>>().join(", ")
        );
    }
    Ok(BenchReport {
        device: ctx.info().name.clone(),
        version: env!("CARGO_PKG_VERSION").to_string(),
        cases,
    })
}

/// The device's family: its name up to the first parenthesis ("llvmpipe" for every
/// lavapipe build and vector width). Counters compare within a family: another build of
/// the same driver rounds a few paths differently, well inside [`COUNTER_MARGIN`].
pub fn device_family(name: &str) -> &str {
    name.split('(').next().unwrap_or(name).trim()
}

/// The stored baseline at `path`.
pub fn load_baseline(path: &Path) -> Result<BenchReport> {
    // A regular file of a report's size: a device such as /dev/zero would be read until
    // memory runs out.
    let meta = std::fs::metadata(path).with_context(|| format!("reading {}", path.display()))?;
    anyhow::ensure!(
        meta.is_file() && meta.len() <= 64 << 20,
        "{}: not a bench report (not a regular file of at most 64 MiB)",
        path.display()
    );
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}: not a bench report", path.display()))
}

/// Writes `report` to `path` as JSON.
pub fn save(report: &BenchReport, path: &Path) -> Result<()> {
    let text = serde_json::to_string_pretty(report)?;
    std::fs::write(path, text + "\n").with_context(|| format!("writing {}", path.display()))
}

/// A counter that moved past [`COUNTER_MARGIN`] against the baseline.
#[derive(Clone, Debug, PartialEq)]
pub struct Regression {
    pub case: String,
    pub stage: String,
    pub counter: String,
    pub baseline: f64,
    pub now: f64,
}

impl std::fmt::Display for Regression {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let unit = if self.counter == "dispatches_per_frame" {
            "per frame"
        } else {
            "per sample"
        };
        write!(
            f,
            "{} {} {}: {:.3} {unit}, baseline {:.3} ({:.2}x; allowed {:.2}x either way)",
            self.case,
            self.stage,
            self.counter,
            self.now,
            self.baseline,
            ratio(self.now, self.baseline),
            COUNTER_MARGIN
        )
    }
}

fn ratio(now: f64, base: f64) -> f64 {
    if base > 0.0 {
        now / base
    } else if now > 0.0 {
        f64::INFINITY
    } else {
        1.0
    }
}

/// Every counter of `now` that moved past [`COUNTER_MARGIN`] against `base` (cases and
/// stages missing on either side count too: the suite changed without a new baseline).
pub fn regressions(now: &BenchReport, base: &BenchReport) -> Vec<Regression> {
    let mut out = Vec::new();
    let mut push = |case: &str, stage: &str, counter: &str, b: f64, n: f64| {
        out.push(Regression {
            case: case.into(),
            stage: stage.into(),
            counter: counter.into(),
            baseline: b,
            now: n,
        })
    };
    for (name, n) in &now.cases {
        let Some(b) = base.cases.get(name) else {
            push(name, "-", "case missing from the baseline", 0.0, 1.0);
            continue;
        };
        let r = ratio(n.dispatches_per_frame, b.dispatches_per_frame);
        if !(1.0 / COUNTER_MARGIN..=COUNTER_MARGIN).contains(&r) {
            push(
                name,
                "-",
                "dispatches_per_frame",
                b.dispatches_per_frame,
                n.dispatches_per_frame,
            );
        }
        for (stage, counters) in &n.counters {
            let Some(base_stage) = b.counters.get(stage) else {
                push(name, stage, "stage missing from the baseline", 0.0, 1.0);
                continue;
            };
            for (counter, &value) in counters {
                let bv = base_stage.get(counter).copied().unwrap_or(0.0);
                if value.max(bv) < COUNTER_FLOOR {
                    continue;
                }
                let r = ratio(value, bv);
                if !(1.0 / COUNTER_MARGIN..=COUNTER_MARGIN).contains(&r) {
                    push(name, stage, counter, bv, value);
                }
            }
        }
    }
    out
}

/// The report as text: per case, ms per frame and per sample, then the counters per
/// sample; with `base`, each with its ratio to the baseline.
pub fn table(now: &BenchReport, base: Option<&BenchReport>) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "device: {}", now.device);
    if let Some(b) = base {
        let _ = writeln!(
            out,
            "baseline: {} ({}){}",
            b.device,
            b.version,
            if device_family(&b.device) == device_family(&now.device) {
                ""
            } else {
                " — another device: compare its timings with care"
            }
        );
    }
    for (name, c) in &now.cases {
        let b = base.and_then(|b| b.cases.get(name));
        let what = CASES.iter().find(|k| k.name == name).map_or("", |k| k.what);
        let _ = writeln!(out, "\n{name}: {what}");
        let cell = |now: f64, base: Option<f64>| match base {
            Some(b) => format!("{now:>12.3} {b:>12.3} {:>7.2}x", ratio(now, b)),
            None => format!("{now:>12.3}"),
        };
        let header = if b.is_some() {
            format!("{:>12} {:>12} {:>8}", "now", "baseline", "ratio")
        } else {
            format!("{:>12}", "now")
        };
        let _ = writeln!(out, "  {:<34} {header}", "GPU ms per frame");
        for (pass, ms) in &c.ms_per_frame {
            let base_ms = b.and_then(|b| b.ms_per_frame.get(pass).copied());
            let _ = writeln!(out, "  {:<34} {}", pass, cell(*ms, base_ms));
        }
        let _ = writeln!(
            out,
            "  {:<34} {}",
            "GPU ns per sample",
            cell(c.ns_per_sample(), b.map(|b| b.ns_per_sample()))
        );
        let _ = writeln!(
            out,
            "  {:<34} {}",
            "dispatches per frame",
            cell(c.dispatches_per_frame, b.map(|b| b.dispatches_per_frame))
        );
        for (stage, counters) in &c.counters {
            let _ = writeln!(out, "  {stage} work per sample");
            for (counter, value) in counters {
                let bv = b
                    .and_then(|b| b.counters.get(stage))
                    .and_then(|s| s.get(counter).copied());
                let _ = writeln!(out, "    {:<32} {}", counter, cell(*value, bv));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(steps: f64, dispatches: f64) -> BenchReport {
        let mut counters = BTreeMap::new();
        counters.insert(
            "baseline".to_string(),
            [
                ("steps".to_string(), steps),
                ("bvh_nodes".to_string(), 0.01),
            ]
            .into_iter()
            .collect(),
        );
        let mut cases = BTreeMap::new();
        cases.insert(
            "c".to_string(),
            CaseResult {
                samples_per_frame: 100,
                ms_per_frame: [("frame".to_string(), 2.0)].into_iter().collect(),
                counters,
                dispatches_per_frame: dispatches,
            },
        );
        BenchReport {
            device: "d".into(),
            version: "0".into(),
            cases,
        }
    }

    #[test]
    fn a_doubled_counter_or_dispatch_count_is_a_regression_and_noise_is_not() {
        let base = report(10.0, 1.0);
        assert!(regressions(&report(11.0, 1.0), &base).is_empty());
        assert!(regressions(&report(9.0, 1.0), &base).is_empty());
        let r = regressions(&report(20.0, 1.0), &base);
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].counter, "steps");
        // A halving is flagged too: the baseline no longer describes the work.
        assert_eq!(regressions(&report(5.0, 1.0), &base).len(), 1);
        // 16 dispatches per frame instead of 1 (one per sample).
        let r = regressions(&report(10.0, 16.0), &base);
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].counter, "dispatches_per_frame");
        // A case the baseline lacks.
        let mut other = report(10.0, 1.0);
        let c = other.cases.remove("c").expect("case");
        other.cases.insert("new".into(), c);
        assert_eq!(regressions(&other, &base).len(), 1);
    }

    #[test]
    fn every_case_parses() {
        for case in &CASES {
            case.scene().expect("bench scene");
        }
    }

    #[test]
    fn ns_per_sample_divides_the_frame_by_its_samples() {
        assert_eq!(report(1.0, 1.0).cases["c"].ns_per_sample(), 2.0e6 / 100.0);
    }
}
