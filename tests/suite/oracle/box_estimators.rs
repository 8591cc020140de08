//! The five estimators of the box-medium paper (MCWVDS, REDS, REES, RM, MCDS) on
//! lavapipe: exactness where nothing occludes, agreement with each other and with the
//! references, multiple scattering against the CPU Monte Carlo reference, and golden
//! images at low sample counts. Validation layers are on.

use crate::common::gpu::{
    assert_means_agree, channels_beyond, context, render_checked, scene, se_of_mean,
};
use crate::common::{compare_with_golden, SAME_DEVICE};
use nimbus::output::ImageRgb;
use nimbus::DEFAULT_SCENE;
use nimbus_reference::quadrature::{self, ReferenceOptions};
use nimbus_scene::{BoxEstimator, Scene};

/// Relative difference of two image means, per channel, largest of the three.
fn mean_rel_diff(a: &ImageRgb, b: &ImageRgb) -> f64 {
    let (ma, mb) = (a.mean(), b.mean());
    (0..3)
        .map(|c| (ma[c] - mb[c]).abs() / mb[c].abs().max(1e-30))
        .fold(0.0, f64::max)
}

/// A rotated box, one light, optionally a gobo, rays through pixel centres.
fn unoccluded_scene(gobo: bool) -> Scene {
    let gobo = if gobo {
        "gobo = [[-0.7, -0.6], [0.8, -0.4], [0.5, 0.8], [-0.6, 0.6]]\ngobo_origin = [0.1, 2.0, 0.0]"
    } else {
        ""
    };
    scene(
        &format!(
            r#"
[render]
width = 20
height = 16
pixel_jitter = false
[camera]
position = [0.5, 0.9, 3.5]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 50
[[light]]
type = "directional"
direction = [0.3, -1.0, -0.4]
irradiance = [2.0, 1.5, 1.0]
{gobo}
[[medium]]
type = "box"
center = [0.0, 0.0, 0.0]
size = [2.0, 1.0, 1.5]
rotation_deg = [5.0, 35.0, -10.0]
sigma_t = 2.0
albedo = 0.8
g = 0.5
[integrator]
box_estimator = "mcwvds"
box_samples = 1
"#
        ),
        "unoccluded.toml",
    )
}

/// With nothing in the way, one MCWVDS sample per ray is the analytic integral: each
/// pixel-centre ray matches the f64 quadrature to float precision (1e-4 relative),
/// with and without a gobo clamping the integration.
#[test]
fn unoccluded_pixels_are_exact_with_one_mcwvds_sample() {
    let ctx = context();
    for gobo in [false, true] {
        let scene = unoccluded_scene(gobo);
        let gpu = render_checked(&ctx, &scene, Some(1));
        let reference = quadrature::render(
            &scene,
            &ReferenceOptions {
                rel_tol: 1e-9,
                footprint_samples: 1,
            },
        )
        .expect("reference");
        let mut lit = 0;
        for (g, r) in gpu.image.data.iter().zip(&reference) {
            for c in 0..3 {
                let (g, r) = (f64::from(g[c]), r[c]);
                if r > 1e-6 {
                    lit += 1;
                }
                assert!(
                    (g - r).abs() <= 1e-4 * r + 1e-9,
                    "gobo {gobo}: gpu {g} vs reference {r}"
                );
            }
        }
        assert!(lit > 100, "the box covers the image (gobo {gobo}): {lit}");
        // A single frame with a single sample has no spread to speak of.
        assert_eq!(gpu.frames, 1);
    }
}

/// The window scene (occluded shafts, several surfaces) at high sample count: every
/// estimator's image mean is within 1% of ray marching's, and within five standard
/// errors of it where the errors allow.
#[test]
fn all_estimators_agree_on_the_window_scene() {
    let ctx = context();
    let mut scene = scene(DEFAULT_SCENE, "window.toml");
    scene.render.width = 48;
    scene.render.height = 36;
    scene.render.frames = 24;
    scene.render.spp = 4;
    scene.integrator.box_estimator = BoxEstimator::Rm;
    let rm = render_checked(&ctx, &scene, Some(32));
    for estimator in BoxEstimator::EXACT {
        scene.integrator.box_estimator = estimator;
        scene.render.seed = 1000 + estimator as u64;
        let img = render_checked(&ctx, &scene, Some(32));
        let diff = mean_rel_diff(&img.image, &rm.image);
        println!(
            "{}: mean {:?}, relative difference to RM {diff:.5} (SE {:.2e} / {:.2e})",
            estimator.name(),
            img.image.mean(),
            se_of_mean(&img.std_error),
            se_of_mean(&rm.std_error)
        );
        assert!(diff < 0.01, "{}: {diff}", estimator.name());
    }
}

/// Golden images of each estimator at a low sample count (1 spp, 4 samples along each
/// segment), where their noise differs the most (limits: `SAME_DEVICE`; a changed
/// sample sequence moves the mean FLIP by > 0.05 at this noise level).
#[test]
fn golden_estimators_at_low_sample_count() {
    let ctx = context();
    let mut scene = scene(DEFAULT_SCENE, "window.toml");
    scene.render.width = 80;
    scene.render.height = 60;
    scene.render.frames = 1;
    scene.render.spp = 1;
    for estimator in BoxEstimator::EXACT {
        scene.integrator.box_estimator = estimator;
        let result = render_checked(&ctx, &scene, Some(4));
        compare_with_golden(
            &format!("window-{}-1spp", estimator.name()),
            &result.image,
            SAME_DEVICE,
        )
        .unwrap();
    }
}

/// Multiple scattering (K = 1, 2, 4, 8) in a rotated box above a Lambertian floor, with
/// a gobo: every estimator's path tracer agrees with the independent CPU Monte Carlo
/// reference (`nimbus_reference::mc`, analog tracking with next-event estimation) on the
/// image mean within 4 combined standard errors plus 1%, and the per-pixel differences
/// are consistent with their standard errors.
#[test]
fn multiple_scattering_matches_the_cpu_monte_carlo_reference() {
    use nimbus_reference::mc::{render_mc, McOptions};
    let ctx = context();
    let mut scene = scene(
        r#"
[render]
width = 12
height = 12
frames = 32
spp = 4
seed = 5
[camera]
position = [0.3, 0.6, 3.2]
look_at = [0.0, -0.1, 0.0]
horizontal_fov_deg = 55
[[light]]
type = "directional"
direction = [0.4, -1.0, -0.2]
irradiance = [3.0, 2.5, 2.0]
gobo = [[-0.9, -0.9], [0.9, -0.9], [0.9, 0.9], [-0.9, 0.9]]
[[medium]]
type = "box"
center = [0.0, 0.0, 0.0]
size = [1.6, 1.0, 1.2]
rotation_deg = [0.0, 25.0, 0.0]
sigma_t = 2.0
albedo = [0.95, 0.9, 0.8]
g = 0.3
[[shape]]
type = "quad"
corner = [-2.0, -0.5, -2.0]
edge_u = [4.0, 0.0, 0.0]
edge_v = [0.0, 0.0, 4.0]
albedo = 0.6
"#,
        "multiple.toml",
    );
    let mut previous_mean = 0.0;
    for k in [1u32, 2, 4, 8] {
        scene.integrator.max_bounces = k;
        let (cpu_mean, cpu_se) = render_mc(
            &scene,
            &McOptions {
                max_bounces: k,
                paths: 2048,
                seed: 99,
            },
            4,
        )
        .expect("cpu reference");
        let cpu = ImageRgb::from_rgb_f64(12, 12, &cpu_mean).unwrap();
        let cpu_se = ImageRgb::from_rgb_f64(12, 12, &cpu_se).unwrap();
        for estimator in [BoxEstimator::Mcwvds, BoxEstimator::Rm, BoxEstimator::Reds] {
            scene.integrator.box_estimator = estimator;
            let gpu = render_checked(&ctx, &scene, Some(8));
            let what = format!("K={k} {}: gpu vs cpu", estimator.name());
            let (gpu, cpu) = ((&gpu.image, &gpu.std_error), (&cpu, &cpu_se));
            assert_means_agree(&what, gpu, cpu, 4.0, 0.01);
            // Per pixel: at most 2% of channels beyond 4.5 combined standard errors.
            let beyond = channels_beyond(gpu, cpu, 4.5);
            assert!(
                beyond * 50 <= 3 * 144,
                "K={k} {}: {beyond} channels beyond 4.5 SE",
                estimator.name()
            );
        }
        // More scattering orders add light.
        let mean = cpu.mean()[0];
        assert!(mean > previous_mean, "K={k}: {mean} <= {previous_mean}");
        previous_mean = mean;
    }
}
