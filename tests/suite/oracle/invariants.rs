//! Physical invariants that hold for every integrator (issue 24): the same scene rendered
//! by the crepuscular pass (a box medium), the baseline path tracer and Volumetric ReSTIR
//! (a grid) must
//! - scale exactly with the light: every light times k gives the image times k (the
//!   random decisions are the same, so pixel by pixel up to float rounding);
//! - treat a medium of zero density as absent: the background, exactly;
//! - never brighten with albedo 0: no pixel above what the background alone gives;
//! - be scale-invariant: the scene k times larger with sigma_t / k renders the same image
//!   (k = 8: exact in floats, identical images on lavapipe).

use nimbus::output::ImageRgb;
use nimbus_scene::Scene;

use crate::common::gpu::{context, render_checked, scene};

/// The integrators, as (name, [integrator] table, medium table given the medium's
/// extinction scale `sigma`, its albedo and its half size `h`).
fn media(sigma: f32, albedo: f32, h: f32) -> Vec<(&'static str, String)> {
    let grid_file = grid_file();
    let grid = |volume: &str| {
        format!(
            "[[medium]]\ntype = \"grid\"\nbounds_min = [-{h}, -{h}, -{h}]\nbounds_max = [{h}, {h}, {h}]\n\
             density = {{ file = {grid_file:?}, dims = [4, 4, 4] }}\ndensity_scale = {sigma}\n\
             albedo = {albedo}\ng = 0.3\n[integrator]\nvolume = \"{volume}\"\nmax_bounces = 2\n"
        )
    };
    vec![
        (
            "crepuscular",
            format!(
                "[[medium]]\ntype = \"box\"\ncenter = [0, 0, 0]\nsize = [{s}, {s}, {s}]\n\
                 sigma_t = {sigma}\nalbedo = {albedo}\ng = 0.3\n",
                s = 2.0 * h
            ),
        ),
        ("baseline", grid("baseline")),
        ("restir", grid("restir")),
    ]
}

/// A 4³ raw grid of densities in [0.25, 1] (written once per test process).
fn grid_file() -> String {
    let path = crate::common::cli::scratch("invariants", "grid").join("grid.raw");
    if !path.exists() {
        let values: Vec<f32> = (0..64)
            .map(|i| 0.25 + 0.75 * ((i * 37 % 64) as f32 / 63.0))
            .collect();
        // Tests run in parallel: each writes its own temporary file, renamed atomically.
        let tmp = path.with_extension(format!("{:?}.tmp", std::thread::current().id()));
        std::fs::write(&tmp, bytemuck::cast_slice::<f32, u8>(&values)).expect("write grid");
        std::fs::rename(&tmp, &path).expect("rename grid");
    }
    path.display().to_string()
}

/// A scene of `medium` at scale `k` (camera and sizes times k) under a sun of irradiance
/// `sun` and a sky of radiance `sky`.
fn scene_text(medium: &str, k: f32, sun: f32, sky: f32) -> String {
    format!(
        "[render]\nwidth = 16\nheight = 12\nframes = 4\nseed = 3\n\
         [camera]\nposition = [0, {y}, {z}]\nlook_at = [0, 0, 0]\nhorizontal_fov_deg = 40\n\
         [[light]]\ntype = \"directional\"\ndirection = [0.3, -1.0, -0.2]\nirradiance = {sun}\n\
         [[light]]\ntype = \"environment\"\nradiance = {sky}\n{medium}",
        y = 0.5 * k,
        z = 4.0 * k
    )
}

fn render(s: &Scene) -> ImageRgb {
    let ctx = context();
    render_checked(&ctx, s, None).image
}

fn mean(img: &ImageRgb) -> f64 {
    img.data
        .iter()
        .map(|p| f64::from(p[0] + p[1] + p[2]))
        .sum::<f64>()
        / (3 * img.data.len()) as f64
}

#[test]
fn light_scaling_scales_every_integrators_image() {
    for (name, medium) in media(3.0, 0.8, 0.5) {
        let one = render(&scene(&scene_text(&medium, 1.0, 2.0, 0.25), "one.toml"));
        let four = render(&scene(&scene_text(&medium, 1.0, 8.0, 1.0), "four.toml"));
        for (i, (a, b)) in one.data.iter().zip(&four.data).enumerate() {
            for c in 0..3 {
                let (x, y) = (4.0 * f64::from(a[c]), f64::from(b[c]));
                assert!(
                    (x - y).abs() <= 1e-4 * x.abs().max(y.abs()) + 1e-7,
                    "{name}: pixel {i} channel {c}: 4 x {} vs {}",
                    a[c],
                    b[c]
                );
            }
        }
    }
}

#[test]
fn zero_density_is_no_medium_and_albedo_zero_never_brightens() {
    let sky = 0.25f32;
    for (name, medium) in media(0.0, 0.8, 0.5) {
        let img = render(&scene(&scene_text(&medium, 1.0, 2.0, sky), "zero.toml"));
        for (i, p) in img.data.iter().enumerate() {
            assert!(
                p.iter().all(|v| (v - sky).abs() <= 1e-6),
                "{name}: pixel {i} of an empty medium is {p:?}, not the sky {sky}"
            );
        }
    }
    // The crepuscular pass and the baseline estimate the transmittance with bounded
    // estimators (closed forms, ratio tracking): every pixel. ReSTIR's resampled estimate
    // of the sky behind the medium is unbiased but not bounded (f / p^ = T / T* > 1 where
    // the conservative grid over-attenuates), so its image mean.
    for (name, medium) in media(3.0, 0.0, 0.5) {
        let img = render(&scene(&scene_text(&medium, 1.0, 2.0, sky), "black.toml"));
        if name == "restir" {
            let m = mean(&img);
            assert!(
                m < f64::from(sky),
                "{name}: the mean {m} behind a black medium is above the sky"
            );
            continue;
        }
        for (i, p) in img.data.iter().enumerate() {
            assert!(
                p.iter().all(|v| *v <= sky * (1.0 + 1e-5)),
                "{name}: pixel {i} behind a black medium is {p:?}, above the sky {sky}"
            );
        }
    }
}

#[test]
fn a_scene_k_times_larger_with_sigma_over_k_renders_the_same() {
    for (name, medium) in media(3.0, 0.8, 0.5) {
        let small = render(&scene(&scene_text(&medium, 1.0, 2.0, 0.25), "small.toml"));
        let (_, large_medium) = media(3.0 / 8.0, 0.8, 4.0)
            .into_iter()
            .find(|(n, _)| *n == name)
            .expect("the same integrator");
        let large = render(&scene(
            &scene_text(&large_medium, 8.0, 2.0, 0.25),
            "large.toml",
        ));
        // A power-of-two scale keeps the floats exact, so on lavapipe the walks match and
        // the images are identical; a device with approximate sqrt or exp may diverge, so
        // the check is the mean.
        let (a, b) = (mean(&small), mean(&large));
        println!("{name}: mean {a} at size 1, {b} at size 8");
        assert!(
            (a / b - 1.0).abs() < 0.01,
            "{name}: the image mean {a} at size 1 vs {b} at size 8 with sigma / 8"
        );
    }
}
