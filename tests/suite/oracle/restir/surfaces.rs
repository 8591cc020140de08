//! ReSTIR with surfaces beside and inside the cloud (a floor, a box shape, emitting
//! shapes, a fog box) against the baseline, and surfaces in hard places.

use super::hard_cases::{hard, small};
use super::*;

/// A floor under the cloud (seen below it and through it) and a box half inside the
/// cloud's grid, its other half in vacuum: surface vertices on the camera segment and
/// after scattering, shadows cast into the medium and onto the floor.
const FLOOR_AND_BOX: &str = r#"
[[shape]]
type = "quad"
corner = [-3.0, -0.65, 3.0]
edge_u = [6.0, 0.0, 0.0]
edge_v = [0.0, 0.0, -6.0]
albedo = [0.7, 0.6, 0.5]
[[shape]]
type = "box"
center = [0.75, -0.3, 0.45]
size = [0.4, 0.5, 0.4]
rotation_deg = [0, 30, 0]
albedo = [0.3, 0.6, 0.8]
"#;

/// A homogeneous box medium between the camera and the cloud (lower left), with its own
/// albedo and a backward g.
const FOG_BOX: &str = r#"
[[medium]]
type = "box"
center = [-0.6, -0.3, 1.25]
size = [0.6, 0.6, 0.4]
sigma_t = 3.0
albedo = [0.8, 0.7, 0.9]
g = -0.3
"#;

/// Emitting shapes: a quad above the cloud shining down (one-sided), and a small
/// octahedron mesh (8 emitting triangles, counter-clockwise from outside) below its front
/// edge, read from `mesh`.
fn emitters(mesh: &std::path::Path) -> String {
    format!(
        r#"
[[shape]]
type = "quad"
corner = [0.2, 0.9, -0.6]
edge_u = [0.8, 0.0, 0.0]
edge_v = [0.0, 0.0, 0.6]
emission = [3.0, 2.5, 2.0]
[[shape]]
type = "mesh"
file = "{}"
to_world = {{ scale = 0.15, translate = [0.5, -0.5, 1.0] }}
emission = [4.0, 1.5, 0.5]
albedo = 0.5
"#,
        mesh.display()
    )
}

/// A regular octahedron about the origin, counter-clockwise seen from outside.
const OCTAHEDRON_OBJ: &str = "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n\
f 1 3 5\nf 1 6 3\nf 1 5 4\nf 1 4 6\nf 2 5 3\nf 2 3 6\nf 2 4 5\nf 2 6 4\n";

/// The scene of the surfaces tests at K = `bounces`: a floor, a box shape half inside the
/// cloud's grid, an emitting quad and an emitting mesh, a fog box in front of the cloud;
/// checked with temporal and spatial reuse against the baseline (criteria in the module
/// docs), which tests/suite/oracle/emitters.rs checks against the CPU oracle.
fn check_surfaces_and_emitters(bounces: u32) {
    let dir = scratch("restir", &format!("emitters-k{bounces}"));
    let mesh = dir.join("octahedron.obj");
    std::fs::write(&mesh, OCTAHEDRON_OBJ).unwrap();
    let shapes = format!("{FLOOR_AND_BOX}{}", emitters(&mesh));
    check_cases(
        Cloud {
            bounces,
            shapes: &shapes,
            medium_extra: FOG_BOX,
            ..Cloud::default()
        },
        &[BOTH],
        &format!("surfaces K={bounces}"),
    );
}

/// Surfaces, emitters and a box medium beside the cloud at K = 3: paths with surface and
/// box vertices (up to three of them, so the one- and two-vertex paths of K = 1 and 2 are
/// candidates too) and light from area lights converge to the baseline. When this was
/// written: image means within +0.22 / -0.25 / -0.65 % (z +0.36 / -0.55 / -1.13), 1 of
/// 1296 channels beyond 4.5 SE. Without reuse, surfaces alone agreed too (0.02-0.15 %, 3
/// of 1296 channels), a case left out for CI time.
#[test]
fn surfaces_and_emitters_match_the_baseline_slow() {
    check_surfaces_and_emitters(3);
}

/// The same at K = 1 (the issue's second depth). Ignored in CI for time (about 3 minutes
/// on two cores); run it with `cargo test --test suite -- --ignored surfaces`. When this
/// was written: image means within +0.38 / -0.06 / -0.23 % (z +0.88 / -0.19 / -0.56), 0
/// of 1296 channels beyond 4.5 SE.
#[test]
#[ignore = "about 3 minutes; K = 3 runs in CI"]
fn surfaces_and_emitters_match_the_baseline_at_k1() {
    check_surfaces_and_emitters(1);
}

/// Surfaces in hard places: a camera inside a closed box sees nothing (exactly 0: every
/// light is outside); a black floor; a floor through the camera (rays along it); a box
/// enclosing the whole cloud with the camera outside (exactly 0 too). All finite with no
/// non-finite sample; the open ones are lit.
#[test]
fn surfaces_in_hard_places_stay_finite() {
    let ctx = context();
    let inside = hard(
        &ctx,
        Cloud {
            shapes: "[[shape]]\ntype = \"box\"\ncenter = [0.0, 0.25, 2.3]\nsize = [0.5, 0.5, 0.5]\nalbedo = 0.9",
            ..small()
        },
        "camera-in-box",
    );
    assert!(
        inside.data.iter().all(|p| *p == [0.0; 3]),
        "{:?}",
        inside.mean()
    );
    let enclosed = hard(
        &ctx,
        Cloud {
            shapes: "[[shape]]\ntype = \"box\"\ncenter = [0.0, 0.0, 0.0]\nsize = [2.2, 1.4, 2.2]\nalbedo = 0.0",
            ..small()
        },
        "cloud-in-black-box",
    );
    assert!(
        enclosed.data.iter().all(|p| *p == [0.0; 3]),
        "{:?}",
        enclosed.mean()
    );
    let black = hard(
        &ctx,
        Cloud {
            shapes: "[[shape]]\ntype = \"quad\"\ncorner = [-3, -0.65, 3]\nedge_u = [6, 0, 0]\nedge_v = [0, 0, -6]\nalbedo = 0.0",
            ..small()
        },
        "black-floor",
    );
    assert!(black.mean()[0] > 0.0);
    let grazing = hard(
        &ctx,
        Cloud {
            shapes: "[[shape]]\ntype = \"quad\"\ncorner = [-3, 0.25, 3]\nedge_u = [6, 0, 0]\nedge_v = [0, 0, -6]\nalbedo = 0.8",
            ..small()
        },
        "floor-through-camera",
    );
    assert!(grazing.mean()[0] > 0.0);
    assert_no_validation_errors(&ctx);
}
