//! The benchmark scenes of `assets/scenes/bench/` (issue 15: paper-like cases for the
//! equal-time studies of tools/gpu-check.sh) load, plan and fit the memory guard; the
//! HDR sky they read is generated as `nimbus make-sky` writes it (`daylight_sky`).

use std::path::Path;

use nimbus::plan::{self, Integrator};

/// Writes `target/bench/sky-sun.exr` with `nimbus make-sky` unless it exists.
fn ensure_sky(root: &Path) {
    let path = root.join("target/bench/sky-sun.exr");
    if path.exists() {
        return;
    }
    let out = crate::common::cli::nimbus(&["make-sky", path.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        crate::common::cli::text(&out.stderr)
    );
    assert!(path.exists());
}

#[test]
fn benchmark_scenes_load_and_plan_for_both_grid_integrators() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    ensure_sky(root);
    let dir = root.join("assets/scenes/bench");
    let mut names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    names.sort();
    assert_eq!(names.len(), 5, "{names:?}");
    for path in names {
        let scene = nimbus::load_scene(Some(&path), &[])
            .unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
        assert_eq!((scene.render.width, scene.render.height), (320, 240));
        for volume in ["restir", "baseline"] {
            let mut s = scene.clone();
            s.integrator.volume = match volume {
                "restir" => nimbus_scene::VolumeIntegrator::Restir,
                _ => nimbus_scene::VolumeIntegrator::Baseline,
            };
            let plan = plan::build(&s, None)
                .unwrap_or_else(|e| panic!("{} with {volume}: {e:#}", path.display()));
            assert!(
                matches!(
                    (&plan.integrator, volume),
                    (Integrator::Restir(_), "restir") | (Integrator::Baseline(_), "baseline")
                ),
                "{}: {volume}",
                path.display()
            );
            nimbus::budget::Footprint::of(&s, &plan)
                .unwrap_or_else(|e| panic!("{} footprint: {e:#}", path.display()));
        }
    }
}

/// The motion benchmarks of `assets/scenes/bench/motion/` (issue 26) are what
/// `tools/make_motion_bench.py` writes, animate over 128 frames, and load, plan and fit
/// the memory guard for both grid integrators.
#[test]
fn motion_benchmarks_are_the_generators_output_and_plan() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    ensure_sky(root);
    let dir = root.join("assets/scenes/bench/motion");
    let fresh = crate::common::cli::scratch("bench", "motion");
    let out = std::process::Command::new("python3")
        .arg(root.join("tools/make_motion_bench.py"))
        .arg(&fresh)
        .output()
        .expect("python3 runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut names: Vec<String> = std::fs::read_dir(&fresh)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "camera-g0.toml",
            "camera-g08.toml",
            "explosion-matched.toml",
            "explosion-mismatched.toml",
            "sky-g06.toml",
            "sun-g0.toml",
            "sun-g08.toml"
        ]
    );
    for name in &names {
        let committed = std::fs::read_to_string(dir.join(name)).unwrap();
        let written = std::fs::read_to_string(fresh.join(name)).unwrap();
        assert!(
            committed == written,
            "{name}: the committed scene is not what tools/make_motion_bench.py writes; re-run it"
        );
        let path = dir.join(name);
        let scene = nimbus::load_scene(Some(&path), &[])
            .unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
        assert!(scene.is_animated(), "{name}");
        assert_eq!(scene.render.frames, 128, "{name}");
        // Something moves between any two frames of the study window (80..96 at Q = 20).
        let moved = |a: u32, b: u32| {
            scene.camera.frame_at(a) != scene.camera.frame_at(b)
                || scene.lights_at(a) != scene.lights_at(b)
        };
        assert!(moved(80, 81) && moved(0, 128), "{name}");
        for volume in [
            nimbus_scene::VolumeIntegrator::Restir,
            nimbus_scene::VolumeIntegrator::Baseline,
        ] {
            let mut s = scene.clone();
            s.integrator.volume = volume;
            let plan = plan::build(&s, None).unwrap_or_else(|e| panic!("{name}: {e:#}"));
            nimbus::budget::Footprint::of(&s, &plan)
                .unwrap_or_else(|e| panic!("{name} footprint: {e:#}"));
        }
    }
}
