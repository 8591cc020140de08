//! The benchmark scenes of `assets/scenes/bench/` (issue 15: paper-like cases for the
//! equal-time studies of tools/gpu-check.sh) load, plan and fit the memory guard; the
//! HDR sky they read is generated as `make_sky` writes it (`daylight_sky`).

use std::path::Path;

use nimbus::plan::{self, Integrator};

/// Writes `target/bench/sky-sun.exr` (what `cargo run --example make_sky --
/// target/bench/sky-sun.exr` writes) unless it exists.
fn ensure_sky(root: &Path) {
    let path = root.join("target/bench/sky-sun.exr");
    if path.exists() {
        return;
    }
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    let (w, h) = (1024, 512);
    let sun = nimbus_scene::sun_direction(25f32.to_radians(), 40f32.to_radians());
    let texels = nimbus_scene::daylight_sky(w, h, sun, 1.5f64.to_radians(), 20.0);
    let tmp = path.with_extension("tmp.exr");
    exr::prelude::write_rgb_file(&tmp, w, h, |x, y| {
        let [r, g, b] = texels[y * w + x];
        (r, g, b)
    })
    .unwrap();
    std::fs::rename(&tmp, &path).unwrap();
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
