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
//! - **Relative MSE**, mean (a − r)² / (r² + ε) with ε = [`REL_MSE_EPSILON`] (the
//!   metric of the golden-image tests).
//! - **Mean relative difference** of the image means: per channel (ā − r̄) / r̄,
//!   averaged over the channels whose reference mean is positive. Signed, so a bias
//!   shows its direction.
//!
//! The reference is the scene rendered once with the reference settings
//! (`--reference-frames/-spp/-estimator/-box-samples`) and a seed different from every
//! configuration's, cached as EXR plus a JSON sidecar (settings, device, its own noise)
//! under a key that hashes ([`fnv1a64`]) the scene file's bytes, the reference settings,
//! the resolution and the Nimbus version. Files the scene refers to (volumes, maps) are
//! not part of the key.
//!
//! Configurations fall into **series**: all configurations that share every varied key
//! except the knobs that buy accuracy with time ([`KNOB_KEYS`]: `spp`, `frames`,
//! `box_samples`). Each series is taken along its Pareto front ([`pareto_front`]): a
//! configuration that another of its series beats in both time and RMSE (two knobs
//! varied, or timing noise) is drawn as a hollow marker and left out of the curve. The
//! plot draws one polyline per series, RMSE against total GPU time on log–log axes;
//! the equal-time comparison interpolates each series' log RMSE linearly in log time
//! ([`interpolate_loglog`]) and reports the RMSE ratio of every series to its baseline
//! series at the baseline's measured times ([`equal_time_ratios`]).

mod plot;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{anyhow, bail, ensure, Context as _, Result};
use nimbus_gpu::{Context, ScopeResult};
use nimbus_scene::{BoxEstimator, Scene, VolumeIntegrator};

use crate::output::{read_exr, write_image, ImageRgb};
use crate::plan::{self, RenderPlan};
use crate::renderer::{self, RenderOptions, RenderResult};

/// ε in the relative MSE (a − r)² / (r² + ε), as in the golden-image tests.
pub const REL_MSE_EPSILON: f64 = 1e-2;

/// The keys `--vary` (and `--baseline`) accept besides the ReSTIR knobs, in the order
/// [`apply`] lists them.
pub const GENERAL_KEYS: [&str; 7] = [
    "box_estimator",
    "spp",
    "box_samples",
    "frames",
    "seed",
    "max_bounces",
    "volume",
];

/// Every key `--vary` accepts: [`GENERAL_KEYS`], then the fields of
/// `[integrator.restir]` (the scene crate's list, so the two cannot drift apart).
pub fn keys() -> Vec<&'static str> {
    GENERAL_KEYS
        .iter()
        .chain(nimbus_scene::RESTIR_KEYS)
        .copied()
        .collect()
}

/// The keys that buy accuracy with time: configurations differing only in these form
/// one series (one polyline of the plot).
pub const KNOB_KEYS: [&str; 3] = ["spp", "frames", "box_samples"];

/// The `[integrator] volume` names of the scene format.
const VOLUME_INTEGRATORS: [(&str, VolumeIntegrator); 2] = [
    ("restir", VolumeIntegrator::Restir),
    ("baseline", VolumeIntegrator::Baseline),
];

/// XORed into the scene's seed for the reference, so that no configuration that keeps
/// the scene's seed shares the reference's random numbers. Its 32-bit fold (what the
/// shaders see, `seed ^ seed >> 32`) is non-zero, so the folded seeds differ too.
const REFERENCE_SEED_MIX: u64 = 0x5EED_0000_0000_5EED;

/// Sets `key` = `value` on `scene`. Returns the `box_samples` override for
/// [`plan::build`] when the key is `box_samples` (the scene's field is set as well).
///
/// Errors name the key and list what it accepts; the message is meant to be prefixed
/// with the flag it came from.
pub fn apply(scene: &mut Scene, key: &str, value: &str) -> Result<Option<u32>> {
    let value = value.trim();
    match key {
        "box_estimator" => {
            scene.integrator.box_estimator = BoxEstimator::ALL
                .into_iter()
                .find(|e| e.name() == value)
                .ok_or_else(|| {
                    let names: Vec<_> = BoxEstimator::ALL.iter().map(|e| e.name()).collect();
                    anyhow!(
                        "box_estimator: unknown estimator {value:?}; valid: {}",
                        names.join(", ")
                    )
                })?;
        }
        "spp" => scene.render.spp = parse_count(key, value, 65_536)?,
        "box_samples" => {
            let n = parse_count(key, value, 65_536)?;
            scene.integrator.box_samples = n;
            return Ok(Some(n));
        }
        "frames" => scene.render.frames = parse_count(key, value, 1_000_000)?,
        "seed" => {
            scene.render.seed = value
                .parse()
                .map_err(|_| anyhow!("seed: {value:?} is not an unsigned 64-bit integer"))?;
        }
        "max_bounces" => scene.integrator.max_bounces = parse_count(key, value, 1024)?,
        "volume" => {
            scene.integrator.volume = VOLUME_INTEGRATORS
                .into_iter()
                .find(|(name, _)| *name == value)
                .map(|(_, v)| v)
                .ok_or_else(|| {
                    let names: Vec<_> = VOLUME_INTEGRATORS.iter().map(|(n, _)| *n).collect();
                    anyhow!(
                        "volume: unknown integrator {value:?}; valid: {}",
                        names.join(", ")
                    )
                })?;
        }
        "candidates" => scene.integrator.restir.candidates = parse_count(key, value, 4096)?,
        "temporal" => scene.integrator.restir.temporal = parse_bool(key, value)?,
        "temporal_limit" => {
            scene.integrator.restir.temporal_limit = parse_count(key, value, 1024)?;
        }
        "spatial_neighbors" => {
            scene.integrator.restir.spatial_neighbors = parse_range(key, value, 0, 64)?;
        }
        "spatial_radius_px" => {
            scene.integrator.restir.spatial_radius_px = match value.parse::<f32>() {
                Ok(r) if (0.0..=16384.0).contains(&r) => r,
                _ => bail!("{key}: {value:?} is not a number in [0, 16384]"),
            };
        }
        "spatial_rounds" => {
            scene.integrator.restir.spatial_rounds = parse_range(key, value, 0, 16)?;
        }
        "reuse" => {
            scene.integrator.restir.reuse = match value {
                "direction" => nimbus_scene::ReuseMode::Direction,
                "vertex" => nimbus_scene::ReuseMode::Vertex,
                _ => bail!("{key}: unknown reuse {value:?}; valid: direction, vertex"),
            };
        }
        "mip_candidates" => {
            scene.integrator.restir.mip_candidates = parse_range(key, value, 0, 16)?
        }
        "mip_indirect" => scene.integrator.restir.mip_indirect = parse_range(key, value, 0, 16)?,
        "mip_reuse" => scene.integrator.restir.mip_reuse = parse_range(key, value, 0, 16)?,
        "final_transmittance" => {
            scene.integrator.restir.final_ratio_tracking = match value {
                "analytic" => false,
                "ratio" => true,
                _ => bail!("{key}: unknown transmittance {value:?}; valid: analytic, ratio"),
            };
        }
        _ => bail!("unknown key {key:?}; valid keys: {}", keys().join(", ")),
    }
    Ok(None)
}

/// An integer in min..=max.
fn parse_range(key: &str, value: &str, min: u32, max: u32) -> Result<u32> {
    match value.parse::<u32>() {
        Ok(n) if (min..=max).contains(&n) => Ok(n),
        _ => bail!("{key}: {value:?} is not an integer in {min}..={max}"),
    }
}

/// `true` or `false`.
fn parse_bool(key: &str, value: &str) -> Result<bool> {
    match value {
        "true" => Ok(true),
        "false" => Ok(false),
        _ => bail!("{key}: {value:?} is not true or false"),
    }
}

/// An integer in 1..=max.
fn parse_count(key: &str, value: &str, max: u32) -> Result<u32> {
    match value.parse::<u32>() {
        Ok(n) if (1..=max).contains(&n) => Ok(n),
        _ => bail!("{key}: {value:?} is not an integer in 1..={max}"),
    }
}

/// One `--vary KEY=V1,V2,...`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Vary {
    pub key: String,
    pub values: Vec<String>,
}

/// Parses `KEY=V1,V2,...`: a known key (see [`keys`]) and a non-empty list of distinct,
/// non-empty values. The values themselves are checked by [`apply`].
pub fn parse_vary(text: &str) -> Result<Vary> {
    let (key, values) = text
        .split_once('=')
        .ok_or_else(|| anyhow!("expected KEY=V1,V2,... (e.g. spp=1,4,16), got {text:?}"))?;
    let key = key.trim();
    ensure!(
        keys().contains(&key),
        "unknown key {key:?}; valid keys: {}",
        keys().join(", ")
    );
    ensure!(
        !values.trim().is_empty(),
        "{key}: the list of values is empty (expected {key}=V1,V2,...)"
    );
    let mut list: Vec<String> = Vec::new();
    for v in values.split(',') {
        let v = v.trim();
        ensure!(!v.is_empty(), "{key}: empty value in {values:?}");
        ensure!(
            !list.iter().any(|x| x == v),
            "{key}: value {v:?} is repeated"
        );
        list.push(v.to_owned());
    }
    Ok(Vary {
        key: key.to_owned(),
        values: list,
    })
}

/// One configuration: the (key, value) of every `--vary`, in `--vary` order.
pub type Assignment = Vec<(String, String)>;

/// The cartesian product of the `--vary` lists, the first list outermost. No lists
/// give one empty assignment (the scene as it is).
pub fn cartesian(varies: &[Vary]) -> Vec<Assignment> {
    let mut out: Vec<Assignment> = vec![Vec::new()];
    for vary in varies {
        out = out
            .into_iter()
            .flat_map(|prefix| {
                vary.values.iter().map(move |v| {
                    let mut a = prefix.clone();
                    a.push((vary.key.clone(), v.clone()));
                    a
                })
            })
            .collect();
    }
    out
}

/// The part of an assignment that names its series: every pair whose key is not a
/// knob ([`KNOB_KEYS`]).
pub fn series_key(assignment: &[(String, String)]) -> Assignment {
    assignment
        .iter()
        .filter(|(k, _)| !KNOB_KEYS.contains(&k.as_str()))
        .cloned()
        .collect()
}

/// A series' name, `key=value key=value`, or `all configurations` when nothing but
/// knobs varies.
pub fn series_label(series: &[(String, String)]) -> String {
    if series.is_empty() {
        "all configurations".to_owned()
    } else {
        format_pairs(series)
    }
}

fn format_pairs(pairs: &[(String, String)]) -> String {
    let parts: Vec<String> = pairs.iter().map(|(k, v)| format!("{k}={v}")).collect();
    parts.join(" ")
}

/// Groups configurations into series: (series key, indices into `assignments`), in
/// order of first appearance.
pub fn group_series(assignments: &[Assignment]) -> Vec<(Assignment, Vec<usize>)> {
    let mut groups: Vec<(Assignment, Vec<usize>)> = Vec::new();
    for (i, a) in assignments.iter().enumerate() {
        let key = series_key(a);
        match groups.iter_mut().find(|(k, _)| *k == key) {
            Some((_, members)) => members.push(i),
            None => groups.push((key, vec![i])),
        }
    }
    groups
}

/// y(x) on the polyline through `points` (x ascending, all coordinates > 0), linear in
/// (log x, log y). `None` outside [x_first, x_last], for an empty polyline, or for a
/// non-positive x. Where several points share x = x_query, the first one's y.
pub fn interpolate_loglog(points: &[(f64, f64)], x: f64) -> Option<f64> {
    let (first, last) = (points.first()?, points.last()?);
    if x.is_nan() || x <= 0.0 || x < first.0 || x > last.0 {
        return None;
    }
    if let Some(p) = points.iter().find(|p| p.0 == x) {
        return Some(p.1);
    }
    let i = points.windows(2).position(|w| w[0].0 <= x && x <= w[1].0)?;
    let (a, b) = (points[i], points[i + 1]);
    // Interpolate log y linearly in log x; x_a < x < x_b here, so the span is positive.
    let t = (x.ln() - a.0.ln()) / (b.0.ln() - a.0.ln());
    Some((a.1.ln() + t * (b.1.ln() - a.1.ln())).exp())
}

/// The indices of the (time, RMSE) points that no other point beats in both: sorted
/// by time, each one with a lower RMSE than every faster point (of equal times, the
/// lower RMSE). This is the best a series buys for a given time, and the curve the
/// equal-time comparison interpolates; with one knob varied it is usually every
/// point.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len())
        .filter(|&i| points[i].0 > 0.0 && points[i].1 > 0.0)
        .collect();
    order.sort_by(|&a, &b| {
        points[a]
            .0
            .total_cmp(&points[b].0)
            .then(points[a].1.total_cmp(&points[b].1))
    });
    let mut front = Vec::new();
    let mut best = f64::INFINITY;
    for i in order {
        if points[i].1 < best {
            best = points[i].1;
            front.push(i);
        }
    }
    front
}

/// The RMSE ratio of `other` to `baseline` at equal GPU time: at every measured time of
/// `baseline` that lies inside `other`'s time range, `other`'s RMSE interpolated there
/// ([`interpolate_loglog`]) over the baseline's RMSE. Both are (time, RMSE) with time
/// ascending. Returns (time, ratio) pairs.
pub fn equal_time_ratios(baseline: &[(f64, f64)], other: &[(f64, f64)]) -> Vec<(f64, f64)> {
    baseline
        .iter()
        .filter_map(|&(t, rmse)| {
            let at = interpolate_loglog(other, t)?;
            (rmse > 0.0).then(|| (t, at / rmse))
        })
        .collect()
}

/// exp(mean ln v), `None` for an empty slice or a non-positive value.
pub fn geometric_mean(values: &[f64]) -> Option<f64> {
    if values.is_empty() || values.iter().any(|v| v.is_nan() || *v <= 0.0) {
        return None;
    }
    Some((values.iter().map(|v| v.ln()).sum::<f64>() / values.len() as f64).exp())
}

/// The median (mean of the middle two for an even count); `None` when empty.
pub fn median(values: &[f64]) -> Option<f64> {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n {
        0 => None,
        _ if n % 2 == 1 => Some(v[n / 2]),
        _ => Some(0.5 * (v[n / 2 - 1] + v[n / 2])),
    }
}

/// FNV-1a, 64 bit, over `bytes`, continuing from `hash` (start with [`FNV_OFFSET`]).
pub fn fnv1a64(mut hash: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        hash ^= u64::from(b);
        hash = hash.wrapping_mul(0x0000_0100_0000_01B3);
    }
    hash
}

/// The FNV-1a 64 offset basis.
pub const FNV_OFFSET: u64 = 0xCBF2_9CE4_8422_2325;

/// How an image differs from the reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorMetrics {
    pub rmse: f64,
    pub rel_mse: f64,
    pub mean_rel_diff: f64,
}

/// The mean over `frames` of each frame's MSE, relative MSE and mean relative
/// difference (RMSE = sqrt of the mean MSE).
pub fn mean_metrics(frames: &[ImageRgb], reference: &ImageRgb) -> Result<ErrorMetrics> {
    ensure!(!frames.is_empty(), "no frames to measure");
    let (mut mse, mut rel, mut diff) = (0.0, 0.0, 0.0);
    for frame in frames {
        let m = measure(frame, reference)?;
        mse += m.rmse * m.rmse;
        rel += m.rel_mse;
        diff += m.mean_rel_diff;
    }
    let n = frames.len() as f64;
    Ok(ErrorMetrics {
        rmse: (mse / n).sqrt(),
        rel_mse: rel / n,
        mean_rel_diff: diff / n,
    })
}

/// RMSE, relative MSE and mean relative difference of the means (see the module docs)
/// of `image` against `reference`, which must have the same size.
pub fn measure(image: &ImageRgb, reference: &ImageRgb) -> Result<ErrorMetrics> {
    ensure!(
        (image.width, image.height) == (reference.width, reference.height),
        "cannot compare a {}x{} image with a {}x{} reference",
        image.width,
        image.height,
        reference.width,
        reference.height
    );
    ensure!(!image.data.is_empty(), "cannot compare empty images");
    let (mut sq, mut rel) = (0.0f64, 0.0f64);
    for (a, r) in image.data.iter().zip(&reference.data) {
        for c in 0..3 {
            let (a, r) = (f64::from(a[c]), f64::from(r[c]));
            sq += (a - r) * (a - r);
            rel += (a - r) * (a - r) / (r * r + REL_MSE_EPSILON);
        }
    }
    let n = (3 * image.data.len()) as f64;
    let (mean_a, mean_r) = (image.mean(), reference.mean());
    let diffs: Vec<f64> = (0..3)
        .filter(|&c| mean_r[c] > 0.0)
        .map(|c| (mean_a[c] - mean_r[c]) / mean_r[c])
        .collect();
    let mean_rel_diff = if diffs.is_empty() {
        0.0
    } else {
        diffs.iter().sum::<f64>() / diffs.len() as f64
    };
    Ok(ErrorMetrics {
        rmse: (sq / n).sqrt(),
        rel_mse: rel / n,
        mean_rel_diff,
    })
}

/// The reference's own noise, from its per-pixel standard error σ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferenceNoise {
    /// √(mean σ²) over pixels and channels: its share of every measured RMSE
    /// (measured² ≈ true² + this²).
    pub rms_std_error: f64,
    /// mean σ / √(r² + ε), ε = [`REL_MSE_EPSILON`].
    pub mean_rel_std_error: f64,
}

impl ReferenceNoise {
    pub fn of(image: &ImageRgb, std_error: &ImageRgb) -> Self {
        let (mut sq, mut rel) = (0.0f64, 0.0f64);
        for (r, s) in image.data.iter().zip(&std_error.data) {
            for c in 0..3 {
                let (r, s) = (f64::from(r[c]), f64::from(s[c]));
                sq += s * s;
                rel += s / (r * r + REL_MSE_EPSILON).sqrt();
            }
        }
        let n = (3 * image.data.len()).max(1) as f64;
        Self {
            rms_std_error: (sq / n).sqrt(),
            mean_rel_std_error: rel / n,
        }
    }
}

/// One field of a CSV row (RFC 4180): quoted when it holds a comma, quote or line
/// break, with quotes doubled.
pub fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_owned()
    }
}

/// A CSV document: the header, then one line per row.
pub fn csv(header: &[String], rows: &[Vec<String>]) -> String {
    let line = |fields: &[String]| {
        let f: Vec<String> = fields.iter().map(|f| csv_field(f)).collect();
        f.join(",") + "\n"
    };
    let mut out = line(header);
    for row in rows {
        out += &line(row);
    }
    out
}

/// A Markdown table with padded columns (readable as plain text too); numeric-looking
/// columns are right-aligned.
pub fn markdown_table(header: &[String], rows: &[Vec<String>]) -> String {
    let widths: Vec<usize> = (0..header.len())
        .map(|i| {
            rows.iter()
                .map(|r| r[i].chars().count())
                .chain([header[i].chars().count(), 3])
                .max()
                .unwrap_or(3)
        })
        .collect();
    let numeric: Vec<bool> = (0..header.len())
        .map(|i| !rows.is_empty() && rows.iter().all(|r| r[i].parse::<f64>().is_ok()))
        .collect();
    let cell = |text: &str, i: usize| {
        if numeric[i] {
            format!("{text:>w$}", w = widths[i])
        } else {
            format!("{text:<w$}", w = widths[i])
        }
    };
    let mut out = String::new();
    let row_line = |cells: Vec<String>| format!("| {} |\n", cells.join(" | "));
    out += &row_line(header.iter().enumerate().map(|(i, h)| cell(h, i)).collect());
    out += &row_line(
        widths
            .iter()
            .zip(&numeric)
            .map(|(&w, &num)| {
                if num {
                    format!("{}:", "-".repeat(w - 1))
                } else {
                    "-".repeat(w)
                }
            })
            .collect(),
    );
    for r in rows {
        out += &row_line(r.iter().enumerate().map(|(i, c)| cell(c, i)).collect());
    }
    out
}

/// `x` with `digits` significant digits, without exponent for moderate magnitudes.
pub fn sig(x: f64, digits: usize) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let magnitude = x.abs().log10().floor() as i32;
    if !(-4..6).contains(&magnitude) {
        return format!("{x:.p$e}", p = digits.saturating_sub(1));
    }
    let decimals = (digits as i32 - 1 - magnitude).max(0) as usize;
    format!("{x:.decimals$}")
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
    /// Defaults to [`default_cache_dir`].
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

/// `$XDG_CACHE_HOME/nimbus/references`, else `$HOME/.cache/nimbus/references`.
pub fn default_cache_dir() -> Result<PathBuf> {
    let from = |var: &str| {
        std::env::var_os(var)
            .map(PathBuf::from)
            .filter(|p| p.is_absolute())
    };
    if let Some(dir) = from("XDG_CACHE_HOME") {
        return Ok(dir.join("nimbus/references"));
    }
    from("HOME")
        .map(|home| home.join(".cache/nimbus/references"))
        .ok_or_else(|| {
            anyhow!("neither XDG_CACHE_HOME nor HOME is set; pass --cache-dir DIR for the reference cache")
        })
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

/// The reference render, its settings and where it is cached.
struct ReferenceJob {
    scene: Scene,
    plan: RenderPlan,
    /// `key=value` lines, hashed into the cache key and stored in the sidecar.
    settings: Vec<(String, String)>,
    key: String,
    exr: PathBuf,
    sidecar: PathBuf,
}

/// The reference image with what is known about it.
struct Reference {
    image: ImageRgb,
    noise: ReferenceNoise,
    device: String,
    cached: bool,
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
        let r = &ref_scene.render;
        let settings: Vec<(String, String)> = [
            ("nimbus_version", env!("CARGO_PKG_VERSION").to_owned()),
            ("width", r.width.to_string()),
            ("height", r.height.to_string()),
            ("frames", r.frames.to_string()),
            ("spp", r.spp.to_string()),
            (
                "box_estimator",
                ref_scene.integrator.box_estimator.name().to_owned(),
            ),
            ("box_samples", ref_scene.integrator.box_samples.to_string()),
            ("seed", r.seed.to_string()),
            (
                "volume",
                match ref_scene.integrator.volume {
                    VolumeIntegrator::Restir => "restir",
                    VolumeIntegrator::Baseline => "baseline",
                }
                .to_owned(),
            ),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_owned(), v))
        .collect();
        let mut hash = fnv1a64(FNV_OFFSET, &scene_bytes);
        for (k, v) in &settings {
            hash = fnv1a64(hash, format!("\n{k}={v}").as_bytes());
        }
        let stem = scene_stem(&opts.scene);
        let key = format!("{stem}-{hash:016x}");
        let cache_dir = match &opts.cache_dir {
            Some(dir) => dir.clone(),
            None => default_cache_dir()?,
        };
        check_writable_dir(&cache_dir)
            .with_context(|| format!("--cache-dir {}", cache_dir.display()))?;
        let reference = ReferenceJob {
            exr: cache_dir.join(format!("{key}.exr")),
            sidecar: cache_dir.join(format!("{key}.json")),
            scene: ref_scene,
            plan: ref_plan,
            settings,
            key,
        };
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

    /// Renders (or loads) the reference, measures every configuration, writes
    /// `study.csv`, `study.md` and `study.png`, and prints the table.
    pub fn run(&self, ctx: &Context) -> Result<()> {
        let device = ctx.info().name.clone();
        let reference = self.reference(ctx)?;

        let total = self.configurations.len();
        let mut rows = Vec::with_capacity(total);
        for (i, config) in self.configurations.iter().enumerate() {
            let label = if config.assignment.is_empty() {
                "scene settings".to_owned()
            } else {
                format_pairs(&config.assignment)
            };
            if let Some(first) = config.same_as {
                let earlier: &Row = &rows[first];
                eprintln!(
                    "[{}/{total}] {label}: renders exactly as {} (its measurement reused)",
                    i + 1,
                    format_pairs(&earlier.assignment)
                );
                let mut row = earlier.clone();
                row.assignment = config.assignment.clone();
                row.spp = config.scene.render.spp;
                rows.push(row);
                continue;
            }
            let opts = RenderOptions {
                warmup_frames: self.warmup.max(1),
                keep_frames: self.per_frame,
                ..Default::default()
            };
            let start = Instant::now();
            let result = renderer::render(ctx, &config.scene, &config.plan, &opts)
                .with_context(|| format!("rendering configuration {label}"))?;
            let (gpu_ms_per_frame, mut gpu_ms_total) = frame_gpu_ms(&result.frame_timings)
                .with_context(|| format!("configuration {label} on device '{device}'"))?;
            let metrics = if self.per_frame {
                // The mean of the frames' own errors, at the cost of one frame.
                gpu_ms_total = gpu_ms_per_frame;
                mean_metrics(&result.frame_images, &reference.image)?
            } else {
                measure(&result.image, &reference.image)?
            };
            warn_non_finite(&result, &label);
            eprintln!(
                "[{}/{total}] {label}: {} ms/frame, {} ms total, RMSE {}, rel MSE {}, mean rel diff {:+.2}% ({:.1} s)",
                i + 1,
                sig(gpu_ms_per_frame, 4),
                sig(gpu_ms_total, 4),
                sig(metrics.rmse, 4),
                sig(metrics.rel_mse, 4),
                metrics.mean_rel_diff * 100.0,
                start.elapsed().as_secs_f64()
            );
            rows.push(Row {
                assignment: config.assignment.clone(),
                frames: config.scene.render.frames,
                spp: config.scene.render.spp,
                box_samples: config.scene.integrator.box_samples,
                gpu_ms_per_frame,
                gpu_ms_total,
                metrics,
            });
        }

        let series = self.series(&rows);
        let comparisons = self.baseline.as_ref().map(|b| equal_time(b, &series));
        let (header, cells) = self.table(&rows, false);
        let (csv_header, csv_cells) = self.table(&rows, true);

        let dir = &self.out_dir;
        let csv_path = dir.join("study.csv");
        std::fs::write(&csv_path, csv(&csv_header, &csv_cells))
            .with_context(|| format!("writing {}", csv_path.display()))?;

        let table = markdown_table(&header, &cells);
        let noise = self.noise_text(&reference, &rows);
        let equal = comparisons
            .as_ref()
            .map(|c| equal_time_text(c, self.baseline.as_ref()));
        let md_path = dir.join("study.md");
        let mut md = self.header_text(&device, &reference);
        md += "\n";
        md += &table;
        md += "\n";
        md += &noise;
        if let Some(text) = &equal {
            md += "\n";
            md += text;
        }
        md += "\n![RMSE versus total GPU time](study.png)\n";
        std::fs::write(&md_path, &md).with_context(|| format!("writing {}", md_path.display()))?;

        let png_path = dir.join("study.png");
        let title = format!(
            "{}: RMSE vs GPU time, {}x{}, {}",
            scene_stem(&self.scene_path),
            self.width,
            self.height,
            device
        );
        let knobs: Vec<&str> = self
            .varies
            .iter()
            .map(|v| v.key.as_str())
            .filter(|k| KNOB_KEYS.contains(k))
            .collect();
        plot::write_png(&png_path, &title, &knobs, &series)
            .with_context(|| format!("writing {}", png_path.display()))?;

        print!("{table}\n{noise}");
        if let Some(text) = &equal {
            print!("\n{text}");
        }
        eprintln!(
            "wrote {}, {} and {}",
            csv_path.display(),
            md_path.display(),
            png_path.display()
        );
        Ok(())
    }

    /// The cached reference if its files and settings match, else a fresh render that
    /// is then cached.
    fn reference(&self, ctx: &Context) -> Result<Reference> {
        let job = &self.reference;
        if let Some(reference) = load_cached(job)? {
            eprintln!(
                "using cached reference {} (rendered on {})",
                job.exr.display(),
                reference.device
            );
            return Ok(reference);
        }
        let r = &job.scene.render;
        eprintln!(
            "rendering reference: {} frame(s) x {} spp, box_estimator={}, box_samples={}, {}x{} (cache key {})",
            r.frames,
            r.spp,
            job.scene.integrator.box_estimator.name(),
            job.scene.integrator.box_samples,
            r.width,
            r.height,
            job.key
        );
        let opts = RenderOptions {
            progress: true,
            ..Default::default()
        };
        let result = renderer::render(ctx, &job.scene, &job.plan, &opts)
            .context("rendering the reference")?;
        warn_non_finite(&result, "reference");
        let noise = ReferenceNoise::of(&result.image, &result.std_error);
        let device = ctx.info().name.clone();
        store_cached(
            job,
            &result.image,
            &noise,
            &device,
            result.wall_time.as_secs_f64(),
        )?;
        eprintln!(
            "reference rendered in {:.1} s, cached as {}",
            result.wall_time.as_secs_f64(),
            job.exr.display()
        );
        Ok(Reference {
            image: result.image,
            noise,
            device,
            cached: false,
        })
    }

    /// The series of the measured rows, each as (label, points sorted by time).
    fn series(&self, rows: &[Row]) -> Vec<plot::Series> {
        let assignments: Vec<Assignment> = rows.iter().map(|r| r.assignment.clone()).collect();
        group_series(&assignments)
            .into_iter()
            .map(|(key, members)| {
                let mut points: Vec<plot::Point> = members
                    .iter()
                    .map(|&i| {
                        let row = &rows[i];
                        let knobs: Vec<(String, String)> = row
                            .assignment
                            .iter()
                            .filter(|(k, _)| KNOB_KEYS.contains(&k.as_str()))
                            .cloned()
                            .collect();
                        plot::Point {
                            time_ms: row.gpu_ms_total,
                            rmse: row.metrics.rmse,
                            knobs,
                        }
                    })
                    .collect();
                points.sort_by(|a, b| a.time_ms.total_cmp(&b.time_ms));
                plot::Series {
                    label: series_label(&key),
                    key,
                    points,
                }
            })
            .collect()
    }

    /// The results table: varied keys, frames/spp/box_samples, then the measurements.
    /// `full` gives every digit (for the CSV); otherwise 4 significant digits.
    fn table(&self, rows: &[Row], full: bool) -> (Vec<String>, Vec<Vec<String>>) {
        let varied: Vec<&str> = self
            .varies
            .iter()
            .map(|v| v.key.as_str())
            .filter(|k| !KNOB_KEYS.contains(k))
            .collect();
        let mut header: Vec<String> = varied.iter().map(|k| (*k).to_owned()).collect();
        header.extend(
            [
                "frames",
                "spp",
                "box_samples",
                "gpu_ms_per_frame",
                "gpu_ms_total",
                "rmse",
                "rel_mse",
                "mean_rel_diff",
            ]
            .map(str::to_owned),
        );
        let num = |x: f64| if full { format!("{x}") } else { sig(x, 4) };
        let cells = rows
            .iter()
            .map(|row| {
                let mut cells: Vec<String> = varied
                    .iter()
                    .map(|k| {
                        row.assignment
                            .iter()
                            .find(|(key, _)| key == k)
                            .map(|(_, v)| v.clone())
                            .unwrap_or_default()
                    })
                    .collect();
                cells.extend([
                    row.frames.to_string(),
                    row.spp.to_string(),
                    row.box_samples.to_string(),
                    num(row.gpu_ms_per_frame),
                    num(row.gpu_ms_total),
                    num(row.metrics.rmse),
                    num(row.metrics.rel_mse),
                    num(row.metrics.mean_rel_diff),
                ]);
                cells
            })
            .collect();
        (header, cells)
    }

    /// The first lines of study.md: scene, device, resolution, reference.
    fn header_text(&self, device: &str, reference: &Reference) -> String {
        let job = &self.reference;
        let r = &job.scene.render;
        let mut out = String::new();
        let _ = writeln!(out, "# Accuracy versus GPU time\n");
        let _ = writeln!(out, "- scene: `{}`", self.scene_path.display());
        let _ = writeln!(out, "- device: {device}");
        let _ = writeln!(out, "- resolution: {}x{}", self.width, self.height);
        let varied: Vec<String> = self
            .varies
            .iter()
            .map(|v| format!("`{}={}`", v.key, v.values.join(",")))
            .collect();
        if !varied.is_empty() {
            let _ = writeln!(out, "- varied: {}", varied.join(", "));
        }
        let _ = writeln!(
            out,
            "- reference: {} frame(s) x {} spp, box_estimator = {}, box_samples = {}, seed {}; {} `{}`{}",
            r.frames,
            r.spp,
            job.scene.integrator.box_estimator.name(),
            job.scene.integrator.box_samples,
            r.seed,
            if reference.cached { "cached" } else { "rendered now and cached as" },
            job.exr.display(),
            if reference.device == device {
                String::new()
            } else {
                format!(" (rendered on {})", reference.device)
            }
        );
        let warmup = self.warmup.max(1);
        let (total, errors) = if self.per_frame {
            (
                "the time of one frame (total)",
                "each measured frame's own error against the reference, averaged over the \
                 frames (RMSE = sqrt of the mean MSE)",
            )
        } else {
            (
                "sum over frames (total)",
                "the error of the mean over the frames against the reference",
            )
        };
        let _ = writeln!(
            out,
            "- GPU time: the \"frame\" timestamp scope, median over frames (per frame) and \
             {total}, after {warmup} warm-up frame(s); errors: {errors}, over all pixels and \
             channels; rel_mse = mean (a−r)²/(r²+{REL_MSE_EPSILON}); mean_rel_diff = mean \
             over channels of (mean a − mean r)/mean r"
        );
        out
    }

    /// The reference's own noise, and a warning when it is not small against the
    /// errors measured.
    fn noise_text(&self, reference: &Reference, rows: &[Row]) -> String {
        let noise = &reference.noise;
        let frames = self.reference.scene.render.frames;
        let mut out = String::new();
        if frames < 2 {
            let _ = writeln!(
                out,
                "Reference noise: unknown (the reference has {frames} frame; its standard \
                 error needs at least 2)."
            );
            return out;
        }
        let _ = writeln!(
            out,
            "Reference noise: mean relative standard error {}, RMS standard error {}.",
            sig(noise.mean_rel_std_error, 3),
            sig(noise.rms_std_error, 3)
        );
        let min_rmse = rows
            .iter()
            .map(|r| r.metrics.rmse)
            .fold(f64::INFINITY, f64::min);
        if min_rmse.is_finite() && min_rmse > 0.0 {
            let q = noise.rms_std_error / min_rmse;
            if q > 0.1 {
                let _ = writeln!(
                    out,
                    "WARNING: the reference is not converged enough for this study: its RMS \
                     standard error is {:.0}% of the smallest RMSE measured ({}), so it \
                     accounts for about {:.0}% of that configuration's MSE. Raise \
                     --reference-frames (the standard error falls as 1/sqrt(frames)).",
                    q * 100.0,
                    sig(min_rmse, 3),
                    (q * q).min(1.0) * 100.0
                );
            } else {
                let _ = writeln!(
                    out,
                    "It is {:.1}% of the smallest RMSE measured ({}): small enough.",
                    q * 100.0,
                    sig(min_rmse, 3)
                );
            }
        }
        out
    }
}

/// A series compared with its baseline at equal GPU time.
struct Comparison {
    series: String,
    baseline: String,
    /// (time ms, baseline RMSE, series RMSE at that time, ratio).
    points: Vec<(f64, f64, f64, f64)>,
    geo_mean: Option<f64>,
}

/// Compares every series that does not have the baseline's value with the baseline
/// series that shares all its other series keys, along both series' Pareto fronts
/// ([`pareto_front`]).
fn equal_time(baseline: &(String, String), series: &[plot::Series]) -> Vec<Comparison> {
    let (bkey, bvalue) = baseline;
    let mut out = Vec::new();
    for s in series {
        if s.key.iter().any(|(k, v)| k == bkey && v == bvalue) {
            continue;
        }
        let want: Assignment = s
            .key
            .iter()
            .map(|(k, v)| {
                if k == bkey {
                    (k.clone(), bvalue.clone())
                } else {
                    (k.clone(), v.clone())
                }
            })
            .collect();
        let Some(base) = series.iter().find(|b| b.key == want) else {
            continue;
        };
        let curve = |s: &plot::Series| -> Vec<(f64, f64)> {
            let all: Vec<(f64, f64)> = s.points.iter().map(|p| (p.time_ms, p.rmse)).collect();
            pareto_front(&all).into_iter().map(|i| all[i]).collect()
        };
        let (base_curve, curve) = (curve(base), curve(s));
        let ratios = equal_time_ratios(&base_curve, &curve);
        let points: Vec<(f64, f64, f64, f64)> = if ratios.is_empty() {
            // The series' times fall between the baseline's (e.g. a series of one
            // time): the baseline interpolated at the series' own times instead.
            curve
                .iter()
                .filter_map(|&(t, rmse)| {
                    let base_rmse = interpolate_loglog(&base_curve, t)?;
                    (base_rmse > 0.0).then(|| (t, base_rmse, rmse, rmse / base_rmse))
                })
                .collect()
        } else {
            ratios
                .iter()
                .map(|&(t, ratio)| {
                    let base_rmse = base_curve
                        .iter()
                        .find(|p| p.0 == t)
                        .map_or(f64::NAN, |p| p.1);
                    (t, base_rmse, base_rmse * ratio, ratio)
                })
                .collect()
        };
        let values: Vec<f64> = points.iter().map(|p| p.3).collect();
        out.push(Comparison {
            series: s.label.clone(),
            baseline: base.label.clone(),
            points,
            geo_mean: geometric_mean(&values),
        });
    }
    out
}

fn equal_time_text(comparisons: &[Comparison], baseline: Option<&(String, String)>) -> String {
    let mut out = String::new();
    let name = baseline.map_or(String::new(), |(k, v)| format!("{k}={v}"));
    let _ = writeln!(out, "## Equal-time RMSE ratio against {name}\n");
    let _ = writeln!(
        out,
        "RMSE of the series over RMSE of the baseline at the baseline's measured GPU times \
         (series interpolated linearly in log RMSE over log time; when the series' times \
         all fall between the baseline's, the baseline interpolated at the series' times); \
         below 1 means more accurate for the same GPU time, and the MSE ratio is its \
         square.\n"
    );
    if comparisons.is_empty() {
        let _ = writeln!(out, "No other series to compare.");
        return out;
    }
    let header: Vec<String> = [
        "series",
        "baseline",
        "gpu_ms_total",
        "baseline_rmse",
        "series_rmse",
        "ratio",
    ]
    .map(str::to_owned)
    .to_vec();
    let mut rows = Vec::new();
    let mut summary = Vec::new();
    for c in comparisons {
        for &(t, b, s, ratio) in &c.points {
            rows.push(vec![
                c.series.clone(),
                c.baseline.clone(),
                sig(t, 4),
                sig(b, 4),
                sig(s, 4),
                sig(ratio, 3),
            ]);
        }
        summary.push(match c.geo_mean {
            Some(g) => format!(
                "- {} vs {}: geometric mean RMSE ratio {} over {} time(s)",
                c.series,
                c.baseline,
                sig(g, 3),
                c.points.len()
            ),
            None => format!(
                "- {} vs {}: no common GPU time range (the series' times do not overlap the baseline's)",
                c.series, c.baseline
            ),
        });
    }
    if !rows.is_empty() {
        out += &markdown_table(&header, &rows);
        out += "\n";
    }
    for line in summary {
        let _ = writeln!(out, "{line}");
    }
    out
}

/// Checks `--baseline KEY=VALUE` against the varied keys; the default is
/// `box_estimator=rm` when box_estimator is varied over rm.
fn resolve_baseline(text: Option<&str>, varies: &[Vary]) -> Result<Option<(String, String)>> {
    let Some(text) = text else {
        let default = varies
            .iter()
            .find(|v| v.key == "box_estimator")
            .filter(|v| v.values.iter().any(|x| x == "rm"));
        return Ok(default.map(|v| (v.key.clone(), "rm".to_owned())));
    };
    let (key, value) = text
        .split_once('=')
        .map(|(k, v)| (k.trim(), v.trim()))
        .ok_or_else(|| anyhow!("--baseline {text}: expected KEY=VALUE, e.g. box_estimator=rm"))?;
    let series_keys: Vec<&str> = varies
        .iter()
        .map(|v| v.key.as_str())
        .filter(|k| !KNOB_KEYS.contains(k))
        .collect();
    ensure!(
        !KNOB_KEYS.contains(&key),
        "--baseline {text}: {key} is a knob that buys accuracy with time (it runs along each \
         series); the baseline picks a series by one of the varied keys {}",
        if series_keys.is_empty() {
            "(none is varied; vary e.g. box_estimator)".to_owned()
        } else {
            series_keys.join(", ")
        }
    );
    let Some(vary) = varies.iter().find(|v| v.key == key) else {
        bail!(
            "--baseline {text}: {key:?} is not varied; the baseline must be one value of a \
             varied key ({})",
            if series_keys.is_empty() {
                "none is varied besides knobs".to_owned()
            } else {
                series_keys.join(", ")
            }
        );
    };
    ensure!(
        vary.values.iter().any(|v| v == value),
        "--baseline {text}: {value:?} is not among the varied values of {key} ({})",
        vary.values.join(", ")
    );
    Ok(Some((key.to_owned(), value.to_owned())))
}

/// (median, sum) over frames of the root "frame" scope's GPU milliseconds.
fn frame_gpu_ms(frames: &[Vec<ScopeResult>]) -> Result<(f64, f64)> {
    ensure!(
        !frames.is_empty(),
        "the device reported no timestamps; a study needs GPU times"
    );
    let ms: Vec<f64> = frames
        .iter()
        .map(|scopes| {
            scopes
                .iter()
                .find(|s| s.label == "frame")
                .map(|s| s.duration_ms())
                .ok_or_else(|| anyhow!("a frame has no \"frame\" timestamp scope"))
        })
        .collect::<Result<_>>()?;
    let median = median(&ms).unwrap_or(0.0);
    Ok((median, ms.iter().sum()))
}

fn warn_non_finite(result: &RenderResult, what: &str) {
    if result.non_finite_samples > 0 {
        eprintln!(
            "warning: {what}: {} sample(s) were not finite and were dropped",
            result.non_finite_samples
        );
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

/// The cached reference when both files exist and the sidecar's key matches.
fn load_cached(job: &ReferenceJob) -> Result<Option<Reference>> {
    if !job.exr.is_file() || !job.sidecar.is_file() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&job.sidecar)
        .with_context(|| format!("reading {}", job.sidecar.display()))?;
    let Ok(meta) = serde_json::from_str::<serde_json::Value>(&text) else {
        eprintln!(
            "warning: {} is not valid JSON; rendering the reference again",
            job.sidecar.display()
        );
        return Ok(None);
    };
    if meta["key"].as_str() != Some(job.key.as_str()) {
        eprintln!(
            "warning: {} belongs to another reference; rendering again",
            job.sidecar.display()
        );
        return Ok(None);
    }
    let image = read_exr(&job.exr)?;
    let r = &job.scene.render;
    if (image.width, image.height) != (r.width, r.height) {
        eprintln!(
            "warning: {} is {}x{}, not {}x{}; rendering the reference again",
            job.exr.display(),
            image.width,
            image.height,
            r.width,
            r.height
        );
        return Ok(None);
    }
    let noise = ReferenceNoise {
        rms_std_error: meta["rms_std_error"].as_f64().unwrap_or(f64::NAN),
        mean_rel_std_error: meta["mean_rel_std_error"].as_f64().unwrap_or(f64::NAN),
    };
    Ok(Some(Reference {
        image,
        noise,
        device: meta["device"].as_str().unwrap_or("unknown").to_owned(),
        cached: true,
    }))
}

/// Writes the reference EXR and its sidecar, each through a temporary file renamed
/// into place, so an interrupted run never leaves a half-written cache entry.
fn store_cached(
    job: &ReferenceJob,
    image: &ImageRgb,
    noise: &ReferenceNoise,
    device: &str,
    wall_s: f64,
) -> Result<()> {
    let dir = job.exr.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)
        .with_context(|| format!("--cache-dir {}: cannot create the directory", dir.display()))?;
    let tmp_exr = dir.join(format!("{}.tmp-{}.exr", job.key, std::process::id()));
    write_image(&tmp_exr, image, 1.0)?;
    std::fs::rename(&tmp_exr, &job.exr)
        .with_context(|| format!("moving {} to {}", tmp_exr.display(), job.exr.display()))?;
    let mut meta = serde_json::Map::new();
    meta.insert("key".into(), job.key.clone().into());
    meta.insert(
        "scene".into(),
        job.scene.source.display().to_string().into(),
    );
    for (k, v) in &job.settings {
        let value = match v.parse::<u64>() {
            Ok(n) => n.into(),
            Err(_) => v.clone().into(),
        };
        meta.insert(k.clone(), value);
    }
    meta.insert("device".into(), device.into());
    meta.insert("render_wall_s".into(), wall_s.into());
    meta.insert("rms_std_error".into(), noise.rms_std_error.into());
    meta.insert("mean_rel_std_error".into(), noise.mean_rel_std_error.into());
    let text = serde_json::to_string_pretty(&serde_json::Value::Object(meta))?;
    let tmp_json = dir.join(format!("{}.tmp-{}.json", job.key, std::process::id()));
    std::fs::write(&tmp_json, text).with_context(|| format!("writing {}", tmp_json.display()))?;
    std::fs::rename(&tmp_json, &job.sidecar)
        .with_context(|| format!("moving {} to {}", tmp_json.display(), job.sidecar.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pairs(items: &[(&str, &str)]) -> Assignment {
        items
            .iter()
            .map(|(k, v)| ((*k).to_owned(), (*v).to_owned()))
            .collect()
    }

    fn scene() -> Scene {
        nimbus_scene::parse_str(crate::DEFAULT_SCENE, Path::new("window.toml")).unwrap()
    }

    #[test]
    fn parse_vary_reads_key_and_values() {
        let v = parse_vary("box_estimator= rm, reds ,mcds").unwrap();
        assert_eq!(v.key, "box_estimator");
        assert_eq!(v.values, ["rm", "reds", "mcds"]);
        assert_eq!(parse_vary("spp=4").unwrap().values, ["4"]);
    }

    #[test]
    fn parse_vary_errors_name_the_problem() {
        let cases = [
            ("spp", "KEY=V1,V2"),
            ("colour=1,2", "valid keys: box_estimator, spp"),
            ("spp=", "empty"),
            ("spp= ", "empty"),
            ("spp=1,,4", "empty value"),
            ("spp=1,4,1", "\"1\" is repeated"),
        ];
        for (text, needle) in cases {
            let message = format!("{:#}", parse_vary(text).unwrap_err());
            assert!(message.contains(needle), "{text}: {message}");
        }
    }

    #[test]
    fn apply_sets_each_key_and_lists_valid_values() {
        let mut s = scene();
        assert_eq!(apply(&mut s, "box_estimator", "reds").unwrap(), None);
        assert_eq!(s.integrator.box_estimator, BoxEstimator::Reds);
        assert_eq!(apply(&mut s, "spp", "8").unwrap(), None);
        assert_eq!(s.render.spp, 8);
        assert_eq!(apply(&mut s, "box_samples", "24").unwrap(), Some(24));
        assert_eq!(s.integrator.box_samples, 24);
        apply(&mut s, "frames", "3").unwrap();
        assert_eq!(s.render.frames, 3);
        apply(&mut s, "seed", "18446744073709551615").unwrap();
        assert_eq!(s.render.seed, u64::MAX);
        apply(&mut s, "max_bounces", "4").unwrap();
        assert_eq!(s.integrator.max_bounces, 4);
        apply(&mut s, "volume", "baseline").unwrap();
        assert_eq!(s.integrator.volume, VolumeIntegrator::Baseline);

        let cases = [
            ("box_estimator", "RM", "mcwvds, reds, rees, rm, mcds"),
            ("spp", "0", "spp: \"0\" is not an integer in 1..=65536"),
            ("spp", "many", "spp"),
            ("box_samples", "70000", "1..=65536"),
            ("seed", "-1", "seed"),
            ("volume", "pt", "restir, baseline"),
            ("exposure", "2", "valid keys: box_estimator"),
        ];
        for (key, value, needle) in cases {
            let message = format!("{:#}", apply(&mut s, key, value).unwrap_err());
            assert!(message.contains(needle), "{key}={value}: {message}");
        }
    }

    #[test]
    fn every_key_is_settable() {
        let values = [
            ("box_estimator", "rm"),
            ("spp", "2"),
            ("box_samples", "2"),
            ("frames", "2"),
            ("seed", "2"),
            ("max_bounces", "2"),
            ("volume", "restir"),
            ("candidates", "8"),
            ("temporal", "false"),
            ("temporal_limit", "20"),
            ("spatial_neighbors", "0"),
            ("spatial_radius_px", "2.5"),
            ("spatial_rounds", "2"),
            ("reuse", "vertex"),
            ("mip_candidates", "0"),
            ("mip_indirect", "3"),
            ("mip_reuse", "2"),
            ("final_transmittance", "ratio"),
        ];
        assert_eq!(values.len(), keys().len());
        let mut s = scene();
        for (key, value) in values {
            assert!(keys().contains(&key));
            apply(&mut s, key, value).unwrap();
        }
        let r = &s.integrator.restir;
        assert_eq!(
            (
                r.candidates,
                r.temporal,
                r.temporal_limit,
                r.spatial_neighbors
            ),
            (8, false, 20, 0)
        );
        assert_eq!((r.spatial_radius_px, r.spatial_rounds), (2.5, 2));
        assert_eq!(r.reuse, nimbus_scene::ReuseMode::Vertex);
        assert_eq!((r.mip_candidates, r.mip_indirect, r.mip_reuse), (0, 3, 2));
        assert!(r.final_ratio_tracking);
        for (key, value) in [
            ("temporal", "yes"),
            ("reuse", "path"),
            ("spatial_neighbors", "65"),
            ("final_transmittance", "exact"),
        ] {
            assert!(apply(&mut s, key, value).is_err(), "{key}={value}");
        }
    }

    #[test]
    fn cartesian_product_has_the_first_list_outermost() {
        let varies = [
            parse_vary("box_estimator=rm,reds").unwrap(),
            parse_vary("spp=1,4,16").unwrap(),
        ];
        let all = cartesian(&varies);
        assert_eq!(all.len(), 6);
        assert_eq!(all[0], pairs(&[("box_estimator", "rm"), ("spp", "1")]));
        assert_eq!(all[2], pairs(&[("box_estimator", "rm"), ("spp", "16")]));
        assert_eq!(all[3], pairs(&[("box_estimator", "reds"), ("spp", "1")]));
        assert_eq!(cartesian(&[]), vec![Vec::new()]);
    }

    #[test]
    fn series_share_everything_but_the_knobs() {
        let varies = [
            parse_vary("spp=1,4").unwrap(),
            parse_vary("box_estimator=rm,reds").unwrap(),
            parse_vary("box_samples=8,16").unwrap(),
            parse_vary("max_bounces=1,2").unwrap(),
        ];
        let all = cartesian(&varies);
        let groups = group_series(&all);
        assert_eq!(groups.len(), 4);
        for (key, members) in &groups {
            assert_eq!(members.len(), 4);
            for &i in members {
                assert_eq!(series_key(&all[i]), *key);
            }
        }
        assert_eq!(series_label(&groups[0].0), "box_estimator=rm max_bounces=1");
        let only_knobs = cartesian(&[parse_vary("spp=1,2").unwrap()]);
        let groups = group_series(&only_knobs);
        assert_eq!(groups, vec![(Vec::new(), vec![0, 1])]);
        assert_eq!(series_label(&groups[0].0), "all configurations");
    }

    #[test]
    fn loglog_interpolation_is_exact_on_power_laws() {
        // RMSE = 3 t^-1/2 is a straight line in log-log.
        let f = |t: f64| 3.0 / t.sqrt();
        let points: Vec<(f64, f64)> = [1.0, 4.0, 100.0].iter().map(|&t| (t, f(t))).collect();
        for t in [1.0, 2.0, 3.5, 4.0, 20.0, 100.0] {
            let y = interpolate_loglog(&points, t).unwrap();
            assert!((y - f(t)).abs() < 1e-12 * f(t), "t {t}: {y} vs {}", f(t));
        }
        assert_eq!(interpolate_loglog(&points, 0.5), None);
        assert_eq!(interpolate_loglog(&points, 101.0), None);
        assert_eq!(interpolate_loglog(&points, 0.0), None);
        assert_eq!(interpolate_loglog(&[], 1.0), None);
        assert_eq!(interpolate_loglog(&[(2.0, 5.0)], 2.0), Some(5.0));
        // Geometric midpoint in x gives the geometric mean in y.
        let y = interpolate_loglog(&[(1.0, 1.0), (100.0, 4.0)], 10.0).unwrap();
        assert!((y - 2.0).abs() < 1e-12);
        // Equal times do not divide by zero.
        assert_eq!(
            interpolate_loglog(&[(1.0, 2.0), (1.0, 3.0), (2.0, 1.0)], 1.0),
            Some(2.0)
        );
    }

    #[test]
    fn equal_time_ratio_uses_baseline_times_inside_the_other_range() {
        // The baseline needs 4x the time for the same error as the other series:
        // baseline RMSE = 1/sqrt(t), other = 1/sqrt(4t) = half at equal time.
        let baseline: Vec<(f64, f64)> = [1.0, 4.0, 16.0, 64.0]
            .iter()
            .map(|&t: &f64| (t, 1.0 / t.sqrt()))
            .collect();
        let other: Vec<(f64, f64)> = [2.0, 8.0, 32.0]
            .iter()
            .map(|&t: &f64| (t, 0.5 / t.sqrt()))
            .collect();
        let ratios = equal_time_ratios(&baseline, &other);
        let times: Vec<f64> = ratios.iter().map(|r| r.0).collect();
        assert_eq!(times, [4.0, 16.0]);
        for (_, r) in &ratios {
            assert!((r - 0.5).abs() < 1e-12, "{r}");
        }
        let values: Vec<f64> = ratios.iter().map(|r| r.1).collect();
        assert!((geometric_mean(&values).unwrap() - 0.5).abs() < 1e-12);
        assert!((geometric_mean(&[2.0, 8.0]).unwrap() - 4.0).abs() < 1e-12);
        assert_eq!(geometric_mean(&[]), None);
        assert_eq!(geometric_mean(&[1.0, 0.0]), None);
        assert!(equal_time_ratios(&baseline, &[(100.0, 1.0), (200.0, 0.5)]).is_empty());
    }

    #[test]
    fn pareto_front_drops_dominated_points() {
        let points = [
            (4.0, 1.0),
            (1.0, 3.0),
            (2.0, 3.5),
            (3.0, 2.0),
            (3.0, 1.5),
            (8.0, 1.2),
        ];
        assert_eq!(pareto_front(&points), [1, 4, 0]);
        assert_eq!(pareto_front(&[]), Vec::<usize>::new());
        assert_eq!(pareto_front(&[(1.0, 0.0), (2.0, 1.0)]), [1]);
    }

    #[test]
    fn baseline_must_name_a_varied_series_value() {
        let varies = [
            parse_vary("box_estimator=rm,reds").unwrap(),
            parse_vary("spp=1,4").unwrap(),
        ];
        assert_eq!(
            resolve_baseline(None, &varies).unwrap(),
            Some(("box_estimator".to_owned(), "rm".to_owned()))
        );
        assert_eq!(
            resolve_baseline(Some("box_estimator=reds"), &varies).unwrap(),
            Some(("box_estimator".to_owned(), "reds".to_owned()))
        );
        assert_eq!(resolve_baseline(None, &varies[1..]).unwrap(), None);
        for (text, needle) in [
            ("box_estimator", "KEY=VALUE"),
            ("spp=1", "knob"),
            ("box_estimator=mcds", "rm, reds"),
            ("seed=1", "not varied"),
        ] {
            let message = format!("{:#}", resolve_baseline(Some(text), &varies).unwrap_err());
            assert!(message.contains("--baseline"), "{message}");
            assert!(message.contains(needle), "{text}: {message}");
        }
    }

    #[test]
    fn equal_time_pairs_each_series_with_its_baseline() {
        let point = |t: f64, rmse: f64| plot::Point {
            time_ms: t,
            rmse,
            knobs: Vec::new(),
        };
        let series = |key: &[(&str, &str)], scale: f64| plot::Series {
            key: pairs(key),
            label: series_label(&pairs(key)),
            points: vec![point(1.0, scale), point(10.0, scale * 0.5)],
        };
        let all = [
            series(&[("box_estimator", "rm"), ("max_bounces", "1")], 1.0),
            series(&[("box_estimator", "reds"), ("max_bounces", "1")], 0.25),
            series(&[("box_estimator", "rm"), ("max_bounces", "2")], 2.0),
            series(&[("box_estimator", "reds"), ("max_bounces", "2")], 3.0),
        ];
        let c = equal_time(&("box_estimator".to_owned(), "rm".to_owned()), &all);
        assert_eq!(c.len(), 2);
        assert_eq!(c[0].baseline, "box_estimator=rm max_bounces=1");
        assert!((c[0].geo_mean.unwrap() - 0.25).abs() < 1e-12);
        assert_eq!(c[1].baseline, "box_estimator=rm max_bounces=2");
        assert!((c[1].geo_mean.unwrap() - 1.5).abs() < 1e-12);
        assert_eq!(c[1].points.len(), 2);
        let text = equal_time_text(&c, Some(&("box_estimator".into(), "rm".into())));
        assert!(text.contains("geometric mean RMSE ratio 0.250"), "{text}");
    }

    /// A series whose times fall between the baseline's (ReSTIR: one time per frame) is
    /// compared with the baseline interpolated in log-log at the series' own time.
    #[test]
    fn equal_time_interpolates_the_baseline_inside_its_range() {
        let point = |t: f64, rmse: f64| plot::Point {
            time_ms: t,
            rmse,
            knobs: Vec::new(),
        };
        let base = plot::Series {
            key: pairs(&[("volume", "baseline")]),
            label: "volume=baseline".into(),
            // RMSE ∝ t^(-1/2): 1 at 10 ms, 0.5 at 40 ms.
            points: vec![point(10.0, 1.0), point(40.0, 0.5)],
        };
        let restir = plot::Series {
            key: pairs(&[("volume", "restir")]),
            label: "volume=restir".into(),
            points: vec![point(20.0, 0.25)],
        };
        let c = equal_time(&("volume".into(), "baseline".into()), &[base, restir]);
        assert_eq!(c.len(), 1);
        let (t, b, r, ratio) = c[0].points[0];
        assert_eq!((t, r), (20.0, 0.25));
        assert!((b - 0.5f64.sqrt()).abs() < 1e-12, "{b}");
        assert!((ratio - 0.25 / 0.5f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn csv_quotes_only_when_needed() {
        assert_eq!(csv_field("rm"), "rm");
        assert_eq!(csv_field("a,b"), "\"a,b\"");
        assert_eq!(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
        let header = vec!["spp".to_owned(), "rmse".to_owned()];
        let rows = vec![
            vec!["1".to_owned(), format!("{}", 0.125)],
            vec!["4".to_owned(), format!("{}", 1e-7)],
        ];
        assert_eq!(csv(&header, &rows), "spp,rmse\n1,0.125\n4,0.0000001\n");
    }

    #[test]
    fn markdown_table_aligns_columns() {
        let header = vec!["box_estimator".to_owned(), "rmse".to_owned()];
        let rows = vec![vec!["rm".to_owned(), "0.5".to_owned()]];
        assert_eq!(
            markdown_table(&header, &rows),
            "| box_estimator | rmse |\n| ------------- | ---: |\n| rm            |  0.5 |\n"
        );
    }

    #[test]
    fn sig_keeps_significant_digits() {
        assert_eq!(sig(1234.567, 4), "1235");
        assert_eq!(sig(0.012345, 3), "0.0123");
        assert_eq!(sig(2.0, 3), "2.00");
        assert_eq!(sig(1.5e-7, 3), "1.50e-7");
        assert_eq!(sig(0.0, 3), "0");
    }

    #[test]
    fn metrics_of_known_images() {
        let reference = ImageRgb {
            width: 2,
            height: 1,
            data: vec![[1.0, 2.0, 0.0], [3.0, 2.0, 0.0]],
        };
        let image = ImageRgb {
            width: 2,
            height: 1,
            data: vec![[2.0, 2.0, 0.0], [3.0, 4.0, 0.0]],
        };
        let m = measure(&image, &reference).unwrap();
        assert!((m.rmse - (5.0f64 / 6.0).sqrt()).abs() < 1e-12);
        let rel = (1.0 / (1.0 + REL_MSE_EPSILON) + 4.0 / (4.0 + REL_MSE_EPSILON)) / 6.0;
        assert!((m.rel_mse - rel).abs() < 1e-12);
        // Means: red 2.5 vs 2 (+25%), green 3 vs 2 (+50%), blue 0 vs 0 (skipped).
        assert!((m.mean_rel_diff - 0.375).abs() < 1e-12);
        assert!(measure(&ImageRgb::new(1, 2), &reference).is_err());
        assert_eq!(measure(&reference, &reference).unwrap().rmse, 0.0);
    }

    #[test]
    fn reference_noise_and_medians() {
        let image = ImageRgb {
            width: 1,
            height: 1,
            data: vec![[0.0, 0.0, 0.0]],
        };
        let se = ImageRgb {
            width: 1,
            height: 1,
            data: vec![[0.1, 0.1, 0.1]],
        };
        let n = ReferenceNoise::of(&image, &se);
        assert!((n.rms_std_error - 0.1).abs() < 1e-7);
        assert!((n.mean_rel_std_error - 1.0).abs() < 1e-6);
        assert_eq!(median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median(&[]), None);
    }

    #[test]
    fn fnv1a64_matches_the_published_vectors() {
        assert_eq!(fnv1a64(FNV_OFFSET, b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(FNV_OFFSET, b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(FNV_OFFSET, b"foobar"), 0x8594_4171_f739_67e8);
        // Hashing in pieces is hashing the concatenation.
        assert_eq!(
            fnv1a64(fnv1a64(FNV_OFFSET, b"foo"), b"bar"),
            fnv1a64(FNV_OFFSET, b"foobar")
        );
    }

    #[test]
    fn configurations_an_integrator_cannot_tell_apart_are_rendered_once() {
        let dir = std::env::temp_dir().join(format!("nimbus-study-dedupe-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let scene = dir.join("grid.toml");
        std::fs::write(
            &scene,
            "[render]\nwidth = 8\nheight = 6\n[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n\
             [[medium]]\ntype = \"grid\"\nbounds_min = [-1, -1, -1]\nbounds_max = [1, 1, 1]\n\
             density = { procedural = \"cloud\", dims = [8, 8, 8] }\n",
        )
        .unwrap();
        let study = Study::new(&StudyOptions {
            scene: scene.clone(),
            vary: vec![
                "volume=baseline,restir".into(),
                "temporal_limit=4,20".into(),
                "spp=1,4".into(),
            ],
            frames: 1,
            reference_frames: 1,
            reference_spp: 1,
            reference_estimator: None,
            reference_box_samples: 1,
            baseline: Some("volume=baseline".into()),
            cache_dir: Some(dir.clone()),
            out_dir: Some(dir.clone()),
            width: None,
            height: None,
            warmup: 1,
            per_frame: false,
        })
        .unwrap();
        let same: Vec<Option<usize>> = study.configurations.iter().map(|c| c.same_as).collect();
        // baseline: Q is ignored (Q=20 repeats Q=4); restir: spp is ignored.
        assert_eq!(
            same,
            [None, None, Some(0), Some(1), None, Some(4), None, Some(6)]
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn reference_seed_differs_after_folding() {
        for seed in [0, 1, 0x5EED, u64::MAX, 0x5EED_0000_0000_0000] {
            assert_ne!(fold_seed(seed), fold_seed(seed ^ REFERENCE_SEED_MIX));
        }
    }
}
