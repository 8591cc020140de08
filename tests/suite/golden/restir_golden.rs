//! Regression images of Volumetric ReSTIR on lavapipe: single frames of the static cloud
//! (every pass on, direction and vertex reuse, emission) and of the Fig. 1-like scene
//! (surfaces, emitting letters and panels, a sky map), and every frame of the short
//! animated plume (camera, sun and density keyframes, velocity reprojection). Limits:
//! `SAME_DEVICE` (same seed, same scene, same device → the same image up to the
//! floating-point reassociation lavapipe's JIT may do). Validation layers are on.

use crate::common::cli::{nimbus, scratch, text};
use crate::common::gpu::{assert_no_validation_errors, context, scene};
use crate::common::{compare_with_golden, SAME_DEVICE};
use nimbus::renderer::{render, RenderOptions};

/// The path of the scene `name` of assets/scenes (what its relative files resolve
/// against).
fn asset_path(name: &str) -> String {
    format!("{}/assets/scenes/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn asset(name: &str) -> String {
    std::fs::read_to_string(format!(
        "{}/assets/scenes/{name}",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// Renders `scene` keeping every frame's own image; checks validation and finiteness.
fn render_frames(
    ctx: &nimbus_gpu::Context,
    scene: &nimbus_scene::Scene,
) -> nimbus::renderer::RenderResult {
    let plan = nimbus::plan::build(scene, None).expect("plan");
    assert!(plan.restir().is_some(), "the scene renders with ReSTIR");
    let opts = RenderOptions {
        keep_frames: true,
        ..Default::default()
    };
    let result = render(ctx, scene, &plan, &opts).expect("render");
    assert_no_validation_errors(ctx);
    assert_eq!(result.non_finite_samples, 0, "non-finite samples");
    assert!(result.image.first_non_finite().is_none());
    assert_eq!(result.frame_images.len(), scene.render.frames as usize);
    result
}

/// The static cloud, K = 3, three frames (so temporal and spatial reuse both run on the
/// last one): the last frame alone, against its golden.
#[test]
fn golden_cloud_restir_last_frame() {
    let ctx = context();
    let mut scene = scene(
        &asset("cloud-restir.toml"),
        &asset_path("cloud-restir.toml"),
    );
    scene.render.width = 48;
    scene.render.height = 36;
    scene.render.frames = 3;
    let result = render_frames(&ctx, &scene);
    let last = result.frame_images.last().expect("frames");
    compare_with_golden("cloud-restir-48x36-frame2", last, SAME_DEVICE).unwrap();
}

/// The emissive cloud with vertex reuse, K = 2: the mean of two frames.
#[test]
fn golden_cloud_restir_emissive_vertex_reuse() {
    let ctx = context();
    let text = asset("cloud-restir.toml")
        .replace("max_bounces = 6", "max_bounces = 2\n[integrator.restir]\nreuse = \"vertex\"")
        .replace(
            "g = 0.6",
            "g = 0.6\nemission = { procedural = \"cloud\", dims = [32, 20, 32], noise_seed = 5 }\nemission_scale = [3.0, 1.2, 0.4]",
        );
    let mut scene = scene(&text, &asset_path("cloud-emissive.toml"));
    scene.render.width = 40;
    scene.render.height = 30;
    scene.render.frames = 2;
    let plan = nimbus::plan::build(&scene, None).unwrap();
    let restir = plan.restir().unwrap();
    assert!(restir.has_emission && restir.vertex_reuse);
    let result = render_frames(&ctx, &scene);
    compare_with_golden(
        "cloud-restir-emissive-vertex-40x30",
        &result.image,
        SAME_DEVICE,
    )
    .unwrap();
}

/// The Fig. 1-like scene (a cloud, a floor, emitting letters and panels, a sky map),
/// K = 4, three frames: the last frame, against its golden. Surface vertices, area lights
/// and the environment map together.
#[test]
fn golden_cloud_logo_last_frame() {
    let ctx = context();
    let path = format!(
        "{}/assets/scenes/cloud-logo.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let mut scene = nimbus_scene::load(std::path::Path::new(&path)).expect("cloud-logo scene");
    scene.render.width = 64;
    scene.render.height = 36;
    scene.render.frames = 3;
    let plan = nimbus::plan::build(&scene, None).unwrap();
    let restir = plan.restir().unwrap();
    assert!(restir.has_shapes && restir.has_meshes && restir.has_area_lights);
    let result = render_frames(&ctx, &scene);
    let last = result.frame_images.last().expect("frames");
    compare_with_golden("cloud-logo-64x36-frame2", last, SAME_DEVICE).unwrap();
}

/// Every frame of the animated plume: camera and sun keyframes, four density frames,
/// temporal reprojection through the velocity grid.
#[test]
fn golden_plume_sequence() {
    let ctx = context();
    let dir = format!("{}/assets/scenes", env!("CARGO_MANIFEST_DIR"));
    let mut scene = nimbus_scene::load(std::path::Path::new(&format!("{dir}/plume-anim.toml")))
        .expect("plume scene");
    scene.render.width = 48;
    scene.render.height = 36;
    let plan = nimbus::plan::build(&scene, None).unwrap();
    let restir = plan.restir().unwrap();
    assert!(restir.has_velocity && restir.animated_density);
    assert!(scene.lights_animated());
    let result = render_frames(&ctx, &scene);
    for (i, frame) in result.frame_images.iter().enumerate() {
        compare_with_golden(&format!("plume-anim-48x36-frame{i}"), frame, SAME_DEVICE).unwrap();
    }
}

/// `nimbus render --sequence DIR` writes one image per frame and the mean to --out.
#[test]
fn cli_writes_one_image_per_frame() {
    let dir = scratch("restir-sequence", "frames");
    let _ = std::fs::remove_dir_all(&dir);
    let out = dir.with_extension("exr");
    let scene = format!(
        "{}/assets/scenes/plume-anim.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let run = nimbus(&[
        "render",
        &scene,
        "--width",
        "16",
        "--height",
        "12",
        "--frames",
        "3",
        "--out",
        out.to_str().unwrap(),
        "--sequence",
        dir.to_str().unwrap(),
    ]);
    assert!(run.status.success(), "{}", text(&run.stderr));
    for i in 0..3 {
        let frame = dir.join(format!("frame_{i:04}.exr"));
        let image = nimbus::output::read_exr(&frame).expect("sequence frame");
        assert_eq!((image.width, image.height), (16, 12));
        assert!(image.first_non_finite().is_none());
    }
    assert!(!dir.join("frame_0003.exr").exists());
    assert!(out.exists());
}
