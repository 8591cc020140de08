//! `nimbus study`: what accuracy costs in GPU time.
//!
//! A study renders one scene under every configuration of the `--vary KEY=V1,V2,...`
//! lists (their cartesian product, the first `--vary` outermost) and measures each
//! image against a converged reference of the same integrand. The protocol:
//!
//! - **Seeds.** Every configuration renders `--seeds N` times (default 3), with N seeds
//!   derived from the scene's seed ([`derive_seeds`]: the scene's seed, then the next
//!   ones, skipping any whose 32-bit fold ([`fold_seed`], what the shaders see) repeats
//!   an earlier one's or the reference's). `--vary seed` picks the seeds by hand instead
//!   and needs `--seeds 1`.
//! - **Warm-up.** Each configuration renders [`warmup_frames`] frames before its
//!   measured ones, which are not measured: at least 1 (pipelines compile lazily on some
//!   devices, so the first frame may hold shader compilation), at least 4·Q for
//!   Volumetric ReSTIR with temporal reuse (Q = `temporal_limit`: its history needs
//!   that long to reach steady state), and at least `--warmup`.
//! - **One row per distinct configuration.** Configurations that the integrator cannot
//!   tell apart (they differ only in settings it does not read, [`effective_scene`]) are
//!   rendered once and reported once; study.md lists which renders as which.
//! - **spp is the baseline's knob.** Volumetric ReSTIR renders one path per pixel per
//!   frame; where `--vary spp` varies other integrators too, ReSTIR's spp > 1
//!   configurations are left out and listed ([`restir_refuses_only_spp`]), so one study
//!   raises the baseline's spp towards ReSTIR's frame time (`--per-frame`: the paper's
//!   equal-time single-frame comparison).
//! - **A reference per integrand.** A configuration is compared with the reference of
//!   its own integrand: the scene with the reference settings and the configuration's
//!   values of the keys that change what is integrated (`vary::INTEGRAND_KEYS`:
//!   `max_bounces`). Estimators, `volume`, the ReSTIR knobs, spp, frames and seeds
//!   change how it is estimated, not what.
//!
//! What is measured, per seed:
//!
//! - **GPU time** from the timestamp scopes: the median over frames of the root
//!   `"frame"` scope (`gpu_ms_per_frame`) and its sum over frames (`gpu_ms_total`).
//! - **RMSE** over pixels and channels, √(mean (a − r)²), in W/(m²·sr).
//! - **Relative MSE**, mean (a − r)² / (r² + ε) with ε = `metrics::REL_MSE_EPSILON` (the
//!   metric of the golden-image tests).
//! - **Mean relative difference** of the image means: per channel (ā − r̄) / r̄,
//!   averaged over the channels whose reference mean is positive. Signed, so a bias
//!   shows its direction.
//!
//! A row reports the mean over seeds of the MSE (its RMSE is √ of that mean), of the
//! relative MSE and of the mean relative difference, the median over seeds of the GPU
//! times, and the spread: the smallest and largest RMSE of one seed
//! (`metrics::summarize`).
//!
//! Each reference is the scene rendered once with the reference settings
//! (`--reference-frames/-spp/-estimator/-box-samples`), the integrand's keys and a seed
//! different from every configuration's, cached as EXR plus a JSON sidecar (settings,
//! input files, device, its own noise) under a key that hashes (FNV-1a) the scene file's
//! bytes, the contents of every file the scene reads (grids, environment maps), the
//! reference settings, the resolution and the Nimbus version (`cache`).
//!
//! Configurations fall into **series**: all configurations that share every varied key
//! except the knobs that buy accuracy with time (`vary::KNOB_KEYS`: `spp`, `frames`,
//! `box_samples`). Each series is taken along its Pareto front
//! (`metrics::pareto_front`): a configuration that another of its series beats in both
//! time and RMSE (two knobs varied, or timing noise) is drawn as a hollow marker and left
//! out of the curve. The plot draws one polyline per series, RMSE against total GPU time
//! on log–log axes, with the seeds' RMSE range as a bar; the equal-time comparison
//! interpolates each series' log RMSE linearly in log time
//! (`metrics::interpolate_loglog`) and reports the RMSE ratio of every series to its
//! baseline series at the baseline's measured times (`metrics::equal_time_ratios`): for
//! the seed-mean series, and per seed (each seed's series against the baseline series
//! of the same seed), whose smallest and largest geometric-mean ratios are the spread
//! (`metrics::equal_time_over_seeds`).
//!
//! The code: [`Study::new`] (here) checks the options and plans every configuration and
//! reference; [`Study::run`] (`run.rs`) renders and measures them. `vary` parses
//! `--vary` and `--baseline` and sets keys on the scene; `metrics` measures errors, GPU
//! time and equal-time ratios; `cache` keeps references on disk; `report` formats the
//! tables and texts; `plot` draws the PNG.

pub(crate) mod cache;
mod metrics;
mod plot;
mod report;
mod run;
mod vary;

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, ensure, Context as _, Result};
use nimbus_scene::{Scene, VolumeIntegrator};

use self::cache::{default_cache_dir, scene_inputs, ReferenceJob};
use self::metrics::{SeedRun, SeedSummary};
use self::vary::{
    apply, cartesian, format_pairs, parse_vary, resolve_baseline, Assignment, Vary, INTEGRAND_KEYS,
};
use crate::plan::{self, RenderPlan};

/// XORed into the scene's seed for the reference, so that no configuration that keeps
/// the scene's seed shares the reference's random numbers. Its 32-bit fold (what the
/// shaders see, `seed ^ seed >> 32`) is non-zero, so the folded seeds differ too.
const REFERENCE_SEED_MIX: u64 = 0x5EED_0000_0000_5EED;

/// Most `--seeds`.
pub const MAX_SEEDS: u32 = 64;

/// Volumetric ReSTIR with temporal reuse warms up for at least this many times Q
/// (`temporal_limit`) frames: its history holds up to Q·M candidates, and its error
/// still falls for a few Q frames after the first.
const WARMUP_PER_TEMPORAL_LIMIT: u32 = 4;

/// Every key `--vary` accepts, in the order `nimbus study --help` lists them.
pub fn vary_keys() -> Vec<&'static str> {
    vary::keys()
}

/// Everything `nimbus study` is asked to do (the CLI's flags).
#[derive(Clone, Debug)]
pub struct StudyOptions {
    pub scene: PathBuf,
    /// `KEY=V1,V2,...`, one per `--vary`.
    pub vary: Vec<String>,
    /// Frames per configuration unless `frames` is varied.
    pub frames: u32,
    pub reference_frames: u32,
    pub reference_spp: u32,
    /// Defaults to the scene's own estimator.
    pub reference_estimator: Option<String>,
    pub reference_box_samples: u32,
    /// `KEY=VALUE`; defaults to `box_estimator=rm` when box_estimator is varied.
    pub baseline: Option<String>,
    /// Defaults to `$XDG_CACHE_HOME/nimbus/references`, else
    /// `$HOME/.cache/nimbus/references`.
    pub cache_dir: Option<PathBuf>,
    /// Defaults to `study-<scene stem>`.
    pub out_dir: Option<PathBuf>,
    pub width: Option<u32>,
    pub height: Option<u32>,
    /// Frames rendered before each configuration's measured ones; raised per
    /// configuration by [`warmup_frames`].
    pub warmup: u32,
    /// Renders of every configuration, each with its own seed (1..=[`MAX_SEEDS`]).
    pub seeds: u32,
    /// Measure each frame's own error and report their mean (the error of one frame at
    /// steady state, as Volumetric ReSTIR reports), with the GPU time of one frame;
    /// otherwise the error of the mean over the frames.
    pub per_frame: bool,
}

/// One configuration, ready to render.
struct Configuration {
    assignment: Assignment,
    /// The scene with the assignment; its seed is the first of `seeds`.
    scene: Scene,
    plan: RenderPlan,
    /// The seeds it renders with, one render each.
    seeds: Vec<u64>,
    /// Frames rendered before the measured ones ([`warmup_frames`]).
    warmup: u32,
    /// Index of its reference in [`Study::references`].
    reference: usize,
    /// An earlier configuration that renders exactly the same (a setting that the
    /// integrator does not read differs): not rendered, and reported as that one.
    same_as: Option<usize>,
}

/// The frames `plan` renders before its measured ones when `--warmup` asks for
/// `requested`: at least 1 (the first frame may compile pipelines), at least
/// [`WARMUP_PER_TEMPORAL_LIMIT`]·Q for Volumetric ReSTIR with temporal reuse.
fn warmup_frames(plan: &RenderPlan, requested: u32) -> u32 {
    let temporal = plan.restir().filter(|r| r.temporal).map_or(0, |r| {
        r.temporal_limit.saturating_mul(WARMUP_PER_TEMPORAL_LIMIT)
    });
    requested.max(1).max(temporal)
}

/// Whether `scene` is refused only because it asks Volumetric ReSTIR for more than one
/// sample per pixel: the same scene with spp = 1 plans as ReSTIR. A study that varies
/// spp leaves such configurations out (ReSTIR's work per frame is set by its candidates,
/// the baseline's by spp) instead of failing, and says so in its report.
fn restir_refuses_only_spp(scene: &Scene, box_samples: Option<u32>) -> bool {
    if scene.render.spp <= 1 {
        return false;
    }
    let mut one = scene.clone();
    one.render.spp = 1;
    plan::build(&one, box_samples).is_ok_and(|p| p.restir().is_some())
}

/// The scene as far as its integrator reads it: the settings of the other integrators
/// are reset to their defaults (the box-medium pass reads neither `volume` nor
/// `[integrator.restir]`; the grid integrators read neither the box estimator nor
/// `box_samples`; the baseline reads no ReSTIR knob).
fn effective_scene(scene: &Scene, plan: &RenderPlan) -> Scene {
    let defaults = nimbus_scene::Integrator::default();
    let mut s = scene.clone();
    let i = &mut s.integrator;
    match &plan.integrator {
        plan::Integrator::Crepuscular(_) => {
            i.volume = defaults.volume;
            i.restir = defaults.restir;
        }
        plan::Integrator::Baseline(_) => {
            i.restir = defaults.restir;
            i.box_estimator = defaults.box_estimator;
            i.box_samples = defaults.box_samples;
        }
        plan::Integrator::Restir(p) => {
            i.box_estimator = defaults.box_estimator;
            i.box_samples = defaults.box_samples;
            if !spatial_on(p) {
                // Without spatial reuse its settings are read by nothing.
                let r = &mut i.restir;
                let d = &defaults.restir;
                r.spatial_neighbors = 0;
                r.spatial_rounds = 0;
                r.spatial_radius_px = d.spatial_radius_px;
                r.spatial_when = d.spatial_when;
                r.spatial_shift = d.spatial_shift;
                r.spatial_max_history = d.spatial_max_history;
            }
        }
    }
    s
}

/// Whether a ReSTIR plan runs spatial reuse.
fn spatial_on(p: &plan::RestirPlan) -> bool {
    p.spatial_neighbors > 0 && p.spatial_rounds > 0
}

/// The plan as far as its passes read it: without spatial reuse, ReSTIR's spatial
/// settings are read by nothing (`mis` is: temporal reuse combines with it too).
fn effective_plan(plan: &RenderPlan) -> RenderPlan {
    let mut p = plan.clone();
    if let plan::Integrator::Restir(r) = &mut p.integrator {
        if !spatial_on(r) {
            r.spatial_neighbors = 0;
            r.spatial_rounds = 0;
            r.spatial_radius_px = 0.0;
            r.spatial_camera_moves = false;
            r.spatial_tau_shift = false;
            r.spatial_max_history = 0.0;
        }
    }
    p
}

/// One measured configuration: one row of the tables and one point of the plot.
#[derive(Clone)]
struct Row {
    assignment: Assignment,
    /// The configurations that render exactly as this one (reported as this row).
    equivalents: Vec<Assignment>,
    /// Index of its reference in [`Study::references`].
    reference: usize,
    frames: u32,
    spp: u32,
    box_samples: u32,
    warmup: u32,
    /// One per seed, in the order of the seeds.
    runs: Vec<SeedRun>,
    /// Over the seeds.
    summary: SeedSummary,
}

/// A prepared study: options checked, every configuration and reference planned.
/// Nothing has touched the GPU yet.
pub struct Study {
    scene_path: PathBuf,
    varies: Vec<Vary>,
    configurations: Vec<Configuration>,
    /// One per distinct integrand, in order of first use.
    references: Vec<ReferenceJob>,
    /// (key, value) of the baseline series, if there is one.
    baseline: Option<(String, String)>,
    /// Configurations left out because they ask Volumetric ReSTIR for more than one
    /// sample per pixel ([`restir_refuses_only_spp`]): `--vary spp` then varies the
    /// other integrators' work (the baseline's spp raised to ReSTIR's frame time).
    left_out: Vec<Assignment>,
    out_dir: PathBuf,
    width: u32,
    height: u32,
    /// `--warmup` (each configuration's own is [`Configuration::warmup`]).
    warmup: u32,
    /// Renders per configuration.
    seeds: u32,
    per_frame: bool,
    /// An animated scene's measured scene frames, the same for every configuration (each
    /// warms up on the frames just before them) and each measured against its own
    /// reference image; `None` for a static scene.
    window: Option<std::ops::Range<u32>>,
}

impl Study {
    /// Checks the options, loads the scene and plans every configuration and
    /// reference, so that a bad flag fails before any rendering.
    pub fn new(opts: &StudyOptions) -> Result<Self> {
        ensure!(
            (1..=MAX_SEEDS).contains(&opts.seeds),
            "--seeds {}: expected 1..={MAX_SEEDS} renders per configuration",
            opts.seeds
        );
        // Read once, as `nimbus render` does: a regular file of a scene's size (issue 24:
        // a device named as the scene was read forever), parsed from the bytes hashed.
        let scene_text = nimbus_scene::read_scene_file(&opts.scene)?;
        let mut base = nimbus_scene::parse_str(&scene_text, &opts.scene)?;
        let scene_bytes = scene_text.into_bytes();
        if let Some(w) = opts.width {
            base.render.width = w;
        }
        if let Some(h) = opts.height {
            base.render.height = h;
        }
        base.render.frames = opts.frames;
        // An animated scene is measured frame by frame, each frame against its own
        // reference (a window of scene frames after the warm-up, see `Study::window`).
        let animated = base.is_animated();
        ensure!(
            !animated || opts.per_frame,
            "{}: the scene is animated ([[camera.keyframe]], [[light.keyframe]] or \
             [[medium.frame]]): a study of it needs --per-frame, which measures each frame \
             against a reference of that same scene frame (the error of a mean over \
             frames would mix different images)",
            opts.scene.display()
        );
        let (width, height) = (base.render.width, base.render.height);

        // Parse the --vary lists.
        let mut varies: Vec<Vary> = Vec::new();
        for text in &opts.vary {
            let vary = parse_vary(text).with_context(|| format!("--vary {text}"))?;
            ensure!(
                !varies.iter().any(|v| v.key == vary.key),
                "--vary {text}: {} is already varied by an earlier --vary",
                vary.key
            );
            ensure!(
                !(animated && vary.key == "frames"),
                "--vary {text}: the scene is animated, so its frames are the animation's: \
                 every configuration measures the same --frames scene frames after the \
                 longest warm-up; vary spp or candidates for more work per frame"
            );
            if vary.key == "seed" && opts.seeds > 1 {
                bail!(
                    "--vary {text} with --seeds {}: both set the seeds. Use --seeds N alone \
                     (every configuration renders N seeds derived from the scene's, and the \
                     tables report their spread), or --vary seed=... with --seeds 1 to pick \
                     the seeds yourself",
                    opts.seeds
                );
            }
            varies.push(vary);
        }

        // The reference settings; the integrand's keys are set per configuration.
        let mut ref_base = base.clone();
        ref_base.render.seed = base.render.seed ^ REFERENCE_SEED_MIX;
        let reference_estimator = opts
            .reference_estimator
            .clone()
            .unwrap_or_else(|| base.integrator.box_estimator.name().to_owned());
        let ref_pairs = [
            (
                "frames",
                opts.reference_frames.to_string(),
                "--reference-frames",
            ),
            ("spp", opts.reference_spp.to_string(), "--reference-spp"),
            (
                "box_estimator",
                reference_estimator,
                "--reference-estimator",
            ),
            (
                "box_samples",
                opts.reference_box_samples.to_string(),
                "--reference-box-samples",
            ),
        ];
        let mut ref_box_samples = None;
        for (key, value, flag) in &ref_pairs {
            if let Some(n) =
                apply(&mut ref_base, key, value).with_context(|| format!("{flag} {value}"))?
            {
                ref_box_samples = Some(n);
            }
        }
        // Grid media: the converged reference is the baseline path tracer's (the unbiased
        // estimator every Volumetric ReSTIR claim is measured against).
        if ref_base
            .media
            .iter()
            .any(|m| matches!(m, nimbus_scene::Medium::Grid(_)))
        {
            ref_base.integrator.volume = VolumeIntegrator::Baseline;
        }
        let ref_fold = fold_seed(ref_base.render.seed);
        let stem = scene_stem(&opts.scene);
        let cache_dir = match &opts.cache_dir {
            Some(dir) => dir.clone(),
            None => default_cache_dir()?,
        };
        check_writable_dir(&cache_dir)
            .with_context(|| format!("--cache-dir {}", cache_dir.display()))?;
        let inputs = scene_inputs(&base)?;
        let derived_seeds = derive_seeds(base.render.seed, opts.seeds, ref_fold);

        // Plan every configuration and the reference of its integrand.
        // (scene, plan) of each reference, made jobs once the window is known.
        let mut pending: Vec<(Scene, RenderPlan)> = Vec::new();
        let mut integrands: Vec<Assignment> = Vec::new();
        let mut configurations: Vec<Configuration> = Vec::new();
        let mut left_out: Vec<Assignment> = Vec::new();
        let spp_varied = varies.iter().any(|v| v.key == "spp");
        for assignment in cartesian(&varies) {
            let mut scene = base.clone();
            let mut box_samples = None;
            for (k, v) in &assignment {
                if let Some(n) =
                    apply(&mut scene, k, v).with_context(|| format!("--vary {k}={v}"))?
                {
                    box_samples = Some(n);
                }
            }
            let label = if assignment.is_empty() {
                "the scene's own settings".to_owned()
            } else {
                format_pairs(&assignment)
            };
            let seeds = if varies.iter().any(|v| v.key == "seed") {
                ensure!(
                    fold_seed(scene.render.seed) != ref_fold,
                    "configuration {label}: seed {} gives the shaders the same random numbers \
                     as the reference's seed {}; vary seed over other values",
                    scene.render.seed,
                    ref_base.render.seed
                );
                vec![scene.render.seed]
            } else {
                derived_seeds.clone()
            };
            if spp_varied && restir_refuses_only_spp(&scene, box_samples) {
                left_out.push(assignment);
                continue;
            }
            let plan = plan::build(&scene, box_samples)
                .with_context(|| format!("configuration {label} cannot be rendered"))?;

            let integrand: Assignment = assignment
                .iter()
                .filter(|(k, _)| INTEGRAND_KEYS.contains(&k.as_str()))
                .cloned()
                .collect();
            let reference = match integrands.iter().position(|i| *i == integrand) {
                Some(i) => i,
                None => {
                    let mut ref_scene = ref_base.clone();
                    for (k, v) in &integrand {
                        apply(&mut ref_scene, k, v).with_context(|| format!("--vary {k}={v}"))?;
                    }
                    let ref_plan = plan::build(&ref_scene, ref_box_samples).with_context(|| {
                        if integrand.is_empty() {
                            "the reference settings cannot be rendered".to_owned()
                        } else {
                            format!(
                                "the reference settings with {} cannot be rendered",
                                format_pairs(&integrand)
                            )
                        }
                    })?;
                    pending.push((ref_scene, ref_plan));
                    integrands.push(integrand);
                    pending.len() - 1
                }
            };

            let effective = effective_scene(&scene, &plan);
            let effective_p = effective_plan(&plan);
            let same_as = configurations.iter().position(|c: &Configuration| {
                effective_plan(&c.plan) == effective_p
                    && c.seeds == seeds
                    && effective_scene(&c.scene, &c.plan) == effective
            });
            configurations.push(Configuration {
                assignment,
                warmup: warmup_frames(&plan, opts.warmup),
                scene,
                plan,
                seeds,
                reference,
                same_as,
            });
        }

        if configurations.is_empty() {
            bail!(
                "every configuration asks Volumetric ReSTIR for spp > 1 ({}): it renders one \
                 path per pixel per frame, so `--vary spp` only varies the other integrators' \
                 work; include spp=1, or vary candidates or frames instead",
                left_out
                    .iter()
                    .map(|a| format_pairs(a))
                    .collect::<Vec<_>>()
                    .join("; ")
            );
        }
        let baseline = resolve_baseline(opts.baseline.as_deref(), &varies)?;

        // An animated scene: every configuration measures the same scene frames, those
        // after the longest warm-up (each configuration warms up on the frames just
        // before them, as an interactive viewer would have rendered them).
        let window = animated.then(|| {
            let start = configurations.iter().map(|c| c.warmup).max().unwrap_or(1);
            start..start.saturating_add(opts.frames)
        });
        let references: Vec<ReferenceJob> = pending
            .into_iter()
            .map(|(scene, plan)| {
                ReferenceJob::new(
                    scene,
                    plan,
                    &scene_bytes,
                    &inputs,
                    &stem,
                    &cache_dir,
                    window.clone(),
                )
            })
            .collect();

        // Make sure the results can be written before spending time on renders.
        let out_dir = opts
            .out_dir
            .clone()
            .unwrap_or_else(|| PathBuf::from(format!("study-{stem}")));
        check_writable_dir(&out_dir).with_context(|| format!("--out-dir {}", out_dir.display()))?;

        Ok(Self {
            scene_path: opts.scene.clone(),
            varies,
            configurations,
            references,
            baseline,
            left_out,
            out_dir,
            width,
            height,
            warmup: opts.warmup,
            seeds: opts.seeds,
            per_frame: opts.per_frame,
            window,
        })
    }
}

/// `n` seeds for the configurations: `scene_seed`, then the seeds after it (wrapping),
/// skipping every seed whose 32-bit fold ([`fold_seed`]) is `avoid` (the reference's)
/// or an earlier chosen seed's, so that no two renders share the shaders' random
/// numbers. With `n` = 1 it is the scene's own seed (its fold never equals the
/// reference's, see [`REFERENCE_SEED_MIX`]).
fn derive_seeds(scene_seed: u64, n: u32, avoid: u32) -> Vec<u64> {
    let mut seeds: Vec<u64> = Vec::with_capacity(n as usize);
    let mut folds = vec![avoid];
    // Consecutive seeds share their high half except across one carry, so each fold
    // is hit at most twice: n + 2·(n + 1) candidates always suffice.
    let mut candidate = scene_seed;
    while seeds.len() < n as usize {
        let fold = fold_seed(candidate);
        if !folds.contains(&fold) {
            folds.push(fold);
            seeds.push(candidate);
        }
        candidate = candidate.wrapping_add(1);
    }
    seeds
}

/// The 32-bit seed the shaders see.
fn fold_seed(seed: u64) -> u32 {
    (seed ^ (seed >> 32)) as u32
}

fn scene_stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "scene".to_owned())
}

/// Creates `dir` if needed and checks that a file can be written in it.
fn check_writable_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| anyhow!("cannot create the directory: {e}"))?;
    let probe = dir.join(format!(".nimbus-study-probe-{}", std::process::id()));
    std::fs::write(&probe, b"").map_err(|e| anyhow!("cannot write in the directory: {e}"))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// Options for a study of a tiny grid-medium scene, written with the cache and the
/// output into a fresh directory `nimbus-study-{name}-{pid}` under the system temp
/// dir; nothing varied. For tests (the scene is the one the CLI tests use).
#[cfg(test)]
fn grid_options(name: &str) -> StudyOptions {
    let dir = std::env::temp_dir().join(format!("nimbus-study-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("grid.toml");
    std::fs::write(
        &scene,
        "[render]\nwidth = 8\nheight = 6\n[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n\
         [[medium]]\ntype = \"grid\"\nbounds_min = [-1, -1, -1]\nbounds_max = [1, 1, 1]\n\
         density = { procedural = \"cloud\", dims = [8, 8, 8] }\n",
    )
    .unwrap();
    StudyOptions {
        scene,
        vary: Vec::new(),
        frames: 1,
        reference_frames: 1,
        reference_spp: 1,
        reference_estimator: None,
        reference_box_samples: 1,
        baseline: None,
        cache_dir: Some(dir.clone()),
        out_dir: Some(dir),
        width: None,
        height: None,
        warmup: 1,
        seeds: 1,
        per_frame: false,
    }
}

/// Removes the directory of [`grid_options`].
#[cfg(test)]
fn remove_scratch(opts: &StudyOptions) {
    if let Some(dir) = &opts.out_dir {
        let _ = std::fs::remove_dir_all(dir);
    }
}

/// A measured row for tests: 2 frames of 1 spp, `box_samples` 8, warm-up 1, one seed
/// with `gpu_ms` in total (half of it per frame) and `rmse` as every error.
#[cfg(test)]
fn test_row(assignment: &[(&str, &str)], gpu_ms: f64, rmse: f64) -> Row {
    test_row_seeds(assignment, &[(gpu_ms, rmse)])
}

/// [`test_row`] with one seed (0, 1, ...) per (total GPU ms, RMSE) of `runs`.
#[cfg(test)]
fn test_row_seeds(assignment: &[(&str, &str)], runs: &[(f64, f64)]) -> Row {
    let runs: Vec<SeedRun> = runs
        .iter()
        .enumerate()
        .map(|(i, &(gpu_ms, rmse))| SeedRun {
            seed: i as u64,
            gpu_ms_per_frame: gpu_ms / 2.0,
            gpu_ms_total: gpu_ms,
            metrics: metrics::ErrorMetrics {
                rmse,
                rel_mse: rmse,
                mean_rel_diff: rmse,
            },
        })
        .collect();
    Row {
        assignment: vary::assignment(assignment),
        equivalents: Vec::new(),
        reference: 0,
        frames: 2,
        spp: 1,
        box_samples: 8,
        warmup: 1,
        summary: metrics::summarize(&runs).unwrap(),
        runs,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn same_as(study: &Study) -> Vec<Option<usize>> {
        study.configurations.iter().map(|c| c.same_as).collect()
    }

    #[test]
    fn configurations_an_integrator_cannot_tell_apart_are_rendered_once() {
        let opts = StudyOptions {
            vary: vec![
                "volume=baseline,restir".into(),
                "temporal_limit=4,20".into(),
                "box_estimator=rm,reds".into(),
            ],
            baseline: Some("volume=baseline".into()),
            ..grid_options("dedupe")
        };
        let study = Study::new(&opts).unwrap();
        // The baseline reads neither Q nor the box estimator; ReSTIR reads Q but not
        // the box estimator.
        assert_eq!(
            same_as(&study),
            [
                None,
                Some(0),
                Some(0),
                Some(0),
                None,
                Some(4),
                None,
                Some(6)
            ]
        );
        remove_scratch(&opts);

        // The box-medium pass reads neither volume nor the ReSTIR knobs.
        let opts = StudyOptions {
            vary: vec![
                "volume=restir,baseline".into(),
                "temporal_limit=4,20".into(),
                "spp=1,2".into(),
            ],
            ..grid_options("dedupe-box")
        };
        std::fs::write(&opts.scene, crate::DEFAULT_SCENE).unwrap();
        let study = Study::new(&opts).unwrap();
        let spp1 = Some(0);
        let spp2 = Some(1);
        assert_eq!(
            same_as(&study),
            [None, None, spp1, spp2, spp1, spp2, spp1, spp2]
        );
        remove_scratch(&opts);

        // Without spatial reuse ReSTIR reads none of its settings.
        let opts = StudyOptions {
            vary: vec![
                "spatial_neighbors=0,3".into(),
                "spatial_shift=distance,optical_depth".into(),
                "spatial_max_history=0,8".into(),
                // (The test scene's camera holds still.)
                "spatial_when=always".into(),
            ],
            ..grid_options("dedupe-spatial")
        };
        let study = Study::new(&opts).unwrap();
        assert_eq!(
            same_as(&study),
            [None, Some(0), Some(0), Some(0), None, None, None, None]
        );
        remove_scratch(&opts);
    }

    /// ReSTIR renders one path per pixel per frame: where `--vary spp` also varies the
    /// baseline, ReSTIR's spp > 1 configurations are left out and listed (the per-frame
    /// equal-time protocol: the baseline's spp raised to ReSTIR's frame time); where
    /// nothing else is left, the study fails saying what sets ReSTIR's work instead.
    #[test]
    fn restir_with_more_than_one_spp_is_left_out_or_refused() {
        let opts = StudyOptions {
            vary: vec!["volume=baseline,restir".into(), "spp=1,4".into()],
            ..grid_options("restir-spp")
        };
        let study = Study::new(&opts).unwrap();
        let labels: Vec<String> = study
            .configurations
            .iter()
            .map(|c| format_pairs(&c.assignment))
            .collect();
        assert_eq!(
            labels,
            [
                "volume=baseline spp=1",
                "volume=baseline spp=4",
                "volume=restir spp=1"
            ]
        );
        assert_eq!(
            study.left_out,
            [vec![
                ("volume".to_owned(), "restir".to_owned()),
                ("spp".to_owned(), "4".to_owned())
            ]]
        );
        let text = report::left_out_text(&study.left_out).expect("a note");
        assert!(text.contains("- `volume=restir spp=4`"), "{text}");
        assert!(text.contains("`candidates`"), "{text}");

        let only = StudyOptions {
            vary: vec!["volume=restir".into(), "spp=2,4".into()],
            ..opts.clone()
        };
        let message = format!("{:#}", Study::new(&only).err().expect("an error"));
        for needle in [
            "volume=restir spp=2; volume=restir spp=4",
            "one path per pixel per frame",
            "candidates or frames",
        ] {
            assert!(message.contains(needle), "{needle:?}: {message}");
        }
        // A baseline scene is never left out: spp is its own knob.
        let baseline = StudyOptions {
            vary: vec!["volume=baseline".into(), "spp=2,4".into()],
            ..opts.clone()
        };
        assert_eq!(Study::new(&baseline).unwrap().configurations.len(), 2);
        remove_scratch(&opts);
    }

    #[test]
    fn the_reference_of_a_grid_medium_is_the_baseline_with_its_own_seed() {
        let opts = StudyOptions {
            vary: vec!["volume=restir".into()],
            reference_frames: 3,
            reference_spp: 2,
            ..grid_options("reference")
        };
        let study = Study::new(&opts).unwrap();
        assert_eq!(study.references.len(), 1);
        let job = &study.references[0];
        assert_eq!(job.scene.integrator.volume, VolumeIntegrator::Baseline);
        assert_eq!((job.scene.render.frames, job.scene.render.spp), (3, 2));
        let seed = study.configurations[0].scene.render.seed;
        assert_eq!(study.configurations[0].seeds, [seed]);
        assert_eq!(job.scene.render.seed, seed ^ REFERENCE_SEED_MIX);
        assert!(job.key.starts_with("grid-"), "{}", job.key);
        assert_eq!(job.exr.parent(), opts.cache_dir.as_deref());
        assert_eq!(study.out_dir, opts.out_dir.clone().unwrap());
        remove_scratch(&opts);
    }

    /// Each max_bounces is compared with a reference of the same max_bounces; keys
    /// that do not change the integrand share one.
    #[test]
    fn each_integrand_has_its_own_reference() {
        let opts = StudyOptions {
            vary: vec![
                "max_bounces=1,3".into(),
                "volume=baseline,restir".into(),
                "candidates=2,4".into(),
            ],
            ..grid_options("integrands")
        };
        let study = Study::new(&opts).unwrap();
        let refs: Vec<usize> = study.configurations.iter().map(|c| c.reference).collect();
        assert_eq!(refs, [0, 0, 0, 0, 1, 1, 1, 1]);
        let k: Vec<u32> = study
            .references
            .iter()
            .map(|r| r.scene.integrator.max_bounces)
            .collect();
        assert_eq!(k, [1, 3]);
        for (r, c) in study.references.iter().zip([0, 4]) {
            let config = &study.configurations[c].scene;
            assert_eq!(
                r.scene.integrator.max_bounces,
                config.integrator.max_bounces
            );
            assert_eq!(r.scene.integrator.volume, VolumeIntegrator::Baseline);
            assert_eq!(r.scene.render.seed, config.render.seed ^ REFERENCE_SEED_MIX);
        }
        assert_ne!(study.references[0].key, study.references[1].key);
        assert_ne!(study.references[0].exr, study.references[1].exr);
        remove_scratch(&opts);

        // Nothing that changes the integrand varied: one reference, of the scene's K.
        let opts = StudyOptions {
            vary: vec!["volume=baseline,restir".into(), "temporal_limit=1,2".into()],
            ..grid_options("one-integrand")
        };
        std::fs::write(
            &opts.scene,
            std::fs::read_to_string(&opts.scene).unwrap() + "[integrator]\nmax_bounces = 2\n",
        )
        .unwrap();
        let study = Study::new(&opts).unwrap();
        assert_eq!(study.references.len(), 1);
        assert_eq!(study.references[0].scene.integrator.max_bounces, 2);
        assert!(study.configurations.iter().all(|c| c.reference == 0));
        remove_scratch(&opts);
    }

    #[test]
    fn seeds_follow_the_scene_seed_and_never_share_a_fold() {
        let avoid = |seed: u64| fold_seed(seed ^ REFERENCE_SEED_MIX);
        assert_eq!(derive_seeds(7, 3, avoid(7)), [7, 8, 9]);
        assert_eq!(derive_seeds(7, 1, avoid(7)), [7]);
        // A seed that folds to the reference's is skipped.
        assert_eq!(derive_seeds(10, 3, fold_seed(11)), [10, 12, 13]);
        // u64::MAX and 0 (after wrapping) both fold to 0: the second is skipped.
        assert_eq!(fold_seed(u64::MAX), fold_seed(0));
        assert_eq!(derive_seeds(u64::MAX, 3, avoid(u64::MAX)), [u64::MAX, 1, 2]);
        // Across the carry into the high half, folds of both halves can meet.
        let edge = 0xFFFF_FFF0u64;
        for seed in [0, 3, 0x5EED, edge, u64::MAX - 5, 0x5EED_0000_0000_0000] {
            let seeds = derive_seeds(seed, MAX_SEEDS, avoid(seed));
            assert_eq!(seeds.len(), MAX_SEEDS as usize);
            assert_eq!(seeds[0], seed);
            let mut folds: Vec<u32> = seeds.iter().map(|&s| fold_seed(s)).collect();
            assert!(!folds.contains(&avoid(seed)), "seed {seed}");
            folds.sort_unstable();
            folds.dedup();
            assert_eq!(
                folds.len(),
                MAX_SEEDS as usize,
                "seed {seed}: a fold repeats"
            );
        }
    }

    #[test]
    fn every_configuration_renders_every_seed() {
        let opts = StudyOptions {
            vary: vec!["volume=baseline,restir".into()],
            seeds: 3,
            ..grid_options("seeds")
        };
        let study = Study::new(&opts).unwrap();
        let reference = study.references[0].scene.render.seed;
        for c in &study.configurations {
            assert_eq!(c.seeds, [0, 1, 2]);
            assert_eq!(c.scene.render.seed, 0);
            assert!(c
                .seeds
                .iter()
                .all(|&s| fold_seed(s) != fold_seed(reference)));
        }
        assert_eq!(study.seeds, 3);
        remove_scratch(&opts);
    }

    #[test]
    fn warmup_covers_compilation_and_the_temporal_history() {
        let plan_of = |extra: &str| {
            let text = format!(
                "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n[[medium]]\ntype = \
                 \"grid\"\nbounds_min = [-1, -1, -1]\nbounds_max = [1, 1, 1]\ndensity = \
                 {{ procedural = \"cloud\", dims = [4, 4, 4] }}\n{extra}"
            );
            let scene = nimbus_scene::parse_str(&text, Path::new("w.toml")).unwrap();
            plan::build(&scene, None).unwrap()
        };
        let restir = |q: u32, temporal: bool| {
            plan_of(&format!(
                "[integrator.restir]\ntemporal_limit = {q}\ntemporal = {temporal}\n"
            ))
        };
        let baseline = plan_of("[integrator]\nvolume = \"baseline\"\n");
        let window = nimbus_scene::parse_str(crate::DEFAULT_SCENE, Path::new("w.toml")).unwrap();
        let boxes = plan::build(&window, None).unwrap();
        // At least one frame, whatever --warmup says.
        assert_eq!(warmup_frames(&boxes, 0), 1);
        assert_eq!(warmup_frames(&baseline, 0), 1);
        assert_eq!(warmup_frames(&baseline, 7), 7);
        // ReSTIR with temporal reuse: 4·Q, or more when asked.
        assert_eq!(warmup_frames(&restir(4, true), 0), 16);
        assert_eq!(warmup_frames(&restir(20, true), 16), 80);
        assert_eq!(warmup_frames(&restir(20, true), 100), 100);
        // Without temporal reuse there is no history to fill.
        assert_eq!(warmup_frames(&restir(20, false), 0), 1);

        let opts = StudyOptions {
            vary: vec![
                "volume=baseline,restir".into(),
                "temporal_limit=4,20".into(),
            ],
            warmup: 0,
            ..grid_options("warmup")
        };
        let study = Study::new(&opts).unwrap();
        let warmups: Vec<u32> = study.configurations.iter().map(|c| c.warmup).collect();
        assert_eq!(warmups, [1, 1, 16, 80]);
        remove_scratch(&opts);
    }

    #[test]
    fn bad_options_fail_before_rendering() {
        let opts = grid_options("bad-options");
        let cases = [
            (vec!["spp=1,2", "spp=4"], None, 1, "already varied"),
            // The scene's seed is 0, so the reference's folds to 0x5EED_5EED.
            (vec!["seed=1592614637"], None, 1, "same random numbers"),
            (vec!["volume=baseline", "spp=1,2"], Some("spp=1"), 1, "knob"),
            (vec!["seed=1,2"], None, 3, "--vary seed=1,2 with --seeds 3"),
            (vec!["seed=1,2"], None, 3, "--seeds 1"),
            (vec![], None, 0, "--seeds 0: expected 1..=64"),
            (vec![], None, 65, "--seeds 65"),
        ];
        for (vary, baseline, seeds, needle) in cases {
            let bad = StudyOptions {
                vary: vary.iter().map(|v| (*v).to_owned()).collect(),
                baseline: baseline.map(str::to_owned),
                seeds,
                ..opts.clone()
            };
            let message = format!("{:#}", Study::new(&bad).err().expect("an error"));
            assert!(message.contains(needle), "{vary:?}: {message}");
        }
        remove_scratch(&opts);
    }

    /// An animated scene is measured frame by frame against each frame's own reference:
    /// without --per-frame it is refused, as is varying its frames; with it, every
    /// configuration measures the frames after the longest warm-up.
    #[test]
    fn an_animated_scene_is_measured_frame_by_frame() {
        let opts = grid_options("animated");
        let scene = std::fs::read_to_string(&opts.scene).unwrap();
        let light = "[[light]]\ntype = \"directional\"\nirradiance = 1\n\
                     [[light.keyframe]]\nframe = 0\ndirection = [0, -1, 0]\n\
                     [[light.keyframe]]\nframe = 4\ndirection = [0, -1, 1]\n";
        std::fs::write(&opts.scene, format!("{scene}{light}")).unwrap();
        let message = format!("{:#}", Study::new(&opts).err().expect("an error"));
        assert!(
            message.contains("animated") && message.contains("--per-frame"),
            "{message}"
        );
        let per_frame = StudyOptions {
            per_frame: true,
            frames: 3,
            warmup: 2,
            ..opts.clone()
        };
        let bad = StudyOptions {
            vary: vec!["frames=1,2".into()],
            ..per_frame.clone()
        };
        let message = format!("{:#}", Study::new(&bad).err().expect("an error"));
        assert!(message.contains("--vary frames=1,2"), "{message}");
        let study = Study::new(&StudyOptions {
            vary: vec!["volume=baseline,restir".into(), "temporal_limit=3".into()],
            ..per_frame
        })
        .unwrap();
        // ReSTIR warms up 4·Q = 12 frames, so every configuration measures 12..15.
        assert_eq!(study.window, Some(12..15));
        assert!(study.references.iter().all(|r| r.window == study.window));
        remove_scratch(&opts);
    }

    #[test]
    fn reference_seed_differs_after_folding() {
        for seed in [0, 1, 0x5EED, u64::MAX, 0x5EED_0000_0000_0000] {
            assert_ne!(fold_seed(seed), fold_seed(seed ^ REFERENCE_SEED_MIX));
        }
    }
}
