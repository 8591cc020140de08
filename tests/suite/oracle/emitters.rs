//! Emitting shapes (`[[shape]] emission`, area lights) in the baseline path tracer on
//! lavapipe: agreement with the independent CPU oracle (its own piece-by-power and
//! uniform-area sampling), one-sided quads, a mesh of 10 200 emitting triangles, bad
//! input refused naming the field, the crepuscular pass refusing them, and `--explain`.
//! Validation layers are on.

use std::path::Path;

use glam::Vec3;
use nimbus_scene::TriangleMesh;

use crate::common::cli::scratch;
use crate::common::gpu::{context, render_checked};
use crate::common::scenes::{LOW_CLOUD, LOW_CLOUD_CAMERA, LOW_CLOUD_FLOOR};
use crate::oracle::baseline::check_against_oracle;

/// A regular octahedron of "radius" 1 about the origin, counter-clockwise seen from
/// outside (so it emits outwards).
fn octahedron_obj() -> String {
    let mut text = String::from("v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n");
    for sx in [0, 1] {
        for sy in [0, 1] {
            for sz in [0, 1] {
                let (x, y, z) = (1 + sx, 3 + sy, 5 + sz);
                // (x, y, z) is counter-clockwise from outside when an even number of the
                // axes is negative.
                if (sx + sy + sz) % 2 == 0 {
                    text += &format!("f {x} {y} {z}\n");
                } else {
                    text += &format!("f {x} {z} {y}\n");
                }
            }
        }
    }
    text
}

/// Writes `text` as `name` in `dir` and loads it as a scene.
fn load(dir: &Path, name: &str, text: &str) -> nimbus_scene::Scene {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    nimbus_scene::load(&path).unwrap_or_else(|e| panic!("{name}: {e:#}"))
}

/// A floor, a small cloud above it, a sun, and `emitters` (shape tables), K = `bounces`.
fn emitter_scene(emitters: &str, bounces: u32, size: (u32, u32)) -> String {
    format!(
        r#"
[render]
width = {w}
height = {h}
frames = 32
spp = 4
seed = 13
{LOW_CLOUD_CAMERA}
[[light]]
type = "directional"
direction = [0.4, -1.0, -0.5]
irradiance = 0.5
{LOW_CLOUD}
[integrator]
volume = "baseline"
max_bounces = {bounces}
{LOW_CLOUD_FLOOR}
{emitters}"#,
        w = size.0,
        h = size.1
    )
}

/// An emitting quad facing down (edge_u × edge_v = −y) and an emitting octahedron mesh.
const QUAD_AND_MESH: &str = r#"
[[shape]]
type = "quad"
corner = [-0.8, 2.0, -0.8]
edge_u = [1.6, 0, 0]
edge_v = [0, 0, 1.6]
albedo = 0.3
emission = 2.5
[[shape]]
type = "mesh"
file = "octahedron.obj"
albedo = 0.5
emission = [3.0, 1.5, 0.75]
to_world = { scale = 0.3, rotate_deg = [0, 20, 0], translate = [1.2, 0.5, 0.6] }
"#;

/// The floor, a cloud and a sun with an emitting quad (facing down) and an emitting
/// octahedron mesh, K = 1 and K = 3: the baseline matches the CPU oracle (image means
/// within 1 % plus 4 combined standard errors, at most 2 % of the pixel channels beyond
/// 4.5; `baseline::check_against_oracle`).
#[test]
fn emitting_quad_and_mesh_match_the_cpu_oracle() {
    let ctx = context();
    let dir = scratch("emitters", "oracle");
    std::fs::write(dir.join("octahedron.obj"), octahedron_obj()).unwrap();
    for bounces in [1u32, 3] {
        let scene = load(
            &dir,
            "emitters.toml",
            &emitter_scene(QUAD_AND_MESH, bounces, (16, 12)),
        );
        check_against_oracle(&ctx, &scene, 21, &format!("area lights K={bounces}"));
    }
}

/// A sphere tessellated into 10 200 emitting triangles (a UV sphere of 100 segments and
/// 52 rings) above the floor: the table's binary search picks among them, the render is
/// finite and matches the CPU oracle (same criteria), and its image mean is within 1 %
/// (plus noise) of an emitting `type = "sphere"` shape of the same radius (the
/// tessellation's area is short by 0.1 %).
#[test]
fn ten_thousand_emitting_triangles_match_the_oracle_and_the_sphere_they_tessellate() {
    let ctx = context();
    let dir = scratch("emitters", "many");
    let mesh = TriangleMesh::uv_sphere(Vec3::ZERO, 1.0, 100, 52);
    assert_eq!(mesh.triangle_count(), 10_200);
    let mut obj = String::new();
    for p in &mesh.positions {
        obj += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    for t in &mesh.indices {
        obj += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(dir.join("sphere.obj"), obj).unwrap();
    let tessellated = "[[shape]]\ntype = \"mesh\"\nfile = \"sphere.obj\"\nalbedo = 0.4\n\
                       emission = [2.0, 1.6, 1.2]\n\
                       to_world = { scale = 0.35, translate = [1.1, 0.8, 0.4] }\n";
    let sphere = "[[shape]]\ntype = \"sphere\"\ncenter = [1.1, 0.8, 0.4]\nradius = 0.35\n\
                  albedo = 0.4\nemission = [2.0, 1.6, 1.2]\n";
    let mesh_scene = load(&dir, "mesh.toml", &emitter_scene(tessellated, 2, (16, 12)));
    check_against_oracle(&ctx, &mesh_scene, 22, "10k emitting triangles");
    let a = render_checked(&ctx, &mesh_scene, None);
    let b = render_checked(
        &ctx,
        &load(&dir, "sphere.toml", &emitter_scene(sphere, 2, (16, 12))),
        None,
    );
    crate::common::gpu::assert_means_agree(
        "tessellated vs sphere",
        (&a.image, &a.std_error),
        (&b.image, &b.std_error),
        4.0,
        0.01,
    );
}

/// A black emitting quad facing +z, K = 1: seen from the front every pixel that sees it
/// is its emission exactly, seen from behind it is black; the sun-lit floor around it
/// is the same from both sides' points of view only where it should be.
#[test]
fn a_quad_emits_on_the_side_of_edge_u_cross_edge_v_only() {
    let ctx = context();
    let quad = "[[shape]]\ntype = \"quad\"\ncorner = [-5, -5, 0]\nedge_u = [10, 0, 0]\n\
                edge_v = [0, 10, 0]\nemission = [1.5, 0.75, 0.25]\n";
    let text = |z: f32| {
        format!(
            "[render]\nwidth = 8\nheight = 6\nspp = 4\n\
             [camera]\nposition = [0.1, 0.2, {z}]\nlook_at = [0.1, 0.2, 0]\nhorizontal_fov_deg = 40\n\
             [[medium]]\ntype = \"grid\"\nbounds_min = [20, 20, 20]\nbounds_max = [21, 21, 21]\n\
             density = {{ procedural = \"cloud\", dims = [4, 4, 4] }}\n\
             [integrator]\nvolume = \"baseline\"\n{quad}"
        )
    };
    let front = render_checked(
        &ctx,
        &crate::common::gpu::scene(&text(3.0), "front.toml"),
        None,
    );
    let back = render_checked(
        &ctx,
        &crate::common::gpu::scene(&text(-3.0), "back.toml"),
        None,
    );
    for px in &front.image.data {
        assert_eq!(&px[..3], &[1.5, 0.75, 0.25], "front");
    }
    for px in &back.image.data {
        assert_eq!(&px[..3], &[0.0, 0.0, 0.0], "back");
    }
}

/// Negative, NaN and infinite emission are refused, naming the scene file, the shape
/// and the field.
#[test]
fn bad_emission_is_refused_naming_the_shape_and_field() {
    let dir = scratch("emitters", "bad");
    for (value, what) in [
        ("-1.0", "must be >= 0"),
        ("[1.0, -0.5, 0.0]", "must be >= 0"),
        ("nan", "finite"),
        ("[0.5, nan, 0.5]", "finite"),
        ("inf", "finite"),
    ] {
        let path = dir.join("bad.toml");
        std::fs::write(
            &path,
            format!(
                "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n\
                 [[shape]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n\
                 [[shape]]\ntype = \"quad\"\ncorner = [0, 0, 0]\nedge_u = [1, 0, 0]\n\
                 edge_v = [0, 1, 0]\nemission = {value}\n"
            ),
        )
        .unwrap();
        let error = format!("{:#}", nimbus_scene::load(&path).unwrap_err());
        for needle in [
            path.display().to_string().as_str(),
            "[[shape]] #2 (type = \"quad\")",
            "field `emission`",
            what,
        ] {
            assert!(
                error.contains(needle),
                "{value}: {needle:?} missing from: {error}"
            );
        }
    }
}

/// The crepuscular pass has no area-light sampling yet: a scene it would render with an
/// emitting shape is refused naming the shape and the integrator that renders it; the
/// same shape without emission is accepted.
#[test]
fn the_crepuscular_pass_refuses_emitting_shapes_naming_them() {
    let text = |emission: &str| {
        format!(
            "[camera]\nposition = [0, 1, 5]\nlook_at = [0, 0, 0]\n\
             [[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1\n\
             [[shape]]\ntype = \"quad\"\ncorner = [-3, 0, -3]\nedge_u = [0, 0, 6]\nedge_v = [6, 0, 0]\n\
             [[shape]]\ntype = \"box\"\ncenter = [0, 1, 0]\nsize = [1, 1, 1]\n{emission}"
        )
    };
    let plain = crate::common::gpu::scene(&text(""), "crepuscular.toml");
    assert!(nimbus::plan::build(&plain, None).is_ok());
    let emitting = crate::common::gpu::scene(&text("emission = 2.0\n"), "crepuscular.toml");
    let error = format!("{:#}", nimbus::plan::build(&emitting, None).unwrap_err());
    for needle in [
        "crepuscular.toml",
        "[[shape]] #2 (type = \"box\")",
        "field `emission`",
        "not supported yet by the crepuscular pass",
        "volume = \"baseline\"",
    ] {
        assert!(error.contains(needle), "{needle:?} missing from: {error}");
    }
}

/// `--explain` says whether emitter sampling is compiled in, and what the table holds.
#[test]
fn explain_says_whether_area_lights_are_compiled_in() {
    let dir = scratch("emitters", "explain");
    std::fs::write(dir.join("octahedron.obj"), octahedron_obj()).unwrap();
    for (emitters, on, expected) in [
        ("", false, "no shape emits"),
        (
            QUAD_AND_MESH,
            true,
            "2 emitting shape(s), 10 emitter primitive(s)",
        ),
    ] {
        let scene = load(&dir, "explain.toml", &emitter_scene(emitters, 1, (8, 6)));
        let plan = nimbus::plan::build(&scene, None).unwrap();
        let row = plan
            .decisions
            .iter()
            .find(|d| d.name.trim() == "SC_HAS_AREA_LIGHTS")
            .expect("an SC_HAS_AREA_LIGHTS row");
        assert_eq!(row.enabled, on, "{row:?}");
        assert!(row.reason.contains(expected), "{row:?}");
        assert!(plan.explain(&scene).contains("SC_HAS_AREA_LIGHTS"));
    }
}
