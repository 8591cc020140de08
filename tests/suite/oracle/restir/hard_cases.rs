//! Hard cases: empty and extremely dense grids, g = ±0.99, a camera inside the medium,
//! black lights, a 1×1 image, a 1-voxel grid, degenerate reuse settings, the optical-depth
//! shifts in those media and M at its limit render finite, non-negative images with no non-finite sample.

use super::*;

/// The cloud of the hard cases: 12×9 pixels, 4 frames (so that temporal reuse runs),
/// K = 3, default reuse settings.
pub(super) fn small() -> Cloud<'static> {
    Cloud {
        size: (12, 9),
        frames: 4,
        bounces: 3,
        ..Cloud::default()
    }
}

/// Renders `cloud`, checks that the image is non-negative and returns it.
pub(super) fn hard(ctx: &Context, cloud: Cloud, label: &str) -> ImageRgb {
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

/// The optical-depth shifts in hard media: spatial reuse on every frame by the exact shift
/// and by the one through the conservative grid, temporal reuse by the exact shift under a
/// camera that moves every frame (so it acts on every frame after the first), in a cloud of
/// density_scale 1e4 (optical depths in the thousands: tau_1 beyond what most neighbour
/// rays reach), at g = 0.99, with the camera inside the medium, and in a one-voxel grid
/// (sigma_t constant, so the Jacobian is 1 wherever x_1 lands): finite, non-negative, lit.
#[test]
fn optical_depth_shifts_stay_finite_in_hard_media() {
    let ctx = context();
    let voxel = raw_grid("one-voxel-shift", [1, 1, 1], &[1.0]);
    // Keyframes after [camera]'s own fields (the `lights` text follows them): the eye
    // moves 0.06 m a frame from `position`'s neighbourhood.
    let moving = |from: &str, to: &str| {
        format!(
            "[[camera.keyframe]]\nframe = 0\nposition = {from}\nlook_at = [0.0, 0.0, 0.0]\n\
             [[camera.keyframe]]\nframe = 3\nposition = {to}\nlook_at = [0.0, 0.0, 0.0]\n{SUN_AND_SKY}"
        )
    };
    let outside = moving("[0.0, 0.25, 2.3]", "[0.18, 0.25, 2.2]");
    let inside = moving("[0.05, 0.0, 0.1]", "[0.2, 0.05, 0.15]");
    for shift in ["optical_depth_exact", "optical_depth"] {
        let restir = format!(
            "spatial_when = \"always\"\nspatial_rounds = 1\nspatial_neighbors = 3\n\
             spatial_shift = \"{shift}\"\ntemporal_shift = \"optical_depth\""
        );
        let cases: [(Cloud, &str); 4] = [
            (
                Cloud {
                    scale: 1e4,
                    lights: &outside,
                    ..small()
                },
                "dense",
            ),
            (
                Cloud {
                    g: 0.99,
                    lights: &outside,
                    ..small()
                },
                "g0.99",
            ),
            (
                Cloud {
                    position: "[0.05, 0.0, 0.1]",
                    lights: &inside,
                    ..small()
                },
                "camera-inside",
            ),
            (
                Cloud {
                    density: &voxel,
                    scale: 4.0,
                    lights: &outside,
                    ..small()
                },
                "one-voxel",
            ),
        ];
        for (cloud, label) in cases {
            let image = hard(
                &ctx,
                Cloud {
                    restir: &restir,
                    ..cloud
                },
                &format!("{label}-{shift}"),
            );
            assert!(image.mean()[2] > 0.0, "{label}-{shift}: black");
        }
    }
    assert_no_validation_errors(&ctx);
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
