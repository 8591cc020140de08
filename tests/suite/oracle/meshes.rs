//! `[[shape]] type = "mesh"` renders: a mesh cube of 12 triangles as a `type = "box"`
//! shape of the same size and rotation (the crepuscular pass in a box medium, the
//! baseline path tracer beside a grid medium), a tessellated sphere of 100 480 triangles
//! (written as binary PLY) as a `type = "sphere"` shape, and bad mesh files refused
//! naming the scene, the shape, the field and the mesh file; ReSTIR's refusal of
//! surfaces names a mesh, and `--explain` says whether the traversal is compiled in.
//! Validation layers are on.
//!
//! The cube renders with the box's random numbers: same seed, same pixel-centre camera
//! rays (`pixel_jitter = false`), and geometry equal up to rounding, so every path makes
//! the same decisions except where a ray meets an edge or a shadow boundary within
//! rounding. The tolerances say how many pixels such rays may move and by how much.

use std::path::Path;

use glam::Vec3;
use nimbus::output::ImageRgb;
use nimbus_scene::TriangleMesh;

use crate::common::cli::scratch;
use crate::common::gpu::{
    assert_means_agree, assert_no_validation_errors, channels_beyond, context, render_checked,
};

/// The cube as OBJ quads: a unit cube centred on the origin (fanned into 12 triangles).
const CUBE_OBJ: &str = "v -0.5 -0.5 -0.5\nv 0.5 -0.5 -0.5\nv -0.5 0.5 -0.5\nv 0.5 0.5 -0.5\n\
v -0.5 -0.5 0.5\nv 0.5 -0.5 0.5\nv -0.5 0.5 0.5\nv 0.5 0.5 0.5\n\
f 1 5 7 3\nf 2 4 8 6\nf 1 2 6 5\nf 3 7 8 4\nf 1 3 4 2\nf 5 6 8 7\n";

/// Where the cube stands: centre, size, rotation (degrees about X, then Y, then Z).
const CENTER: &str = "[0.15, 0.7, -0.2]";
const SIZE: &str = "[0.9, 0.6, 0.7]";
const ROTATION: &str = "[15, 30, -10]";

/// The cube as a box shape, or as the mesh `cube.obj` placed alike.
fn cube(mesh: bool) -> String {
    if mesh {
        format!(
            "[[shape]]\ntype = \"mesh\"\nfile = \"cube.obj\"\nalbedo = 0.6\n\
             to_world = {{ scale = {SIZE}, rotate_deg = {ROTATION}, translate = {CENTER} }}\n"
        )
    } else {
        format!(
            "[[shape]]\ntype = \"box\"\ncenter = {CENTER}\nsize = {SIZE}\n\
             rotation_deg = {ROTATION}\nalbedo = 0.6\n"
        )
    }
}

/// The camera and the sun of the cube scenes.
const CAMERA_AND_SUN: &str = r#"[camera]
position = [0.3, 1.6, 4.2]
look_at = [0.0, 0.6, 0.0]
horizontal_fov_deg = 50
[[light]]
type = "directional"
direction = [0.35, -1.0, -0.45]
irradiance = 3.0"#;
const FLOOR: &str = "[[shape]]\ntype = \"quad\"\ncorner = [-3, 0, -3]\nedge_u = [6, 0, 0]\n\
edge_v = [0, 0, 6]\nalbedo = 0.5\n";

/// Writes `text` as `name` in `dir` and loads it as a scene.
fn load(dir: &Path, name: &str, text: &str) -> nimbus_scene::Scene {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    nimbus_scene::load(&path).unwrap_or_else(|e| panic!("{name}: {e:#}"))
}

/// Per-pixel comparison of two renders: the largest channel difference, and how many
/// pixels differ by more than `tol`.
fn pixel_differences(a: &ImageRgb, b: &ImageRgb, tol: f32) -> (f32, usize) {
    let mut largest = 0.0f32;
    let mut beyond = 0;
    for (pa, pb) in a.data.iter().zip(&b.data) {
        let d = (0..3).map(|c| (pa[c] - pb[c]).abs()).fold(0.0, f32::max);
        largest = largest.max(d);
        beyond += usize::from(d > tol);
    }
    (largest, beyond)
}

/// In a box medium under a directional light (single scattering, then K = 3 with
/// reflections off the cube, then the ME estimator, whose moment shadow maps trace the
/// cube along the light), the mesh cube renders as the box shape pixel by pixel:
/// within 1e-4 of the image's brightest pixel, except in at most 0.2 % of the pixels
/// (where a ray could pass an edge or a shadow boundary within rounding; measured:
/// none, the largest difference 2e-7 of the peak, 5.6e-6 with ME), and the means within
/// noise.
#[test]
fn a_mesh_cube_renders_as_a_box_shape_in_the_crepuscular_pass() {
    let ctx = context();
    let dir = scratch("meshes", "crepuscular-cube");
    std::fs::write(dir.join("cube.obj"), CUBE_OBJ).unwrap();
    for (bounces, estimator) in [(1, "mcwvds"), (3, "mcwvds"), (1, "me")] {
        let text = |mesh: bool| {
            format!(
                r#"
[render]
width = 64
height = 48
frames = 4
seed = 5
pixel_jitter = false
{CAMERA_AND_SUN}
[[medium]]
type = "box"
center = [0.0, 1.25, 0.0]
size = [3.0, 2.5, 3.0]
sigma_t = 0.4
albedo = 0.8
g = 0.3
[integrator]
max_bounces = {bounces}
box_estimator = "{estimator}"
{FLOOR}{}"#,
                cube(mesh)
            )
        };
        let box_scene = load(&dir, "box.toml", &text(false));
        let mesh_scene = load(&dir, "mesh.toml", &text(true));
        let a = render_checked(&ctx, &box_scene, None);
        let b = render_checked(&ctx, &mesh_scene, None);
        let peak = a.image.data.iter().flatten().fold(0.0f32, |m, v| m.max(*v));
        let (largest, beyond) = pixel_differences(&a.image, &b.image, 1e-4 * peak);
        let what = format!("crepuscular {estimator} K = {bounces}");
        println!(
            "{what}: largest difference {:.2e} of the peak, {beyond} of {} pixels beyond 1e-4",
            largest / peak,
            a.image.data.len()
        );
        assert!(
            beyond * 500 <= a.image.data.len(),
            "{what}: {beyond} pixels differ by more than 1e-4 of the peak"
        );
        assert_means_agree(
            &what,
            (&b.image, &b.std_error),
            (&a.image, &a.std_error),
            4.0,
            1e-3,
        );
    }
}

/// Beside a grid medium (the baseline path tracer, K = 2), the mesh cube renders as the
/// box shape, with the same bounds (measured: the largest difference 1.5e-6 of the peak).
/// The cube scene of the grid passes: a cloud above the floor and the cube, rendered by
/// `volume` ("baseline" or "restir") with the cube as a mesh or as a box shape.
fn grid_cube_text(mesh: bool, volume: &str) -> String {
    let spp = if volume == "baseline" { 2 } else { 1 };
    format!(
        r#"
[render]
width = 48
height = 36
frames = 4
spp = {spp}
seed = 9
pixel_jitter = false
{CAMERA_AND_SUN}
[[light]]
type = "environment"
radiance = 0.2
[[medium]]
type = "grid"
bounds_min = [-1.4, 1.2, -1.2]
bounds_max = [1.0, 2.2, 0.8]
density = {{ procedural = "cloud", dims = [16, 8, 16], noise_seed = 4 }}
density_scale = 6.0
albedo = 0.9
[integrator]
volume = "{volume}"
max_bounces = 2
{FLOOR}{}"#,
        cube(mesh)
    )
}

/// Renders the cube scene of `volume` with the box shape and with the mesh, and checks
/// that they agree pixel by pixel (the same random numbers meet the same surfaces, up to
/// float rounding at the cube's edges) and in their means.
fn mesh_cube_matches_the_box_shape(volume: &str) {
    let ctx = context();
    let dir = scratch("meshes", &format!("{volume}-cube"));
    std::fs::write(dir.join("cube.obj"), CUBE_OBJ).unwrap();
    let box_scene = load(&dir, "box.toml", &grid_cube_text(false, volume));
    let mesh_scene = load(&dir, "mesh.toml", &grid_cube_text(true, volume));
    let a = render_checked(&ctx, &box_scene, None);
    let b = render_checked(&ctx, &mesh_scene, None);
    let peak = a.image.data.iter().flatten().fold(0.0f32, |m, v| m.max(*v));
    let (largest, beyond) = pixel_differences(&a.image, &b.image, 1e-4 * peak);
    println!(
        "{volume}: largest difference {:.2e} of the peak, {beyond} of {} pixels beyond 1e-4",
        largest / peak,
        a.image.data.len()
    );
    assert!(
        beyond * 500 <= a.image.data.len(),
        "{volume}: {beyond} pixels differ by more than 1e-4 of the peak"
    );
    let noisy = channels_beyond((&b.image, &b.std_error), (&a.image, &a.std_error), 4.5);
    println!("{volume}: {noisy} pixel channels beyond 4.5 standard errors");
    assert_means_agree(
        volume,
        (&b.image, &b.std_error),
        (&a.image, &a.std_error),
        4.0,
        1e-3,
    );
    assert_no_validation_errors(&ctx);
}

#[test]
fn a_mesh_cube_renders_as_a_box_shape_in_the_baseline_pass() {
    mesh_cube_matches_the_box_shape("baseline");
}

/// Volumetric ReSTIR's surface vertices on a mesh: the same image as on the box shape.
#[test]
fn a_mesh_cube_renders_as_a_box_shape_in_restir_slow() {
    mesh_cube_matches_the_box_shape("restir");
}

fn binary_ply(mesh: &TriangleMesh) -> Vec<u8> {
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nelement face {}\n\
         property list uchar int vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.indices.len()
    )
    .into_bytes();
    for p in &mesh.positions {
        for v in p.to_array() {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    for t in &mesh.indices {
        out.push(3);
        for k in t {
            out.extend_from_slice(&(*k as i32).to_le_bytes());
        }
    }
    out
}

/// A sphere of 100 480 triangles (a UV sphere of 320 segments and 158 rings, binary
/// PLY) loads and renders as a `type = "sphere"` shape of the same radius, lit directly
/// (the crepuscular pass without media, deterministic): the facets' normals differ from
/// the sphere's by at most half a facet (0.01 rad), so pixels agree within 3 % of the
/// brightest, except where the silhouette or the shadow's edge crosses a pixel centre
/// differently (at most 0.2 % of the pixels: the tessellation's radius is short by
/// 5e-5 of the sphere's, a thousandth of a pixel here); the means agree within 0.5 %.
/// Measured: the largest difference 1.1 % of the peak, no pixel beyond 3 %. The budget's estimate
/// holds what the render allocates.
#[test]
fn a_tessellated_sphere_of_100k_triangles_renders_as_a_sphere_shape() {
    let ctx = context();
    let dir = scratch("meshes", "sphere-100k");
    let mesh = TriangleMesh::uv_sphere(Vec3::ZERO, 1.0, 320, 158);
    assert_eq!(mesh.triangle_count(), 100_480);
    std::fs::write(dir.join("sphere.ply"), binary_ply(&mesh)).unwrap();
    let text = |shape: &str| {
        format!(
            r#"
[render]
width = 96
height = 72
seed = 2
pixel_jitter = false
[camera]
position = [0.4, 1.8, 4.5]
look_at = [0.0, 0.7, 0.0]
horizontal_fov_deg = 45
[[light]]
type = "directional"
direction = [0.5, -1.0, -0.3]
irradiance = 3.0
{FLOOR}{shape}"#
        )
    };
    let sphere = text(
        "[[shape]]\ntype = \"sphere\"\ncenter = [0.1, 0.8, -0.1]\nradius = 0.75\nalbedo = 0.7\n",
    );
    let tessellated = text(
        "[[shape]]\ntype = \"mesh\"\nfile = \"sphere.ply\"\nalbedo = 0.7\n\
         to_world = { scale = 0.75, translate = [0.1, 0.8, -0.1] }\n",
    );
    let a = render_checked(&ctx, &load(&dir, "sphere.toml", &sphere), None);
    let scene = load(&dir, "mesh.toml", &tessellated);
    let b = render_checked(&ctx, &scene, None);
    let peak = a.image.data.iter().flatten().fold(0.0f32, |m, v| m.max(*v));
    let (largest, beyond) = pixel_differences(&a.image, &b.image, 0.03 * peak);
    println!(
        "100k sphere: largest difference {:.2e} of the peak, {beyond} of {} pixels beyond 3 %",
        largest / peak,
        a.image.data.len()
    );
    assert!(beyond * 500 <= a.image.data.len(), "{beyond} pixels differ");
    let (ma, mb) = (a.image.mean(), b.image.mean());
    for c in 0..3 {
        assert!(
            (ma[c] - mb[c]).abs() <= 5e-3 * ma[c],
            "channel {c}: mean {} (sphere) vs {} (mesh)",
            ma[c],
            mb[c]
        );
    }
    // The budget counts the mesh's buffers: what the render allocated is within it.
    let plan = nimbus::plan::build(&scene, None).unwrap();
    let estimate = nimbus::budget::Footprint::of(&scene, &plan)
        .unwrap()
        .device_bytes();
    let slack = 64 << 10;
    assert!(
        b.device_bytes <= estimate + slack && 2 * b.device_bytes >= estimate,
        "{} bytes allocated, {estimate} estimated",
        b.device_bytes
    );
}

/// A bad mesh in a scene: the error names the scene file, the shape, the field and the
/// mesh file, through the library and on the command line.
#[test]
fn bad_mesh_files_are_refused_naming_scene_shape_field_and_mesh_file() {
    let dir = scratch("meshes", "bad");
    let shape = |file: &str| {
        format!(
            "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n{FLOOR}\
             [[shape]]\ntype = \"mesh\"\nfile = \"{file}\"\n"
        )
    };
    std::fs::write(
        dir.join("nan.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n",
    )
    .unwrap();
    let cases = [
        ("missing.toml", "gone.obj", "file not found"),
        ("nan.toml", "nan.obj", "vertex 3 is not finite"),
    ];
    for (scene_name, file, what) in cases {
        let path = dir.join(scene_name);
        std::fs::write(&path, shape(file)).unwrap();
        let error = format!("{:#}", nimbus_scene::load(&path).unwrap_err());
        for needle in [
            path.display().to_string().as_str(),
            "[[shape]] #2 (type = \"mesh\")",
            "field `file`",
            file,
            what,
        ] {
            assert!(
                error.contains(needle),
                "{scene_name}: {needle:?} missing from: {error}"
            );
        }
        let out = crate::common::cli::nimbus(&["render", path.to_str().unwrap(), "--explain"]);
        let stderr = crate::common::cli::text(&out.stderr);
        assert!(
            !out.status.success(),
            "{scene_name}: the command accepted it"
        );
        assert!(
            stderr.contains("field `file`") && stderr.contains(file) && stderr.contains(what),
            "{scene_name}: {stderr}"
        );
    }
}

/// `--explain` says whether the BVH traversal is compiled in, and what the meshes hold.
#[test]
fn explain_says_whether_the_mesh_traversal_is_compiled_in() {
    let dir = scratch("meshes", "explain");
    std::fs::write(dir.join("cube.obj"), CUBE_OBJ).unwrap();
    let base = "[camera]\nposition = [0, 1, 5]\nlook_at = [0, 0, 0]\n\
                [[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1\n";
    for mesh in [false, true] {
        let scene = load(
            &dir,
            "explain.toml",
            &format!("{base}{FLOOR}{}", cube(mesh)),
        );
        let plan = nimbus::plan::build(&scene, None).unwrap();
        let row = plan
            .decisions
            .iter()
            .find(|d| d.name.trim() == "SC_HAS_MESHES")
            .expect("an SC_HAS_MESHES row");
        assert_eq!(row.enabled, mesh, "{row:?}");
        let expected = if mesh {
            "1 mesh(es), 12 triangles"
        } else {
            "BVH traversal compiled out"
        };
        assert!(row.reason.contains(expected), "{row:?}");
        assert!(plan.explain(&scene).contains("SC_HAS_MESHES"));
    }
}
