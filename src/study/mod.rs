//! `nimbus study`: what accuracy costs in GPU time.
//!
//! A study renders one scene under every configuration of the `--vary KEY=V1,V2,...`
//! lists (their cartesian product, the first `--vary` outermost) and measures each
//! image against a converged reference of the same scene:
//!
//! - **GPU time** from the timestamp scopes: the median over frames of the root
//!   `"frame"` scope (`gpu_ms_per_frame`) and its sum over frames (`gpu_ms_total`).
//!   Each configuration renders `--warmup` frames (at least one) first, which are not
//!   measured.
//! - **RMSE** over pixels and channels, √(mean (a − r)²), in W/(m²·sr).
//! - **Relative MSE**, mean (a − r)² / (r² + ε) with ε = `metrics::REL_MSE_EPSILON` (the
//!   metric of the golden-image tests).
//! - **Mean relative difference** of the image means: per channel (ā − r̄) / r̄,
//!   averaged over the channels whose reference mean is positive. Signed, so a bias
//!   shows its direction.
//!
//! The reference is the scene rendered once with the reference settings
//! (`--reference-frames/-spp/-estimator/-box-samples`) and a seed different from every
//! configuration's, cached as EXR plus a JSON sidecar (settings, device, its own noise)
//! under a key that hashes (FNV-1a) the scene file's bytes, the reference settings, the
//! resolution and the Nimbus version. Files the scene refers to (volumes, maps) are not
//! part of the key.
//!
//! Configurations fall into **series**: all configurations that share every varied key
//! except the knobs that buy accuracy with time (`vary::KNOB_KEYS`: `spp`, `frames`,
//! `box_samples`). Each series is taken along its Pareto front
//! (`metrics::pareto_front`): a configuration that another of its series beats in both
//! time and RMSE (two knobs varied, or timing noise) is drawn as a hollow marker and left
//! out of the curve. The plot draws one polyline per series, RMSE against total GPU time
//! on log–log axes; the equal-time comparison interpolates each series' log RMSE
//! linearly in log time (`metrics::interpolate_loglog`) and reports the RMSE ratio of
//! every series to its baseline series at the baseline's measured times
//! (`metrics::equal_time_ratios`).
//!
//! The code: [`Study::new`] (here) checks the options and plans every configuration and
//! the reference; [`Study::run`] (`run.rs`) renders and measures them. `vary` parses
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

use anyhow::{anyhow, ensure, Context as _, Result};
use nimbus_scene::{Scene, VolumeIntegrator};

use self::cache::{default_cache_dir, ReferenceJob};
use self::metrics::ErrorMetrics;
pub use self::vary::keys as vary_keys;
use self::vary::{apply, cartesian, format_pairs, parse_vary, resolve_baseline, Assignment, Vary};
use crate::plan::{self, RenderPlan};

/// XORed into the scene's seed for the reference, so that no configuration that keeps
/// the scene's seed shares the reference's random numbers. Its 32-bit fold (what the
/// shaders see, `seed ^ seed >> 32`) is non-zero, so the folded seeds differ too.
const REFERENCE_SEED_MIX: u64 = 0x5EED_0000_0000_5EED;

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
    /// Frames rendered before each configuration's measured ones (ReSTIR's temporal
    /// history); at least 1 (the first frame also compiles pipelines lazily).
    pub warmup: u32,
    /// Measure each frame's own error and report their mean (the error of one frame at
    /// steady state, as Volumetric ReSTIR reports), with the GPU time of one frame;
    /// otherwise the error of the mean over the frames.
    pub per_frame: bool,
}

/// One configuration, ready to render.
struct Configuration {
    assignment: Assignment,
    scene: Scene,
    plan: RenderPlan,
    /// An earlier configuration that renders exactly the same (a knob that the
    /// integrator ignores differs), whose measurement is reused.
    same_as: Option<usize>,
}

/// The scene as far as its integrator reads it: ReSTIR renders one sample per pixel per
/// frame (spp is unused), the other integrators ignore `[integrator.restir]`.
fn effective_scene(scene: &Scene, plan: &RenderPlan) -> Scene {
    let mut s = scene.clone();
    if plan.restir().is_some() {
        s.render.spp = 1;
    } else {
        s.integrator.restir = nimbus_scene::RestirSettings::default();
    }
    s
}
/// One measured configuration.
#[derive(Clone)]
struct Row {
    assignment: Assignment,
    frames: u32,
    spp: u32,
    box_samples: u32,
    gpu_ms_per_frame: f64,
    gpu_ms_total: f64,
    metrics: ErrorMetrics,
}

/// A prepared study: options checked, every configuration and the reference planned.
/// Nothing has touched the GPU yet.
pub struct Study {
    scene_path: PathBuf,
    varies: Vec<Vary>,
    configurations: Vec<Configuration>,
    reference: ReferenceJob,
    /// (key, value) of the baseline series, if there is one.
    baseline: Option<(String, String)>,
    out_dir: PathBuf,
    width: u32,
    height: u32,
    warmup: u32,
    per_frame: bool,
}

impl Study {
    /// Checks the options, loads the scene and plans every configuration and the
    /// reference, so that a bad flag fails before any rendering.
    pub fn new(opts: &StudyOptions) -> Result<Self> {
        let scene_bytes = std::fs::read(&opts.scene)
            .with_context(|| format!("{}: cannot read scene file", opts.scene.display()))?;
        let mut base = nimbus_scene::load(&opts.scene)?;
        if let Some(w) = opts.width {
            base.render.width = w;
        }
        if let Some(h) = opts.height {
            base.render.height = h;
        }
        base.render.frames = opts.frames;
        ensure!(
            base.camera.keyframes.is_empty(),
            "{}: [[camera.keyframe]]: a study needs a static camera (the reference and the \
             configurations average different numbers of frames)",
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
            varies.push(vary);
        }

        // Plan the reference.
        let mut ref_scene = base.clone();
        ref_scene.render.seed = base.render.seed ^ REFERENCE_SEED_MIX;
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
                apply(&mut ref_scene, key, value).with_context(|| format!("{flag} {value}"))?
            {
                ref_box_samples = Some(n);
            }
        }
        // Grid media: the converged reference is the baseline path tracer's (the unbiased
        // estimator every Volumetric ReSTIR claim is measured against).
        if ref_scene
            .media
            .iter()
            .any(|m| matches!(m, nimbus_scene::Medium::Grid(_)))
        {
            ref_scene.integrator.volume = VolumeIntegrator::Baseline;
        }
        let ref_plan = plan::build(&ref_scene, ref_box_samples)
            .context("the reference settings cannot be rendered")?;
        let stem = scene_stem(&opts.scene);
        let cache_dir = match &opts.cache_dir {
            Some(dir) => dir.clone(),
            None => default_cache_dir()?,
        };
        check_writable_dir(&cache_dir)
            .with_context(|| format!("--cache-dir {}", cache_dir.display()))?;
        let reference = ReferenceJob::new(ref_scene, ref_plan, &scene_bytes, &stem, &cache_dir);
        let ref_fold = fold_seed(reference.scene.render.seed);

        // Plan every configuration.
        let mut configurations = Vec::new();
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
            ensure!(
                fold_seed(scene.render.seed) != ref_fold,
                "configuration {label}: seed {} gives the shaders the same random numbers as \
                 the reference's seed {}; vary seed over other values",
                scene.render.seed,
                reference.scene.render.seed
            );
            let plan = plan::build(&scene, box_samples)
                .with_context(|| format!("configuration {label} cannot be rendered"))?;
            let effective = effective_scene(&scene, &plan);
            let same_as = configurations.iter().position(|c: &Configuration| {
                c.plan == plan && effective_scene(&c.scene, &c.plan) == effective
            });
            configurations.push(Configuration {
                assignment,
                scene,
                plan,
                same_as,
            });
        }

        let baseline = resolve_baseline(opts.baseline.as_deref(), &varies)?;

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
            reference,
            baseline,
            out_dir,
            width,
            height,
            warmup: opts.warmup,
            per_frame: opts.per_frame,
        })
    }
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

/// A measured row for tests: 2 frames of 1 spp, `box_samples` 8, `gpu_ms` in total
/// (half of it per frame) and `rmse` as every error.
#[cfg(test)]
fn test_row(assignment: &[(&str, &str)], gpu_ms: f64, rmse: f64) -> Row {
    Row {
        assignment: vary::assignment(assignment),
        frames: 2,
        spp: 1,
        box_samples: 8,
        gpu_ms_per_frame: gpu_ms / 2.0,
        gpu_ms_total: gpu_ms,
        metrics: ErrorMetrics {
            rmse,
            rel_mse: rmse,
            mean_rel_diff: rmse,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn configurations_an_integrator_cannot_tell_apart_are_rendered_once() {
        let opts = StudyOptions {
            vary: vec![
                "volume=baseline,restir".into(),
                "temporal_limit=4,20".into(),
                "spp=1,4".into(),
            ],
            baseline: Some("volume=baseline".into()),
            ..grid_options("dedupe")
        };
        let study = Study::new(&opts).unwrap();
        let same: Vec<Option<usize>> = study.configurations.iter().map(|c| c.same_as).collect();
        // baseline: Q is ignored (Q=20 repeats Q=4); restir: spp is ignored.
        assert_eq!(
            same,
            [None, None, Some(0), Some(1), None, Some(4), None, Some(6)]
        );
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
        let job = &study.reference;
        assert_eq!(job.scene.integrator.volume, VolumeIntegrator::Baseline);
        assert_eq!((job.scene.render.frames, job.scene.render.spp), (3, 2));
        let seed = study.configurations[0].scene.render.seed;
        assert_eq!(job.scene.render.seed, seed ^ REFERENCE_SEED_MIX);
        assert!(job.key.starts_with("grid-"), "{}", job.key);
        assert_eq!(job.exr.parent(), opts.cache_dir.as_deref());
        assert_eq!(study.out_dir, opts.out_dir.clone().unwrap());
        remove_scratch(&opts);
    }

    #[test]
    fn bad_options_fail_before_rendering() {
        let opts = grid_options("bad-options");
        let cases = [
            (vec!["spp=1,2", "spp=4"], None, "already varied"),
            // The scene's seed is 0, so the reference's folds to 0x5EED_5EED.
            (vec!["seed=1592614637"], None, "same random numbers"),
            (vec!["spp=1,2"], Some("spp=1"), "knob"),
        ];
        for (vary, baseline, needle) in cases {
            let bad = StudyOptions {
                vary: vary.iter().map(|v| (*v).to_owned()).collect(),
                baseline: baseline.map(str::to_owned),
                ..opts.clone()
            };
            let message = format!("{:#}", Study::new(&bad).err().expect("an error"));
            assert!(message.contains(needle), "{vary:?}: {message}");
        }
        remove_scratch(&opts);
    }

    #[test]
    fn reference_seed_differs_after_folding() {
        for seed in [0, 1, 0x5EED, u64::MAX, 0x5EED_0000_0000_0000] {
            assert_ne!(fold_seed(seed), fold_seed(seed ^ REFERENCE_SEED_MIX));
        }
    }
}
