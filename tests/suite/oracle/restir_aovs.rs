//! ReSTIR's AOVs (`[integrator] volume = "restir"`, docs/restir.md "AOVs"):
//!
//! - the geometric AOVs (Z, N, albedo, motion) of a quad, a dense box medium and the
//!   grid cloud: the known values within 1 %, the same as the baseline's (one tracing
//!   function, deterministic), and the motion of a dollying camera and of a cloud moved
//!   by its velocity field against the analytic reprojection;
//! - the path AOVs: emission + direct + indirect and the light groups sum to the RGB per
//!   pixel (to rounding) with split NEE, with one-light NEE and emission candidates,
//!   with folded emission, and with a sphere light and emitting shapes; the RGB is the
//!   render's without AOVs (to rounding: the decomposition loses no term);
//! - each path AOV's mean agrees with the baseline's within their standard errors
//!   (independent ReSTIR runs against a long baseline render).

use glam::Vec3;
use nimbus::output::layers::find_channel;
use nimbus::renderer::RenderResult;
use nimbus_gpu::Context;
use nimbus_scene::{Aov, Scene};

use super::aovs::centre_ray;
use super::restir::{Cloud, SUN_AND_SKY};
use crate::common::cli::scratch;
use crate::common::gpu::{context, render_checked};

/// The values of AOV channel `name` (`Z`, `N.X`, `direct.R`, ...) of a render.
fn channel<'a>(r: &'a RenderResult, name: &str) -> &'a [f32] {
    find_channel(&r.aovs, name).unwrap_or_else(|| panic!("the render has no AOV channel {name}"))
}

/// Layer `layer`'s three channels per pixel (`layer.R/G/B` or `layer.X/Y/Z`).
fn layer3(r: &RenderResult, layer: &str, names: [&str; 3]) -> Vec<[f32; 3]> {
    let c: Vec<&[f32]> = names
        .iter()
        .map(|n| channel(r, &format!("{layer}.{n}")))
        .collect();
    (0..c[0].len())
        .map(|i| [c[0][i], c[1][i], c[2][i]])
        .collect()
}

fn rgb(r: &RenderResult, layer: &str) -> Vec<[f32; 3]> {
    layer3(r, layer, ["R", "G", "B"])
}

/// `scene` with `aovs` asked for (as `[render] aovs` would).
fn with_aovs(mut scene: Scene, aovs: &[Aov]) -> Scene {
    scene.render.aovs = aovs.to_vec();
    scene
}

/// The pixel position of world point p in camera frame `f` (camera.glsl's
/// camera_project): x right, y down.
fn project(scene: &Scene, frame: u32, p: Vec3) -> [f64; 2] {
    let c = scene.camera.frame_at(frame);
    let (w, h) = (
        f64::from(scene.render.width),
        f64::from(scene.render.height),
    );
    let tan_x = f64::from(c.tan_half_fov_x);
    let tan_y = tan_x * h / w;
    let v = (p - c.position).as_dvec3();
    let z = v.dot(c.forward.as_dvec3());
    let sx = v.dot(c.right.as_dvec3()) / (z * tan_x);
    let sy = v.dot(c.up.as_dvec3()) / (z * tan_y);
    [(sx + 1.0) * 0.5 * w, (1.0 - sy) * 0.5 * h]
}

/// Where the ray o + t d enters the axis-aligned box [lo, hi], if it does (t > 0).
fn box_entry(o: Vec3, d: Vec3, lo: Vec3, hi: Vec3) -> Option<f32> {
    let inv = d.recip();
    let (t0, t1) = ((lo - o) * inv, (hi - o) * inv);
    let near = t0.min(t1).max_element();
    let far = t0.max(t1).min_element();
    (near <= far && near > 0.0).then_some(near)
}

fn close(a: f32, b: f32, rel: f32) -> bool {
    (a - b).abs() <= rel * b.abs().max(1e-6)
}

// ---------------------------------------------------------------------------------------
// Geometric AOVs.

/// A quad backdrop at z = -1, a dense box medium in front of it and the grid cloud
/// (ReSTIR renders one grid medium) above, seen from z = 3.
const GEOMETRY_SCENE: &str = r#"
[render]
width = 32
height = 24
frames = 2
seed = 3
[camera]
position = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 50
[[light]]
type = "directional"
direction = [0.5, -0.7, -0.4]
irradiance = [3.0, 2.7, 2.4]
[[light]]
type = "environment"
radiance = [0.2, 0.3, 0.45]
[[medium]]
type = "grid"
bounds_min = [-1.2, 0.35, -0.5]
bounds_max = [-0.2, 0.95, 0.5]
density = { procedural = "cloud", dims = [16, 12, 16], noise_seed = 3 }
density_scale = 24.0
albedo = 0.9
g = 0.5
[[medium]]
type = "box"
center = [0.5, -0.2, 0.5]
size = [0.6, 0.6, 0.6]
sigma_t = 2000.0
albedo = [0.8, 0.7, 0.6]
[[shape]]
type = "quad"
corner = [-4.0, -4.0, -1.0]
edge_u = [8.0, 0.0, 0.0]
edge_v = [0.0, 8.0, 0.0]
albedo = [0.2, 0.4, 0.6]
[integrator]
volume = "restir"
max_bounces = 2
"#;

const GEOMETRIC: [Aov; 4] = [Aov::Depth, Aov::Normal, Aov::Albedo, Aov::Motion];

/// Z, N and albedo of the quad and of the dense box within 1 % of their known values;
/// every geometric channel (the grid cloud's included) equal to the baseline's.
#[test]
fn restir_geometric_aovs_match_known_values_and_the_baseline() {
    let ctx = context();
    let scene = with_aovs(
        crate::common::gpu::scene(GEOMETRY_SCENE, "restir-aov-geometry.toml"),
        &GEOMETRIC,
    );
    let restir = render_checked(&ctx, &scene, None);
    let (w, h) = (scene.render.width, scene.render.height);
    let z = channel(&restir, "Z");
    let n = layer3(&restir, "N", ["X", "Y", "Z"]);
    let albedo = rgb(&restir, "albedo");
    let grid = (Vec3::new(-1.2, 0.35, -0.5), Vec3::new(-0.2, 0.95, 0.5));
    let dense = (Vec3::new(0.2, -0.5, 0.2), Vec3::new(0.8, 0.1, 0.8));
    let (mut quads, mut boxes) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let (o, d) = centre_ray(&scene, 1, x, y);
            if box_entry(o, d, grid.0, grid.1).is_some() {
                continue;
            }
            let forward = scene.camera.frame_at(1).forward;
            if let Some(t) = box_entry(o, d, dense.0, dense.1) {
                // Transmittance 0.5 at ln 2 / sigma_t past the entry (0.35 mm).
                let t_half = t + std::f32::consts::LN_2 / 2000.0;
                let expected = (t_half * d).dot(forward);
                assert!(
                    close(z[i], expected, 0.01),
                    "box pixel ({x}, {y}): Z {} vs {expected}",
                    z[i]
                );
                for (c, want) in [0.8, 0.7, 0.6].into_iter().enumerate() {
                    assert!(
                        close(albedo[i][c], want, 0.01),
                        "box pixel ({x}, {y}): albedo {:?}",
                        albedo[i]
                    );
                }
                // The entry face's normal (the point is within the face's epsilon).
                if (o + t * d).z > 0.8 - 1e-4 {
                    assert!(
                        close(n[i][2], 1.0, 0.01),
                        "box pixel ({x}, {y}): N {:?}",
                        n[i]
                    );
                    boxes += 1;
                }
            } else {
                // The quad at z = -1: depth 4 along the view axis.
                assert!(close(z[i], 4.0, 0.01), "quad pixel ({x}, {y}): Z {}", z[i]);
                assert!(close(n[i][2], 1.0, 0.01) && n[i][0].abs() < 0.01 && n[i][1].abs() < 0.01);
                for (c, want) in [0.2, 0.4, 0.6].into_iter().enumerate() {
                    assert!(
                        close(albedo[i][c], want, 0.01),
                        "quad pixel ({x}, {y}): albedo {:?}",
                        albedo[i]
                    );
                }
                quads += 1;
            }
        }
    }
    assert!(
        quads > 100 && boxes > 20,
        "{quads} quad and {boxes} box pixels checked"
    );

    // The baseline traces the same function: the same values everywhere (the cloud's
    // depth at transmittance 0.5 through the exact trilinear grid included).
    let mut base_scene = scene.clone();
    base_scene.integrator.volume = nimbus_scene::VolumeIntegrator::Baseline;
    let baseline = render_checked(&ctx, &base_scene, None);
    let mut cloud = 0;
    for name in [
        "Z", "N.X", "N.Y", "N.Z", "albedo.R", "albedo.G", "albedo.B", "motion.X", "motion.Y",
    ] {
        let (a, b) = (channel(&restir, name), channel(&baseline, name));
        for i in 0..a.len() {
            let same = a[i] == b[i] || (a[i] - b[i]).abs() <= 1e-5 * b[i].abs().max(1.0);
            assert!(
                same,
                "{name} at pixel {i}: ReSTIR {} vs baseline {}",
                a[i], b[i]
            );
        }
    }
    for y in 0..h {
        for x in 0..w {
            let (o, d) = centre_ray(&scene, 1, x, y);
            let i = (y * w + x) as usize;
            if let Some(t) = box_entry(o, d, grid.0, grid.1) {
                let forward = scene.camera.frame_at(1).forward;
                if z[i] > (t * d).dot(forward) && z[i] < 3.5 {
                    cloud += 1;
                }
            }
        }
    }
    assert!(
        cloud > 10,
        "only {cloud} pixels see the cloud's half-transmittance point"
    );
}

/// A camera dollying in and a cloud moving by its velocity field (0.05 m per frame
/// along +x): the motion AOV of the last frame is the analytic reprojection of the
/// point each pixel's Z names.
#[test]
fn restir_motion_follows_the_camera_and_the_velocity_field() {
    let dir = scratch("restir_aovs", "motion");
    let dims = [4usize, 4, 4];
    let velocity: Vec<u8> = (0..dims.iter().product::<usize>())
        .flat_map(|_| [0.05f32, 0.0, 0.0])
        .flat_map(f32::to_le_bytes)
        .collect();
    let vel_path = dir.join("velocity.raw");
    std::fs::write(&vel_path, velocity).unwrap();
    let text = format!(
        r#"
[render]
width = 32
height = 24
frames = 2
[camera]
position = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 50
[[camera.keyframe]]
frame = 0
position = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
[[camera.keyframe]]
frame = 1
position = [0.1, 0.05, 2.8]
look_at = [0.0, 0.0, 0.0]
{SUN_AND_SKY}
[[medium]]
type = "grid"
bounds_min = [-1.0, -0.6, -1.0]
bounds_max = [1.0, 0.6, 1.0]
density = {{ procedural = "cloud", dims = [24, 16, 24], noise_seed = 3 }}
density_scale = 16.0
albedo = 0.9
velocity = {{ file = "{}", dims = [4, 4, 4] }}
[[shape]]
type = "quad"
corner = [-4.0, -4.0, -1.5]
edge_u = [8.0, 0.0, 0.0]
edge_v = [0.0, 8.0, 0.0]
albedo = 0.5
[integrator]
volume = "restir"
max_bounces = 1
"#,
        vel_path.display()
    );
    let scene = with_aovs(
        crate::common::gpu::scene(&text, "restir-aov-motion.toml"),
        &GEOMETRIC,
    );
    let ctx = context();
    let r = render_checked(&ctx, &scene, None);
    let (w, h) = (scene.render.width, scene.render.height);
    let z = channel(&r, "Z");
    let (mx, my) = (channel(&r, "motion.X"), channel(&r, "motion.Y"));
    let forward = scene.camera.frame_at(1).forward;
    let (mut surface, mut medium) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let (o, d) = centre_ray(&scene, 1, x, y);
            // Domain: the quad backdrop behind everything, so Z is finite.
            let p = o + d * (z[i] / d.dot(forward));
            let on_quad = (p.z + 1.5).abs() < 1e-3;
            let before = if on_quad {
                surface += 1;
                p
            } else {
                medium += 1;
                p - Vec3::new(0.05, 0.0, 0.0)
            };
            let (now, then) = (project(&scene, 1, p), project(&scene, 0, before));
            let want = [now[0] - then[0], now[1] - then[1]];
            for (got, want) in [(mx[i], want[0]), (my[i], want[1])] {
                assert!(
                    (f64::from(got) - want).abs() <= 0.02 + 0.01 * want.abs(),
                    "pixel ({x}, {y}) ({}): motion {:?} vs {want:?}",
                    if on_quad { "quad" } else { "cloud" },
                    (mx[i], my[i])
                );
            }
        }
    }
    assert!(
        surface > 50 && medium > 50,
        "{surface} quad and {medium} cloud pixels"
    );
    // The baseline's motion AOV does not follow a velocity field: the same scene with the
    // baseline integrator is refused by its plan, before anything is allocated.
    let mut baseline = scene.clone();
    baseline.integrator.volume = nimbus_scene::VolumeIntegrator::Baseline;
    let e = format!("{:#}", nimbus::plan::build(&baseline, None).unwrap_err());
    for needle in [
        "restir-aov-motion.toml",
        "motion",
        "[[medium]] #1",
        "velocity",
    ] {
        assert!(e.contains(needle), "{needle:?} not in: {e}");
    }
}

// ---------------------------------------------------------------------------------------
// Path AOVs sum to the RGB.

/// A sun in group "key", a point light in group "fill" and a sky in none (`default`).
const GROUPED_LIGHTS: &str = r#"
[[light]]
type = "directional"
direction = [0.5, -0.7, -0.4]
irradiance = [3.0, 2.7, 2.4]
group = "key"
[[light]]
type = "point"
position = [-0.8, 1.2, 1.2]
intensity = [1.5, 1.0, 0.6]
group = "fill"
[[light]]
type = "environment"
radiance = [0.2, 0.3, 0.45]
"#;

const EMISSION: &str =
    "emission = { procedural = \"cloud\", dims = [12, 8, 12], noise_seed = 5 }\n\
                        emission_scale = [2.0, 1.0, 0.5]";

const PATHS: [Aov; 4] = [Aov::Emission, Aov::Direct, Aov::Indirect, Aov::LightGroups];

/// The render's RGB per pixel.
fn beauty(r: &RenderResult) -> Vec<[f32; 3]> {
    r.image.data.clone()
}

/// Asserts that the layers' per-pixel sum is `total` to rounding (each frame's sums are
/// exact or within one rounding per term; the means over frames differ by rounding).
fn assert_sums_to(what: &str, parts: &[Vec<[f32; 3]>], total: &[[f32; 3]]) {
    for (i, t) in total.iter().enumerate() {
        for c in 0..3 {
            let sum: f64 = parts.iter().map(|p| f64::from(p[i][c])).sum();
            let want = f64::from(t[c]);
            assert!(
                (sum - want).abs() <= 1e-5 * want.abs() + 1e-7,
                "{what}: pixel {i} channel {c}: parts sum to {sum}, RGB is {want}"
            );
        }
    }
}

/// Renders `cloud` with the path AOVs and checks that the kinds and the groups each sum
/// to the RGB, that every named part is present, and that the RGB is the render's
/// without AOVs to rounding; returns the render.
fn check_sums(ctx: &Context, label: &str, cloud: Cloud, groups: &[&str]) -> RenderResult {
    let plain = render_checked(ctx, &cloud.scene("restir-aov-sums.toml"), None);
    let r = render_checked(
        ctx,
        &with_aovs(cloud.scene("restir-aov-sums.toml"), &PATHS),
        None,
    );
    let total = beauty(&r);
    let kinds: Vec<Vec<[f32; 3]>> = ["emission", "direct", "indirect"]
        .iter()
        .map(|k| rgb(&r, k))
        .collect();
    assert_sums_to(
        &format!("{label}: emission + direct + indirect"),
        &kinds,
        &total,
    );
    let parts: Vec<Vec<[f32; 3]>> = groups
        .iter()
        .map(|g| rgb(&r, &format!("lightgroup.{g}")))
        .collect();
    assert_sums_to(&format!("{label}: light groups"), &parts, &total);
    assert_sums_to(
        &format!("{label}: RGB without AOVs"),
        &[beauty(&plain)],
        &total,
    );
    for (name, part) in ["emission", "direct", "indirect"]
        .iter()
        .zip(&kinds)
        .chain(groups.iter().zip(&parts))
    {
        let mean: f64 = part
            .iter()
            .map(|p| f64::from(p[0] + p[1] + p[2]))
            .sum::<f64>();
        println!("{label}: {name} sums to {mean:.4}");
    }
    r
}

/// Split NEE (a sun, a point light and a sky, K = 3), with and without emission and with
/// folded emission; one-light NEE with emission candidates; the camera rays' emission
/// resampled (the paper's) instead of estimated in shading.
#[test]
fn restir_path_aovs_sum_to_the_rgb_slow() {
    let ctx = context();
    let base = Cloud {
        size: (20, 14),
        frames: 4,
        bounces: 3,
        lights: GROUPED_LIGHTS,
        ..Cloud::default()
    };
    let groups = ["key", "fill", "default"];
    let r = check_sums(&ctx, "split NEE", base, &groups);
    // Every part is there: the sky seen through the cloud, single and multiple
    // scattering, each group.
    for layer in [
        "emission",
        "direct",
        "indirect",
        "lightgroup.key",
        "lightgroup.fill",
        "lightgroup.default",
    ] {
        let sum: f32 = rgb(&r, layer).iter().map(|p| p[0] + p[1] + p[2]).sum();
        assert!(sum > 0.0, "split NEE: {layer} is black");
    }
    check_sums(
        &ctx,
        "folded emission",
        Cloud {
            medium_extra: EMISSION,
            restir: "emission = \"folded\"",
            ..base
        },
        &groups,
    );
    check_sums(
        &ctx,
        "one-light NEE, emission candidates",
        Cloud {
            medium_extra: EMISSION,
            restir: "nee = \"one\"",
            ..base
        },
        &groups,
    );
    // The camera rays' emission resampled as every path is (the paper's; the cases above
    // estimate it in shading, apart from the reservoirs, into the emission layer and the
    // default group).
    let r = check_sums(
        &ctx,
        "camera emission resampled",
        Cloud {
            medium_extra: EMISSION,
            restir: "camera_emission = \"reservoir\"",
            ..base
        },
        &groups,
    );
    let sum: f32 = rgb(&r, "emission").iter().map(|p| p[0] + p[1] + p[2]).sum();
    assert!(
        sum > 0.0,
        "camera emission resampled: the emission layer is black"
    );
}

/// A sphere light (group "bulb"), an emitting quad (the default group) and a floor:
/// emission seen directly from each, one-light NEE (sphere and area lights), and light
/// groups alone (no kinds asked): the groups then sum to the RGB.
#[test]
fn restir_path_aovs_sum_to_the_rgb_with_emitters_slow() {
    let ctx = context();
    let lights = r#"
[[light]]
type = "sphere"
center = [0.9, 0.9, 0.6]
radius = 0.15
radiance = [6.0, 5.0, 3.0]
group = "bulb"
[[light]]
type = "environment"
radiance = [0.1, 0.15, 0.2]
group = "sky"
"#;
    let shapes = r#"
[[shape]]
type = "quad"
corner = [-3.0, -0.65, 3.0]
edge_u = [6.0, 0.0, 0.0]
edge_v = [0.0, 0.0, -6.0]
albedo = [0.7, 0.6, 0.5]
[[shape]]
type = "quad"
corner = [-0.9, 0.7, -0.3]
edge_u = [0.6, 0.0, 0.0]
edge_v = [0.0, 0.0, 0.6]
emission = [3.0, 2.5, 2.0]
"#;
    let cloud = Cloud {
        size: (20, 14),
        frames: 4,
        bounces: 2,
        lights,
        shapes,
        position: "[0.0, 0.6, 2.3]",
        ..Cloud::default()
    };
    let r = check_sums(&ctx, "emitters", cloud, &["bulb", "sky", "default"]);
    for layer in ["lightgroup.bulb", "lightgroup.sky", "lightgroup.default"] {
        let sum: f32 = rgb(&r, layer).iter().map(|p| p[0] + p[1] + p[2]).sum();
        assert!(sum > 0.0, "emitters: {layer} is black");
    }
    // Light groups alone: the RGB is their sum.
    let scene = with_aovs(cloud.scene("restir-aov-groups.toml"), &[Aov::LightGroups]);
    let g = render_checked(&ctx, &scene, None);
    let parts: Vec<Vec<[f32; 3]>> = ["bulb", "sky", "default"]
        .iter()
        .map(|n| rgb(&g, &format!("lightgroup.{n}")))
        .collect();
    assert_sums_to("light groups alone", &parts, &beauty(&g));
}

// ---------------------------------------------------------------------------------------
// Unbiasedness of each path AOV.

/// Independent ReSTIR runs.
const RUNS: u64 = 12;

/// Each path AOV of ReSTIR (K = 3, temporal reuse, split NEE, folded emission; a sun, a
/// point light and a sky in three groups) against the baseline's: the image means agree
/// within 4.5 combined standard errors (the ReSTIR side's from the spread of independent
/// runs, the baseline's its own), and at most 3 % of the pixel channels differ by more
/// than 4.5.
#[test]
fn restir_path_aovs_match_the_baseline_slow() {
    let ctx = context();
    let cloud = Cloud {
        size: (16, 12),
        frames: 16,
        bounces: 3,
        lights: GROUPED_LIGHTS,
        medium_extra: EMISSION,
        restir: "emission = \"folded\"",
        ..Cloud::default()
    };
    let layers = [
        "emission",
        "direct",
        "indirect",
        "lightgroup.key",
        "lightgroup.fill",
        "lightgroup.default",
    ];
    let reference = render_checked(
        &ctx,
        &with_aovs(
            Cloud {
                volume: "baseline",
                frames: 32,
                spp: 32,
                seed: 7,
                ..cloud
            }
            .scene("restir-aov-reference.toml"),
            &PATHS,
        ),
        None,
    );
    let runs: Vec<RenderResult> = (0..RUNS)
        .map(|i| {
            let scene = Cloud {
                seed: 101 + i,
                ..cloud
            }
            .scene("restir-aov-run.toml");
            render_checked(&ctx, &with_aovs(scene, &PATHS), None)
        })
        .collect();
    let r = RUNS as f64;
    let pixels = reference.image.data.len();
    for layer in layers {
        let ref_mean = rgb(&reference, layer);
        let ref_se = rgb(&reference, &format!("{layer}_stderr"));
        let run_values: Vec<Vec<[f32; 3]>> = runs.iter().map(|x| rgb(x, layer)).collect();
        let mut beyond = 0;
        for c in 0..3 {
            // Image means: the reference's error from its independent pixels, ReSTIR's
            // from the spread of its runs' image means.
            let ref_image: f64 =
                ref_mean.iter().map(|p| f64::from(p[c])).sum::<f64>() / pixels as f64;
            let ref_image_se = ref_se
                .iter()
                .map(|p| f64::from(p[c]).powi(2))
                .sum::<f64>()
                .sqrt()
                / pixels as f64;
            let means: Vec<f64> = run_values
                .iter()
                .map(|v| v.iter().map(|p| f64::from(p[c])).sum::<f64>() / pixels as f64)
                .collect();
            let m = means.iter().sum::<f64>() / r;
            let se = (means.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (r - 1.0) / r).sqrt();
            let combined = se.hypot(ref_image_se);
            println!(
                "{layer} channel {c}: ReSTIR {m:.5} ± {se:.5}, baseline {ref_image:.5} ± {ref_image_se:.5}"
            );
            assert!(
                (m - ref_image).abs() <= 4.5 * combined + 1e-6,
                "{layer} channel {c}: ReSTIR's mean {m} vs the baseline's {ref_image} ({:.2} SE)",
                (m - ref_image) / combined
            );
            for p in 0..pixels {
                let v: Vec<f64> = run_values.iter().map(|x| f64::from(x[p][c])).collect();
                let pm = v.iter().sum::<f64>() / r;
                let pse = (v.iter().map(|x| (x - pm).powi(2)).sum::<f64>() / (r - 1.0) / r).sqrt();
                let s = pse.hypot(f64::from(ref_se[p][c]));
                let excess =
                    ((pm - f64::from(ref_mean[p][c])).abs() - 1e-5 * pm.abs() - 1e-6).max(0.0);
                if excess > 4.5 * s {
                    beyond += 1;
                }
            }
        }
        assert!(
            beyond as f64 <= 0.03 * (3 * pixels) as f64,
            "{layer}: {beyond} of {} pixel channels beyond 4.5 SE",
            3 * pixels
        );
    }
}
