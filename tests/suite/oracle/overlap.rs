//! Overlapping media: extinctions add, a collision picks a medium in proportion to its σt
//! (docs/scene-format.md, "Overlapping media"). The baseline path tracer renders a grid
//! overlapping box and convex media, also overlapping each other, and so does Volumetric
//! ReSTIR; the crepuscular pass refuses overlaps.

use std::path::Path;

use crate::common::cli::scratch;
use crate::common::gpu::{assert_means_agree, channels_beyond, context, render_checked, scene};
use crate::common::scenes::{CLOUD_BOUNDS, CLOUD_SUN_AND_SKY};
use crate::oracle::baseline::check_against_oracle;

const DIMS: [u32; 3] = [16, 10, 16];

/// Writes `values` as a raw float32 grid of [`DIMS`].
fn write_raw(dir: &Path, name: &str, values: &[f32]) -> String {
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    let path = dir.join(name);
    std::fs::write(&path, bytes).expect("write raw grid");
    path.display().to_string()
}

/// A grid medium of density file `density` (scaled by 8) on the box ±(1, 0.6, 1), under
/// a sun and a sky, K = 3, with `extra` media after it.
fn grid_scene(density: &str, extra: &str) -> String {
    format!(
        r#"
[render]
width = 16
height = 12
spp = 8
frames = 32
seed = 11
[camera]
position = [0.4, 0.5, 2.6]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 60
{CLOUD_SUN_AND_SKY}
[[medium]]
type = "grid"
{CLOUD_BOUNDS}
density = {{ file = {density:?}, dims = [{}, {}, {}] }}
density_scale = 8.0
albedo = [0.9, 0.8, 0.7]
g = 0.4
{extra}
[integrator]
volume = "baseline"
max_bounces = 3
"#,
        DIMS[0], DIMS[1], DIMS[2]
    )
}

/// A box of fog (σt 2) filling a grid's box renders as one grid whose density is the
/// sum (the grid's values plus 2 / 8 at every voxel: trilinear of a constant is that
/// constant, and the face clamp is the same), both with the same albedo and g.
#[test]
fn a_fog_box_filling_a_grid_renders_as_one_grid_of_the_summed_density() {
    let ctx = context();
    let dir = scratch("overlap", "filling");
    let cloud = nimbus_scene::procedural_cloud(DIMS, 5);
    let alone = write_raw(&dir, "cloud.raw", &cloud.data);
    let summed: Vec<f32> = cloud.data.iter().map(|v| v + 2.0 / 8.0).collect();
    let summed = write_raw(&dir, "summed.raw", &summed);
    let fog = "[[medium]]\ntype = \"box\"\ncenter = [0.0, 0.0, 0.0]\nsize = [2.0, 1.2, 2.0]\n\
               sigma_t = 2.0\nalbedo = [0.9, 0.8, 0.7]\ng = 0.4";
    let two = scene(&grid_scene(&alone, fog), "grid-and-fog.toml");
    assert_eq!(two.overlaps, [(0, 1)]);
    let two = render_checked(&ctx, &two, None);
    let one = render_checked(&ctx, &scene(&grid_scene(&summed, ""), "summed.toml"), None);
    let (a, b) = ((&two.image, &two.std_error), (&one.image, &one.std_error));
    assert_means_agree("grid + fog box vs summed grid", a, b, 4.0, 0.01);
    let beyond = channels_beyond(a, b, 4.5);
    assert!(
        beyond * 50 <= 3 * one.image.data.len(),
        "{beyond} channels beyond 4.5 SE"
    );
}

/// A box of another albedo and g reaching half into the grid, and a second one inside
/// it (three media, two overlapping pairs), K = 3: the baseline matches the CPU oracle,
/// whose nearest-collision race picks media as the contract says.
#[test]
fn boxes_overlapping_a_grid_match_the_cpu_oracle() {
    let ctx = context();
    let dir = scratch("overlap", "oracle");
    let cloud = nimbus_scene::procedural_cloud(DIMS, 6);
    let density = write_raw(&dir, "cloud.raw", &cloud.data);
    let boxes = "[[medium]]\ntype = \"box\"\ncenter = [0.8, -0.2, 0.3]\nsize = [1.0, 0.8, 1.0]\n\
                 rotation_deg = [0, 30, 0]\nsigma_t = 1.5\nalbedo = [0.3, 0.6, 0.9]\ng = -0.3\n\
                 [[medium]]\ntype = \"box\"\ncenter = [-0.4, 0.1, 0.0]\nsize = [0.5, 0.5, 0.5]\n\
                 sigma_t = 3.0\nalbedo = 0.5\ng = 0.8";
    let s = scene(&grid_scene(&density, boxes), "grid-and-boxes.toml");
    assert_eq!(s.overlaps, [(0, 1), (0, 2)]);
    check_against_oracle(&ctx, &s, 8, "grid overlapping boxes K=3");
}

/// The crepuscular pass takes disjoint media: its plan refuses overlapping ones, naming
/// both and the integrator that renders them.
#[test]
fn the_crepuscular_pass_refuses_overlapping_media() {
    let two_boxes = "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n\
                     [[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1.0\n\
                     [[medium]]\ntype = \"box\"\ncenter = [0, 0, 0]\nsize = [1, 1, 1]\nsigma_t = 1.0\n\
                     [[medium]]\ntype = \"box\"\ncenter = [0.5, 0, 0]\nsize = [1, 1, 1]\nsigma_t = 1.0\n";
    let err = nimbus::plan::build(&scene(two_boxes, "boxes-overlap.toml"), None)
        .err()
        .map(|e| format!("{e:#}"))
        .unwrap_or_default();
    for part in [
        "boxes-overlap.toml",
        "[[medium]] #1 and [[medium]] #2 overlap",
        "crepuscular",
    ] {
        assert!(err.contains(part), "{part:?} missing from: {err}");
    }
}

/// A dodecahedron (a convex medium) reaching into the grid and a rotated box beside it
/// (K = 3): the baseline matches the CPU oracle, the convex medium's planes clipping its
/// free flights and shadow rays where it overlaps the grid's density.
#[test]
fn a_convex_medium_overlapping_a_grid_matches_the_cpu_oracle() {
    let ctx = context();
    let dir = scratch("overlap", "convex");
    let cloud = nimbus_scene::procedural_cloud(DIMS, 7);
    let density = write_raw(&dir, "cloud.raw", &cloud.data);
    let s = scene(
        &grid_scene(&density, &convex_and_box()),
        "grid-and-convex.toml",
    );
    assert_eq!(s.overlaps, [(0, 1)]);
    check_against_oracle(&ctx, &s, 8, "grid overlapping a convex medium K=3");
}

/// A regular dodecahedron of circumradius 0.6 centred at (0.7, 0.1, 0.4) (σt 2.5, its
/// own albedo and g), half inside the grid, and a box beside the grid.
pub(crate) fn convex_and_box() -> String {
    let phi = (1.0 + 5.0f64.sqrt()) / 2.0;
    let normals = [
        [0.0, 1.0, phi],
        [0.0, -1.0, phi],
        [0.0, 1.0, -phi],
        [0.0, -1.0, -phi],
        [1.0, phi, 0.0],
        [-1.0, phi, 0.0],
        [1.0, -phi, 0.0],
        [-1.0, -phi, 0.0],
        [phi, 0.0, 1.0],
        [-phi, 0.0, 1.0],
        [phi, 0.0, -1.0],
        [-phi, 0.0, -1.0],
    ];
    let centre = [0.7, 0.1, 0.4];
    // Inradius of a regular dodecahedron: 0.7947 × its circumradius.
    let inradius = 0.7947 * 0.6;
    let planes: Vec<String> = normals
        .iter()
        .map(|n| {
            let len: f64 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
            let u = n.map(|c: f64| c / len.sqrt());
            let d = inradius + u[0] * centre[0] + u[1] * centre[1] + u[2] * centre[2];
            format!("[{}, {}, {}, {d}]", u[0], u[1], u[2])
        })
        .collect();
    format!(
        "[[medium]]\ntype = \"convex\"\nplanes = [{}]\nsigma_t = 2.5\nalbedo = [0.4, 0.7, 0.9]\n\
         g = -0.4\n[[medium]]\ntype = \"box\"\ncenter = [-1.5, 0.0, 0.2]\nsize = [0.6, 0.6, 0.6]\n\
         rotation_deg = [20, 0, 30]\nsigma_t = 1.5\nalbedo = 0.7\ng = 0.6",
        planes.join(", ")
    )
}
