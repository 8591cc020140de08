//! Light keyframes drive every integrator (issue 24): the frame of an animated scene
//! renders as the static scene of that frame, in the crepuscular pass and the baseline
//! path tracer too, not only in ReSTIR.

use nimbus::output::ImageRgb;
use nimbus_scene::Scene;

use crate::common::gpu::{assert_no_validation_errors, context, scene};

fn mean(image: &ImageRgb) -> f64 {
    image
        .data
        .iter()
        .map(|p| f64::from(p[0] + p[1] + p[2]))
        .sum::<f64>()
        / (3 * image.data.len()) as f64
}

/// Scene frame `frame` of `s` alone, `passes` dispatches of it.
fn frame_mean(ctx: &nimbus_gpu::Context, s: &Scene, frame: u32, passes: u32) -> f64 {
    let r = crate::common::gpu::render_scene_frame(ctx, s, frame, passes);
    assert_no_validation_errors(ctx);
    mean(&r.image)
}

const BOX: &str = r#"
[render]
width = 24
height = 18
frames = 3
spp = 1
pixel_jitter = false

[camera]
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 40

[[light]]
type = "directional"
direction = [0.3, -1.0, 0.2]
irradiance = [1.0, 1.0, 1.0]

[[light.keyframe]]
frame = 0
irradiance = [1.0, 1.0, 1.0]

[[light.keyframe]]
frame = 2
irradiance = [3.0, 3.0, 3.0]

[[medium]]
type = "box"
center = [0.0, 0.0, 0.0]
size = [2.0, 2.0, 2.0]
sigma_t = 0.8
albedo = 0.9
g = 0.3
"#;

#[test]
fn a_keyed_directional_light_scales_the_box_medium_frame_by_frame() {
    let ctx = context();
    let s = scene(BOX, "light_keys_box.toml");
    // MCWVDS with no occluder is exact with one sample and pixel centres: the frames'
    // images are exactly proportional to the irradiance.
    let m0 = frame_mean(&ctx, &s, 0, 1);
    let m1 = frame_mean(&ctx, &s, 1, 1);
    let m2 = frame_mean(&ctx, &s, 2, 1);
    assert!(m0 > 0.0);
    assert!(
        (m2 / m0 - 3.0).abs() < 1e-4,
        "frame 2 / frame 0 = {}",
        m2 / m0
    );
    assert!(
        (m1 / m0 - 2.0).abs() < 1e-4,
        "frame 1 / frame 0 = {}",
        m1 / m0
    );
}

const GRID: &str = r#"
[render]
width = 20
height = 16
frames = 3
spp = 16
seed = 5

[camera]
position = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 45

[[light]]
type = "directional"
direction = [0.4, -1.0, -0.3]
irradiance = [1.0, 1.0, 1.0]

[[light.keyframe]]
frame = 0
irradiance = [1.0, 1.0, 1.0]

[[light.keyframe]]
frame = 2
irradiance = [3.0, 3.0, 3.0]

[[medium]]
type = "grid"
bounds_min = [-1.0, -1.0, -1.0]
bounds_max = [1.0, 1.0, 1.0]
density = { procedural = "cloud", dims = [16, 16, 16], noise_seed = 2 }
density_scale = 4.0
albedo = 0.9
g = 0.0

[integrator]
volume = "baseline"
max_bounces = 2
"#;

#[test]
fn a_keyed_directional_light_drives_the_baseline_path_tracer() {
    let ctx = context();
    let s = scene(GRID, "light_keys_grid.toml");
    // Without an environment every path's radiance is linear in the one light's
    // irradiance; the two frames draw different random numbers, so the ratio is 3 within
    // the noise of 16 passes x 16 spp (about 1 % here).
    let m0 = frame_mean(&ctx, &s, 0, 16);
    let m2 = frame_mean(&ctx, &s, 2, 16);
    assert!(m0 > 0.0);
    assert!(
        (m2 / m0 / 3.0 - 1.0).abs() < 0.05,
        "frame 2 / frame 0 = {}",
        m2 / m0
    );
    // A keyed direction moves the lit side: the static scene of frame 2 agrees.
    let mut fixed = s.clone();
    fixed.lights = s.lights_at(2);
    fixed.light_keyframes.clear();
    let f2 = frame_mean(&ctx, &fixed, 2, 16);
    assert!((m2 / f2 - 1.0).abs() < 0.05, "keyed {m2} vs static {f2}");
}
