//! The `nimbus` command line: rendering, explaining, profiling, and clear errors for
//! bad input. Runs the real binary with validation layers on (NIMBUS_VALIDATION=1),
//! under which any validation error makes the command fail.

use std::process::Command;

use crate::common::cli::{nimbus, text};

fn scratch(name: &str) -> std::path::PathBuf {
    crate::common::cli::scratch("cli", name)
}

#[test]
fn explain_prints_the_plan_of_the_default_scene() {
    let out = nimbus(&["render", "--explain"]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(stdout.contains("[on ] pass crepuscular"), "{stdout}");
    assert!(stdout.contains("[on ]   SC_HAS_GOBOS"), "{stdout}");
    assert!(stdout.contains("by mcwvds"), "{stdout}");
    assert!(stdout.contains("[on ]   SC_HAS_SHAPES"), "{stdout}");
    assert!(stdout.contains("[off] pass baseline"), "{stdout}");
}

/// A convex medium switches plane clipping on and sizes the piece tables by its
/// light-facing planes: an octahedron lit from straight above faces the light with its
/// four upper planes; a box scene keeps the three pieces of a box.
#[test]
fn explain_names_convex_media_and_their_pieces() {
    let dir = scratch("explain-convex");
    let octahedron: Vec<String> = (0..8)
        .map(|i| {
            let s = |b: i32| if i & b != 0 { -1 } else { 1 };
            format!("[{}, {}, {}, 1]", s(1), s(2), s(4))
        })
        .collect();
    let path = dir.join("octahedron.toml");
    std::fs::write(
        &path,
        format!(
            "[camera]\nposition = [0, 0, 4]\nlook_at = [0, 0, 0]\n[[light]]\ntype = \"directional\"\n\
             direction = [0, -1, 0]\nirradiance = 1\n[[medium]]\ntype = \"convex\"\nplanes = [{}]\n\
             sigma_t = 1\n",
            octahedron.join(", ")
        ),
    )
    .unwrap();
    let out = nimbus(&["render", path.to_str().unwrap(), "--explain"]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(stdout.contains("[on ]   SC_HAS_CONVEX"), "{stdout}");
    assert!(stdout.contains("up to 4 trapezoid pieces"), "{stdout}");

    let out = nimbus(&["render", "--explain"]);
    let stdout = text(&out.stdout);
    assert!(stdout.contains("[off]   SC_HAS_CONVEX"), "{stdout}");
    assert!(
        stdout.contains("3 trapezoid pieces per segment"),
        "{stdout}"
    );
}

#[test]
fn render_writes_exr_and_png() {
    let dir = scratch("render");
    for name in ["small.exr", "small.png"] {
        let path = dir.join(name);
        let out = nimbus(&[
            "render",
            "--out",
            path.to_str().unwrap(),
            "--width",
            "32",
            "--height",
            "24",
            "--frames",
            "1",
            "--spp",
            "1",
        ]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        assert!(path.exists());
    }
    let img = nimbus::output::read_exr(&dir.join("small.exr")).expect("read exr");
    assert_eq!((img.width, img.height), (32, 24));
    assert!(img.mean()[0] > 0.0, "the default scene is not black");
}

#[test]
fn profile_reports_the_crepuscular_pass_from_timestamps() {
    let dir = scratch("profile");
    let json = dir.join("profile.json");
    let trace = dir.join("trace.json");
    let out = nimbus(&[
        "profile",
        "--width",
        "32",
        "--height",
        "24",
        "--frames",
        "3",
        "--warmup",
        "1",
        "--json",
        json.to_str().unwrap(),
        "--trace",
        trace.to_str().unwrap(),
    ]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(stdout.contains("frame/crepuscular"), "{stdout}");

    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).expect("JSON report");
    assert_eq!(report["frames"], 3);
    // No settling load on lavapipe (a CPU device has no clocks to raise).
    assert!(report["settle_ms"].is_null(), "{report}");
    assert!(!stdout.contains("settled:"), "{stdout}");
    let passes = report["passes"].as_array().expect("passes");
    let pass = passes
        .iter()
        .find(|p| p["pass"] == "frame/crepuscular")
        .expect("crepuscular pass in the report");
    let (min, median, max) = (
        pass["min_ms"].as_f64().unwrap(),
        pass["median_ms"].as_f64().unwrap(),
        pass["max_ms"].as_f64().unwrap(),
    );
    assert!(min > 0.0 && min <= median && median <= max, "{pass}");
    // Each measured frame's time in order, within the frame pass's range.
    let frame_ms = report["frame_ms"].as_array().expect("frame_ms");
    assert_eq!(frame_ms.len(), 3, "{report}");
    let frame = passes
        .iter()
        .find(|p| p["pass"] == "frame")
        .expect("frame pass in the report");
    for ms in frame_ms.iter().map(|v| v.as_f64().unwrap()) {
        assert!(
            ms >= frame["min_ms"].as_f64().unwrap() - 1e-9
                && ms <= frame["max_ms"].as_f64().unwrap() + 1e-9,
            "{ms} outside {frame}"
        );
    }
    assert!(stdout.contains("frame ms in order:"), "{stdout}");

    let trace: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&trace).unwrap()).expect("trace JSON");
    let events = trace["traceEvents"].as_array().expect("traceEvents");
    assert_eq!(
        events.iter().filter(|e| e["name"] == "crepuscular").count(),
        3
    );
}

/// `nimbus profile` of an animation renders its first scene frames as the warm-up and
/// measures the frames after them: a moving camera is measured on moving frames only.
/// (Before, the warm-up repeated scene frame 0 and the measured frames restarted at it,
/// so the first measured frame was a still frame: spatial reuse, which runs on the
/// frames whose camera moved, then counted 2 frames' pixels of 3.)
#[test]
fn profile_of_an_animation_measures_the_frames_after_its_warmup() {
    let dir = scratch("profile-motion");
    let scene = dir.join("dolly.toml");
    std::fs::write(
        &scene,
        "[render]\nwidth = 16\nheight = 12\nframes = 8\n\
         [camera]\nhorizontal_fov_deg = 55\n\
         [[camera.keyframe]]\nframe = 0\nposition = [0.0, 0.3, 2.6]\nlook_at = [0.0, 0.0, 0.0]\n\
         [[camera.keyframe]]\nframe = 8\nposition = [0.5, 0.3, 1.5]\nlook_at = [0.0, 0.0, 0.0]\n\
         [[light]]\ntype = \"directional\"\ndirection = [0.6, -0.5, -0.6]\nirradiance = 4.0\n\
         [[medium]]\ntype = \"grid\"\nbounds_min = [-1.0, -0.6, -1.0]\nbounds_max = [1.0, 0.6, 1.0]\n\
         density = { procedural = \"cloud\", dims = [16, 10, 16], noise_seed = 7 }\n\
         density_scale = 12.0\nalbedo = 0.9\n\
         [integrator]\nvolume = \"restir\"\nmax_bounces = 2\n",
    )
    .unwrap();
    let json = dir.join("profile.json");
    let out = nimbus(&[
        "profile",
        scene.to_str().unwrap(),
        "--frames",
        "3",
        "--warmup",
        "2",
        "--counters",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).expect("JSON report");
    let samples = |stage: &str| {
        report["work"]["stages"]
            .as_array()
            .expect("work stages")
            .iter()
            .find(|s| s["stage"] == stage)
            .unwrap_or_else(|| panic!("{stage} in {report}"))["totals"]["samples"]
            .as_u64()
            .unwrap()
    };
    let pixels = 16 * 12;
    // Scene frames 2, 3 and 4: the camera moves on each, so spatial reuse runs on each.
    assert_eq!(samples("restir/initial"), 3 * pixels, "{report}");
    assert_eq!(samples("restir/spatial"), 3 * pixels, "{report}");
}

/// Bad input ends in an error that names the file, the table and the field.
#[test]
fn bad_scenes_give_clear_errors() {
    let dir = scratch("bad");
    let cases = [
        (
            "unknown.toml",
            "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\nfov = 3\n",
            &["unknown.toml", "[camera]", "fov"][..],
        ),
        (
            "zero.toml",
            "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\n[[light]]\ntype = \"directional\"\ndirection = [0, 0, 0]\nirradiance = 1\n",
            &["zero.toml", "[[light]] #1", "direction"][..],
        ),
        (
            "nan.toml",
            "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\n[[medium]]\ntype = \"box\"\ncenter = [0, 0, 0]\nsize = [1, 1, 1]\nsigma_t = nan\n",
            &["nan.toml", "[[medium]] #1", "sigma_t"][..],
        ),
        (
            "grid.toml",
            "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n[[medium]]\ntype = \"grid\"\nbounds_min = [-1, -1, -1]\nbounds_max = [1, 1, 1]\ndensity = { procedural = \"cloud\", dims = [8, 8, 8] }\n[[shape]]\ntype = \"sphere\"\ncenter = [0, 3, 0]\nradius = 1\n[integrator.restir]\nreuse = \"vertex\"\n",
            &["grid.toml", "[[shape]] #1", "`reuse`", "reuse = \"direction\""][..],
        ),
        (
            "point.toml",
            "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n[[light]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = 1\n",
            &["point.toml", "[[light]] #1", "not supported yet"][..],
        ),
        (
            "two-grids.toml",
            "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n[[medium]]\ntype = \"grid\"\nbounds_min = [-1, -1, -1]\nbounds_max = [1, 1, 1]\ndensity = { procedural = \"cloud\", dims = [8, 8, 8] }\n[[medium]]\ntype = \"grid\"\nbounds_min = [0, 0, 0]\nbounds_max = [2, 2, 2]\ndensity = { procedural = \"cloud\", dims = [8, 8, 8] }\n",
            &["two-grids.toml", "[[medium]] #2", "one grid medium"][..],
        ),
    ];
    for (name, body, needles) in cases {
        let path = dir.join(name);
        std::fs::write(&path, body).unwrap();
        let out = nimbus(&["render", path.to_str().unwrap(), "--explain"]);
        let stderr = text(&out.stderr);
        assert!(!out.status.success(), "{name} should fail");
        assert!(!stderr.contains("panicked"), "{name}: {stderr}");
        for needle in needles {
            assert!(
                stderr.contains(needle),
                "{name}: {needle:?} missing in: {stderr}"
            );
        }
    }

    let missing = dir.join("missing.toml");
    let out = nimbus(&["render", missing.to_str().unwrap(), "--out", "x.exr"]);
    assert!(!out.status.success());
    assert!(text(&out.stderr).contains("missing.toml"));

    let out = nimbus(&["render", "--out", dir.join("image.jpg").to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(text(&out.stderr).contains(".exr"), "{}", text(&out.stderr));
}

/// A scene "file" that is a FIFO or a device is refused at once, naming it (issue 24: a
/// FIFO hung `nimbus render`, /dev/zero was read until memory ran out).
#[test]
fn a_pipe_or_a_device_as_the_scene_is_refused_without_reading_it() {
    let dir = scratch("scene-fifo");
    let fifo = dir.join("p.toml");
    let made = Command::new("mkfifo").arg(&fifo).status().expect("mkfifo");
    assert!(made.success());
    for path in [fifo.to_str().unwrap(), "/dev/zero"] {
        let start = std::time::Instant::now();
        let out = nimbus(&["render", path, "--out", dir.join("x.png").to_str().unwrap()]);
        let stderr = text(&out.stderr);
        assert!(!out.status.success());
        assert!(
            stderr.contains(path) && stderr.contains("not a regular file"),
            "{stderr}"
        );
        assert!(start.elapsed() < std::time::Duration::from_secs(30));
    }
    // A scene file over the limit is refused from its size.
    let big = dir.join("big.toml");
    let file = std::fs::File::create(&big).unwrap();
    file.set_len(nimbus_scene::MAX_SCENE_FILE_BYTES + 1)
        .unwrap();
    let out = nimbus(&["render", big.to_str().unwrap(), "--explain"]);
    let stderr = text(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("big.toml") && stderr.contains("MiB"),
        "{stderr}"
    );
}

/// Renders the default scene at 8x6 with `seed` and `frames` to `path` (a merge part).
fn render_default_8x6(path: &std::path::Path, seed: &str, frames: &str) {
    let out = nimbus(&[
        "render",
        "--width",
        "8",
        "--height",
        "6",
        "--frames",
        frames,
        "--seed",
        seed,
        "--out",
        path.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
}

/// `nimbus merge --out` naming one of its inputs (by any spelling) is refused and the
/// input is left as it was (issue 24: it overwrote it).
#[test]
fn merge_never_overwrites_an_input() {
    let dir = scratch("merge-overwrite");
    let (a, b) = (dir.join("a.exr"), dir.join("b.exr"));
    for (path, seed) in [(&a, "1"), (&b, "2")] {
        render_default_8x6(path, seed, "1");
    }
    let before = std::fs::read(&a).unwrap();
    let other_spelling = dir.join(".").join("a.exr");
    for target in [a.clone(), other_spelling] {
        let out = nimbus(&[
            "merge",
            "--out",
            target.to_str().unwrap(),
            a.to_str().unwrap(),
            b.to_str().unwrap(),
        ]);
        let stderr = text(&out.stderr);
        assert!(!out.status.success());
        assert!(stderr.contains("is also an input"), "{stderr}");
    }
    assert_eq!(std::fs::read(&a).unwrap(), before, "the input is untouched");
    let merged = dir.join("merged.exr");
    let out = nimbus(&[
        "merge",
        "--out",
        merged.to_str().unwrap(),
        a.to_str().unwrap(),
        b.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
}

/// Parts rendered from one scene file whose density file changed between them are
/// refused by `nimbus merge` (issue 24: the scene hash covered the scene file alone, so
/// parts of two different clouds merged into an image of neither).
#[test]
fn merge_refuses_parts_rendered_from_different_data() {
    let dir = scratch("merge-data");
    let grid = dir.join("density.raw");
    let scene = dir.join("cube.toml");
    std::fs::write(
        &scene,
        "[render]\nwidth = 8\nheight = 6\n[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n\
         [[light]]\ntype = \"environment\"\nradiance = 1\n[[medium]]\ntype = \"grid\"\n\
         bounds_min = [-0.5, -0.5, -0.5]\nbounds_max = [0.5, 0.5, 0.5]\n\
         density = { file = \"density.raw\", dims = [2, 2, 2] }\n\
         [integrator]\nvolume = \"baseline\"\n",
    )
    .unwrap();
    let part = |seed: &str, value: f32| {
        std::fs::write(&grid, bytemuck::cast_slice::<f32, u8>(&[value; 8])).unwrap();
        let path = dir.join(format!("part{seed}.exr"));
        let out = nimbus(&[
            "render",
            scene.to_str().unwrap(),
            "--frames",
            "2",
            "--seed",
            seed,
            "--out",
            path.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        path
    };
    let (a, b, c) = (part("1", 1.0), part("2", 3.0), part("3", 3.0));
    let merged = dir.join("merged.exr");
    let merge = |x: &std::path::Path, y: &std::path::Path| {
        nimbus(&[
            "merge",
            "--out",
            merged.to_str().unwrap(),
            x.to_str().unwrap(),
            y.to_str().unwrap(),
        ])
    };
    let out = merge(&a, &b);
    let stderr = text(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(stderr.contains("scene_hash"), "{stderr}");
    // The same data merges.
    let out = merge(&b, &c);
    assert!(out.status.success(), "{}", text(&out.stderr));
}

/// `nimbus merge` names the part it refuses and why: a PNG (it said "file identifier
/// missing"), a part holding NaN (it blamed "the renderer"); a value refused only because
/// of `--set` says it came from there.
#[test]
fn refusals_name_the_part_and_the_source_of_the_value() {
    let dir = scratch("merge-parts");
    let render = |name: &str, seed: &str| {
        let path = dir.join(name);
        render_default_8x6(&path, seed, "2");
        path
    };
    let (a, png) = (render("a.exr", "1"), render("c.png", "3"));
    let merged = dir.join("m.exr");
    let merge = |x: &std::path::Path, y: &std::path::Path| {
        let out = nimbus(&[
            "merge",
            "--out",
            merged.to_str().unwrap(),
            x.to_str().unwrap(),
            y.to_str().unwrap(),
        ]);
        assert!(!out.status.success());
        text(&out.stderr)
    };
    let stderr = merge(&a, &png);
    assert!(
        stderr.contains("c.png") && stderr.contains("render the parts as .exr"),
        "{stderr}"
    );
    // Nimbus never writes a NaN; another tool does.
    let nan = dir.join("nan.exr");
    exr::prelude::write_rgba_file(&nan, 8, 6, |x, y| {
        let g = if (x, y) == (7, 0) { f32::NAN } else { 0.5 };
        (0.5f32, g, 0.5f32, 1.0f32)
    })
    .unwrap();
    let stderr = merge(&a, &nan);
    assert!(
        stderr.contains("nan.exr: RGB of pixel (7, 0) is NaN") && !stderr.contains("the renderer"),
        "{stderr}"
    );
    let out = nimbus(&[
        "render",
        "--set",
        "render.width=abc",
        "--out",
        a.to_str().unwrap(),
    ]);
    let stderr = text(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("field `width`") && stderr.contains("comes from --set render.width"),
        "{stderr}"
    );
}

/// A velocity grid is metres per frame times `velocity_scale`; one that moves points
/// more than a few voxels per frame gets a note naming the field (issue 24: a Houdini
/// `vel` in units per second smeared a still scene into streaks without a word).
#[test]
fn a_fast_velocity_grid_is_noted_with_its_unit() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenes/plume-anim.toml");
    let dir = scratch("velocity-unit");
    let run = |scale: &str| {
        let out = nimbus(&[
            "render",
            scene,
            "--width",
            "24",
            "--height",
            "18",
            "--frame",
            "1",
            "--set",
            &format!("medium.1.velocity_scale={scale}"),
            "--out",
            dir.join("v.exr").to_str().unwrap(),
        ]);
        let stderr = text(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        stderr
    };
    let stderr = run("1");
    assert!(!stderr.contains("voxels per frame"), "{stderr}");
    let stderr = run("1000");
    assert!(
        stderr.contains("[[medium]] #1 > velocity moves points up to")
            && stderr.contains("velocity_scale = 1/fps"),
        "{stderr}"
    );
    // The largest accepted scale overflows the half-float velocity texels to infinity:
    // reprojection finds no previous pixel, and the frame stays finite.
    let stderr = run("1e6");
    assert!(!stderr.contains("not finite"), "{stderr}");
}

/// `--frame N --passes P` renders one scene frame P times, and says so (issue 24: it
/// reported "P frame(s)").
#[test]
fn one_frame_rendered_several_times_is_reported_as_passes() {
    let dir = scratch("frame-passes");
    let path = dir.join("keyed.toml");
    std::fs::write(
        &path,
        "[render]\nwidth = 8\nheight = 6\nframes = 3\n[camera]\nposition = [0, 0, 4]\n\
         look_at = [0, 0, 0]\n[[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\n\
         irradiance = 1\n[[light.keyframe]]\nframe = 0\nirradiance = 1\n[[light.keyframe]]\n\
         frame = 2\nirradiance = 3\n[[medium]]\ntype = \"box\"\ncenter = [0, 0, 0]\n\
         size = [1, 1, 1]\nsigma_t = 1\n",
    )
    .unwrap();
    let out = nimbus(&[
        "render",
        path.to_str().unwrap(),
        "--frame",
        "2",
        "--passes",
        "4",
        "--out",
        dir.join("f2.exr").to_str().unwrap(),
    ]);
    let stderr = text(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("frame 2: 4 pass(es) x 1 spp"), "{stderr}");
}

/// A transparent PNG sequence (frames written as RGB) is refused before rendering, and
/// a time limit past the writable range says why (issue 24). A single transparent .png
/// is RGBA (alpha.rs).
#[test]
fn a_transparent_png_sequence_and_an_absurd_time_limit_are_refused_with_the_reason() {
    let dir = scratch("transparent-png");
    let out = nimbus(&[
        "render",
        "--transparent",
        "--sequence",
        dir.join("seq").to_str().unwrap(),
        "--sequence-format",
        "png",
        "--out",
        dir.join("t.exr").to_str().unwrap(),
    ]);
    let stderr = text(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("sequence") && stderr.contains("alpha"),
        "{stderr}"
    );
    assert!(!dir.join("t.exr").exists());
    let out = nimbus(&[
        "render",
        "--time-limit",
        "1e9",
        "--out",
        dir.join("x.exr").to_str().unwrap(),
    ]);
    let stderr = text(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("31 years"), "{stderr}");
}

/// A still of a static scene by ReSTIR says which integrator stills want (issue 23:
/// accumulated ReSTIR frames converge 8x slower per second than the baseline's samples
/// on lavapipe with temporal reuse, 1.4x without it, which `temporal = "auto"` leaves out
/// of a still and the note names); an animation does not.
#[test]
fn explain_says_which_integrator_renders_stills() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let still = root.join("assets/scenes/cloud-restir.toml");
    let out = nimbus(&["render", still.to_str().unwrap(), "--explain"]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(
        stdout.contains("note: this static scene renders a still")
            && stdout.contains("ReSTIR's frames are independent here")
            && stdout.contains("[off] pass restir temporal"),
        "{stdout}"
    );
    let temporal = nimbus(&[
        "render",
        still.to_str().unwrap(),
        "--explain",
        "--set",
        "integrator.restir.temporal=true",
    ]);
    let stdout = text(&temporal.stdout);
    assert!(
        stdout.contains("[on ] pass restir temporal")
            && stdout
                .contains("temporal = \"auto\" (the default) makes a still's frames independent"),
        "{stdout}"
    );
    let baseline = nimbus(&[
        "render",
        still.to_str().unwrap(),
        "--explain",
        "--set",
        "integrator.volume=\"baseline\"",
    ]);
    assert!(!text(&baseline.stdout).contains("renders a still"));
    let anim = root.join("assets/scenes/plume-anim.toml");
    let out = nimbus(&["render", anim.to_str().unwrap(), "--explain"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(!text(&out.stdout).contains("renders a still"));
}

/// `--explain` shows the mip levels ReSTIR really uses, decided by the plan: `auto` ones
/// chosen from the grid's content, with the errors that chose them; fixed ones as asked.
#[test]
fn explain_shows_the_mip_levels_restir_uses() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = root.join("assets/scenes/cloud-restir.toml");
    let scene = scene.to_str().unwrap();
    let out = nimbus(&["render", scene, "--explain"]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(
        stdout.contains("delta tracking on the exact density, NEE marched on mip 1 (auto)"),
        "{stdout}"
    );
    let regular = nimbus(&[
        "render",
        scene,
        "--explain",
        "--set",
        "integrator.restir.candidate_tracking=\"regular\"",
    ]);
    assert!(
        text(&regular.stdout)
            .contains("regular tracking on mip 1 for camera rays and 1 (auto) for scattered ones"),
        "{}",
        text(&regular.stdout)
    );
    assert!(
        stdout.contains("note: ReSTIR chose mip 1 (scattered segments) and 0 (reuse targets)"),
        "{stdout}"
    );
    let fixed = nimbus(&[
        "render",
        scene,
        "--explain",
        "--set",
        "integrator.restir.mip_indirect=2",
        "--set",
        "integrator.restir.mip_reuse=1",
    ]);
    let stdout = text(&fixed.stdout);
    assert!(fixed.status.success(), "{}", text(&fixed.stderr));
    assert!(stdout.contains("NEE marched on mip 2,"), "{stdout}");
    assert!(
        !stdout.contains("(auto)") && !stdout.contains("ReSTIR chose mip"),
        "{stdout}"
    );
}

/// A reader that closes our standard output early (`nimbus render --explain | head -1`)
/// ends the command quietly (SIGPIPE), never with a panic in print!.
#[test]
fn a_closed_stdout_ends_the_command_without_a_panic() {
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args(["render", "--explain"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Close the pipe before nimbus writes its plan.
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = text(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// `nimbus study ARGS` is `nimbus-study ARGS` in its place: every argument (help flags
/// included) reaches it unchanged, its exit status is the command's, and a missing
/// binary is named with how to build it.
#[cfg(unix)]
#[test]
fn study_runs_the_study_binary_with_the_arguments_as_given() {
    use std::os::unix::fs::PermissionsExt as _;
    let dir = scratch("study-forward");
    let stub = dir.join("fake-study");
    std::fs::write(&stub, "#!/bin/sh\nprintf '%s|' \"$@\"\nexit 7\n").unwrap();
    std::fs::set_permissions(&stub, std::fs::Permissions::from_mode(0o755)).unwrap();
    let run = |program: &std::path::Path| {
        Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .args([
                "study",
                "scene.toml",
                "--vary",
                "spp=1,2",
                "-h",
                "--",
                "a b",
            ])
            .env("NIMBUS_STUDY", program)
            .output()
            .unwrap()
    };
    let out = run(&stub);
    assert_eq!(out.status.code(), Some(7), "{}", text(&out.stderr));
    assert_eq!(text(&out.stdout), "scene.toml|--vary|spp=1,2|-h|--|a b|");
    let missing = run(&dir.join("none"));
    assert!(!missing.status.success());
    let stderr = text(&missing.stderr);
    assert!(
        stderr.contains("none") && stderr.contains("cargo build --release -p nimbus-study"),
        "{stderr}"
    );
}
