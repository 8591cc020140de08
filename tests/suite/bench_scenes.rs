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
