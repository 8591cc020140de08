//! Accepted extremes render right (issue 24), one per class the hostile suites accept
//! (`crates/nimbus-scene/tests/suite/hostile/mod.rs`, `cli_hostile.rs`) that `hard_cases.rs`
//! does not already render: a scene at the largest and at a tiny scale, a field of view
//! of a thousandth of a degree and of nearly 180°, a single pixel and a 4096-pixel row,
//! rotations of 10³⁰ degrees, directions with components near the f32 limit, irradiance
//! of 10¹² and of 10⁻³⁰, and albedo 0 and 1 in one colour. Each image is tiny and checked
//! against something exact: the f64 quadrature oracle (the box medium's single
//! scattering is exact with one MCWVDS sample on pixel-centre rays), or the same scene
//! rendered with an ordinary value (linearity, identity).

use std::path::Path;

use nimbus::output::ImageRgb;
use nimbus::plan;
use nimbus::renderer::{render, RenderOptions};
use nimbus_gpu::Context;
use nimbus_scene::Scene;

use crate::common::gpu::{assert_no_validation_errors, context};

const FILE: &str = "extremes/scene.toml";

/// A box medium of half size `h` at the origin under a sun, seen from 3h; `edit`
/// replaces lines of it (`(from, to)`).
fn scene_text(h: f64, sigma_t: f64, edits: &[(&str, &str)]) -> String {
    let mut text = format!(
        "[render]\nwidth = 12\nheight = 12\npixel_jitter = false\n\
         [camera]\nposition = [{}, {}, {}]\nlook_at = [0, 0, 0]\nhorizontal_fov_deg = 50\n\
         [[light]]\ntype = \"directional\"\ndirection = [0.5, -1.0, -0.3]\nirradiance = 5.0\n\
         [[medium]]\ntype = \"box\"\ncenter = [0, 0, 0]\nsize = [{s}, {s}, {s}]\n\
         rotation_deg = [0, 0, 0]\nsigma_t = {sigma_t:e}\nalbedo = 0.8\ng = 0.3\n",
        0.3 * h,
        0.8 * h,
        3.0 * h,
        s = 2.0 * h
    );
    for (from, to) in edits {
        assert!(text.contains(from), "{from:?} not in the scene");
        text = text.replace(from, to);
    }
    text
}

fn parse(text: &str) -> Scene {
    nimbus_scene::parse_str(text, Path::new(FILE))
        .unwrap_or_else(|e| panic!("the scene should be accepted: {e:#}\n{text}"))
}

/// Renders `scene`: finite, no dropped sample, no validation error.
fn gpu(ctx: &Context, scene: &Scene) -> ImageRgb {
    let plan = plan::build(scene, None).unwrap();
    let result = render(ctx, scene, &plan, &RenderOptions::default()).unwrap();
    assert_no_validation_errors(ctx);
    assert_eq!(result.non_finite_samples, 0, "non-finite samples");
    assert!(result.image.first_non_finite().is_none());
    result.image
}

/// Every pixel within `rel` of the f64 oracle's (relative to the image's largest), and
/// the image not black.
fn assert_matches_oracle(what: &str, ctx: &Context, scene: &Scene, rel: f64) {
    let image = gpu(ctx, scene);
    let oracle = nimbus_reference::quadrature::render(
        scene,
        &nimbus_reference::quadrature::ReferenceOptions {
            rel_tol: 1e-5,
            footprint_samples: 1,
        },
    )
    .unwrap();
    let peak = oracle
        .iter()
        .map(|p| p[0].max(p[1]).max(p[2]))
        .fold(0.0, f64::max);
    assert!(peak > 0.0, "{what}: the oracle's image is black");
    for (i, (got, want)) in image.data.iter().zip(&oracle).enumerate() {
        for c in 0..3 {
            let (g, w) = (f64::from(got[c]), want[c]);
            assert!(
                (g - w).abs() <= rel * peak,
                "{what}: pixel {i} channel {c}: {g} vs the oracle's {w} (peak {peak})"
            );
        }
    }
}

/// `a` is `k` times `b` in every pixel, within `rel` of the larger.
fn assert_scaled(what: &str, a: &ImageRgb, b: &ImageRgb, k: f64, rel: f64) {
    let peak = b
        .data
        .iter()
        .map(|p| f64::from(p[0].max(p[1]).max(p[2])))
        .fold(0.0, f64::max);
    assert!(peak > 0.0, "{what}: black image");
    for (i, (x, y)) in a.data.iter().zip(&b.data).enumerate() {
        for c in 0..3 {
            let (x, y) = (f64::from(x[c]), k * f64::from(y[c]));
            assert!(
                (x - y).abs() <= rel * k * peak,
                "{what}: pixel {i} channel {c}: {x} vs {y}"
            );
        }
    }
}

/// Sizes at both ends of what the format takes: the scene at 10⁶ m (size 2·10⁶ m, near
/// the 10⁷ m limit) and at a millimetre, with the optical depth of the unit scene; and
/// rotations of 10³⁰ degrees, which render as the same angle modulo one turn. Each
/// matches the f64 oracle.
#[test]
fn extreme_sizes_and_rotations_match_the_oracle() {
    let ctx = context();
    for (h, sigma) in [(1e6, 1e-6), (1e-3, 1e3), (1.0, 1.0)] {
        let scene = parse(&scene_text(h, sigma, &[]));
        assert_matches_oracle(&format!("half size {h:e} m"), &ctx, &scene, 0.01);
    }
    let huge = "rotation_deg = [1e30, -7e29, 3.3e38]";
    let scene = parse(&scene_text(1.0, 1.0, &[("rotation_deg = [0, 0, 0]", huge)]));
    match &scene.media[0] {
        nimbus_scene::Medium::Box(b) => {
            assert!(b.rotation_deg.abs().max_element() <= 360.0, "{b:?}")
        }
        other => panic!("{other:?}"),
    }
    assert_matches_oracle(huge, &ctx, &scene, 0.01);
}

/// A field of view of 10⁻³ degrees (every pixel sees the centre ray's radiance: the
/// image is uniform and equal to the oracle's) and of 179.9°, a single-pixel image and a
/// 4096 x 1 row: all match the oracle.
#[test]
fn extreme_fields_of_view_and_image_shapes_match_the_oracle() {
    let ctx = context();
    let cases = [
        ("horizontal_fov_deg = 50", "horizontal_fov_deg = 1e-3"),
        // An odd size: at 179.9° only the centre pixel's ray meets the box.
        (
            "width = 12\nheight = 12\npixel_jitter = false\n[camera]\nposition = [0.3, 0.8, 3]\nlook_at = [0, 0, 0]\nhorizontal_fov_deg = 50",
            "width = 13\nheight = 13\npixel_jitter = false\n[camera]\nposition = [0.3, 0.8, 3]\nlook_at = [0, 0, 0]\nhorizontal_fov_deg = 179.9",
        ),
        ("width = 12\nheight = 12", "width = 1\nheight = 1"),
        ("width = 12\nheight = 12", "width = 4096\nheight = 1"),
    ];
    for (from, to) in cases {
        let scene = parse(&scene_text(1.0, 1.0, &[(from, to)]));
        assert_matches_oracle(to, &ctx, &scene, 0.01);
        if to.contains("1e-3") {
            let image = gpu(&ctx, &scene);
            let first = image.data[0];
            for p in &image.data {
                for c in 0..3 {
                    assert!((p[c] - first[c]).abs() <= 1e-4 * first[c].abs().max(1e-6));
                }
            }
        }
    }
}

/// A direction whose components are near the f32 limit renders exactly as its
/// normalized twin; irradiance 10¹² and 10⁻³⁰ scale the image of irradiance 1 by
/// exactly that (the estimator's random decisions do not depend on the light's scale).
#[test]
fn extreme_light_values_render_as_their_ordinary_twins_scaled() {
    let ctx = context();
    let one = parse(&scene_text(
        1.0,
        1.0,
        &[("irradiance = 5.0", "irradiance = 1")],
    ));
    let base = gpu(&ctx, &one);
    for k in [1e12, 1e-30] {
        let text = scene_text(
            1.0,
            1.0,
            &[("irradiance = 5.0", &format!("irradiance = {k:e}"))],
        );
        let image = gpu(&ctx, &parse(&text));
        assert_scaled(&format!("irradiance {k:e}"), &image, &base, k, 1e-5);
    }
    let huge = "direction = [1.7e38, -3.4e38, -1.02e38]";
    let text = scene_text(
        1.0,
        1.0,
        &[
            ("irradiance = 5.0", "irradiance = 1"),
            ("direction = [0.5, -1.0, -0.3]", huge),
        ],
    );
    let image = gpu(&ctx, &parse(&text));
    assert_scaled(huge, &image, &base, 1.0, 1e-5);
}

/// Albedo 0, 0.5 and 1 in one colour: single scattering is linear in the albedo, so the
/// red channel is exactly black and blue is twice green in every pixel.
#[test]
fn albedo_zero_and_one_in_one_colour_scale_the_channels() {
    let ctx = context();
    let text = scene_text(1.0, 1.0, &[("albedo = 0.8", "albedo = [0, 0.5, 1]")]);
    let image = gpu(&ctx, &parse(&text));
    let peak = image.data.iter().map(|p| p[2]).fold(0.0, f32::max);
    assert!(peak > 0.0);
    for p in &image.data {
        assert_eq!(p[0], 0.0, "albedo 0 scatters nothing: {p:?}");
        assert!((p[2] - 2.0 * p[1]).abs() <= 1e-5 * peak, "{p:?}");
    }
}
