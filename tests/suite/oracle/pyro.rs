//! Pyro shading: a `temperature` grid glowing as a blackbody
//! (crates/nimbus-scene/src/blackbody.rs), in both grid integrators and the CPU oracle.

use std::path::{Path, PathBuf};

use glam::DVec3;
use nimbus_scene::cie1931::{CIE_1931_XYZ, CIE_FIRST_NM, CIE_STEP_NM};

use crate::common::cli::scratch;
use crate::common::gpu::{context, render_checked, render_scene_frame, scene};
use crate::common::scenes::{CLOUD_BOUNDS, CLOUD_SUN_AND_SKY};
use crate::oracle::baseline::check_against_oracle;

/// RGB(T) by this test's own integration: Simpson's rule at every half nanometre over
/// 360..830 nm of Planck's law times the CIE 1931 observer (linear between its 5 nm
/// rows), through the IEC 61966-2-1 XYZ → sRGB matrix, negative channels clamped.
fn blackbody_by_simpson(kelvin: f64) -> DVec3 {
    let (h, c, k) = (6.626_070_15e-34, 299_792_458.0, 1.380_649e-23);
    let cmf = |nm: f64| {
        let x = (nm - f64::from(CIE_FIRST_NM)) / f64::from(CIE_STEP_NM);
        let i = (x.floor() as usize).min(CIE_1931_XYZ.len() - 2);
        let f = x - i as f64;
        let row = |i: usize| DVec3::from(CIE_1931_XYZ[i].map(f64::from));
        row(i) * (1.0 - f) + row(i + 1) * f
    };
    let planck = |nm: f64| {
        let l = nm * 1e-9;
        2.0 * h * c * c / l.powi(5) / ((h * c / (l * k * kelvin)).exp() - 1.0) * 1e-9
    };
    let n = 940;
    let step = 470.0 / n as f64;
    let mut xyz = DVec3::ZERO;
    for i in 0..=n {
        let nm = 360.0 + step * i as f64;
        let w = match i {
            0 => 1.0,
            i if i == n => 1.0,
            i if i % 2 == 1 => 4.0,
            _ => 2.0,
        };
        xyz += cmf(nm) * planck(nm) * w;
    }
    xyz *= step / 3.0;
    let rgb = DVec3::new(
        3.2406 * xyz.x - 1.5372 * xyz.y - 0.4986 * xyz.z,
        -0.9689 * xyz.x + 1.8758 * xyz.y + 0.0415 * xyz.z,
        0.0557 * xyz.x - 0.2040 * xyz.y + 1.0570 * xyz.z,
    );
    rgb.max(DVec3::ZERO)
}

/// A raw float32 grid of `dims` holding `value` everywhere.
fn constant_raw(dir: &Path, name: &str, dims: [u32; 3], value: f32) -> PathBuf {
    let n = (dims[0] * dims[1] * dims[2]) as usize;
    let bytes: Vec<u8> = std::iter::repeat_n(value.to_le_bytes(), n)
        .flatten()
        .collect();
    let path = dir.join(name);
    std::fs::write(&path, bytes).expect("write raw grid");
    path
}

/// An opaque (optical depth 400 across), black (albedo 0) cube of constant temperature
/// `kelvin` seen head-on: every pixel on it shows Le = `blackbody_scale` · RGB(T).
fn opaque_emitter(volume: &str, grid: &Path, kelvin: f64, blackbody_scale: f64) -> String {
    // ReSTIR takes one path per pixel per frame.
    let spp = if volume == "restir" { 1 } else { 16 };
    format!(
        r#"
[render]
width = 8
height = 8
spp = {spp}
frames = 4
seed = 5
[camera]
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 12
[[light]]
type = "environment"
radiance = 0.5
[[medium]]
type = "grid"
bounds_min = [-1.0, -1.0, -1.0]
bounds_max = [1.0, 1.0, 1.0]
density = {{ file = {grid:?}, dims = [4, 4, 4] }}
density_scale = 200.0
albedo = 0.0
temperature = {{ file = {grid:?}, dims = [4, 4, 4] }}
temperature_scale = {kelvin:?}
blackbody_scale = {blackbody_scale:e}
[integrator]
volume = "{volume}"
max_bounces = 2
"#
    )
}

/// The issue's acceptance test: a constant-temperature opaque emitter renders
/// `blackbody_scale` · RGB(T) within 1 % in chromaticity and 5 % in radiance at 1800 to
/// 6500 K, in the baseline and in ReSTIR, against this test's own integration.
#[test]
fn an_opaque_emitter_shows_its_blackbody_colour_at_1800_to_6500_kelvin() {
    let ctx = context();
    let dir = scratch("pyro", "opaque");
    let grid = constant_raw(&dir, "one.raw", [4, 4, 4], 1.0);
    for volume in ["baseline", "restir"] {
        for kelvin in [1800.0, 3000.0, 4500.0, 6500.0] {
            let want = blackbody_by_simpson(kelvin);
            // Scaled so that the brightest channel is about 1.
            let scale = 1.0 / want.max_element();
            let text = opaque_emitter(volume, &grid, kelvin, scale);
            let result = render_checked(&ctx, &scene(&text, "opaque.toml"), None);
            let want = want * scale;
            // The cube covers the whole 12° view.
            let img = &result.image;
            let mean = img.mean();
            let got = DVec3::new(mean[0], mean[1], mean[2]);
            let chroma = |v: DVec3| v / (v.x + v.y + v.z);
            let (a, b) = (chroma(got), chroma(want));
            println!("{volume} {kelvin} K: got {got:.4}, want {want:.4}");
            assert!(
                (a - b).abs().max_element() <= 0.01 * b.max_element(),
                "{volume} {kelvin} K: chromaticity {a:.4} vs {b:.4}"
            );
            let sum = |v: DVec3| v.x + v.y + v.z;
            assert!(
                (sum(got) / sum(want) - 1.0).abs() <= 0.05,
                "{volume} {kelvin} K: radiance {got:.4} vs {want:.4}"
            );
        }
    }
}

/// A cloud whose temperature is another cloud (800 to 3300 K), beside an rgb emission
/// grid and under a sun, K = 2: the baseline matches the CPU oracle, so the blackbody
/// radiance of the trilinear temperature adds to the emission grid's.
#[test]
fn blackbody_beside_an_emission_grid_matches_the_cpu_oracle() {
    let ctx = context();
    let text = r#"
[render]
width = 16
height = 12
spp = 4
frames = 32
seed = 11
[camera]
position = [0.3, 0.5, 2.4]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 60
[[light]]
type = "directional"
direction = [0.5, -0.7, -0.4]
irradiance = 1.0
[[medium]]
type = "grid"
bounds_min = [-1.0, -0.6, -1.0]
bounds_max = [1.0, 0.6, 1.0]
density = { procedural = "cloud", dims = [32, 20, 32], noise_seed = 3 }
density_scale = 16.0
albedo = 0.6
g = 0.3
emission = { procedural = "cloud", dims = [12, 8, 12], noise_seed = 9 }
emission_scale = [0.2, 0.5, 1.0]
temperature = { procedural = "cloud", dims = [16, 10, 16], noise_seed = 4 }
temperature_offset = 800.0
temperature_scale = 2500.0
blackbody_scale = 2e-4
[integrator]
volume = "baseline"
max_bounces = 2
"#;
    check_against_oracle(&ctx, &scene(text, "pyro-cloud.toml"), 8, "blackbody K=2");
}

/// Animated fire and colour (issue 27): `[[medium.frame]]` entries swap the temperature,
/// albedo and emission grids with the density. Frame k of the animation, rendered by the
/// baseline, is exactly the image of the static scene holding frame k's density and the
/// grids in effect then (frame 4 gives no temperature, so frame 2's holds; frame 2 no
/// albedo or emission, so the medium's hold), and a frame that changes only the
/// temperature changes the image. ReSTIR, which keeps one grid of each, refuses the
/// scene, naming the frame and the way out.
#[test]
fn temperature_frames_swap_the_fire_in_the_baseline() {
    let ctx = context();
    let cloud = |seed: u32| {
        format!("{{ procedural = \"cloud\", dims = [16, 10, 16], noise_seed = {seed} }}")
    };
    let text = format!(
        r#"
[render]
width = 16
height = 12
spp = 2
frames = 6
seed = 11
[camera]
position = [0.3, 0.5, 2.4]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 60
[[camera.keyframe]]
frame = 0
position = [0.3, 0.5, 2.4]
look_at = [0.0, 0.0, 0.0]
[[camera.keyframe]]
frame = 5
position = [0.35, 0.5, 2.4]
look_at = [0.0, 0.0, 0.0]
[[light]]
type = "environment"
radiance = 0.05
[[medium]]
type = "grid"
bounds_min = [-1.0, -0.6, -1.0]
bounds_max = [1.0, 0.6, 1.0]
density = {d0}
density_scale = 16.0
temperature = {t0}
temperature_offset = 800.0
temperature_scale = 2500.0
blackbody_scale = 2e-4
albedo = {a0}
emission = {e0}
emission_scale = [0.2, 0.1, 0.05]
[[medium.frame]]
frame = 2
density = {d0}
temperature = {t2}
[[medium.frame]]
frame = 4
density = {d4}
albedo = {a4}
emission = {e4}
[integrator]
volume = "baseline"
max_bounces = 2
"#,
        d0 = cloud(3),
        d4 = cloud(5),
        t0 = cloud(4),
        t2 = cloud(8),
        a0 = cloud(20),
        a4 = cloud(24),
        e0 = cloud(30),
        e4 = cloud(34),
    );
    let animated = scene(&text, "fire-frames.toml");
    let frame = |s: &nimbus_scene::Scene, f: u32| render_scene_frame(&ctx, s, f, 2).image;
    // The scene of frame k alone: its density and the temperature in effect, no frames
    // (the camera keyframes keep it animated, so frame k draws frame k's numbers).
    let single = |k: u32| {
        let mut s = animated.clone();
        if let nimbus_scene::Medium::Grid(g) = &mut s.media[0] {
            let index = g.density_index_at(k);
            let temperature = g.temperature_source_at_index(index).unwrap().clone();
            g.albedo_grid = g.albedo_source_at_index(index).cloned();
            g.emission = g.emission_source_at_index(index).cloned();
            g.density = g.density_at(k).clone();
            g.temperature.as_mut().unwrap().source = temperature;
            g.frames.clear();
        }
        assert!(s.is_animated());
        s
    };
    let images: Vec<_> = [0u32, 2, 4].iter().map(|&k| frame(&animated, k)).collect();
    for (i, k) in [0u32, 2, 4].into_iter().enumerate() {
        assert_eq!(images[i].data, frame(&single(k), k).data, "frame {k}");
    }
    // What the frames hold: frame 2 the base density with the second temperature, frame
    // 4 the second density with the second temperature still.
    let source = |s: &nimbus_scene::Scene| match &s.media[0] {
        nimbus_scene::Medium::Grid(g) => (
            g.density.clone(),
            g.temperature.as_ref().unwrap().source.clone(),
            g.albedo_grid.clone(),
            g.emission.clone(),
        ),
        _ => unreachable!(),
    };
    let (s0, s2, s4) = (source(&single(0)), source(&single(2)), source(&single(4)));
    assert_eq!(s2.1, s4.1, "frame 4 keeps frame 2's temperature");
    assert_ne!(s2.0, s4.0);
    assert_ne!(s2.1, s0.1);
    assert_eq!(
        (&s0.2, &s0.3),
        (&s2.2, &s2.3),
        "frame 2 keeps the medium's colour grids"
    );
    assert_ne!((&s2.2, &s2.3), (&s4.2, &s4.3), "frame 4 swaps them");
    assert_ne!(
        images[0].data, images[1].data,
        "frame 2 changes only the temperature"
    );

    let mut restir = animated.clone();
    restir.integrator.volume = nimbus_scene::VolumeIntegrator::Restir;
    restir.render.spp = 1;
    let err = nimbus::plan::build(&restir, None)
        .err()
        .map(|e| format!("{e:#}"))
        .unwrap_or_default();
    for part in [
        "fire-frames.toml",
        "[[medium.frame]] #1",
        "temperature",
        "volume = \"baseline\"",
    ] {
        assert!(err.contains(part), "{part:?} missing from: {err}");
    }
    crate::common::gpu::assert_no_validation_errors(&ctx);
}

/// A temperature whose blackbody outshines every radiometric input is refused when the
/// grid loads, naming the scene, the medium, the field and the voxel.
#[test]
fn a_blackbody_brighter_than_any_input_is_refused() {
    let ctx = context();
    let dir = scratch("pyro", "too-bright");
    let grid = constant_raw(&dir, "one.raw", [4, 4, 4], 1.0);
    let text = opaque_emitter("baseline", &grid, 1e6, 1e3);
    let scene = scene(&text, "too-bright.toml");
    let plan = nimbus::plan::build(&scene, None).expect("plan");
    let Err(err) = nimbus::renderer::render(
        &ctx,
        &scene,
        &plan,
        &nimbus::renderer::RenderOptions::default(),
    ) else {
        panic!("a blackbody of 1e6 K times 1e3 rendered");
    };
    let message = format!("{err:#}");
    for part in [
        "too-bright.toml",
        "[[medium]] #1 > temperature",
        "`blackbody_scale`",
        "1000000 K",
    ] {
        assert!(message.contains(part), "{part:?} missing from: {message}");
    }
}

#[test]
fn the_table_the_gpu_reads_agrees_with_this_integration() {
    let table = nimbus_scene::blackbody::BlackbodyTable::get();
    for kelvin in [
        450.0, 800.0, 1000.0, 1800.0, 2600.0, 6500.0, 12000.0, 40000.0,
    ] {
        let (got, want) = (table.rgb(kelvin), blackbody_by_simpson(kelvin));
        let err = (got - want).abs().max_element() / want.max_element();
        assert!(err < 2e-3, "{kelvin} K: {got} vs {want}");
    }
}

// ---------------------------------------------------------------------------------------
// Albedo grids (`albedo` given as a grid source).

/// Writes a `.vol` albedo grid of `dims` with one channel per seed: channel c is
/// 0.25 + 0.7 · (procedural cloud `seeds[c]`) / its maximum, in [0.25, 0.95].
pub(crate) fn albedo_vol(dir: &Path, name: &str, dims: [u32; 3], seeds: &[u64]) -> PathBuf {
    let clouds: Vec<Vec<f32>> = seeds
        .iter()
        .map(|&seed| {
            let cloud = nimbus_scene::procedural_cloud(dims, seed);
            let max = cloud.data.iter().fold(0.0f32, |a, &v| a.max(v));
            cloud.data.iter().map(|v| 0.25 + 0.7 * v / max).collect()
        })
        .collect();
    let grid = nimbus_scene::VoxelGrid {
        dims,
        channels: seeds.len() as u32,
        data: (0..clouds[0].len())
            .flat_map(|i| clouds.iter().map(move |c| c[i]))
            .collect(),
    };
    let path = dir.join(name);
    nimbus_scene::write_vol_encoded(
        &path,
        &grid,
        glam::Vec3::ZERO,
        glam::Vec3::ONE,
        nimbus_scene::VolEncoding::F32,
    )
    .expect("write albedo .vol");
    path
}

/// A cloud under a sun and a sky whose `albedo` is `albedo` (a TOML value), K = 3.
fn albedo_scene(albedo: &str, extra: &str) -> String {
    format!(
        r#"
[render]
width = 16
height = 12
spp = 4
frames = 32
seed = 11
[camera]
position = [0.3, 0.5, 2.4]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 60
{CLOUD_SUN_AND_SKY}
[[medium]]
type = "grid"
{CLOUD_BOUNDS}
density = {{ procedural = "cloud", dims = [32, 20, 32], noise_seed = 3 }}
density_scale = 16.0
albedo = {albedo}
g = 0.3
{extra}
[integrator]
volume = "baseline"
max_bounces = 3
"#
    )
}

/// An rgb albedo grid renders, channel by channel, as the three grey grids of its
/// channels: the baseline's image of channel c with the rgb grid agrees with channel c
/// of the render with grey grid c.
#[test]
fn an_rgb_albedo_grid_renders_as_three_grey_ones() {
    use crate::common::gpu::{assert_means_agree, channels_beyond};
    let ctx = context();
    let dir = scratch("pyro", "albedo-rgb");
    let dims = [12, 8, 12];
    let seeds = [21, 22, 23];
    let rgb_path = albedo_vol(&dir, "rgb.vol", dims, &seeds);
    let table = |p: &Path| format!("{{ file = {:?} }}", p.display().to_string());
    let rgb = render_checked(
        &ctx,
        &scene(&albedo_scene(&table(&rgb_path), ""), "rgb.toml"),
        None,
    );
    let (mut grey, mut grey_se) = (rgb.image.clone(), rgb.std_error.clone());
    let mut max_diff = 0.0f32;
    for (c, seed) in seeds.iter().enumerate() {
        let path = albedo_vol(&dir, &format!("grey{c}.vol"), dims, &[*seed]);
        let one = render_checked(
            &ctx,
            &scene(&albedo_scene(&table(&path), ""), "grey.toml"),
            None,
        );
        for (i, px) in one.image.data.iter().enumerate() {
            grey.data[i][c] = px[c];
            grey_se.data[i][c] = one.std_error.data[i][c];
            max_diff = max_diff.max((px[c] - rgb.image.data[i][c]).abs());
        }
    }
    println!("largest pixel difference {max_diff:e}");
    let (a, b) = ((&rgb.image, &rgb.std_error), (&grey, &grey_se));
    assert_means_agree("rgb albedo vs three grey", a, b, 4.0, 0.01);
    let beyond = channels_beyond(a, b, 4.5);
    assert!(
        beyond * 50 <= 3 * grey.data.len(),
        "{beyond} channels beyond 4.5 SE"
    );
}

/// An rgb albedo grid with an emission grid (absorbed emission (1 − albedo(x))·Le) under
/// a sun and a sky, K = 3: the baseline matches the CPU oracle.
#[test]
fn an_rgb_albedo_grid_matches_the_cpu_oracle() {
    let ctx = context();
    let dir = scratch("pyro", "albedo-oracle");
    let path = albedo_vol(&dir, "rgb.vol", [12, 8, 12], &[31, 32, 33]);
    let text = albedo_scene(
        &format!("{{ file = {:?} }}", path.display().to_string()),
        "emission = { procedural = \"cloud\", dims = [12, 8, 12], noise_seed = 9 }\n\
         emission_scale = [1.0, 0.6, 0.3]",
    );
    check_against_oracle(
        &ctx,
        &scene(&text, "albedo-grid.toml"),
        8,
        "albedo grid K=3",
    );
}

/// An albedo grid with a value above 1 is refused when it loads, naming the scene, the
/// medium, the field and the value.
#[test]
fn an_albedo_above_one_is_refused() {
    let ctx = context();
    let dir = scratch("pyro", "albedo-above-one");
    let path = constant_raw(&dir, "albedo.raw", [4, 4, 4], 1.25);
    let text = albedo_scene(
        &format!(
            "{{ file = {:?}, dims = [4, 4, 4] }}",
            path.display().to_string()
        ),
        "",
    );
    let scene = scene(&text, "albedo-above-one.toml");
    let plan = nimbus::plan::build(&scene, None).expect("plan");
    let Err(err) = nimbus::renderer::render(
        &ctx,
        &scene,
        &plan,
        &nimbus::renderer::RenderOptions::default(),
    ) else {
        panic!("an albedo of 1.25 rendered");
    };
    let message = format!("{err:#}");
    for part in [
        "albedo-above-one.toml",
        "[[medium]] #1 > albedo",
        "1.25",
        "[0, 1]",
    ] {
        assert!(message.contains(part), "{part:?} missing from: {message}");
    }
}
