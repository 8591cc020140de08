//! The output layers (AOVs, issue 28 item 1) against what is known of their scenes, in the
//! baseline path tracer and the crepuscular box pass: depth, normal and albedo of a quad
//! and of an opaque box medium, the depth of the half-transmittance point of a constant
//! grid, light groups and emission + direct + indirect summing to RGB per pixel, motion
//! of a dollying and panning camera against the analytic reprojection; and the scene and
//! command-line refusals.

use std::path::Path;

use glam::Vec3;
use nimbus::output::layers::{find_channel, read_layers};
use nimbus::plan;
use nimbus::renderer::{render, FrameSelection, RenderOptions, RenderResult};
use nimbus_gpu::Context;
use nimbus_scene::Scene;

use crate::common::cli::{nimbus, scratch, text};
use crate::common::gpu::{assert_no_validation_errors, context};

/// A grid medium far behind the camera (the baseline needs one; no ray meets it).
const FAR_GRID: &str = r#"[[medium]]
type = "grid"
bounds_min = [40.0, 40.0, 40.0]
bounds_max = [41.0, 41.0, 41.0]
density = { procedural = "cloud", dims = [4, 4, 4] }
density_scale = 1.0
[integrator]
volume = "baseline""#;

/// The camera 5 m in front of the origin looking down -Z, 60° wide, 16 x 12 pixels.
const CAMERA: &str = r#"[camera]
position = [0.0, 0.0, 5.0]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 60"#;

/// A 20 m quad in the plane z = `z`, facing +Z (the camera), of `albedo`.
fn wall(z: f32, albedo: &str) -> String {
    format!(
        "[[shape]]\ntype = \"quad\"\ncorner = [-10.0, -10.0, {z}]\nedge_u = [20.0, 0.0, 0.0]\n\
         edge_v = [0.0, 20.0, 0.0]\nalbedo = {albedo}"
    )
}

fn render_header(aovs: &str, frames: u32, spp: u32) -> String {
    format!(
        "[render]\nwidth = 16\nheight = 12\nframes = {frames}\nspp = {spp}\naovs = {aovs}\n{CAMERA}\n\
         [[light]]\ntype = \"directional\"\ndirection = [0.3, -0.5, -1.0]\nirradiance = 1.5"
    )
}

fn scene_of(text: &str, name: &str) -> Scene {
    nimbus_scene::parse_str(text, Path::new(name)).unwrap_or_else(|e| panic!("{e:#}"))
}

fn run(ctx: &Context, scene: &Scene, frames: FrameSelection) -> RenderResult {
    let plan = plan::build(scene, None).expect("plan");
    let opts = RenderOptions {
        frames,
        ..RenderOptions::default()
    };
    let result = render(ctx, scene, &plan, &opts).expect("render");
    assert_no_validation_errors(ctx);
    assert_eq!(result.non_finite_samples, 0);
    result
}

fn channel<'a>(result: &'a RenderResult, name: &str) -> &'a [f32] {
    find_channel(&result.aovs, name).unwrap_or_else(|| {
        let names: Vec<String> = result
            .aovs
            .iter()
            .flat_map(|a| a.channels.iter().map(|(c, _)| a.channel_name(c)))
            .collect();
        panic!("no AOV channel {name}; the render has {names:?}")
    })
}

/// The unit direction of pixel (x, y)'s centre ray, as camera.glsl computes it.
pub(crate) fn centre_ray(scene: &Scene, frame: u32, x: u32, y: u32) -> (Vec3, Vec3) {
    let c = scene.camera.frame_at(frame);
    let (w, h) = (scene.render.width as f32, scene.render.height as f32);
    let tan_y = c.tan_half_fov_x * h / w;
    let sx = (2.0 * (x as f32 + 0.5) / w - 1.0) * c.tan_half_fov_x;
    let sy = (1.0 - 2.0 * (y as f32 + 0.5) / h) * tan_y;
    (
        c.position,
        (c.forward + sx * c.right + sy * c.up).normalize(),
    )
}

/// Pixel position of `p` seen by the camera of `frame`.
fn project(scene: &Scene, frame: u32, p: Vec3) -> [f32; 2] {
    let c = scene.camera.frame_at(frame);
    let (w, h) = (scene.render.width as f32, scene.render.height as f32);
    let tan_y = c.tan_half_fov_x * h / w;
    let v = p - c.position;
    let z = v.dot(c.forward);
    let sx = v.dot(c.right) / (z * c.tan_half_fov_x);
    let sy = v.dot(c.up) / (z * tan_y);
    [(sx + 1.0) * 0.5 * w, (1.0 - sy) * 0.5 * h]
}

fn close(a: f32, b: f32, rel: f32) -> bool {
    (a - b).abs() <= rel * b.abs().max(1e-3)
}

/// Z, N and albedo of every pixel: `expect(x, y)` gives (Z, N, albedo) or None to skip.
fn check_geometry(
    what: &str,
    result: &RenderResult,
    scene: &Scene,
    expect: impl Fn(u32, u32) -> Option<(f32, Vec3, Vec3)>,
) {
    let w = scene.render.width;
    let (z, nx, ny, nz) = (
        channel(result, "Z"),
        channel(result, "N.X"),
        channel(result, "N.Y"),
        channel(result, "N.Z"),
    );
    let (ar, ag, ab) = (
        channel(result, "albedo.R"),
        channel(result, "albedo.G"),
        channel(result, "albedo.B"),
    );
    let mut checked = 0;
    for y in 0..scene.render.height {
        for x in 0..w {
            let Some((z_want, n_want, a_want)) = expect(x, y) else {
                continue;
            };
            let i = (y * w + x) as usize;
            assert!(
                close(z[i], z_want, 0.01),
                "{what}: Z at ({x}, {y}) is {}, expected {z_want}",
                z[i]
            );
            let n = Vec3::new(nx[i], ny[i], nz[i]);
            assert!(
                (n - n_want).length() < 0.01,
                "{what}: N at ({x}, {y}) is {n}, expected {n_want}"
            );
            let a = Vec3::new(ar[i], ag[i], ab[i]);
            assert!(
                (a - a_want).abs().max_element() <= 0.01 * a_want.max_element().max(1e-3),
                "{what}: albedo at ({x}, {y}) is {a}, expected {a_want}"
            );
            checked += 1;
        }
    }
    assert!(checked > 20, "{what}: only {checked} pixels checked");
}

#[test]
fn quad_depth_normal_and_albedo_are_exact_in_both_integrators() {
    let ctx = context();
    for (integrator, extra) in [("baseline", FAR_GRID), ("crepuscular", "")] {
        let text = format!(
            "{}\n{}\n{extra}\n",
            render_header("[\"depth\", \"normal\", \"albedo\"]", 1, 1),
            wall(0.0, "[0.2, 0.4, 0.6]")
        );
        let scene = scene_of(&text, "quad.toml");
        let result = run(&ctx, &scene, FrameSelection::Mean);
        // The plane z = 0 is perpendicular to the view: depth 5 along the view axis at
        // every pixel.
        check_geometry(integrator, &result, &scene, |_, _| {
            Some((5.0, Vec3::Z, Vec3::new(0.2, 0.4, 0.6)))
        });
        // Only what was asked for is written.
        assert!(find_channel(&result.aovs, "motion.X").is_none());
        assert!(find_channel(&result.aovs, "direct.R").is_none());
    }
}

#[test]
fn opaque_box_medium_depth_normal_and_albedo() {
    let ctx = context();
    for (integrator, extra) in [("baseline", FAR_GRID), ("crepuscular", "")] {
        let text = format!(
            "{}\n{}\n[[medium]]\ntype = \"box\"\ncenter = [0.0, 0.0, 0.0]\nsize = [2.0, 2.0, 2.0]\n\
             sigma_t = 500.0\nalbedo = [0.3, 0.6, 0.9]\n{extra}\n",
            render_header("[\"depth\", \"normal\", \"albedo\"]", 1, 1),
            wall(-3.0, "0.5")
        );
        let scene = scene_of(&text, "opaque.toml");
        let result = run(&ctx, &scene, FrameSelection::Mean);
        let forward = scene.camera.frame_at(0).forward;
        check_geometry(integrator, &result, &scene, |x, y| {
            let (o, d) = centre_ray(&scene, 0, x, y);
            // The front face z = 1; transmittance 0.5 at ln 2 / sigma_t inside.
            let t = (1.0 - o.z) / d.z;
            let p = o + t * d;
            if p.x.abs() > 0.95 || p.y.abs() > 0.95 {
                // The wall behind, away from the box's edges.
                let t_wall = (-3.0 - o.z) / d.z;
                let q = o + t_wall * d;
                let hidden = q.x.abs() < 1.6 && q.y.abs() < 1.6;
                return (!hidden).then(|| (8.0, Vec3::Z, Vec3::splat(0.5)));
            }
            let z = (t + std::f32::consts::LN_2 / 500.0) * d.dot(forward);
            Some((z, Vec3::Z, Vec3::new(0.3, 0.6, 0.9)))
        });
    }
}

#[test]
fn grid_depth_at_half_transmittance_and_normal_against_the_gradient() {
    let ctx = context();
    let dir = scratch("aovs", "constant_grid");
    let ones: Vec<u8> = [1.0f32; 8].iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(dir.join("ones.raw"), ones).unwrap();
    let sigma = 3.0f32;
    let text = format!(
        "{}\n{}\n[[medium]]\ntype = \"grid\"\nbounds_min = [-1.0, -1.0, -1.0]\n\
         bounds_max = [1.0, 1.0, 1.0]\ndensity = {{ file = \"ones.raw\", dims = [2, 2, 2] }}\n\
         density_scale = {sigma}\nalbedo = [0.7, 0.8, 0.9]\n[integrator]\nvolume = \"baseline\"\n",
        render_header("[\"depth\", \"albedo\"]", 1, 1),
        wall(-3.0, "0.5")
    );
    let path = dir.join("grid.toml");
    std::fs::write(&path, text).unwrap();
    let scene = nimbus_scene::load(&path).unwrap_or_else(|e| panic!("{e:#}"));
    let result = run(&ctx, &scene, FrameSelection::Mean);
    let forward = scene.camera.frame_at(0).forward;
    let (z, ar) = (channel(&result, "Z"), channel(&result, "albedo.R"));
    let mut checked = 0;
    for y in 0..12 {
        for x in 0..16 {
            let (o, d) = centre_ray(&scene, 0, x, y);
            let t = (1.0 - o.z) / d.z;
            let p = o + t * d;
            // Pixels whose ray stays in the grid for more than ln 2 / sigma.
            if p.x.abs() > 0.7 || p.y.abs() > 0.7 {
                continue;
            }
            let want = (t + std::f32::consts::LN_2 / sigma) * d.dot(forward);
            let i = (y * 16 + x) as usize;
            assert!(
                close(z[i], want, 0.01),
                "Z at ({x}, {y}): {} vs {want}",
                z[i]
            );
            assert!(close(ar[i], 0.7, 0.01), "albedo.R at ({x}, {y}): {}", ar[i]);
            checked += 1;
        }
    }
    assert!(checked > 10);

    // A density rising along +x: the normal is the negative gradient, -x.
    let ramp: Vec<u8> = (0..8)
        .flat_map(|v| (1.0f32 + 2.0 * (v % 2) as f32).to_le_bytes())
        .collect();
    std::fs::write(dir.join("ramp.raw"), ramp).unwrap();
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("ones.raw", "ramp.raw")
        .replace("[\"depth\", \"albedo\"]", "[\"normal\"]");
    std::fs::write(&path, text).unwrap();
    let scene = nimbus_scene::load(&path).unwrap_or_else(|e| panic!("{e:#}"));
    let result = run(&ctx, &scene, FrameSelection::Mean);
    let (nx, ny, nz) = (
        channel(&result, "N.X"),
        channel(&result, "N.Y"),
        channel(&result, "N.Z"),
    );
    let mut checked = 0;
    for y in 0..12 {
        for x in 0..16 {
            let (o, d) = centre_ray(&scene, 0, x, y);
            let p = o + ((1.0 - o.z) / d.z) * d;
            // Where the ramp's trilinear field rises (between the two voxel centres).
            if p.x.abs() > 0.3 || p.y.abs() > 0.7 {
                continue;
            }
            let i = (y * 16 + x) as usize;
            let n = Vec3::new(nx[i], ny[i], nz[i]);
            assert!((n - Vec3::NEG_X).length() < 0.01, "N at ({x}, {y}): {n}");
            checked += 1;
        }
    }
    assert!(checked > 4, "{checked}");
}

/// Per pixel and channel, |Σ parts − RGB| within float rounding of their magnitudes.
fn assert_sums_to_rgb(what: &str, result: &RenderResult, layers: &[String]) {
    let n = result.image.data.len();
    for (c, ch) in ["R", "G", "B"].into_iter().enumerate() {
        let parts: Vec<&[f32]> = layers
            .iter()
            .map(|l| channel(result, &format!("{l}.{ch}")))
            .collect();
        for i in 0..n {
            let rgb = result.image.data[i][c];
            let sum: f32 = parts.iter().map(|p| p[i]).sum();
            let scale: f32 = parts.iter().map(|p| p[i].abs()).sum::<f32>() + rgb.abs();
            assert!(
                (sum - rgb).abs() <= 1e-5 * scale + 1e-7,
                "{what}: pixel {i} channel {ch}: the layers {layers:?} sum to {sum}, RGB is {rgb}"
            );
        }
    }
}

/// The mean of a layer's channel R over the image.
fn mean_of(result: &RenderResult, name: &str) -> f64 {
    let v = channel(result, name);
    v.iter().map(|x| f64::from(*x)).sum::<f64>() / v.len() as f64
}

#[test]
fn light_groups_and_path_layers_sum_to_rgb() {
    let ctx = context();
    // 40 samples per pixel: on lavapipe a frame's samples are shared among dispatches
    // (the loop budget), so the partial sums must carry the AOVs too.
    let baseline = format!(
        "[render]\nwidth = 16\nheight = 12\nframes = 2\nspp = 40\naovs = [\"all\"]\n{}\n\
         [[light]]\ntype = \"directional\"\ndirection = [0.3, -0.8, -0.4]\nirradiance = 2.0\ngroup = \"key\"\n\
         [[light]]\ntype = \"point\"\nposition = [-1.5, 2.0, 1.0]\nintensity = 3.0\ngroup = \"fill\"\n\
         [[light]]\ntype = \"environment\"\nradiance = [0.2, 0.3, 0.5]\n\
         {}\n{}\n[integrator]\nmax_bounces = 3\nvolume = \"baseline\"\n",
        crate::common::scenes::LOW_CLOUD_CAMERA,
        crate::common::scenes::LOW_CLOUD,
        crate::common::scenes::LOW_CLOUD_FLOOR,
    );
    let crepuscular = format!(
        "[render]\nwidth = 16\nheight = 12\nframes = 3\nspp = 2\naovs = [\"all\"]\n{CAMERA}\n\
         [[light]]\ntype = \"directional\"\ndirection = [0.3, -0.8, -0.4]\nirradiance = 2.0\ngroup = \"key\"\n\
         [[light]]\ntype = \"directional\"\ndirection = [-0.5, -0.6, -0.3]\nirradiance = 1.0\ngroup = \"fill\"\n\
         [[light]]\ntype = \"environment\"\nradiance = [0.2, 0.3, 0.5]\n\
         [[medium]]\ntype = \"box\"\ncenter = [0.0, 0.0, 0.0]\nsize = [2.0, 1.5, 1.0]\nsigma_t = 1.2\nalbedo = 0.8\n\
         [[shape]]\ntype = \"quad\"\ncorner = [-3.0, -1.0, -3.0]\nedge_u = [0.0, 0.0, 6.0]\n\
         edge_v = [6.0, 0.0, 0.0]\nalbedo = 0.6\n[integrator]\nmax_bounces = 3\n",
    );
    for (integrator, text) in [("baseline", baseline), ("crepuscular", crepuscular)] {
        let scene = scene_of(&text, "groups.toml");
        let result = run(&ctx, &scene, FrameSelection::Mean);
        let groups: Vec<String> = ["key", "fill", "default"]
            .iter()
            .map(|g| format!("lightgroup.{g}"))
            .collect();
        assert_sums_to_rgb(integrator, &result, &groups);
        let paths: Vec<String> = ["emission", "direct", "indirect"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        assert_sums_to_rgb(integrator, &result, &paths);
        // Each part carries light: the sky is seen directly, both lights scatter once
        // and more than once.
        for layer in [
            "emission.B",
            "direct.R",
            "indirect.R",
            "lightgroup.key.R",
            "lightgroup.fill.R",
            "lightgroup.default.B",
        ] {
            assert!(
                mean_of(&result, layer) > 0.0,
                "{integrator}: {layer} is black"
            );
        }
        // Standard errors come with the estimates.
        assert!(mean_of(&result, "direct_stderr.R") > 0.0, "{integrator}");
    }
}

#[test]
fn motion_of_a_dollying_and_panning_camera_is_the_analytic_reprojection() {
    let ctx = context();
    let camera = r#"[camera]
horizontal_fov_deg = 60
[[camera.keyframe]]
frame = 0
position = [0.0, 0.0, 5.0]
look_at = [0.0, 0.0, 0.0]
[[camera.keyframe]]
frame = 1
position = [0.4, 0.2, 4.2]
look_at = [0.5, -0.1, 0.0]"#;
    for (integrator, extra) in [("baseline", FAR_GRID), ("crepuscular", "")] {
        let text = format!(
            "[render]\nwidth = 16\nheight = 12\nframes = 2\naovs = [\"motion\", \"depth\"]\n{camera}\n\
             [[light]]\ntype = \"directional\"\ndirection = [0.3, -0.5, -1.0]\nirradiance = 1.5\n{}\n{extra}\n",
            wall(0.0, "0.5")
        );
        let scene = scene_of(&text, "motion.toml");
        for frame in [0u32, 1] {
            let result = run(
                &ctx,
                &scene,
                FrameSelection::Each {
                    frames: vec![frame],
                    passes: 1,
                },
            );
            let (mx, my) = (channel(&result, "motion.X"), channel(&result, "motion.Y"));
            let mut largest = 0.0f32;
            for y in 0..12u32 {
                for x in 0..16u32 {
                    let i = (y * 16 + x) as usize;
                    let want = if frame == 0 {
                        [0.0, 0.0]
                    } else {
                        let (o, d) = centre_ray(&scene, 1, x, y);
                        let p = o + (-o.z / d.z) * d;
                        let before = project(&scene, 0, p);
                        [x as f32 + 0.5 - before[0], y as f32 + 0.5 - before[1]]
                    };
                    largest = largest.max(want[0].abs().max(want[1].abs()));
                    assert!(
                        (mx[i] - want[0]).abs() < 0.01 * want[0].abs().max(1.0)
                            && (my[i] - want[1]).abs() < 0.01 * want[1].abs().max(1.0),
                        "{integrator} frame {frame}: motion at ({x}, {y}) is ({}, {}), \
                         expected {want:?}",
                        mx[i],
                        my[i]
                    );
                }
            }
            if frame == 1 {
                assert!(largest > 2.0, "the camera barely moved: {largest} px");
            }
        }
    }
}

#[test]
fn a_bad_aov_name_or_light_group_is_refused_naming_the_field() {
    let bad = format!("[render]\naovs = [\"depth\", \"velocity\"]\n{CAMERA}\n");
    let e = format!(
        "{:#}",
        nimbus_scene::parse_str(&bad, Path::new("bad-aovs.toml")).unwrap_err()
    );
    for needle in [
        "bad-aovs.toml",
        "[render]",
        "`aovs`",
        "\"velocity\"",
        "\"depth\"",
        "\"all\"",
    ] {
        assert!(e.contains(needle), "{needle:?} not in: {e}");
    }
    let not_array = format!("[render]\naovs = \"depth\"\n{CAMERA}\n");
    let e = format!(
        "{:#}",
        nimbus_scene::parse_str(&not_array, Path::new("a.toml")).unwrap_err()
    );
    assert!(e.contains("`aovs`") && e.contains("array"), "{e}");
    let bad_group = format!(
        "{CAMERA}\n[[light]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = 1.0\ngroup = \"a.b\"\n"
    );
    let e = format!(
        "{:#}",
        nimbus_scene::parse_str(&bad_group, Path::new("g.toml")).unwrap_err()
    );
    assert!(
        e.contains("g.toml") && e.contains("`group`") && e.contains("a.b"),
        "{e}"
    );
    let mut many = CAMERA.to_string();
    for g in 0..9 {
        many += &format!(
            "\n[[light]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = 1.0\ngroup = \"g{g}\""
        );
    }
    let e = format!(
        "{:#}",
        nimbus_scene::parse_str(&many, Path::new("many.toml")).unwrap_err()
    );
    assert!(
        e.contains("many.toml") && e.contains("`group`") && e.contains("g7"),
        "{e}"
    );
}

#[test]
fn the_command_line_writes_aov_layers_only_when_asked() {
    let dir = scratch("aovs", "cli");
    let scene = dir.join("quad.toml");
    std::fs::write(
        &scene,
        format!("{}\n{}\n", render_header("[]", 1, 1), wall(0.0, "0.5")),
    )
    .unwrap();
    let plain = dir.join("plain.exr");
    let out = nimbus(&[
        "render",
        scene.to_str().unwrap(),
        "--out",
        plain.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(read_layers(&plain).unwrap().aovs.is_empty());

    let with = dir.join("with.exr");
    let out = nimbus(&[
        "render",
        scene.to_str().unwrap(),
        "--aovs",
        "depth,normal,direct",
        "--out",
        with.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let layers = read_layers(&with).unwrap();
    for name in ["Z", "N.X", "N.Y", "N.Z", "direct.R", "direct_stderr.B"] {
        assert!(find_channel(&layers.aovs, name).is_some(), "no {name}");
    }
    assert!(find_channel(&layers.aovs, "albedo.R").is_none());
    let z = find_channel(&layers.aovs, "Z").unwrap();
    assert!(z.iter().all(|v| (v - 5.0).abs() < 0.05), "{z:?}");

    let out = nimbus(&[
        "render",
        scene.to_str().unwrap(),
        "--aovs",
        "depth,speed",
        "--out",
        with.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert!(
        err.contains("--aovs") && err.contains("\"speed\"") && err.contains("\"motion\""),
        "{err}"
    );

    let png = dir.join("x.png");
    let out = nimbus(&[
        "render",
        scene.to_str().unwrap(),
        "--aovs",
        "depth",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert!(err.contains("x.png") && err.contains(".exr"), "{err}");
    assert!(!png.exists());

    let out = nimbus(&[
        "render",
        scene.to_str().unwrap(),
        "--aovs",
        "depth,lightgroups",
        "--explain",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let explain = text(&out.stdout);
    assert!(
        explain.contains("output layers (AOVs)") && explain.contains("lightgroup.default"),
        "{explain}"
    );
}

#[test]
fn merge_weights_path_layers_like_the_beauty_and_keeps_the_first_geometry() {
    let dir = scratch("aovs", "merge");
    let scene = dir.join("box.toml");
    std::fs::write(
        &scene,
        format!(
            "{}\n{}\n[[medium]]\ntype = \"box\"\ncenter = [0.0, 0.0, 0.0]\nsize = [2.0, 1.5, 1.0]\n\
             sigma_t = 1.2\nalbedo = 0.8\n",
            render_header("[\"depth\", \"albedo\", \"direct\", \"lightgroups\"]", 2, 1),
            wall(-1.0, "0.6")
        ),
    )
    .unwrap();
    let part = |seed: &str, spp: &str| {
        let exr = dir.join(format!("part{seed}.exr"));
        let out = nimbus(&[
            "render",
            scene.to_str().unwrap(),
            "--seed",
            seed,
            "--spp",
            spp,
            "--out",
            exr.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        exr
    };
    let (a, b) = (part("1", "1"), part("2", "3"));
    let merged = dir.join("merged.exr");
    let out = nimbus(&[
        "merge",
        "--out",
        merged.to_str().unwrap(),
        a.to_str().unwrap(),
        b.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let (la, lb, lm) = (
        read_layers(&a).unwrap(),
        read_layers(&b).unwrap(),
        read_layers(&merged).unwrap(),
    );
    // Samples 2 x 1 and 2 x 3: weights 1/4 and 3/4.
    let get = |l: &nimbus::output::layers::Layers, name: &str| -> Vec<f32> {
        find_channel(&l.aovs, name)
            .unwrap_or_else(|| panic!("no {name}"))
            .to_vec()
    };
    for name in ["direct.R", "lightgroup.default.G"] {
        let (x, y, m) = (get(&la, name), get(&lb, name), get(&lm, name));
        for i in 0..m.len() {
            let want = 0.25 * x[i] + 0.75 * y[i];
            assert!(
                (m[i] - want).abs() <= 1e-5 * want.abs() + 1e-7,
                "{name} {i}"
            );
        }
    }
    let (x, y, m) = (
        get(&la, "direct_stderr.R"),
        get(&lb, "direct_stderr.R"),
        get(&lm, "direct_stderr.R"),
    );
    for i in 0..m.len() {
        let want = ((0.25 * x[i]).powi(2) + (0.75 * y[i]).powi(2)).sqrt();
        assert!((m[i] - want).abs() <= 1e-5 * want + 1e-7, "stderr {i}");
    }
    assert_eq!(get(&lm, "Z"), get(&la, "Z"));
    assert_eq!(get(&lm, "albedo.B"), get(&la, "albedo.B"));
    // The geometric layers do not depend on the seed.
    assert_eq!(get(&la, "Z"), get(&lb, "Z"));
}
