//! A turning environment map (`rotation_deg` and `[[light.keyframe]]` of an
//! "environment" light; issue 26, item 1, the paper's rotating HDR sky), on lavapipe with
//! validation layers on:
//!
//! - **the exact oracle**: a map turned by 90° renders as the map whose columns are
//!   shifted a quarter turn, unturned, in the baseline path tracer and in the crepuscular
//!   pass (box medium and floor), within the noise of both; the wrong sign (−90°) does
//!   not (so the test sees the convention, not only "some turn");
//! - **ReSTIR under a turning sky**: the mean of 16 independent renders of a map turning
//!   5° a frame (each frame's temporal history turned by the previous frame's angle)
//!   agrees pixel by pixel with the baseline's renders of every frame's static scene,
//!   with the criteria of tests/suite/oracle/restir/mod.rs.

use std::path::PathBuf;

use nimbus::output::ImageRgb;
use nimbus_gpu::Context;
use nimbus_scene::Scene;

use crate::common::cli::scratch;
use crate::common::gpu::{assert_means_agree, channels_beyond, context, render_checked, scene};
use crate::oracle::restir::{
    check_cases_against, Case, Cloud, Estimate, BOTH, PAIRWISE, RUN_FRAMES,
};

/// Map size: 64 × 32 texels, 5.625° a column.
const MAP: (usize, usize) = (64, 32);

/// A daylight sky (`nimbus_scene::daylight_sky`) with a sun `diameter_deg` wide, 35° high
/// at 50° from −Z towards +X, and beside it the same map with its columns shifted a
/// quarter turn: column x of the second is column x + 16 of the first, so that
/// shifted(u) = map(u + 1/4), which is what the first shows turned by +90°
/// (docs/scene-format.md: u = frac(0.5 + atan2(d.x, −d.z)/(2π) + θ/360°)).
fn maps(name: &str, diameter_deg: f32) -> (PathBuf, PathBuf) {
    let dir = scratch("env_rotation", name);
    let (w, h) = MAP;
    let sun = nimbus_scene::sun_direction(35f32.to_radians(), 50f32.to_radians());
    let texels = nimbus_scene::daylight_sky(w, h, sun, f64::from(diameter_deg).to_radians(), 3.0);
    let (map, shifted) = (dir.join("sky.exr"), dir.join("sky-shifted.exr"));
    exr::prelude::write_rgb_file(&map, w, h, |x, y| {
        let [r, g, b] = texels[y * w + x];
        (r, g, b)
    })
    .unwrap();
    exr::prelude::write_rgb_file(&shifted, w, h, |x, y| {
        let [r, g, b] = texels[y * w + (x + w / 4) % w];
        (r, g, b)
    })
    .unwrap();
    (map, shifted)
}

/// The environment light of the map at `file` turned by `rotation_deg`.
fn map_light(file: &std::path::Path, rotation_deg: f32) -> String {
    format!(
        "[[light]]\ntype = \"environment\"\nfile = \"{}\"\nrotation_deg = {rotation_deg:?}\n",
        file.display()
    )
}

/// An image and its standard errors as the harness compares them.
fn pair(a: &(ImageRgb, ImageRgb)) -> (&ImageRgb, &ImageRgb) {
    (&a.0, &a.1)
}

/// Renders `text` with the map turned and the shifted map unturned, and the map turned
/// the wrong way: the first two agree within noise (image means within 4 combined
/// standard errors + 1 %, at most 2 % of the pixel channels beyond 4.5), the wrong turn
/// differs in at least a tenth of them (a fifth to a quarter on these scenes).
fn turned_matches_shifted(ctx: &Context, what: &str, text: impl Fn(&str) -> String) {
    let (map, shifted) = maps(what, 14.0);
    let render = |lights: String, name: &str| -> (ImageRgb, ImageRgb) {
        let s: Scene = scene(&text(&lights), name);
        let r = render_checked(ctx, &s, Some(8));
        (r.image, r.std_error)
    };
    let turned = render(map_light(&map, 90.0), "turned.toml");
    let reference = render(map_light(&shifted, 0.0), "shifted.toml");
    let wrong = render(map_light(&map, -90.0), "wrong.toml");
    let channels = 3 * turned.0.data.len();
    assert_means_agree(
        &format!("{what}: turned by 90° vs shifted a quarter"),
        pair(&turned),
        pair(&reference),
        4.0,
        0.01,
    );
    let beyond = channels_beyond(pair(&turned), pair(&reference), 4.5);
    let wrong_beyond = channels_beyond(pair(&wrong), pair(&reference), 4.5);
    println!(
        "{what}: turned vs shifted {beyond} of {channels} channels beyond 4.5 SE; \
         turned the wrong way {wrong_beyond}"
    );
    assert!(
        beyond * 50 <= channels,
        "{what}: {beyond} of {channels} channels beyond 4.5 SE"
    );
    assert!(
        wrong_beyond * 10 >= channels,
        "{what}: the wrong turn differs in only {wrong_beyond} of {channels} channels"
    );
}

/// The baseline path tracer: a cloud lit by the sun of the map (next-event estimation
/// samples the turned map, escaping camera rays look it up), two bounces.
#[test]
fn the_baseline_turns_the_map_by_rotation_deg() {
    let ctx = context();
    turned_matches_shifted(&ctx, "baseline", |lights| {
        format!(
            "[render]\nwidth = 20\nheight = 16\nframes = 24\nspp = 8\nseed = 3\n\
             [camera]\nposition = [0.0, 0.4, 2.4]\nlook_at = [0.0, 0.0, 0.0]\nhorizontal_fov_deg = 70\n\
             {lights}\
             [[medium]]\ntype = \"grid\"\nbounds_min = [-0.8, -0.5, -0.8]\nbounds_max = [0.8, 0.5, 0.8]\n\
             density = {{ procedural = \"cloud\", dims = [16, 12, 16], noise_seed = 4 }}\n\
             density_scale = 8.0\nalbedo = 0.9\ng = 0.3\n\
             [integrator]\nvolume = \"baseline\"\nmax_bounces = 2\n"
        )
    });
}

/// The crepuscular pass: a box medium and a floor under the map (their next-event
/// estimation samples the turned map and its pdf, the sky around them is looked up).
#[test]
fn the_crepuscular_pass_turns_the_map_by_rotation_deg() {
    let ctx = context();
    turned_matches_shifted(&ctx, "crepuscular", |lights| {
        format!(
            "[render]\nwidth = 16\nheight = 12\nframes = 24\nspp = 4\nseed = 5\n\
             [camera]\nposition = [0.3, 0.9, 3.2]\nlook_at = [0.0, -0.2, 0.0]\nhorizontal_fov_deg = 70\n\
             {lights}\
             [[medium]]\ntype = \"box\"\ncenter = [0.0, 0.0, 0.0]\nsize = [1.6, 1.0, 1.2]\n\
             rotation_deg = [0.0, 25.0, 0.0]\nsigma_t = 2.0\nalbedo = [0.95, 0.9, 0.8]\ng = 0.3\n\
             [[shape]]\ntype = \"quad\"\ncorner = [-2.5, -0.5, -2.5]\nedge_u = [5.0, 0.0, 0.0]\n\
             edge_v = [0.0, 0.0, 5.0]\nalbedo = [0.7, 0.6, 0.5]\n\
             [integrator]\nmax_bounces = 2\n"
        )
    });
}

/// The turn of the sky of [`restir_under_a_turning_sky`]: 0° at frame 0 to 115° at frame
/// 23, 5° a frame (under one column of the map: the history's sun samples land half on
/// the sun, half beside it).
const TURNING: &str = "[[light.keyframe]]\nframe = 0\nrotation_deg = 0\n\
                       [[light.keyframe]]\nframe = 23\nrotation_deg = 115\n";

/// The baseline reference of `cloud`'s animation (frames 0 .. RUN_FRAMES − 1, each
/// scene frame once): per frame the static scene of that frame (its lights, no keys),
/// `frames` × `spp` paths per pixel; the mean over the animation's frames with its
/// standard errors combined (the frames are independent).
fn animated_reference(ctx: &Context, cloud: &Cloud, frames: u32, spp: u32) -> Estimate {
    let animated = cloud.scene("restir-turning.toml");
    let n = RUN_FRAMES as f64;
    let pixels = (cloud.size.0 * cloud.size.1) as usize;
    let mut mean = vec![[0.0; 3]; pixels];
    let mut var = vec![[0.0; 3]; pixels];
    let mut image_mean = [0.0; 3];
    let mut image_var = [0.0; 3];
    for f in 0..RUN_FRAMES {
        let mut s = Cloud {
            volume: "baseline",
            frames,
            spp,
            seed: 1000 + u64::from(f),
            ..*cloud
        }
        .scene("restir-turning-reference.toml");
        s.lights = animated.lights_at(f);
        s.light_keyframes.clear();
        let r = render_checked(ctx, &s, None);
        let m = r.image.mean();
        for c in 0..3 {
            image_mean[c] += m[c] / n;
            let se2: f64 = r
                .std_error
                .data
                .iter()
                .map(|p| f64::from(p[c]).powi(2))
                .sum();
            image_var[c] += se2 / (pixels * pixels) as f64 / (n * n);
        }
        for (p, (pm, ps)) in r.image.data.iter().zip(&r.std_error.data).enumerate() {
            for c in 0..3 {
                mean[p][c] += f64::from(pm[c]) / n;
                var[p][c] += f64::from(ps[c]).powi(2) / (n * n);
            }
        }
    }
    Estimate {
        mean,
        se: var.iter().map(|v| v.map(f64::sqrt)).collect(),
        image_mean,
        image_mean_se: image_var.map(f64::sqrt),
    }
}

/// [`BOTH`] with the environment samples kept in the world (`env_reuse = "world"`, the
/// paper's direction reuse): the history's sun samples stay put as the sun turns. (BOTH
/// keeps them in the map's frame, the default, with Q = 2 on the turning frames.)
const WORLD_REUSE: Case = Case {
    label: "temporal + spatial, environment samples in the world",
    restir: "temporal = true\ntemporal_limit = 4\nspatial_rounds = 1\nspatial_neighbors = 3\n\
             spatial_when = \"always\"\nspatial_radius_px = 10\nenv_reuse = \"world\"",
};

/// ReSTIR renders a map turning 5° a frame (a sun 6° wide and a sky, alone: split NEE;
/// and beside a directional light: one light per vertex, pairwise MIS) as the baseline
/// renders each frame's static scene. Every reused path's environment vertex is looked
/// up with the frame it is shaded in; looking it up with the frame it was found in
/// moves the sun's light with the history and fails here. The sky alone with its samples
/// turning with the map (the default, `env_reuse = "map"`) and kept in the world.
#[test]
fn restir_under_a_turning_sky_matches_the_baseline_slow() {
    let ctx = context();
    let (map, _) = maps("restir", 6.0);
    let sky = format!(
        "[[light]]\ntype = \"environment\"\nfile = \"{}\"\n{TURNING}",
        map.display()
    );
    let with_sun = format!(
        "{sky}[[light]]\ntype = \"directional\"\ndirection = [0.5, -0.7, -0.4]\nirradiance = 1.5\n"
    );
    for (lights, cases, group) in [
        (sky.as_str(), &[BOTH, WORLD_REUSE][..], "turning sky"),
        (with_sun.as_str(), &[PAIRWISE][..], "turning sky and a sun"),
    ] {
        let base = Cloud {
            lights,
            ..Cloud::default()
        };
        let start = std::time::Instant::now();
        let reference = animated_reference(&ctx, &base, 8, 16);
        println!(
            "{group}: baseline reference {:?} ± {:?} ({:.1?})",
            reference.image_mean,
            reference.image_mean_se,
            start.elapsed()
        );
        check_cases_against(&ctx, &reference, base, cases, group);
    }
}
