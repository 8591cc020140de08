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
//!   tell apart (they differ only in settings it does not read, [`plan::effective_scene`]) are
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

// The protocol above links the private functions that implement each rule: the crate's
// docs are for the people who change it (`cargo doc --document-private-items`).
#![allow(rustdoc::private_intra_doc_links)]

pub(crate) mod cache;
mod metrics;
mod plot;
mod report;
mod run;
mod vary;

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, ensure, Context as _, Result};
use nimbus_scene::{FieldOverride, Scene};

use self::cache::{default_cache_dir, scene_inputs, ReferenceJob};
use self::metrics::{SeedRun, SeedSummary};
use self::vary::{
    cartesian, format_pairs, parse_vary, resolve_baseline, Assignment, Vary, INTEGRAND_KEYS,
};
use nimbus::plan::{self, RenderPlan};

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
    /// Arithmetic load on a GPU right before each render's measured frames
    /// (`nimbus::renderer::settle`), so that every configuration is timed at the
    /// device's working clocks; zero for none. Never on a CPU device.
    pub settle: std::time::Duration,
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
fn restir_refuses_only_spp(scene: &Scene) -> bool {
    if scene.render.spp <= 1 {
        return false;
    }
    let mut one = scene.clone();
    one.render.spp = 1;
    plan::build(&one, None).is_ok_and(|p| p.restir().is_some())
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
    /// [`StudyOptions::settle`].
    settle: std::time::Duration,
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
        let (file, base, animated) = load_base(opts)?;
        let (width, height) = (base.render.width, base.render.height);

        let varies = parse_varies(opts, animated)?;

        let ref_overrides = reference_overrides(&base, opts);
        // The reference settings are checked now, also when nothing varies the integrand.
        let ref_base = reference_scene(&file, &base, &ref_overrides, &[])
            .context("the reference settings cannot be rendered")?;
        let ref_fold = fold_seed(ref_base.render.seed);
        // Without --per-frame a static scene's measured image is the mean of its frames,
        // as `nimbus render` makes it: ReSTIR's `temporal = "auto"` decides as there.
        let product = if opts.per_frame {
            plan::Product::Frames
        } else {
            plan::Product::Still
        };
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
            let scene = file.scene(&vary::overrides(&assignment)?)?;
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
            if spp_varied && restir_refuses_only_spp(&scene) {
                left_out.push(assignment);
                continue;
            }
            let plan = plan::build_for(&scene, None, product)
                .with_context(|| format!("configuration {label} cannot be rendered"))?;

            let integrand: Assignment = assignment
                .iter()
                .filter(|(k, _)| INTEGRAND_KEYS.contains(&k.as_str()))
                .cloned()
                .collect();
            let reference = match integrands.iter().position(|i| *i == integrand) {
                Some(i) => i,
                None => {
                    let ref_scene = reference_scene(&file, &base, &ref_overrides, &integrand)?;
                    let ref_plan = plan::build(&ref_scene, None).with_context(|| {
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

            let effective = plan::effective_scene(&scene, &plan);
            let effective_p = plan::effective_plan(&plan);
            let same_as = configurations.iter().position(|c: &Configuration| {
                plan::effective_plan(&c.plan) == effective_p
                    && c.seeds == seeds
                    && plan::effective_scene(&c.scene, &c.plan) == effective
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
        // Those frames, and the warm-up before them, are scene frames: the scene must be
        // valid at every one (the camera's path, a camera inside a sphere light), as a
        // scene file rendering that many frames is checked.
        if let Some(w) = &window {
            file.scene(&[FieldOverride {
                key: "render.frames".into(),
                value: i64::from(w.end).into(),
                origin: Some(format!(
                    "the study's scene frames 0..{} (a warm-up of {} frames, then --frames {})",
                    w.end, w.start, opts.frames
                )),
            }])?;
        }
        let references: Vec<ReferenceJob> = pending
            .into_iter()
            .map(|(scene, plan)| {
                ReferenceJob::new(
                    scene,
                    plan,
                    file.text.as_bytes(),
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
            settle: opts.settle,
            window,
        })
    }
}

/// The scene file with the study's `--width`, `--height` and `--frames` (its text is what
/// the reference cache hashes), the scene they give, and whether it is animated.
fn load_base(opts: &StudyOptions) -> Result<(SceneFile, Scene, bool)> {
    // Read once, as `nimbus render` does: a regular file of a scene's size (issue 24:
    // a device named as the scene was read forever), parsed from the bytes hashed.
    let text = nimbus_scene::read_scene_file(&opts.scene)?;
    // The size and frame count are fields of the scene, set before validation as
    // `nimbus render --width` sets them (a size out of range, or a camera that leaves its
    // keyframes at a later frame, is refused naming the flag).
    let mut flags = vec![FieldOverride::from_flag(
        "--frames",
        "render.frames",
        i64::from(opts.frames),
    )];
    if let Some(w) = opts.width {
        flags.push(FieldOverride::from_flag(
            "--width",
            "render.width",
            i64::from(w),
        ));
    }
    if let Some(h) = opts.height {
        flags.push(FieldOverride::from_flag(
            "--height",
            "render.height",
            i64::from(h),
        ));
    }
    let file = SceneFile {
        text,
        path: opts.scene.clone(),
        flags,
    };
    let base = file.scene(&[])?;
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
    Ok((file, base, animated))
}

/// The study's scene file, read once: every configuration and reference is this text
/// parsed with its own field overrides (after the study's `--width`, `--height` and
/// `--frames`), so each is validated as a scene file holding those values would be.
struct SceneFile {
    text: String,
    path: PathBuf,
    flags: Vec<FieldOverride>,
}

impl SceneFile {
    /// The scene with `overrides` applied after the study's flags.
    fn scene(&self, overrides: &[FieldOverride]) -> Result<Scene> {
        let all: Vec<FieldOverride> = self.flags.iter().chain(overrides).cloned().collect();
        nimbus_scene::parse_str_with(&self.text, &self.path, &all)
    }
}

/// The `--vary` lists, each key varied once.
fn parse_varies(opts: &StudyOptions, animated: bool) -> Result<Vec<Vary>> {
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
    Ok(varies)
}

/// The reference's overrides (`--reference-*`; grid media by the baseline), the
/// integrand's keys being added per configuration.
fn reference_overrides(base: &Scene, opts: &StudyOptions) -> Vec<FieldOverride> {
    let reference_estimator = opts
        .reference_estimator
        .clone()
        .unwrap_or_else(|| base.integrator.box_estimator.name().to_owned());
    let mut out = vec![
        FieldOverride::from_flag(
            "--reference-frames",
            "render.frames",
            i64::from(opts.reference_frames),
        ),
        FieldOverride::from_flag(
            "--reference-spp",
            "render.spp",
            i64::from(opts.reference_spp),
        ),
        FieldOverride {
            key: "integrator.box_estimator".into(),
            origin: Some(format!("--reference-estimator {reference_estimator}")),
            value: reference_estimator.into(),
        },
        FieldOverride::from_flag(
            "--reference-box-samples",
            "integrator.box_samples",
            i64::from(opts.reference_box_samples),
        ),
    ];
    // Grid media: the converged reference is the baseline path tracer's (the unbiased
    // estimator every Volumetric ReSTIR claim is measured against).
    if base
        .media
        .iter()
        .any(|m| matches!(m, nimbus_scene::Medium::Grid(_)))
    {
        out.push(FieldOverride {
            key: "integrator.volume".into(),
            value: "baseline".into(),
            origin: Some("the reference (grid media: the baseline path tracer)".into()),
        });
    }
    out
}

/// The reference scene of `integrand` (its keys set after the reference's overrides),
/// with the reference's seed.
fn reference_scene(
    file: &SceneFile,
    base: &Scene,
    ref_overrides: &[FieldOverride],
    integrand: &[(String, String)],
) -> Result<Scene> {
    let mut given = ref_overrides.to_vec();
    given.extend(vary::overrides(integrand)?);
    let mut scene = file.scene(&given)?;
    scene.render.seed = base.render.seed ^ REFERENCE_SEED_MIX;
    Ok(scene)
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
        settle: std::time::Duration::ZERO,
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
mod tests;
