//! Volumetric ReSTIR (`[integrator] volume = "restir"`, shaders/restir/*.comp) on
//! lavapipe with validation layers on:
//!
//! - **unbiasedness**: on a small static cloud, every reuse configuration (none, temporal
//!   only, spatial only, both; direction and vertex reuse; with and without emission; with
//!   surfaces beside and inside the cloud) converges to the unbiased baseline path tracer (decomposition tracking + residual
//!   ratio tracking, itself checked against the CPU oracle in tests/suite/oracle/baseline.rs);
//! - **hard cases**: empty and extremely dense grids, g = ±0.99, a camera inside the
//!   medium, black lights, a 1×1 image, a 1-voxel grid, a spatial radius of 0,
//!   Q = 1 and surfaces in odd places (around the camera, around the cloud, black, through
//!   the camera) render finite, non-negative images with no non-finite sample;
//! - **the plan**: `nimbus render --explain` names the four passes and what switches
//!   them off, and scenes ReSTIR cannot render are errors naming the file and table.
//!
//! Every render goes through [`render_checked`]: no validation error, no non-finite
//! sample, a finite image.
//!
//! The unbiasedness cases are in [`unbiased`] (media) and [`surfaces`], the hard cases in
//! [`hard_cases`], the plan in [`plan`]; this module holds the scene they vary
//! ([`Cloud`]) and the comparison with the baseline.
//!
//! ## How the unbiasedness criteria are built
//!
//! ReSTIR renders one sample per pixel per frame and, with temporal reuse, consecutive
//! frames share reservoirs, so the per-pixel standard error that a render reports (from
//! the frame-to-frame variance) underestimates the error of its mean. The ReSTIR side of
//! every comparison is therefore [`RUNS`] **independent** renders (different
//! `[render] seed`) of [`RUN_FRAMES`] frames each, and its standard errors come from the
//! spread of the run means: per pixel channel, and for the image mean (spatial reuse
//! correlates neighbouring pixels, so the image mean's error is not the per-pixel errors
//! added in quadrature either). 16 runs rather than 8: run means under reuse are skewed
//! (rare bright samples), and with 8 runs a draw without them gave both a low mean and
//! an estimated standard error half the true one (measured over 48-128 runs), which
//! turns noise into a 4-5 SE "bias". The baseline reference is one render of
//! [`REFERENCE_FRAMES`] × [`REFERENCE_SPP`] samples per pixel: its frames and pixels are
//! independent, so its reported per-pixel standard error and their quadrature sum are
//! honest. The criteria, all of which must hold per case (see [`compare`]):
//!
//! 1. the image mean of every channel differs from the reference by **less than 1%**
//!    (relative) — a bias large enough to see in a picture fails here even where the
//!    noise would hide it;
//! 2. and by at most **4 combined standard errors** — the 1% alone would let a small
//!    but real bias pass wherever the estimate is much more precise than 1% (with 16
//!    runs the ratio is Student-t with 15 degrees of freedom: |t| > 4 has probability
//!    0.001 under the null);
//! 3. at most **2% of the pixel channels** differ from the reference by more than **4.5
//!    combined standard errors** — a bias confined to part of the image (an edge, the
//!    lit side) shows up here. Under the null a channel exceeds 4.5 SE with probability
//!    0.0004 (t with 15 degrees of freedom, which covers the noise of the per-pixel error
//!    estimate from 16 runs), i.e. less than one of 1296 channels; 2% is 26 channels.
//!    The slack is for pixels whose estimate has a rare-event distribution the runs
//!    cannot resolve: where a camera ray grazes the cloud's conservative (mip 1)
//!    majorant grid but not its density, the baseline sees exactly the sky (standard
//!    error 0) and ReSTIR's direct estimate is L T / T* with T = 1 > T* almost always,
//!    and 3/4 of that when one of the M = 4 walks collides (probability ~4 (1 − T*)):
//!    unbiased, but a few hundred frames rarely see the collision, so the mean sits
//!    ~0.1% high with a tiny spread (5-8 such pixels, ~16 channels, on this scene).
//!    Where both standard errors are 0 (sky pixels seen through empty space, the same
//!    value every run) a channel may differ by float rounding only: 1e-5 relative + 1e-6.
//!
//! The seeds are fixed, so the outcome is deterministic on a given device.

use crate::common::cli::{nimbus, scratch, text};
use crate::common::gpu::{assert_no_validation_errors, context, render_checked, scene};
use nimbus::output::ImageRgb;
use nimbus_gpu::Context;

mod hard_cases;
mod plan;
mod surfaces;
mod unbiased;

/// Independent ReSTIR renders per case (different seeds).
const RUNS: u64 = 16;
/// Frames of each ReSTIR run.
pub(crate) const RUN_FRAMES: u32 = 24;
/// Frames and samples per pixel per frame of the baseline reference (2048 paths per
/// pixel: its standard error is a fifth to a third of the ReSTIR side's).
const REFERENCE_FRAMES: u32 = 64;
const REFERENCE_SPP: u32 = 32;
/// Image size of the unbiasedness scenes.
const SIZE: (u32, u32) = (24, 18);

/// Limits of the unbiasedness comparison (see the module docs for why).
const MAX_REL_MEAN_DIFF: f64 = 0.01;
const MEAN_Z: f64 = 4.0;
const PIXEL_Z: f64 = 4.5;
const MAX_FRACTION_BEYOND: f64 = 0.02;
/// Float rounding allowed on top of the standard errors, relative and absolute.
const ROUNDING_REL: f64 = 1e-5;
const ROUNDING_ABS: f64 = 1e-6;

/// A sun and a sky: the directional light is seen only through the medium, the sky
/// also directly.
pub(crate) const SUN_AND_SKY: &str = r#"
[[light]]
type = "directional"
direction = [0.5, -0.7, -0.4]
irradiance = [3.0, 2.7, 2.4]
[[light]]
type = "environment"
radiance = [0.2, 0.3, 0.45]
"#;

/// The procedural cloud's `density = ...` line.
const CLOUD_DENSITY: &str =
    r#"density = { procedural = "cloud", dims = [24, 16, 24], noise_seed = 3 }"#;

/// The scene the tests vary: `[render]`, the camera, `lights`, one grid medium (its
/// `density` line, `scale`, `g` and `medium_extra` lines), the integrator and an
/// `[integrator.restir]` table holding `restir`.
#[derive(Clone, Copy)]
pub(crate) struct Cloud<'a> {
    pub(crate) size: (u32, u32),
    pub(crate) frames: u32,
    pub(crate) spp: u32,
    pub(crate) seed: u64,
    pub(crate) position: &'a str,
    pub(crate) lights: &'a str,
    pub(crate) density: &'a str,
    pub(crate) scale: f32,
    /// The medium's `albedo` (a colour or a grid table).
    pub(crate) albedo: &'a str,
    pub(crate) g: f32,
    pub(crate) medium_extra: &'a str,
    pub(crate) volume: &'a str,
    pub(crate) bounces: u32,
    pub(crate) restir: &'a str,
    /// `[[shape]]` tables.
    pub(crate) shapes: &'a str,
}

impl Default for Cloud<'_> {
    fn default() -> Self {
        Self {
            size: SIZE,
            frames: RUN_FRAMES,
            spp: 1,
            seed: 1,
            position: "[0.0, 0.25, 2.3]",
            lights: SUN_AND_SKY,
            density: CLOUD_DENSITY,
            scale: 16.0,
            albedo: "0.9",
            g: 0.5,
            medium_extra: "",
            volume: "restir",
            bounces: 1,
            restir: "",
            shapes: "",
        }
    }
}

impl Cloud<'_> {
    fn text(&self) -> String {
        format!(
            r#"
[render]
width = {w}
height = {h}
frames = {frames}
spp = {spp}
seed = {seed}
[camera]
position = {position}
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 55
{lights}
[[medium]]
type = "grid"
bounds_min = [-1.0, -0.6, -1.0]
bounds_max = [1.0, 0.6, 1.0]
{density}
density_scale = {scale:?}
albedo = {albedo}
g = {g:?}
{medium_extra}
{shapes}
[integrator]
volume = "{volume}"
max_bounces = {bounces}
[integrator.restir]
{restir}
"#,
            w = self.size.0,
            h = self.size.1,
            frames = self.frames,
            spp = self.spp,
            seed = self.seed,
            position = self.position,
            lights = self.lights,
            density = self.density,
            scale = self.scale,
            albedo = self.albedo,
            g = self.g,
            medium_extra = self.medium_extra,
            volume = self.volume,
            bounces = self.bounces,
            restir = self.restir,
            shapes = self.shapes,
        )
    }

    pub(crate) fn scene(&self, name: &str) -> nimbus_scene::Scene {
        scene(&self.text(), name)
    }
}

// ---------------------------------------------------------------------------------------
// Unbiasedness against the baseline.

/// An estimate of an image: per pixel channel a mean and its standard error, and the
/// image mean per channel with its standard error.
pub(crate) struct Estimate {
    pub(crate) mean: Vec<[f64; 3]>,
    pub(crate) se: Vec<[f64; 3]>,
    pub(crate) image_mean: [f64; 3],
    pub(crate) image_mean_se: [f64; 3],
}

/// The baseline reference of `cloud` (volume = "baseline", [`REFERENCE_FRAMES`] ×
/// [`REFERENCE_SPP`]): frames and pixels are independent, so the render's own standard
/// errors are used.
fn reference(ctx: &Context, cloud: &Cloud) -> Estimate {
    let scene = Cloud {
        volume: "baseline",
        frames: REFERENCE_FRAMES,
        spp: REFERENCE_SPP,
        seed: 7,
        ..*cloud
    }
    .scene("restir-reference.toml");
    let result = render_checked(ctx, &scene, None);
    let widen = |img: &ImageRgb| -> Vec<[f64; 3]> {
        img.data
            .iter()
            .map(|p| p.map(f64::from))
            .collect::<Vec<_>>()
    };
    let mean = widen(&result.image);
    let se = widen(&result.std_error);
    let n = se.len() as f64;
    let mut image_mean_se = [0.0; 3];
    for (c, s) in image_mean_se.iter_mut().enumerate() {
        *s = se.iter().map(|p| p[c] * p[c]).sum::<f64>().sqrt() / n;
    }
    Estimate {
        mean,
        se,
        image_mean: result.image.mean(),
        image_mean_se,
    }
}

/// [`RUNS`] independent ReSTIR renders of `cloud` (seeds 101, 102, ...); standard errors
/// from the spread of the run means.
fn restir_runs(ctx: &Context, cloud: &Cloud) -> Estimate {
    let runs: Vec<ImageRgb> = (0..RUNS)
        .map(|i| {
            let scene = Cloud {
                volume: "restir",
                frames: RUN_FRAMES,
                spp: 1,
                seed: 101 + i,
                ..*cloud
            }
            .scene("restir-run.toml");
            render_checked(ctx, &scene, None).image
        })
        .collect();
    let r = RUNS as f64;
    // Mean and standard error of the mean of `values` (sample variance, R - 1).
    let stats = |values: &mut dyn Iterator<Item = f64>| {
        let v: Vec<f64> = values.collect();
        let m = v.iter().sum::<f64>() / r;
        let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (r - 1.0);
        (m, (var / r).sqrt())
    };
    let pixels = runs[0].data.len();
    let mut mean = vec![[0.0; 3]; pixels];
    let mut se = vec![[0.0; 3]; pixels];
    for p in 0..pixels {
        for c in 0..3 {
            let (m, s) = stats(&mut runs.iter().map(|img| f64::from(img.data[p][c])));
            mean[p][c] = m;
            se[p][c] = s;
        }
    }
    let run_means: Vec<[f64; 3]> = runs.iter().map(ImageRgb::mean).collect();
    let mut image_mean = [0.0; 3];
    let mut image_mean_se = [0.0; 3];
    for c in 0..3 {
        let (m, s) = stats(&mut run_means.iter().map(|m| m[c]));
        image_mean[c] = m;
        image_mean_se[c] = s;
    }
    Estimate {
        mean,
        se,
        image_mean,
        image_mean_se,
    }
}

/// What [`compare`] measured for one case.
#[derive(Debug)]
struct Comparison {
    /// (ReSTIR − reference) / reference of the image mean, per channel.
    rel_mean_diff: [f64; 3],
    /// Image-mean difference in combined standard errors, per channel.
    mean_z: [f64; 3],
    /// Largest per-pixel-channel difference in combined standard errors.
    worst_pixel_z: f64,
    /// Pixel channels beyond [`PIXEL_Z`] combined standard errors.
    beyond: usize,
    channels: usize,
}

impl Comparison {
    fn fraction_beyond(&self) -> f64 {
        self.beyond as f64 / self.channels as f64
    }

    /// Why the case fails the criteria of the module docs, if it does.
    fn failure(&self) -> Option<String> {
        let mut why = Vec::new();
        for c in 0..3 {
            if self.rel_mean_diff[c].abs() >= MAX_REL_MEAN_DIFF {
                why.push(format!(
                    "channel {c}: image mean differs by {:+.3}% (limit 1%)",
                    100.0 * self.rel_mean_diff[c]
                ));
            }
            if self.mean_z[c].abs() > MEAN_Z {
                why.push(format!(
                    "channel {c}: image mean differs by {:+.2} SE (limit {MEAN_Z})",
                    self.mean_z[c]
                ));
            }
        }
        if self.fraction_beyond() > MAX_FRACTION_BEYOND {
            why.push(format!(
                "{} of {} pixel channels beyond {PIXEL_Z} SE (limit {}%)",
                self.beyond,
                self.channels,
                100.0 * MAX_FRACTION_BEYOND
            ));
        }
        (!why.is_empty()).then(|| why.join("; "))
    }
}

/// Compares a ReSTIR estimate with the reference (criteria in the module docs).
fn compare(restir: &Estimate, reference: &Estimate) -> Comparison {
    let mut rel_mean_diff = [0.0; 3];
    let mut mean_z = [0.0; 3];
    for c in 0..3 {
        let diff = restir.image_mean[c] - reference.image_mean[c];
        let se = restir.image_mean_se[c].hypot(reference.image_mean_se[c]);
        rel_mean_diff[c] = diff / reference.image_mean[c];
        mean_z[c] = diff / se;
    }
    let mut worst_pixel_z: f64 = 0.0;
    let mut beyond = 0;
    for p in 0..reference.mean.len() {
        for c in 0..3 {
            let (a, b) = (restir.mean[p][c], reference.mean[p][c]);
            let se = restir.se[p][c].hypot(reference.se[p][c]);
            // Float rounding: sky pixels seen through empty space are the same value in
            // every run and every reference sample, up to the rounding of the sums.
            let excess = ((a - b).abs() - ROUNDING_REL * b.abs() - ROUNDING_ABS).max(0.0);
            let z = if excess == 0.0 {
                0.0
            } else if se > 0.0 {
                excess / se
            } else {
                f64::INFINITY
            };
            worst_pixel_z = worst_pixel_z.max(z);
            if z > PIXEL_Z {
                beyond += 1;
            }
        }
    }
    Comparison {
        rel_mean_diff,
        mean_z,
        worst_pixel_z,
        beyond,
        channels: 3 * reference.mean.len(),
    }
}

/// One ReSTIR configuration: a label and the lines of its `[integrator.restir]`.
pub(crate) struct Case {
    pub(crate) label: &'static str,
    pub(crate) restir: &'static str,
}

const NO_REUSE: Case = Case {
    label: "no reuse",
    restir: "temporal = false\nspatial_rounds = 0",
};
const TEMPORAL: Case = Case {
    label: "temporal only, delta-tracked candidates",
    restir:
        "temporal = true\ntemporal_limit = 4\nspatial_rounds = 0\ncandidate_tracking = \"delta\"",
};
const SPATIAL: Case = Case {
    label: "spatial only, delta-tracked candidates",
    restir: "temporal = false\nspatial_rounds = 1\nspatial_neighbors = 3\nspatial_when = \"always\"\nspatial_radius_px = 10\n\
             candidate_tracking = \"delta\"",
};
pub(crate) const BOTH: Case = Case {
    label: "temporal + spatial",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 1\nspatial_neighbors = 3\nspatial_when = \"always\"\nspatial_radius_px = 10",
};
const VERTEX: Case = Case {
    label: "temporal + spatial, vertex reuse, one light per vertex, regular tracking, direct paths of escaping walks",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 1\nspatial_neighbors = 3\nspatial_when = \"always\"\nspatial_radius_px = 10\nreuse = \"vertex\"\n\
             nee = \"one\"\ncandidate_tracking = \"regular\"\ndirect = \"escape\"",
};

const LEVERS: Case = Case {
    label: "temporal + 2 spatial rounds, pairwise MIS, optical-depth shift, pre-spatial history, regular tracking with a sigma* floor",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 2\nspatial_neighbors = 4\nspatial_when = \"always\"\nspatial_radius_px = 10\n\
             mis = \"pairwise\"\nspatial_shift = \"optical_depth\"\ntemporal_history = \"temporal\"\n\
             candidate_tracking = \"regular\"\nsigma_star_floor = 0.25\n\
             spatial_anchor = true\nspatial_feature_tolerance = 0.3",
};
const FOLDED: Case = Case {
    label: "temporal + spatial, emission folded into the split-NEE candidates",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 1\nspatial_neighbors = 3\nspatial_when = \"always\"\n\
             spatial_radius_px = 10\nemission = \"folded\"",
};
const ANCHORED: Case = Case {
    label: "temporal + spatial, depth anchors, neighbours tested by their camera rays",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 1\nspatial_neighbors = 3\nspatial_when = \"always\"\nspatial_radius_px = 10\n\
             spatial_anchor = true\nspatial_feature_tolerance = 0.3",
};
/// Spatial reuse alone by the exact optical-depth shift, two rounds of four neighbours
/// within 10 px (the image is 24 px wide): where no temporal history dilutes it, a wrong
/// Jacobian of the shift (sigma_t at the shifted x_1) shows (single_scattering_matches_...).
/// The temporal optical-depth shift acts under a moving camera only: restir_history.rs
/// checks both exact shifts there.
const SPATIAL_TAU_EXACT: Case = Case {
    label: "spatial only, 2 rounds of 4 neighbours, x_1 shifted by its exact optical depth",
    restir: "temporal = false\nspatial_rounds = 2\nspatial_neighbors = 4\nspatial_when = \"always\"\nspatial_radius_px = 10\n\
             spatial_shift = \"optical_depth_exact\"",
};
/// The same through the conservative grid (tau* of regular tracking, sigma* the Jacobian);
/// `LEVERS` runs this shift under temporal reuse too.
const SPATIAL_TAU_STAR: Case = Case {
    label: "spatial only, 2 rounds of 4 neighbours, x_1 shifted by its optical depth through the conservative grid",
    restir: "temporal = false\nspatial_rounds = 2\nspatial_neighbors = 4\nspatial_when = \"always\"\nspatial_radius_px = 10\n\
             spatial_shift = \"optical_depth\"",
};
const TARGET_LUMINANCE: Case = Case {
    label: "temporal + spatial, the target the luminance (the paper's)",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 1\nspatial_neighbors = 3\nspatial_when = \"always\"\n\
             spatial_radius_px = 10\ntarget = \"luminance\"",
};
const TARGET_MAX: Case = Case {
    label: "temporal + spatial, the target the largest channel",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 1\nspatial_neighbors = 3\nspatial_when = \"always\"\n\
             spatial_radius_px = 10\ntarget = \"max\"",
};
const CAMERA_RESERVOIR: Case = Case {
    label: "temporal + spatial, the camera rays' emission resampled (the paper's)",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 1\nspatial_neighbors = 3\nspatial_when = \"always\"\n\
             spatial_radius_px = 10\ncamera_emission = \"reservoir\"",
};
pub(crate) const PAIRWISE: Case = Case {
    label: "temporal + spatial, pairwise MIS, one light per vertex, regular tracking",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 1\nspatial_neighbors = 3\nspatial_when = \"always\"\nspatial_radius_px = 10\nmis = \"pairwise\"\n\
             nee = \"one\"\ncandidate_tracking = \"regular\"",
};

/// Renders the baseline reference of `base` once, then every case against it; prints
/// each case's numbers and fails with all failing cases at the end.
fn check_cases(base: Cloud, cases: &[Case], group: &str) {
    let ctx = context();
    let start = std::time::Instant::now();
    let reference = reference(&ctx, &base);
    println!(
        "{group}: baseline reference {:?} ± {:?} ({:.1?})",
        reference.image_mean,
        reference.image_mean_se,
        start.elapsed()
    );
    check_cases_against(&ctx, &reference, base, cases, group);
}

/// Every case of `base` against `reference` (criteria in the module docs): [`RUNS`]
/// ReSTIR renders of [`RUN_FRAMES`] frames each (of an animated scene: its frames 0,
/// 1, ...).
pub(crate) fn check_cases_against(
    ctx: &Context,
    reference: &Estimate,
    base: Cloud,
    cases: &[Case],
    group: &str,
) {
    let mut failures = Vec::new();
    for case in cases {
        let start = std::time::Instant::now();
        let estimate = restir_runs(
            ctx,
            &Cloud {
                restir: case.restir,
                ..base
            },
        );
        let cmp = compare(&estimate, reference);
        println!(
            "{group}, {}: mean {:?}, rel. diff [{:+.3}%, {:+.3}%, {:+.3}%], mean z [{:+.2}, {:+.2}, {:+.2}], \
             worst pixel z {:.2}, {} of {} channels ({:.2}%) beyond {PIXEL_Z} SE ({:.1?})",
            case.label,
            estimate.image_mean,
            100.0 * cmp.rel_mean_diff[0],
            100.0 * cmp.rel_mean_diff[1],
            100.0 * cmp.rel_mean_diff[2],
            cmp.mean_z[0],
            cmp.mean_z[1],
            cmp.mean_z[2],
            cmp.worst_pixel_z,
            cmp.beyond,
            cmp.channels,
            100.0 * cmp.fraction_beyond(),
            start.elapsed()
        );
        if let Some(why) = cmp.failure() {
            failures.push(format!("{group}, {}: {why}", case.label));
        }
    }
    assert_no_validation_errors(ctx);
    assert!(
        failures.is_empty(),
        "ReSTIR differs from the baseline:\n{}",
        failures.join("\n")
    );
}
