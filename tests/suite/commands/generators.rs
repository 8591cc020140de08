//! The volume generators of `examples/` (paper-scale assets, written under `target/`):
//! each runs at a small size, writes a scene that loads, and renders a finite image of
//! what it promises. `cargo test` builds the examples next to the test binary.

use std::path::PathBuf;
use std::process::Command;

use nimbus_scene::FieldOverride;

use crate::common::cli::scratch;
use crate::common::gpu::{context, render_checked};

/// `target/<profile>/examples/<name>`, built by `cargo test`.
fn example(name: &str) -> PathBuf {
    let exe = PathBuf::from(env!("CARGO_BIN_EXE_nimbus"));
    exe.parent().unwrap().join("examples").join(name)
}

fn run(name: &str, args: &[&str]) {
    let out = Command::new(example(name))
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("{name}: {e} (cargo test builds the examples)"));
    assert!(
        out.status.success(),
        "{name} {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn render_small(scene: &std::path::Path) -> nimbus::renderer::RenderResult {
    let overrides = [
        FieldOverride::new("render.width", 32),
        FieldOverride::new("render.height", 18),
        FieldOverride::new("render.frames", 2),
    ];
    let scene = nimbus_scene::load_with(scene, &overrides).unwrap_or_else(|e| panic!("{e:#}"));
    let result = render_checked(&context(), &scene, None);
    assert!(result
        .image
        .data
        .iter()
        .all(|p| p.iter().all(|c| c.is_finite() && *c >= 0.0)));
    result
}

/// The smoke column in ground fog (issue 27's gallery): a grid of smoke inside three
/// overlapping fog boxes for the baseline path tracer; the smoke darkens the fog behind
/// it (its column of pixels differs from the fog beside it), and a size out of range is
/// refused.
#[test]
fn the_smoke_generator_writes_smoke_in_fog() {
    let dir = scratch("generators", "smoke");
    run("make_smoke", &[dir.to_str().unwrap(), "32"]);
    let path = dir.join("smoke-fog-32.toml");
    let scene = nimbus_scene::load(&path).unwrap_or_else(|e| panic!("{e:#}"));
    assert_eq!(
        scene.integrator.volume,
        nimbus_scene::VolumeIntegrator::Baseline
    );
    match &scene.media[..] {
        [nimbus_scene::Medium::Grid(g), fog @ ..] => {
            assert!(
                matches!(&g.density, nimbus_scene::GridSource::MitsubaVol { file } if file.ends_with("smoke-32.vol"))
            );
            assert_eq!(fog.len(), 3);
            assert!(fog
                .iter()
                .all(|m| matches!(m, nimbus_scene::Medium::Box(_))));
        }
        other => panic!("{other:?}"),
    }
    let with_smoke = render_small(&path);
    let text = std::fs::read_to_string(&path).unwrap();
    let fog_only = dir.join("fog-only.toml");
    std::fs::write(
        &fog_only,
        text.replace("density_scale = 12.0", "density_scale = 0.0"),
    )
    .unwrap();
    let without = render_small(&fog_only);
    let differ = with_smoke
        .image
        .data
        .iter()
        .zip(&without.image.data)
        .filter(|(a, b)| (a[1] - b[1]).abs() > 0.05 * b[1].max(1e-3))
        .count();
    assert!(differ > 20, "the smoke changes {differ} pixels");
    let out = Command::new(example("make_smoke"))
        .args([dir.to_str().unwrap(), "8"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("N = 8"));
}

/// The explosion glows: some pixels are far brighter than its dim sky (0.08 at most),
/// and orange (red over blue), from the emission alone.
#[test]
fn the_explosion_generator_writes_a_glowing_explosion() {
    let dir = scratch("generators", "explosion");
    run("make_explosion", &[dir.to_str().unwrap(), "32"]);
    let result = render_small(&dir.join("explosion-32.toml"));
    let brightest = result
        .image
        .data
        .iter()
        .max_by(|a, b| a[0].total_cmp(&b[0]))
        .unwrap();
    assert!(
        brightest[0] > 0.5 && brightest[0] > 2.0 * brightest[2],
        "{brightest:?}"
    );
    // Refuses a size it cannot write.
    let out = Command::new(example("make_explosion"))
        .args([dir.to_str().unwrap(), "4"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("N = 4"));
}

/// The plume at another resolution: four frames and a velocity, and a scene animating
/// them; the plume is seen against the sky.
#[test]
fn the_plume_generator_writes_an_animated_plume_at_any_size() {
    let dir = scratch("generators", "plume");
    run("make_plume", &[dir.to_str().unwrap(), "40"]);
    for f in ["f0", "f1", "f2", "f3", "velocity"] {
        assert!(dir.join(format!("plume-40-{f}.vol")).is_file(), "{f}");
    }
    let result = render_small(&dir.join("plume-anim-40.toml"));
    let sky = result.image.data[0];
    assert!(
        result
            .image
            .data
            .iter()
            .any(|p| (p[0] - sky[0]).abs() > 0.05),
        "the plume is seen"
    );

    // More frames: the motion benchmark scene, one density frame per scene frame.
    let dir = scratch("generators", "plume-motion");
    run("make_plume", &[dir.to_str().unwrap(), "16", "6"]);
    assert!(dir.join("plume-16-f5.vol").is_file());
    let path = dir.join("plume-motion-16.toml");
    let scene = nimbus_scene::load(&path).unwrap_or_else(|e| panic!("{e:#}"));
    assert!(scene.is_animated());
    assert_eq!(scene.render.frames, 6);
    match &scene.media[0] {
        nimbus_scene::Medium::Grid(g) => {
            assert_eq!(g.frames.len(), 5);
            assert!(g.velocity.is_some());
        }
        other => panic!("{other:?}"),
    }
    render_small(&path);
    let out = Command::new(example("make_plume"))
        .args([dir.to_str().unwrap(), "16", "1"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("F = \"1\""));
}
