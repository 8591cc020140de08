//! Volumetric ReSTIR (`[integrator] volume = "restir"`, shaders/restir/*.comp) on
//! lavapipe with validation layers on:
//!
//! - **unbiasedness**: on a small static cloud, every reuse configuration (none, temporal
//!   only, spatial only, both; direction and vertex reuse; with and without emission; with
//!   surfaces beside and inside the cloud) converges to the unbiased baseline path tracer (decomposition tracking + residual
//!   ratio tracking, itself checked against the CPU oracle in tests/suite/baseline.rs);
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
    label: "temporal only",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 0",
};
const SPATIAL: Case = Case {
    label: "spatial only",
    restir: "temporal = false\nspatial_rounds = 1\nspatial_neighbors = 3\nspatial_when = \"always\"\nspatial_radius_px = 10",
};
pub(crate) const BOTH: Case = Case {
    label: "temporal + spatial",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 1\nspatial_neighbors = 3\nspatial_when = \"always\"\nspatial_radius_px = 10",
};
const VERTEX: Case = Case {
    label: "temporal + spatial, vertex reuse, one light per vertex, direct paths of escaping walks",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 1\nspatial_neighbors = 3\nspatial_when = \"always\"\nspatial_radius_px = 10\nreuse = \"vertex\"\n\
             nee = \"one\"\ndirect = \"escape\"",
};

const LEVERS: Case = Case {
    label: "temporal + 2 spatial rounds, pairwise MIS, optical-depth shift, pre-spatial history, sigma* floor",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 2\nspatial_neighbors = 4\nspatial_when = \"always\"\nspatial_radius_px = 10\n\
             mis = \"pairwise\"\nspatial_shift = \"optical_depth\"\ntemporal_history = \"temporal\"\nsigma_star_floor = 0.25",
};
const FOLDED: Case = Case {
    label: "temporal + spatial, emission folded into the split-NEE candidates",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 1\nspatial_neighbors = 3\nspatial_when = \"always\"\n\
             spatial_radius_px = 10\nemission = \"folded\"",
};
const TAU_SHIFT: Case = Case {
    label: "temporal + spatial, x_1 shifted by its optical depth",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 1\nspatial_neighbors = 3\nspatial_when = \"always\"\nspatial_radius_px = 10\n\
             spatial_shift = \"optical_depth\"",
};
pub(crate) const PAIRWISE: Case = Case {
    label: "temporal + spatial, pairwise MIS, one light per vertex",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 1\nspatial_neighbors = 3\nspatial_when = \"always\"\nspatial_radius_px = 10\nmis = \"pairwise\"\n\
             nee = \"one\"",
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

/// Single scattering (K = 1): no reuse, temporal only, spatial only, both, and both with
/// pairwise MIS converge to the baseline (criteria in the module docs).
#[test]
fn single_scattering_matches_the_baseline() {
    check_cases(
        Cloud {
            bounces: 1,
            ..Cloud::default()
        },
        &[NO_REUSE, TEMPORAL, SPATIAL, BOTH, PAIRWISE, TAU_SHIFT],
        "K=1",
    );
}

/// Multiple scattering (K = 3): no reuse, both reuses, both with vertex reuse, and the
/// levers together (two rounds of pairwise MIS, the pre-spatial history, a σ* floor)
/// converge to the baseline (criteria in the module docs). Temporal-only and
/// spatial-only reuse are checked apart at K = 1 (single_scattering_matches_the_baseline);
/// here they were left out for CI time (the root suite had grown to 26 minutes on two
/// cores), as any bias of theirs shows in "both".
#[test]
fn multiple_scattering_matches_the_baseline() {
    check_cases(
        Cloud {
            bounces: 3,
            ..Cloud::default()
        },
        &[NO_REUSE, BOTH, VERTEX, LEVERS],
        "K=3",
    );
}

/// An emitting cloud (emission candidates at every vertex), K = 2, temporal and spatial
/// reuse: converges to the baseline (criteria in the module docs).
#[test]
fn emission_matches_the_baseline() {
    check_cases(
        Cloud {
            bounces: 2,
            medium_extra:
                "emission = { procedural = \"cloud\", dims = [12, 8, 12], noise_seed = 5 }\n\
                           emission_scale = [2.0, 1.0, 0.5]",
            ..Cloud::default()
        },
        &[BOTH, FOLDED],
        "emission K=2",
    );
    // Under a sky alone (one-light NEE, the environment drawn at every vertex).
    check_cases(
        Cloud {
            bounces: 2,
            lights: "[[light]]\ntype = \"environment\"\nradiance = [0.25, 0.35, 0.55]\n",
            medium_extra:
                "emission = { procedural = \"cloud\", dims = [12, 8, 12], noise_seed = 5 }\n\
                           emission_scale = [2.0, 1.0, 0.5]",
            ..Cloud::default()
        },
        &[FOLDED],
        "emission under a sky alone K=2",
    );
}

/// A cloud glowing as a blackbody (a temperature cloud, 1200 to 2400 K) beside a scalar
/// emission grid, K = 2: the emission candidates see the sum, and ReSTIR converges to the
/// baseline (crates/nimbus-scene/src/blackbody.rs; criteria in the module docs).
#[test]
fn blackbody_matches_the_baseline() {
    check_cases(
        Cloud {
            bounces: 2,
            medium_extra:
                "emission = { procedural = \"cloud\", dims = [12, 8, 12], noise_seed = 5 }\n\
                 emission_scale = [0.5, 0.5, 1.0]\n\
                 temperature = { procedural = \"cloud\", dims = [16, 10, 16], noise_seed = 8 }\n\
                 temperature_offset = 1200.0\n\
                 temperature_scale = 1200.0\n\
                 blackbody_scale = 1e-3",
            ..Cloud::default()
        },
        &[BOTH],
        "blackbody K=2",
    );
}

/// An rgb albedo grid (each channel its own cloud, 0.25 to 0.95), K = 3: every
/// scattering vertex of ReSTIR's paths (candidates, reuse and final shading) reads the
/// albedo where it is, and ReSTIR converges to the baseline.
#[test]
fn albedo_grid_matches_the_baseline() {
    let dir = crate::common::cli::scratch("restir", "albedo-grid");
    let path = crate::pyro::albedo_vol(&dir, "rgb.vol", [12, 8, 12], &[21, 22, 23]);
    let albedo = format!("{{ file = {:?} }}", path.display().to_string());
    check_cases(
        Cloud {
            bounces: 3,
            albedo: &albedo,
            ..Cloud::default()
        },
        &[BOTH],
        "albedo grid K=3",
    );
}

/// A fog box reaching into the cloud (its own albedo, a backward g, with an emitting
/// cloud) and a second one in vacuum beside it, K = 3: where box and grid overlap a vertex
/// scatters by both media's sigma_s rho and the walk's collision density is the summed
/// majorant; ReSTIR converges to the baseline, which races the media's free flights
/// (tests/suite/overlap.rs checks that against the CPU oracle).
#[test]
fn a_box_overlapping_the_grid_matches_the_baseline() {
    let boxes = "[[medium]]\ntype = \"box\"\ncenter = [0.3, -0.2, 0.5]\nsize = [0.8, 0.6, 0.8]\n\
                 sigma_t = 3.0\nalbedo = [0.8, 0.7, 0.9]\ng = -0.3\n\
                 [[medium]]\ntype = \"box\"\ncenter = [-0.6, -0.3, 1.25]\nsize = [0.6, 0.6, 0.4]\n\
                 sigma_t = 2.0\nalbedo = 0.6\ng = 0.5\n";
    let cloud = Cloud {
        bounces: 3,
        medium_extra: "emission = { procedural = \"cloud\", dims = [12, 8, 12], noise_seed = 5 }\n\
             emission_scale = [0.5, 0.3, 0.2]",
        shapes: boxes,
        ..Cloud::default()
    };
    assert_eq!(cloud.scene("overlap.toml").overlaps, [(0, 1)]);
    check_cases(cloud, &[BOTH], "box overlapping the grid K=3");
}

/// A dodecahedron (convex medium) half inside the cloud and a box beside it, K = 3: a
/// vertex in the polyhedron is found by its planes (box_medium_at), overlapping the grid
/// it scatters by both media, and ReSTIR converges to the baseline
/// (tests/suite/overlap.rs checks the baseline against the CPU oracle).
#[test]
fn a_convex_medium_overlapping_the_grid_matches_the_baseline() {
    let media = crate::overlap::convex_and_box();
    let cloud = Cloud {
        bounces: 3,
        shapes: &media,
        ..Cloud::default()
    };
    assert_eq!(cloud.scene("convex.toml").overlaps, [(0, 1)]);
    check_cases(cloud, &[BOTH], "convex overlapping the grid K=3");
}

/// Two fog boxes overlapping each other and the cloud (each its own albedo and g), K = 3:
/// a vertex where all three meet scatters by all three, its next direction follows one
/// of them in proportion to its sigma_s, and ReSTIR converges to the baseline.
#[test]
fn boxes_overlapping_each_other_and_the_grid_match_the_baseline() {
    let boxes = "[[medium]]\ntype = \"box\"\ncenter = [0.3, -0.2, 0.5]\nsize = [0.8, 0.6, 0.8]\n\
                 sigma_t = 3.0\nalbedo = [0.8, 0.7, 0.9]\ng = -0.3\n\
                 [[medium]]\ntype = \"box\"\ncenter = [0.5, 0.0, 0.3]\nsize = [0.6, 0.6, 0.6]\n\
                 rotation_deg = [0, 35, 10]\nsigma_t = 2.0\nalbedo = [0.5, 0.9, 0.6]\ng = 0.7\n";
    let cloud = Cloud {
        bounces: 3,
        shapes: boxes,
        ..Cloud::default()
    };
    assert_eq!(cloud.scene("boxes.toml").overlaps, [(0, 1), (0, 2), (1, 2)]);
    check_cases(
        cloud,
        &[BOTH],
        "boxes overlapping each other and the grid K=3",
    );
}

/// A floor under the cloud (seen below it and through it) and a box half inside the
/// cloud's grid, its other half in vacuum: surface vertices on the camera segment and
/// after scattering, shadows cast into the medium and onto the floor.
const FLOOR_AND_BOX: &str = r#"
[[shape]]
type = "quad"
corner = [-3.0, -0.65, 3.0]
edge_u = [6.0, 0.0, 0.0]
edge_v = [0.0, 0.0, -6.0]
albedo = [0.7, 0.6, 0.5]
[[shape]]
type = "box"
center = [0.75, -0.3, 0.45]
size = [0.4, 0.5, 0.4]
rotation_deg = [0, 30, 0]
albedo = [0.3, 0.6, 0.8]
"#;

/// A homogeneous box medium between the camera and the cloud (lower left), with its own
/// albedo and a backward g.
const FOG_BOX: &str = r#"
[[medium]]
type = "box"
center = [-0.6, -0.3, 1.25]
size = [0.6, 0.6, 0.4]
sigma_t = 3.0
albedo = [0.8, 0.7, 0.9]
g = -0.3
"#;

/// Emitting shapes: a quad above the cloud shining down (one-sided), and a small
/// octahedron mesh (8 emitting triangles, counter-clockwise from outside) below its front
/// edge, read from `mesh`.
fn emitters(mesh: &std::path::Path) -> String {
    format!(
        r#"
[[shape]]
type = "quad"
corner = [0.2, 0.9, -0.6]
edge_u = [0.8, 0.0, 0.0]
edge_v = [0.0, 0.0, 0.6]
emission = [3.0, 2.5, 2.0]
[[shape]]
type = "mesh"
file = "{}"
to_world = {{ scale = 0.15, translate = [0.5, -0.5, 1.0] }}
emission = [4.0, 1.5, 0.5]
albedo = 0.5
"#,
        mesh.display()
    )
}

/// A regular octahedron about the origin, counter-clockwise seen from outside.
const OCTAHEDRON_OBJ: &str = "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n\
f 1 3 5\nf 1 6 3\nf 1 5 4\nf 1 4 6\nf 2 5 3\nf 2 3 6\nf 2 4 5\nf 2 6 4\n";

/// The scene of the surfaces tests at K = `bounces`: a floor, a box shape half inside the
/// cloud's grid, an emitting quad and an emitting mesh, a fog box in front of the cloud;
/// checked with temporal and spatial reuse against the baseline (criteria in the module
/// docs), which tests/suite/emitters.rs checks against the CPU oracle.
fn check_surfaces_and_emitters(bounces: u32) {
    let dir = scratch("restir", &format!("emitters-k{bounces}"));
    let mesh = dir.join("octahedron.obj");
    std::fs::write(&mesh, OCTAHEDRON_OBJ).unwrap();
    let shapes = format!("{FLOOR_AND_BOX}{}", emitters(&mesh));
    check_cases(
        Cloud {
            bounces,
            shapes: &shapes,
            medium_extra: FOG_BOX,
            ..Cloud::default()
        },
        &[BOTH],
        &format!("surfaces K={bounces}"),
    );
}

/// Surfaces, emitters and a box medium beside the cloud at K = 3: paths with surface and
/// box vertices (up to three of them, so the one- and two-vertex paths of K = 1 and 2 are
/// candidates too) and light from area lights converge to the baseline. When this was
/// written: image means within +0.22 / -0.25 / -0.65 % (z +0.36 / -0.55 / -1.13), 1 of
/// 1296 channels beyond 4.5 SE. Without reuse, surfaces alone agreed too (0.02-0.15 %, 3
/// of 1296 channels), a case left out for CI time.
#[test]
fn surfaces_and_emitters_match_the_baseline() {
    check_surfaces_and_emitters(3);
}

/// The same at K = 1 (the issue's second depth). Ignored in CI for time (about 3 minutes
/// on two cores); run it with `cargo test --test suite -- --ignored surfaces`. When this
/// was written: image means within +0.38 / -0.06 / -0.23 % (z +0.88 / -0.19 / -0.56), 0
/// of 1296 channels beyond 4.5 SE.
#[test]
#[ignore = "about 3 minutes; K = 3 runs in CI"]
fn surfaces_and_emitters_match_the_baseline_at_k1() {
    check_surfaces_and_emitters(1);
}

/// Surfaces in hard places: a camera inside a closed box sees nothing (exactly 0: every
/// light is outside); a black floor; a floor through the camera (rays along it); a box
/// enclosing the whole cloud with the camera outside (exactly 0 too). All finite with no
/// non-finite sample; the open ones are lit.
#[test]
fn surfaces_in_hard_places_stay_finite() {
    let ctx = context();
    let inside = hard(
        &ctx,
        Cloud {
            shapes: "[[shape]]\ntype = \"box\"\ncenter = [0.0, 0.25, 2.3]\nsize = [0.5, 0.5, 0.5]\nalbedo = 0.9",
            ..small()
        },
        "camera-in-box",
    );
    assert!(
        inside.data.iter().all(|p| *p == [0.0; 3]),
        "{:?}",
        inside.mean()
    );
    let enclosed = hard(
        &ctx,
        Cloud {
            shapes: "[[shape]]\ntype = \"box\"\ncenter = [0.0, 0.0, 0.0]\nsize = [2.2, 1.4, 2.2]\nalbedo = 0.0",
            ..small()
        },
        "cloud-in-black-box",
    );
    assert!(
        enclosed.data.iter().all(|p| *p == [0.0; 3]),
        "{:?}",
        enclosed.mean()
    );
    let black = hard(
        &ctx,
        Cloud {
            shapes: "[[shape]]\ntype = \"quad\"\ncorner = [-3, -0.65, 3]\nedge_u = [6, 0, 0]\nedge_v = [0, 0, -6]\nalbedo = 0.0",
            ..small()
        },
        "black-floor",
    );
    assert!(black.mean()[0] > 0.0);
    let grazing = hard(
        &ctx,
        Cloud {
            shapes: "[[shape]]\ntype = \"quad\"\ncorner = [-3, 0.25, 3]\nedge_u = [6, 0, 0]\nedge_v = [0, 0, -6]\nalbedo = 0.8",
            ..small()
        },
        "floor-through-camera",
    );
    assert!(grazing.mean()[0] > 0.0);
    assert_no_validation_errors(&ctx);
}

// ---------------------------------------------------------------------------------------
// Hard cases.

/// The cloud of the hard cases: 12×9 pixels, 4 frames (so that temporal reuse runs),
/// K = 3, default reuse settings.
fn small() -> Cloud<'static> {
    Cloud {
        size: (12, 9),
        frames: 4,
        bounces: 3,
        ..Cloud::default()
    }
}

/// Renders `cloud`, checks that the image is non-negative and returns it.
fn hard(ctx: &Context, cloud: Cloud, label: &str) -> ImageRgb {
    let result = render_checked(ctx, &cloud.scene(&format!("{label}.toml")), None);
    for (i, p) in result.image.data.iter().enumerate() {
        assert!(
            p.iter().all(|v| *v >= 0.0),
            "{label}: pixel {i} is negative: {p:?}"
        );
    }
    println!("{label}: mean {:?}", result.image.mean());
    result.image
}

/// Writes `values` as a raw little-endian float32 grid into a scratch directory and
/// returns its `density = ...` line.
fn raw_grid(name: &str, dims: [u32; 3], values: &[f32]) -> String {
    assert_eq!(values.len(), (dims[0] * dims[1] * dims[2]) as usize);
    let path = scratch("restir", name).join("density.raw");
    std::fs::write(&path, bytemuck::cast_slice::<f32, u8>(values)).expect("write grid");
    format!(
        "density = {{ file = {:?}, dims = [{}, {}, {}] }}",
        path.display().to_string(),
        dims[0],
        dims[1],
        dims[2]
    )
}

/// An all-zero density grid: the camera sees the environment through empty space (the
/// sun lights only the medium), so every pixel is the environment radiance, exactly up
/// to float rounding: the only candidates are the camera rays' direct ones, whose
/// weight w_sum / (p_hat M) is 1 up to the rounding of the sums (allowed: 1e-6
/// relative; the frame mean of dyadic values adds no rounding of its own).
#[test]
fn empty_grid_shows_the_environment_exactly() {
    let ctx = context();
    let density = raw_grid("zero-density", [4, 4, 4], &[0.0; 64]);
    let lights =
        "[[light]]\ntype = \"directional\"\ndirection = [0.5, -0.7, -0.4]\nirradiance = 3.0\n\
                  [[light]]\ntype = \"environment\"\nradiance = [0.25, 0.5, 1.0]";
    for (k, label) in [(1, "empty-k1"), (3, "empty-k3")] {
        let image = hard(
            &ctx,
            Cloud {
                density: &density,
                lights,
                bounces: k,
                ..small()
            },
            label,
        );
        let env = [0.25f32, 0.5, 1.0];
        for (i, p) in image.data.iter().enumerate() {
            assert!(
                (0..3).all(|c| (p[c] - env[c]).abs() <= 1e-6 * env[c]),
                "{label}: pixel {i} is {p:?}, not the environment {env:?}"
            );
        }
    }
    assert_no_validation_errors(&ctx);
}

/// No light at all reaches anything (a black sun and a black point light, no
/// environment, no emission): every reservoir is empty and the image is exactly 0.
#[test]
fn black_lights_render_exactly_zero() {
    let ctx = context();
    let lights =
        "[[light]]\ntype = \"directional\"\ndirection = [0.5, -0.7, -0.4]\nirradiance = 0.0\n\
                  [[light]]\ntype = \"point\"\nposition = [1.4, 0.9, 0.6]\nintensity = 0.0";
    let image = hard(&ctx, Cloud { lights, ..small() }, "black-lights");
    assert!(
        image.data.iter().all(|p| *p == [0.0; 3]),
        "{:?}",
        image.mean()
    );
    assert_no_validation_errors(&ctx);
}

/// Extreme media: density_scale 1e4 (optical depths in the thousands), g = 0.99 and -0.99,
/// each finite and non-negative with no non-finite sample; the dense cloud still lets
/// the sky through around it and the anisotropic clouds are lit.
#[test]
fn extreme_media_stay_finite() {
    let ctx = context();
    let dense = hard(
        &ctx,
        Cloud {
            scale: 1e4,
            ..small()
        },
        "dense",
    );
    assert!(dense.mean()[2] > 0.0);
    for g in [0.99f32, -0.99] {
        let image = hard(&ctx, Cloud { g, ..small() }, &format!("g{g}"));
        assert!(image.mean()[0] > 0.0);
    }
    assert_no_validation_errors(&ctx);
}

/// Odd geometry: a camera inside the medium, a 1×1 image, and a grid of one voxel (a
/// homogeneous box of σt = 4): finite, non-negative, lit.
#[test]
fn odd_geometry_stays_finite() {
    let ctx = context();
    let inside = hard(
        &ctx,
        Cloud {
            position: "[0.05, 0.0, 0.1]",
            ..small()
        },
        "camera-inside",
    );
    assert!(inside.mean()[0] > 0.0);
    let single = hard(
        &ctx,
        Cloud {
            size: (1, 1),
            ..small()
        },
        "one-pixel",
    );
    assert!(single.mean()[0] > 0.0);
    let voxel = raw_grid("one-voxel", [1, 1, 1], &[1.0]);
    let image = hard(
        &ctx,
        Cloud {
            density: &voxel,
            scale: 4.0,
            ..small()
        },
        "one-voxel",
    );
    assert!(image.mean()[0] > 0.0);
    assert_no_validation_errors(&ctx);
}

/// Degenerate reuse settings: spatial radius 0 with 3 neighbours (every neighbour is
/// the pixel itself), and Q = 1 (temporal history clamped to one frame's M): finite,
/// non-negative, lit.
#[test]
fn degenerate_reuse_settings_stay_finite() {
    let ctx = context();
    for (restir, label) in [
        (
            "spatial_radius_px = 0\nspatial_neighbors = 3\nspatial_when = \"always\"\nspatial_rounds = 2",
            "radius-0",
        ),
        ("temporal_limit = 1", "q-1"),
    ] {
        let image = hard(&ctx, Cloud { restir, ..small() }, label);
        assert!(image.mean()[0] > 0.0);
    }
    assert_no_validation_errors(&ctx);
}

// ---------------------------------------------------------------------------------------
// The plan.

/// Writes `cloud`'s scene text into a scratch directory and returns its path.
fn scene_file(name: &str, cloud: &Cloud) -> std::path::PathBuf {
    let path = scratch("restir", name).join("scene.toml");
    std::fs::write(&path, cloud.text()).expect("write scene");
    path
}

/// `nimbus render --explain FILE ARGS`: stdout, after checking that it succeeded.
fn explain(path: &std::path::Path, args: &[&str]) -> String {
    let mut all = vec!["render", "--explain", path.to_str().unwrap()];
    all.extend_from_slice(args);
    let out = nimbus(&all);
    assert!(out.status.success(), "{}", text(&out.stderr));
    text(&out.stdout)
}

/// `--explain` lists the four ReSTIR passes; temporal reuse is off with `temporal =
/// false` and with a single frame; SC_HAS_EMISSION follows the medium.
#[test]
fn explain_lists_the_restir_passes() {
    // The defaults: no spatial reuse, split NEE under a sun and a sky.
    let defaults = scene_file("explain-default", &Cloud::default());
    let out = explain(&defaults, &[]);
    for line in [
        "[on ] pass restir initial",
        "[on ] pass restir temporal",
        "[off] pass restir spatial",
        "[on ] pass restir shade",
        "[off]   SC_HAS_EMISSION",
        "[on ]   SC_NEE_SPLIT",
        "[off] pass baseline path tracer",
    ] {
        assert!(out.contains(line), "missing {line:?} in:\n{out}");
    }

    let spatial = scene_file(
        "explain-spatial",
        &Cloud {
            restir: "spatial_neighbors = 3\nspatial_when = \"always\"\nnee = \"one\"",
            ..Cloud::default()
        },
    );
    let out = explain(&spatial, &[]);
    assert!(out.contains("[on ] pass restir spatial"), "{out}");
    assert!(out.contains("[off]   SC_NEE_SPLIT"), "{out}");
    let one_frame = explain(&spatial, &["--frames", "1"]);
    assert!(
        one_frame.contains("[off] pass restir temporal"),
        "{one_frame}"
    );
    assert!(
        one_frame.contains("[on ] pass restir spatial"),
        "{one_frame}"
    );

    let no_temporal = scene_file(
        "explain-no-temporal",
        &Cloud {
            restir: "temporal = false",
            ..Cloud::default()
        },
    );
    let out = explain(&no_temporal, &[]);
    assert!(out.contains("[off] pass restir temporal"), "{out}");
    assert!(out.contains("[on ] pass restir initial"), "{out}");
    assert!(out.contains("[on ] pass restir shade"), "{out}");

    let emitting = scene_file(
        "explain-emission",
        &Cloud {
            medium_extra: "emission = { procedural = \"cloud\", dims = [4, 4, 4], noise_seed = 5 }",
            ..Cloud::default()
        },
    );
    let out = explain(&emitting, &[]);
    assert!(out.contains("[on ]   SC_HAS_EMISSION"), "{out}");
}

/// The plan error for `cloud` (named `name`).
fn plan_error(cloud: &Cloud, name: &str) -> String {
    match nimbus::plan::build(&cloud.scene(name), None) {
        Ok(_) => panic!("{name}: the plan was accepted"),
        Err(e) => e.to_string(),
    }
}

/// Scenes ReSTIR cannot render are errors naming the file, the table and the field:
/// vertex reuse with a shape (a surface x2 has no volume-measure geometry term), K above
/// 16 (plan errors), more than 16 spatial neighbours (a scene error). The limits
/// themselves (16) are accepted, and so are shapes with direction reuse.
#[test]
fn unsupported_scenes_are_plan_errors() {
    let sphere = "[[shape]]\ntype = \"sphere\"\ncenter = [0.0, -2.0, 0.0]\nradius = 0.5";
    let with_shape = Cloud {
        shapes: sphere,
        restir: "reuse = \"vertex\"",
        ..Cloud::default()
    };
    let e = plan_error(&with_shape, "restir-shape.toml");
    for needle in [
        "restir-shape.toml",
        "[integrator.restir] field `reuse`",
        "[[shape]] #1",
        "reuse = \"direction\"",
    ] {
        assert!(e.contains(needle), "{needle:?} missing from: {e}");
    }
    let direction = Cloud {
        shapes: sphere,
        ..Cloud::default()
    };
    nimbus::plan::build(&direction.scene("restir-shape-direction.toml"), None)
        .expect("shapes with direction reuse");

    // Split NEE needs the environment alone besides the delta lights.
    let sphere_light = Cloud {
        lights:
            "[[light]]\ntype = \"sphere\"\ncenter = [0.0, 2.0, 0.0]\nradius = 0.2\nradiance = 5.0\n\
                 [[light]]\ntype = \"environment\"\nradiance = 0.2",
        restir: "nee = \"split\"",
        ..Cloud::default()
    };
    let e = plan_error(&sphere_light, "restir-split.toml");
    assert!(
        e.contains("restir-split.toml") && e.contains("field `nee`") && e.contains("nee = \"one\""),
        "{e}"
    );

    let e = plan_error(
        &Cloud {
            bounces: 17,
            ..Cloud::default()
        },
        "restir-k17.toml",
    );
    assert!(
        e.contains("restir-k17.toml") && e.contains("[integrator]") && e.contains("`max_bounces`"),
        "{e}"
    );

    // More than 16 spatial neighbours is refused by the scene loader itself, so the
    // loader's documented range and what the plan accepts are one.
    let text = Cloud {
        restir: "spatial_neighbors = 17",
        ..Cloud::default()
    }
    .text();
    let e = nimbus_scene::parse_str(&text, std::path::Path::new("restir-n17.toml"))
        .expect_err("17 neighbours are refused")
        .to_string();
    assert!(
        e.contains("restir-n17.toml")
            && e.contains("[integrator.restir]")
            && e.contains("`spatial_neighbors`"),
        "{e}"
    );

    let at_limits = Cloud {
        bounces: 16,
        restir: "spatial_neighbors = 16\nspatial_when = \"always\"",
        ..Cloud::default()
    };
    let plan = nimbus::plan::build(&at_limits.scene("restir-limits.toml"), None).expect("plan");
    let restir = plan.restir().cloned().expect("a ReSTIR plan");
    assert_eq!((restir.max_bounces, restir.spatial_neighbors), (16, 16));
}

/// M = 4096 candidates render the same image as M = 4 within noise: RIS stays unbiased
/// at the top of the range, and on lavapipe, whose invocations stop their loops after
/// 65535 iterations, the candidates are drawn over several dispatches (M = 4096 used to
/// draw about a third of them and render the cloud at a third of its brightness).
#[test]
fn candidates_at_the_limit_match_a_few() {
    let ctx = context();
    let at = |candidates: u32, frames: u32| {
        let restir = format!("candidates = {candidates}\ntemporal = false\nspatial_neighbors = 0");
        let cloud = Cloud {
            size: (10, 8),
            frames,
            restir: &restir,
            ..Cloud::default()
        };
        render_checked(
            &ctx,
            &cloud.scene(&format!("restir-m{candidates}.toml")),
            None,
        )
    };
    let many = at(4096, 3);
    let few = at(4, 96);
    let se = (crate::common::gpu::se_of_mean(&many.std_error).powi(2)
        + crate::common::gpu::se_of_mean(&few.std_error).powi(2))
    .sqrt();
    let (a, b) = (many.image.mean()[1], few.image.mean()[1]);
    assert!(
        (a - b).abs() <= 4.5 * se + 0.01 * b,
        "M = 4096: {a}, M = 4: {b} (combined SE {se})"
    );
}
