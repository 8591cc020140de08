//! Hard cases: every numeric field class at and just inside its limits renders a right
//! image or is refused, before any GPU allocation, with a message naming the file, the
//! table and the field. "Right" is checked against an analytic twin (the box medium's
//! exact single scattering, or a sum of separately rendered lights), never just "finite".
//!
//! The rule behind the limits is `nimbus_scene::precision`: f32 positions resolve a
//! scene reaching R metres from the origin to R·2⁻²³; features must span 256 of those
//! and extinctions where light enters a medium must keep σt·R·2⁻²³ ≤ 1/256.

use std::path::Path;

use nimbus::output::ImageRgb;
use nimbus::plan;
use nimbus::renderer::{render, RenderOptions, RenderResult};
use nimbus_gpu::Context;
use nimbus_scene::Scene;

use crate::common::cli::{nimbus, scratch, text};
use crate::common::gpu::{assert_no_validation_errors, context, se_of_mean};

const FILE: &str = "hard/scene.toml";

/// A unit cube medium at the origin under a sun, seen from 3 m; `medium` is its table
/// body after `[[medium]]`, `extra` more tables. 2 spp, or 1 where `extra` picks ReSTIR
/// (one path per pixel per frame).
fn cube_scene(medium: &str, extra: &str) -> String {
    let spp = if extra.contains("volume = \"restir\"") {
        1
    } else {
        2
    };
    format!(
        r#"
[render]
width = 24
height = 24
frames = 16
spp = {spp}
pixel_jitter = false
[camera]
position = [0.3, 0.8, 3.0]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 50
[[light]]
type = "directional"
direction = [0.5, -1.0, -0.3]
irradiance = 5.0
[[medium]]
{medium}
{extra}
"#
    )
}

fn box_medium(sigma_t: &str, g: &str) -> String {
    format!(
        "type = \"box\"\ncenter = [0, 0, 0]\nsize = [1, 1, 1]\nsigma_t = {sigma_t}\nalbedo = 0.8\ng = {g}"
    )
}

/// A uniform grid (2³ voxels of 1.0) filling the same cube as [`box_medium`].
fn uniform_grid(dir: &Path, scale: &str, g: &str) -> String {
    let raw = dir.join("ones2.raw");
    let bytes: Vec<u8> = [1.0f32; 8].iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(&raw, bytes).unwrap();
    format!(
        "type = \"grid\"\nbounds_min = [-0.5, -0.5, -0.5]\nbounds_max = [0.5, 0.5, 0.5]\n\
         density = {{ file = \"{}\", dims = [2, 2, 2] }}\ndensity_scale = {scale}\nalbedo = 0.8\ng = {g}",
        raw.display()
    )
}

/// The scene parsed, or the refusal's message.
fn parse(text: &str) -> Result<Scene, String> {
    nimbus_scene::parse_str(text, Path::new(FILE)).map_err(|e| format!("{e:#}"))
}

/// Plans and renders `scene`; a refusal (plan or render) is returned as its message.
fn try_render(ctx: &Context, scene: &Scene) -> Result<RenderResult, String> {
    let plan = plan::build(scene, None).map_err(|e| format!("{e:#}"))?;
    let result =
        render(ctx, scene, &plan, &RenderOptions::default()).map_err(|e| format!("{e:#}"))?;
    assert_no_validation_errors(ctx);
    assert_eq!(result.non_finite_samples, 0, "non-finite samples");
    assert_eq!(result.step_cap_hits, 0, "walks stopped at the step limit");
    assert!(result.image.first_non_finite().is_none());
    Ok(result)
}

/// A refusal names the file, the table and the field.
fn assert_names(message: &str, table: &str, field: &str) {
    assert!(
        message.contains(FILE)
            && message.contains(table)
            && message.contains(&format!("`{field}`")),
        "the message should name {FILE}, {table} and `{field}`: {message}"
    );
}

fn mean(image: &ImageRgb) -> f64 {
    image.mean()[0]
}

/// |a − b| within `k` combined standard errors plus `rel` of b.
fn assert_agree(what: &str, a: &RenderResult, b: &RenderResult, k: f64, rel: f64) {
    let (ma, mb) = (mean(&a.image), mean(&b.image));
    let se = (se_of_mean(&a.std_error).powi(2) + se_of_mean(&b.std_error).powi(2)).sqrt();
    assert!(
        (ma - mb).abs() <= k * se + rel * mb.abs(),
        "{what}: {ma} vs {mb} (combined SE {se})"
    );
}

/// A uniform grid renders like the same medium as a box (whose single scattering is
/// exact with one MCWVDS sample on pixel-centre rays) across σt = 1e-2 … the largest
/// the scene resolves, with both grid integrators; beyond it, box and grid are refused
/// naming `sigma_t` / `density_scale`. Thinner grids are unbiased but need ~1/τ samples
/// to see a collision at all (decomposition tracking and ReSTIR's regular tracking both
/// sample free flights), so below 1e-2 this checks finiteness only; the box pass itself
/// is checked down to 1e-6 against the f64 oracle in `render_box`.
#[test]
fn uniform_grids_match_the_box_twin_up_to_the_resolvable_extinction() {
    let ctx = context();
    let dir = scratch("hard_cases", "uniform");
    let limit = parse(&cube_scene(&box_medium("1", "0"), ""))
        .unwrap()
        .position_scale()
        .max_sigma_t();
    for sigma in [1e-6, 1e-2, 1.0, 30.0, 1e3, 0.9 * limit] {
        let s = format!("{sigma:e}");
        let twin = try_render(&ctx, &parse(&cube_scene(&box_medium(&s, "0"), "")).unwrap())
            .unwrap_or_else(|e| panic!("box sigma_t {s}: {e}"));
        for volume in ["baseline", "restir"] {
            let text = cube_scene(
                &uniform_grid(&dir, &s, "0"),
                // Independent frames (no temporal reuse): the per-pixel standard errors
                // then measure the real noise.
                &format!(
                    "[integrator]\nvolume = \"{volume}\"\n[integrator.restir]\ntemporal = false\nspatial_neighbors = 0"
                ),
            );
            let grid = try_render(&ctx, &parse(&text).unwrap())
                .unwrap_or_else(|e| panic!("{volume} sigma_t {s}: {e}"));
            if sigma >= 1e-2 {
                assert_agree(&format!("{volume} at sigma_t {s}"), &grid, &twin, 4.5, 0.01);
            }
        }
    }
    for sigma in [1.2 * limit, 1e6, 1e9] {
        let s = format!("{sigma:e}");
        let e = parse(&cube_scene(&box_medium(&s, "0"), "")).unwrap_err();
        assert_names(&e, "[[medium]] #1", "sigma_t");
        let e = try_render(
            &ctx,
            &parse(&cube_scene(
                &uniform_grid(&dir, &s, "0"),
                "[integrator]\nvolume = \"baseline\"",
            ))
            .unwrap(),
        )
        .err()
        .unwrap_or_else(|| panic!("grid at sigma_t {s} was accepted"));
        assert!(e.contains(FILE) && e.contains("density_scale"), "{e}");
    }
}

/// Values validated in f64 but used in f32: what rounds onto a limit is refused.
#[test]
fn values_that_round_onto_a_limit_in_f32_are_refused() {
    let cases = [
        (
            "horizontal_fov_deg = 50",
            "horizontal_fov_deg = 179.999999999",
            "[camera]",
            "horizontal_fov_deg",
        ),
        ("g = 0", "g = 0.99999999", "[[medium]] #1", "g"),
        ("g = 0", "g = -0.99999999", "[[medium]] #1", "g"),
        (
            "size = [1, 1, 1]",
            "size = [1, 1e-46, 1]",
            "[[medium]] #1",
            "size",
        ),
    ];
    for (from, to, table, field) in cases {
        let text = cube_scene(&box_medium("1", "0"), "").replace(from, to);
        assert_ne!(text, cube_scene(&box_medium("1", "0"), ""), "{from}");
        assert_names(&parse(&text).unwrap_err(), table, field);
    }
}

/// Strong anisotropy just inside |g| < 1 renders finite and matches the box twin.
#[test]
fn strong_anisotropy_renders_right() {
    let ctx = context();
    let dir = scratch("hard_cases", "anisotropy");
    for g in ["0.999", "-0.999"] {
        let twin = try_render(&ctx, &parse(&cube_scene(&box_medium("2", g), "")).unwrap()).unwrap();
        let grid = try_render(
            &ctx,
            &parse(&cube_scene(
                &uniform_grid(&dir, "2", g),
                "[integrator]\nvolume = \"baseline\"",
            ))
            .unwrap(),
        )
        .unwrap();
        assert_agree(&format!("g = {g}"), &grid, &twin, 4.5, 0.02);
    }
}

/// Radiometric inputs up to 1e12 render, and lights add: a 1e12 W/sr point light far
/// away does not touch the sun's share of the image (a 1e38 one used to turn the light
/// selection CDF into NaN and black out every light). Above 1e12 is refused.
#[test]
fn extreme_intensities_render_additively_or_are_refused() {
    let ctx = context();
    let dir = scratch("hard_cases", "intensity");
    let far_point = "[[light]]\ntype = \"point\"\nposition = [0, 0, 80]\nintensity = 1e12";
    let grid = uniform_grid(&dir, "2", "0");
    let with = |extra: &str| {
        cube_scene(
            &grid,
            &format!("{extra}\n[integrator]\nvolume = \"baseline\""),
        )
    };
    let both = try_render(&ctx, &parse(&with(far_point)).unwrap()).unwrap();
    let sun = try_render(&ctx, &parse(&with("")).unwrap()).unwrap();
    let point_only_text = with(far_point).replace("irradiance = 5.0", "irradiance = 0.0");
    let point = try_render(&ctx, &parse(&point_only_text).unwrap()).unwrap();
    assert!(mean(&sun.image) > 0.0 && mean(&point.image) > 0.0);
    let sum = mean(&sun.image) + mean(&point.image);
    let se = (se_of_mean(&sun.std_error).powi(2)
        + se_of_mean(&point.std_error).powi(2)
        + se_of_mean(&both.std_error).powi(2))
    .sqrt();
    assert!(
        (mean(&both.image) - sum).abs() <= 4.5 * se + 0.02 * sum,
        "sun + point {} vs both {}",
        sum,
        mean(&both.image)
    );
    let e = parse(&with(&far_point.replace("1e12", "1e13"))).unwrap_err();
    assert_names(&e, "[[light]] #2", "intensity");
    let env = "[[light]]\ntype = \"environment\"\nradiance = 1e10\nscale = 1e10";
    assert_names(&parse(&with(env)).unwrap_err(), "[[light]] #2", "scale");
}

/// A camera far from a small scene cannot resolve it in f32: refused, naming the
/// camera. At 1e4 m the unit cube still resolves (features of 0.3 m would) and renders
/// its exact single scattering: it matches the f64 quadrature oracle.
#[test]
fn far_cameras_render_right_or_are_refused() {
    let ctx = context();
    let far = cube_scene(&box_medium("1", "0"), "")
        .replace("position = [0.3, 0.8, 3.0]", "position = [0.0, 0.0, 2e19]");
    let e = parse(&far).unwrap_err();
    assert!(e.contains(FILE) && e.contains("[camera]"), "{e}");
    let fov = 2.0 * (0.9f64 / 1e4).atan().to_degrees();
    let distant = cube_scene(&box_medium("1", "0"), "")
        .replace(
            "position = [0.3, 0.8, 3.0]",
            "position = [1000.0, 2666.0, 9586.0]",
        )
        .replace(
            "horizontal_fov_deg = 50",
            &format!("horizontal_fov_deg = {fov}"),
        )
        .replace("frames = 16", "frames = 1");
    let scene = parse(&distant).unwrap();
    let gpu = try_render(&ctx, &scene).unwrap();
    let oracle = nimbus_reference::quadrature::render(
        &scene,
        &nimbus_reference::quadrature::ReferenceOptions {
            rel_tol: 1e-5,
            footprint_samples: 1,
        },
    )
    .unwrap();
    let want = oracle.iter().map(|p| p[0]).sum::<f64>() / oracle.len() as f64;
    let got = mean(&gpu.image);
    assert!(
        want > 0.0 && (got - want).abs() <= 0.01 * want,
        "{got} vs {want}"
    );
}

/// The command line goes through the same checks as the file: `--frames` re-runs the
/// per-frame camera check, bad exposures and unwritable outputs are refused before
/// rendering.
#[test]
fn command_line_values_are_checked_like_the_file() {
    let dir = scratch("hard_cases", "cli");
    // Keyframes whose interpolation passes through look_at at frame 10.
    let scene = cube_scene(&box_medium("1", "0"), "").replace(
        "horizontal_fov_deg = 50",
        "horizontal_fov_deg = 50\n[[camera.keyframe]]\nframe = 0\nposition = [0, 0, 3]\n\
         look_at = [0, 0, 0]\n[[camera.keyframe]]\nframe = 20\nposition = [0, 0, -3]\nlook_at = [0, 0, 0]",
    );
    let path = dir.join("keyframes.toml");
    std::fs::write(&path, scene.replace("frames = 16", "frames = 1")).unwrap();
    let p = path.to_str().unwrap();
    let out_png = dir.join("out.png");
    let out = out_png.to_str().unwrap();
    let ok = nimbus(&["render", p, "--explain"]);
    assert!(ok.status.success(), "{}", text(&ok.stderr));
    let frames = nimbus(&["render", p, "--frames", "11", "--explain"]);
    assert!(!frames.status.success());
    let e = text(&frames.stderr);
    assert!(
        e.contains("keyframes.toml") && e.contains("frame 10"),
        "{e}"
    );
    for bad in ["nan", "inf", "0", "-1"] {
        let flag = format!("--exposure={bad}");
        let o = nimbus(&["render", p, "--out", out, &flag]);
        assert!(!o.status.success(), "--exposure {bad} accepted");
        assert!(text(&o.stderr).contains("exposure"), "{}", text(&o.stderr));
    }
    let o = nimbus(&["render", p, "--out", "/nonexistent-dir/x.exr"]);
    assert!(!o.status.success());
    let e = text(&o.stderr);
    assert!(
        e.contains("/nonexistent-dir") && !e.contains("wrote"),
        "{e}"
    );
    assert!(!out_png.exists());
}

/// The memory guard: a budget below what the scene needs refuses the render before
/// allocating, and the estimate bounds the process's real peak (VmHWM) for a 384³ grid
/// with both integrators (up to what the process holds without any scene: the driver,
/// the binary, the loader). On lavapipe the GPU's allocations are host memory too, so
/// they count.
#[test]
fn the_host_memory_estimate_bounds_the_real_peak_slow() {
    let dir = scratch("hard_cases", "memory");
    // ReSTIR's levels are fixed: `auto` ones are counted at the finest they can be (an
    // upper bound by design), which would hide how close the estimate is for given levels.
    let scene = cube_scene(
        "type = \"grid\"\nbounds_min = [-0.5, -0.5, -0.5]\nbounds_max = [0.5, 0.5, 0.5]\n\
         density = { procedural = \"cloud\", dims = [384, 384, 384] }\ndensity_scale = 8",
        "[integrator.restir]\nmip_indirect = 1\nmip_reuse = 1",
    )
    .replace("frames = 16", "frames = 1")
    // Rendered by both integrators (ReSTIR takes 1 spp).
    .replace("spp = 2", "spp = 1")
    .replace("width = 24", "width = 8")
    .replace("height = 24", "height = 8");
    let path = dir.join("big.toml");
    std::fs::write(&path, &scene).unwrap();
    let p = path.to_str().unwrap();
    let out = dir.join("big.exr");
    let mib = |line: &str, key: &str| -> f64 {
        let at = line
            .find(key)
            .unwrap_or_else(|| panic!("no {key:?} in {line:?}"));
        line[at + key.len()..]
            .split_whitespace()
            .next()
            .and_then(|w| w.parse().ok())
            .unwrap_or_else(|| panic!("no number after {key:?} in {line:?}"))
    };
    // What the process holds with a 1-voxel grid: the floor of the comparison.
    // (384³, not 256³: stored sparsely, a 256³ cloud's ~40 MiB above the floor were
    // within the floor's own spread between runs, up to ~50 MiB for ReSTIR on lavapipe.)
    let tiny = scene.replace("dims = [384, 384, 384]", "dims = [1, 1, 1]");
    let tiny_path = dir.join("tiny.toml");
    std::fs::write(&tiny_path, tiny).unwrap();
    for volume in ["baseline", "restir"] {
        let set = format!("integrator.volume={volume}");
        let explain = text(&nimbus(&["render", p, "--set", &set, "--explain"]).stdout);
        // Host memory, plus the GPU allocations, which live in host memory on lavapipe.
        // (The memory line: the plan's notes may say "about" too.)
        let memory = explain
            .lines()
            .find(|l| l.trim_start().starts_with("memory: "))
            .unwrap_or_else(|| panic!("no memory line in {explain}"));
        let estimate = mib(memory, "about ") + mib(memory, "memory: ");
        let floor_run = nimbus(&[
            "render",
            tiny_path.to_str().unwrap(),
            "--set",
            &set,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(floor_run.status.success(), "{}", text(&floor_run.stderr));
        let floor = mib(&text(&floor_run.stderr), "peak host memory ");
        let run = nimbus(&["render", p, "--set", &set, "--out", out.to_str().unwrap()]);
        assert!(run.status.success(), "{}", text(&run.stderr));
        let peak = mib(&text(&run.stderr), "peak host memory ");
        eprintln!("{volume}: peak {peak} MiB, floor {floor} MiB, estimate {estimate} MiB");
        // 5 % + 4 MiB for what the estimate cannot see: allocator arenas and rounding,
        // the driver's bookkeeping per allocation.
        assert!(
            peak <= floor + 1.05 * estimate + 4.0,
            "{volume}: peak {peak} MiB above {floor} MiB floor + {estimate} MiB estimate"
        );
        // Not loose beyond what the estimate knows it bounds: the procedural cloud's
        // bricks are bounded per super-voxel (measured 1.9x the stored ones here). For
        // ReSTIR the floor also holds lavapipe's pipeline compilation, a transient the
        // grid's data later reuses, so the growth over the floor understates the data
        // (measured: 0.52 of the estimate for the baseline, 0.23-0.40 for ReSTIR, whose
        // floor itself moved from 180 to 228 MiB between runs).
        let least = if volume == "restir" { 0.15 } else { 0.25 };
        assert!(
            peak - floor >= least * estimate,
            "{volume}: the estimate {estimate} MiB is loose (peak {peak}, floor {floor})"
        );
        let refused = std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .args(["render", p, "--set", &set, "--out", out.to_str().unwrap()])
            .env("NIMBUS_HOST_MEMORY_BUDGET", "16")
            .output()
            .unwrap();
        assert!(!refused.status.success());
        let e = text(&refused.stderr);
        assert!(
            e.contains("host memory") && e.contains("NIMBUS_HOST_MEMORY_BUDGET"),
            "{e}"
        );
        if volume == "restir" {
            // The plan chooses ReSTIR's levels from the density's content: it refuses a
            // density over the budget before reading it, even where only the plan is
            // built (--explain) and the renderer's check never runs.
            let explain = std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
                .args(["render", p, "--set", &set, "--explain"])
                .env("NIMBUS_HOST_MEMORY_BUDGET", "1")
                .output()
                .unwrap();
            let e = text(&explain.stderr);
            assert!(!explain.status.success(), "{e}");
            assert!(
                e.contains("> density") && e.contains("mip levels") && e.contains("host memory"),
                "{e}"
            );
        }
    }
}

/// A long render holds no more host memory than a short one, with every integrator: the
/// film, reservoirs and pipelines are allocated once. On lavapipe (Mesa 22.3) a pass whose
/// parameters were a uniform buffer was compiled again at every dispatch and the copy never
/// freed: 3 MiB (ReSTIR) to 11 MiB (the window's crepuscular pass) per frame, 1.6-5.9 GiB
/// after 512 frames, until the test suite was killed for memory (the parameter blocks are
/// storage buffers since; shaders/include/film.glsl).
///
/// What the frames after the second add, not the whole render's peak, is compared: that
/// peak is the shader compiler's, and varied between two runs of the same ReSTIR render by
/// 84 MiB (260 and 344 MiB) with how the pipelines' compiles overlapped in their threads.
#[test]
fn host_memory_does_not_grow_with_frames() {
    let dir = scratch("hard_cases", "memory_frames");
    let out = dir.join("frames.exr");
    // The stripped shader modules come from a folder of this test's own, filled by a
    // first render of each case, so that no measured run strips a module.
    let cache = dir.join("shaders");
    // (peak host memory, what the frames after the second added), MiB.
    let memory = |scene: &str, volume: Option<&str>, frames: u32| -> (f64, f64) {
        let frames = frames.to_string();
        let mut args = vec![
            "render", scene, "--width", "8", "--height", "8", "--frames", &frames, "--out",
        ];
        args.push(out.to_str().unwrap());
        let set = volume.map(|v| format!("integrator.volume={v}"));
        if let Some(set) = &set {
            args.extend(["--set", set]);
        }
        let run = std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .args(&args)
            .env("NIMBUS_VALIDATION", "1")
            .env("NIMBUS_SHADER_CACHE_DIR", &cache)
            .output()
            .expect("run nimbus");
        let e = text(&run.stderr);
        assert!(run.status.success(), "{e}");
        let number = |key: &str| -> f64 {
            let at = e.find(key).unwrap_or_else(|| panic!("no {key:?} in {e:?}"));
            e[at + key.len()..]
                .split_whitespace()
                .next()
                .and_then(|w| w.parse().ok())
                .unwrap_or_else(|| panic!("no number after {key:?} in {e:?}"))
        };
        (
            number("peak host memory "),
            number("frames after the second added "),
        )
    };
    let cases = [
        ("assets/scenes/window.toml", None),
        ("assets/scenes/cloud-restir-study.toml", Some("restir")),
        ("assets/scenes/cloud-restir-study.toml", Some("baseline")),
    ];
    for (scene, volume) in cases {
        memory(scene, volume, 3);
        let (short_peak, short) = memory(scene, volume, 4);
        let (long_peak, long) = memory(scene, volume, 300);
        eprintln!(
            "{scene} {volume:?}: frames after the second added {short} MiB of 4 frames \
             (peak {short_peak} MiB), {long} MiB of 300 (peak {long_peak} MiB)"
        );
        // 296 more frames; the leak was 3-11 MiB each. 24 MiB covers allocator arenas.
        assert!(
            long <= short + 24.0,
            "{scene} {volume:?}: frames after the second added {short} MiB of 4 frames, \
             {long} MiB of 300"
        );
    }
}

/// One voxel of 1e6 in a 0.5 grid (within what the scene resolves: its ramp, not its
/// peak, is where light enters it): the baseline renders it in about the time of the grid
/// without it (its hot super-voxel spans are tracked exactly instead of by 1e6 null
/// collisions per metre, which used to hit the step limit and bias the image dark), no
/// walk stops at the step limit, and both integrators agree.
#[test]
fn a_hot_voxel_costs_only_where_it_is_and_both_integrators_agree() {
    let ctx = context();
    let dir = scratch("hard_cases", "hot_voxel");
    let n = 16usize;
    let mut data = vec![0.5f32; n * n * n];
    data[8 + n * (8 + n * 8)] = 1e6;
    let raw = dir.join("hot16.raw");
    std::fs::write(
        &raw,
        data.iter()
            .flat_map(|v| v.to_le_bytes())
            .collect::<Vec<u8>>(),
    )
    .unwrap();
    let medium = format!(
        "type = \"grid\"\nbounds_min = [-0.5, -0.5, -0.5]\nbounds_max = [0.5, 0.5, 0.5]\n\
         density = {{ file = \"{}\", dims = [16, 16, 16] }}\nalbedo = 0.8",
        raw.display()
    );
    let text = |volume: &str| {
        cube_scene(
            &medium,
            &format!(
                "[[light]]\ntype = \"environment\"\nradiance = 0.3\n[integrator]\nmax_bounces = 2\n\
                 volume = \"{volume}\"\n[integrator.restir]\ntemporal = false\nspatial_neighbors = 0"
            ),
        )
        .replace("frames = 16", "frames = 48")
    };
    let baseline = try_render(&ctx, &parse(&text("baseline")).unwrap()).unwrap();
    let restir = try_render(&ctx, &parse(&text("restir")).unwrap()).unwrap();
    assert_agree(
        "hot voxel: ReSTIR vs baseline",
        &restir,
        &baseline,
        4.5,
        0.01,
    );
}

/// An environment map larger than a storage buffer of the device can hold is refused
/// before anything is allocated or its pixels are read (only its header is), naming the
/// scene, the light, the field and the file, and the device limit. A 16384×8192 map used
/// to be staged as a 2 GiB buffer and crash the driver after 25 s.
#[test]
fn environment_maps_beyond_the_device_are_refused_before_allocation() {
    use exr::prelude::{Encoding, Image, SpecificChannels, Vec2, WritableImage};
    let ctx = context();
    let dir = scratch("hard_cases", "envmap");
    let limit = u64::from(ctx.info().max_storage_buffer_range);
    // The smallest square map whose RGBA f32 texels exceed the limit.
    let mut side = 256usize;
    while (side * side * 16) as u64 <= limit {
        side *= 2;
    }
    assert!(
        side <= 16384,
        "the device allows maps larger than the format's limit"
    );
    let path = dir.join(format!("sky{side}.exr"));
    if !path.exists() {
        let channels = SpecificChannels::rgb(|_: Vec2<usize>| {
            (
                half::f16::from_f32(0.5),
                half::f16::from_f32(0.6),
                half::f16::from_f32(0.9),
            )
        });
        Image::from_encoded_channels((side, side), Encoding::FAST_LOSSLESS, channels)
            .write()
            .to_file(&path)
            .unwrap();
    }
    let text = cube_scene(&box_medium("1", "0"), "").replace(
        "[[light]]\ntype = \"directional\"",
        &format!(
            "[[light]]\ntype = \"environment\"\nfile = \"{}\"\n[[light]]\ntype = \"directional\"",
            path.display()
        ),
    ) + "\n[integrator]\nvolume = \"baseline\"\n";
    // Grid scenes light the medium with the map; a box scene only shows it as background,
    // so use a uniform grid.
    let text = text.replace(&box_medium("1", "0"), &uniform_grid(&dir, "1", "0"));
    let scene = parse(&text).unwrap();
    let started = std::time::Instant::now();
    let e = try_render(&ctx, &scene)
        .err()
        .unwrap_or_else(|| panic!("a {side}² map was accepted"));
    assert!(
        e.contains(FILE)
            && e.contains("[[light]] #1")
            && e.contains("`file`")
            && e.contains(&format!("sky{side}.exr"))
            && e.contains("maxStorageBufferRange"),
        "{e}"
    );
    assert!(
        started.elapsed().as_secs_f64() < 5.0,
        "refusal took {:?}",
        started.elapsed()
    );
}
