//! `[[medium]] type = "vdb"` scenes on the files OpenVDB wrote (`assets/test-vdb/`): the
//! grid placed by its own transform and `to_world`, every active voxel at its world
//! position in the dense window the renderer uploads, and bad files and tables refused
//! with messages naming the scene file, the table, the field, the `.vdb` file and the
//! grid.

use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3, IVec3};
use nimbus_scene::{
    load_grid, read_vdb_grid, BrickGrid, GridSource, Medium, VdbGridKind, VoxelGrid,
};

use crate::common::{assert_contains, parse, TempDir, CAMERA};

fn asset(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets/test-vdb")
        .join(name)
        .canonicalize()
        .expect("test file")
}

fn medium(body: &str) -> String {
    format!("{CAMERA}[[medium]]\ntype = \"vdb\"\n{body}\n")
}

fn grid_of(scene: &nimbus_scene::Scene) -> &nimbus_scene::GridMedium {
    match &scene.media[0] {
        Medium::Grid(g) => g,
        Medium::Box(_) | Medium::Convex(_) => panic!("a grid medium"),
    }
}

fn close(a: DVec3, b: DVec3) -> bool {
    (a - b).abs().max_element() <= 1e-6 * (1.0 + b.abs().max_element())
}

/// The world position of the centre of dense voxel `d` of `grid` in the medium's box.
fn dense_centre(g: &nimbus_scene::GridMedium, grid: &VoxelGrid, d: [u32; 3]) -> DVec3 {
    let (lo, hi) = (g.bounds_min.as_dvec3(), g.bounds_max.as_dvec3());
    let n = DVec3::from_array(grid.dims.map(f64::from));
    lo + (DVec3::from_array(d.map(f64::from)) + 0.5) / n * (hi - lo)
}

/// A grid with a non-uniform scale, with and without a `to_world` that scales (one
/// axis negatively) and translates: the placement composes the transforms, the window
/// is the active box grown by one voxel, and every voxel of the window holds the file's
/// value (0 where inactive) at the centre that `index_to_world` maps the voxel to.
#[test]
fn vdb_grids_load_into_their_window_at_their_world_positions() {
    let file = asset("half_zip.vdb");
    let sparse = read_vdb_grid(&file, None, VdbGridKind::Scalar, "t").unwrap();
    let (bmin, bmax) = sparse.active_bbox.unwrap();
    for to_world in [
        "",
        "to_world = { scale = [2, -1, 0.5], translate = [1, 2, -3] }",
    ] {
        let text = medium(&format!(
            "density = {{ file = \"{}\" }}\ndensity_scale = 3\n{to_world}",
            file.display()
        ));
        let scene = parse(&text).unwrap_or_else(|e| panic!("{e:#}"));
        let g = grid_of(&scene);
        assert_eq!(g.density_scale, 3.0);
        let placement = g.vdb.as_ref().expect("a vdb placement");
        let expected_to_world = if to_world.is_empty() {
            DMat4::IDENTITY
        } else {
            DMat4::from_translation(DVec3::new(1.0, 2.0, -3.0))
                * DMat4::from_scale(DVec3::new(2.0, -1.0, 0.5))
        };
        let m = expected_to_world * sparse.index_to_world;
        assert!(placement.index_to_world.abs_diff_eq(m, 1e-12));
        assert_eq!(placement.active_bbox, (bmin, bmax));
        let GridSource::Vdb { window, .. } = &g.density else {
            panic!("a vdb source");
        };
        assert_eq!(window.origin, bmin - 1);
        let span = bmax - bmin + 3;
        assert_eq!(window.dims, [span.x as u32, span.y as u32, span.z as u32]);
        assert_eq!(window.flip, [false, !to_world.is_empty(), false]);
        assert_eq!(g.density.dims().unwrap(), window.dims);

        let dense = load_grid(&g.density, 1, "t").unwrap();
        let mut active = 0;
        for dk in 0..window.dims[2] {
            for dj in 0..window.dims[1] {
                for di in 0..window.dims[0] {
                    let d = [di, dj, dk];
                    let world = dense_centre(g, &dense, d);
                    let index = (m.inverse() * world.extend(1.0)).truncate();
                    let ijk = index.round().as_ivec3();
                    assert!((index - ijk.as_dvec3()).abs().max_element() < 1e-6);
                    let (value, on) = sparse.value_at(ijk);
                    let expected = if on { value[0] } else { 0.0 };
                    assert_eq!(dense.get(di, dj, dk), expected, "voxel {ijk}");
                    active += usize::from(on);
                    let inside = ijk.cmpge(bmin).all() && ijk.cmple(bmax).all();
                    assert!(inside || !on);
                }
            }
        }
        assert_eq!(active as u64, sparse.active_voxels);
        // The field falls to 0 at the box's faces (the window's outer layer is empty).
        for a in 0..3 {
            let mut p = [
                0.5 * f64::from(window.dims[0]),
                0.5 * f64::from(window.dims[1]),
                0.5 * f64::from(window.dims[2]),
            ];
            p[a] = 0.0;
            assert_eq!(dense.sample_trilinear(p), 0.0);
            p[a] = f64::from(window.dims[a]);
            assert_eq!(dense.sample_trilinear(p), 0.0);
        }
        // The extent is the grown active box, half a voxel inside the rendered box.
        let corner_a = (m * (bmin - 1).as_dvec3().extend(1.0)).truncate();
        let corner_b = (m * (bmax + 1).as_dvec3().extend(1.0)).truncate();
        let half = DVec3::new(m.x_axis.x, m.y_axis.y, m.z_axis.z).abs() * 0.5;
        assert!(close(
            g.bounds_min.as_dvec3(),
            corner_a.min(corner_b) - half
        ));
        assert!(close(
            g.bounds_max.as_dvec3(),
            corner_a.max(corner_b) + half
        ));
    }
}

/// Grids chosen by name in a file of many; emission and velocity share the density's
/// window, the velocity's vectors turned by `to_world`; frames widen the window.
#[test]
fn grid_selection_emission_velocity_and_frames() {
    let multi = asset("multi.vdb");
    for (to_world, sign) in [("", 1.0), ("to_world = { scale = [2, -1, 1] }", -1.0)] {
        let scene = parse(&medium(&format!(
            "density = {{ file = \"{0}\", grid = \"density\" }}\n\
             emission = {{ file = \"{0}\", grid = \"density_copy\" }}\n\
             emission_scale = [1, 2, 3]\n\
             velocity = {{ file = \"{0}\" }}\n{to_world}",
            multi.display()
        )))
        .unwrap_or_else(|e| panic!("{e:#}"));
        let g = grid_of(&scene);
        let GridSource::Vdb { window, grid, file } = &g.density else {
            panic!("a vdb source");
        };
        assert_eq!((file, grid.as_deref()), (&multi, Some("density")));
        assert_eq!(window.origin, IVec3::new(0, 1, 2));
        assert_eq!(window.dims, [5, 4, 6]);
        assert_eq!(
            g.vdb.as_ref().unwrap().active_bbox,
            (IVec3::new(1, 2, 3), IVec3::new(3, 3, 6))
        );
        let density = load_grid(&g.density, 1, "t").unwrap();
        let emission = load_grid(g.emission.as_ref().unwrap(), 1, "t").unwrap();
        assert_eq!(density, emission);
        assert!(matches!(
            &g.velocity,
            Some(GridSource::Vdb { grid: None, .. })
        ));
        let velocity = load_grid(g.velocity.as_ref().unwrap(), 3, "t").unwrap();
        assert_eq!(velocity.channels, 3);
        assert_eq!(velocity.dims, window.dims);
        // Voxel (1, 2, 3) of "vel" is (_, -2, _) in the file; y flips with to_world.
        let sparse = read_vdb_grid(&multi, Some("vel"), VdbGridKind::Vec3, "t").unwrap();
        let v = sparse.value_at(IVec3::new(1, 2, 3)).0;
        assert_eq!(v[1], -2.0);
        let d = IVec3::new(1, 2, 3) - window.origin;
        let dy = if sign < 0.0 {
            window.dims[1] as i32 - 1 - d.y
        } else {
            d.y
        };
        let scale = if sign < 0.0 {
            [2.0, -1.0, 1.0]
        } else {
            [1.0; 3]
        };
        for c in 0..3 {
            assert_eq!(
                velocity.get_channel(d.x as u32, dy as u32, d.z as u32, c),
                v[c as usize] * scale[c as usize]
            );
        }
    }

    // A frame with another grid of the same transform widens the window.
    let float = asset("half_zip.vdb");
    let scene = parse(&medium(&format!(
        "density = {{ file = \"{0}\" }}\n[[medium.frame]]\nframe = 4\ndensity = {{ file = \"{0}\" }}",
        float.display()
    )))
    .unwrap();
    let g = grid_of(&scene);
    assert_eq!(g.frames.len(), 1);
    assert_eq!(g.frames[0].density, g.density);
}

/// A vec3 emission grid is rgb radiance: loaded with its three channels as the file
/// holds them, not turned by `to_world` as a velocity's vectors are (the bricks' rgb
/// path is checked with a 3-channel .vol in `assets.rs`).
#[test]
fn vec3_emission_is_rgb_and_not_rotated() {
    let multi = asset("multi.vdb");
    let sparse = read_vdb_grid(&multi, Some("vel"), VdbGridKind::Vec3, "t").unwrap();
    for to_world in [
        "",
        "to_world = { scale = [2, -1, 1], rotate_deg = [0, 90, 0] }",
    ] {
        let scene = parse(&medium(&format!(
            "density = {{ file = \"{0}\", grid = \"density\" }}\n\
             emission = {{ file = \"{0}\", grid = \"vel\" }}\n{to_world}",
            multi.display()
        )))
        .unwrap_or_else(|e| panic!("{e:#}"));
        let g = grid_of(&scene);
        let GridSource::Vdb { window, .. } = g.emission.as_ref().unwrap() else {
            panic!("a vdb source");
        };
        let dense = load_grid(g.emission.as_ref().unwrap(), 3, "t").unwrap();
        // "vel" holds negative components: the renderer's loader refuses them as
        // radiance, naming the grid and the voxel.
        let e = nimbus_scene::BrickGrid::load(g.emission.as_ref().unwrap(), 0, "t").unwrap_err();
        assert_contains(
            &format!("{e:#}"),
            &["multi.vdb", "grid \"vel\"", "is negative"],
        );
        let ijk = IVec3::new(1, 2, 3);
        let v = sparse.value_at(ijk).0;
        let d = ijk - window.origin;
        let di = IVec3::from_array([0, 1, 2].map(|a| {
            if window.flip[a] {
                window.dims[a] as i32 - 1 - d[a]
            } else {
                d[a]
            }
        }));
        for c in 0..3 {
            assert_eq!(
                dense.get_channel(di.x as u32, di.y as u32, di.z as u32, c),
                v[c as usize]
            );
        }
    }
}

/// `albedo` as a vdb grid (Houdini's `Cd`): a float or vec3 grid on the density's window,
/// its values colours that `to_world` does not turn, and the colour then 1. A box medium
/// takes no albedo grid.
#[test]
fn vdb_albedo_grid_shares_the_density_window() {
    let multi = asset("multi.vdb");
    for (grid, channels) in [("density", 1), ("vel", 3)] {
        let scene = parse(&medium(&format!(
            "density = {{ file = \"{0}\", grid = \"density\" }}\n\
             albedo = {{ file = \"{0}\", grid = \"{grid}\" }}\n\
             to_world = {{ rotate_deg = [0, 90, 0] }}",
            multi.display()
        )))
        .unwrap_or_else(|e| panic!("{e:#}"));
        let g = grid_of(&scene);
        assert_eq!(g.albedo, glam::Vec3::ONE);
        let (GridSource::Vdb { window: d, .. }, Some(GridSource::Vdb { window: a, .. })) =
            (&g.density, g.albedo_grid.as_ref())
        else {
            panic!("vdb sources");
        };
        assert_eq!((a.origin, a.dims, a.flip), (d.origin, d.dims, d.flip));
        assert_eq!(a.vector_map, glam::DMat3::IDENTITY);
        let dense = load_grid(g.albedo_grid.as_ref().unwrap(), channels, "t").unwrap();
        assert_eq!(dense.channels, channels);
    }
    let err = parse(
        "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n\
         [[light]]\ntype = \"environment\"\nradiance = 1.0\n\
         [[medium]]\ntype = \"box\"\ncenter = [0, 0, 0]\nsize = 1.0\nsigma_t = 1.0\n\
         albedo = { procedural = \"cloud\", dims = [4, 4, 4] }\n",
    )
    .unwrap_err();
    assert_contains(
        &format!("{err:#}"),
        &["[[medium]] #1", "`albedo`", "colour"],
    );
}

/// Bad files and tables: each error names the scene file, the table, the field, the
/// `.vdb` file and the grid.
#[test]
fn bad_vdb_media_are_refused_naming_file_and_grid() {
    let dir = TempDir::new("vdb-scenes");
    let float = asset("float_blosc.vdb");
    let half = asset("half_zip.vdb");
    let multi = asset("multi.vdb");
    let bytes = std::fs::read(&float).unwrap();
    let truncated = dir.write("truncated.vdb", &bytes[..bytes.len() * 3 / 5]);
    let not_vdb = dir.write("not.vdb", b"hello, this is not a VDB file at all");
    let density = |file: &Path, extra: &str| {
        medium(&format!(
            "density = {{ file = \"{}\"{extra} }}",
            file.display()
        ))
    };
    let table = "[[medium]] #1 (type = \"vdb\")";
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            density(&truncated, ""),
            vec!["truncated.vdb", "(\"density\")", "corrupt file"],
        ),
        (density(&not_vdb, ""), vec!["not.vdb", "not a VDB file"]),
        (
            density(&asset("vec3_blosc.vdb"), ", grid = \"vel\""),
            vec!["grid \"vel\"", "it holds vec3s values; a scalar grid"],
        ),
        (
            density(&asset("levelset_blosc.vdb"), ""),
            vec!["grid \"surface\"", "level set"],
        ),
        (
            density(&multi, ", grid = \"smoke\""),
            vec!["no grid named \"smoke\"", "density (float)"],
        ),
        (
            density(&multi, ", grid = \"mask\""),
            vec!["grid \"mask\"", "it holds bool values"],
        ),
        (
            density(&asset("inactive_modes_blosc.vdb"), ""),
            vec!["inactive_modes_blosc.vdb", "its background", "must be 0"],
        ),
        (
            format!(
                "{}to_world = {{ scale = [1e6, 1e-6, 1e-6] }}",
                density(&half, "")
            ),
            vec!["field `to_world`", "half_zip.vdb", "is degenerate"],
        ),
        (
            format!(
                "{}\n[[medium.frame]]\nframe = 1\ndensity = {{ file = \"{}\" }}",
                density(&half, ""),
                float.display()
            ),
            vec!["[[medium.frame]] #1", "float_blosc.vdb", "index-to-world transform"],
        ),
        (
            format!(
                "{}emission = {{ file = \"{}\" }}",
                density(&multi, ", grid = \"temperature\""),
                half.display()
            ),
            vec!["field `emission`", "half_zip.vdb", "index-to-world transform"],
        ),
        (
            format!("{}emission_scale = 2", density(&half, "")),
            vec!["field `emission_scale`", "without `emission`"],
        ),
        (
            format!("{}to_world = {{ scale = [1, 0, 1] }}", density(&half, "")),
            vec!["to_world", "`scale`", "non-zero"],
        ),
        (
            format!("{}to_world = {{ translate = [1e9, 0, 0] }}", density(&half, "")),
            vec!["to_world", "`translate`"],
        ),
        (
            format!("{}bounds_min = [0, 0, 0]", density(&half, "")),
            vec!["bounds_min"],
        ),
        (
            format!(
                "{CAMERA}[[medium]]\ntype = \"grid\"\nbounds_min = [0, 0, 0]\nbounds_max = [1, 1, 1]\ndensity = {{ file = \"{}\" }}",
                float.display()
            ),
            vec!["type = \"vdb\"", "OpenVDB file"],
        ),
    ];
    for (text, needles) in cases {
        let e = match parse(&text) {
            Ok(_) => panic!("should be refused:\n{text}"),
            Err(e) => format!("{e:#}"),
        };
        assert_contains(&e, &["scenes/test.toml"]);
        if !text.contains("type = \"grid\"") {
            assert_contains(&e, &[table]);
        }
        assert_contains(&e, &needles);
    }
    // Tiles 8000 voxels apart: the scene loads (only its topology is read); the dense
    // window over that box is refused before it is allocated.
    let tiles = asset("tiles_blosc.vdb");
    let scene = parse(&density(&tiles, "")).unwrap();
    let e = format!(
        "{:#}",
        load_grid(&grid_of(&scene).density, 1, "scene.toml: density").unwrap_err()
    );
    assert_contains(
        &e,
        &[
            "scene.toml: density",
            "tiles_blosc.vdb",
            "exceeds the limit",
        ],
    );
}

/// The same grids as 8³ bricks (the sparse form the GPU storage is built on): every
/// lattice point of the window holds the dense window's value, `p_to_world` puts it where
/// the dense grid's voxel centre is, and the bricks hold only the file's leaves and
/// their neighbours, not the window.
#[test]
fn vdb_bricks_hold_the_window_values_at_their_world_positions() {
    let file = asset("half_zip.vdb");
    for to_world in [
        "",
        "to_world = { scale = [2, -1, 0.5], translate = [1, 2, -3] }",
    ] {
        let scene = parse(&medium(&format!(
            "density = {{ file = \"{}\" }}\n{to_world}",
            file.display()
        )))
        .unwrap();
        let g = grid_of(&scene);
        let GridSource::Vdb { window, .. } = &g.density else {
            panic!("a vdb source");
        };
        let dense = load_grid(&g.density, 1, "t").unwrap();
        let bricks = BrickGrid::load(&g.density, 1, "t").unwrap();
        assert_eq!(bricks.lattice_min + bricks.origin, window.origin);
        let p_to_world = g.p_to_world(&bricks).unwrap();
        for dk in 0..window.dims[2] {
            for dj in 0..window.dims[1] {
                for di in 0..window.dims[0] {
                    let d = [di, dj, dk];
                    let ijk = IVec3::from_array([0, 1, 2].map(|a| {
                        let o = if window.flip[a] {
                            window.dims[a] - 1 - d[a]
                        } else {
                            d[a]
                        };
                        window.origin[a] + o as i32
                    }));
                    let l = ijk - bricks.origin;
                    assert_eq!(bricks.get(l), dense.get(di, dj, dk), "voxel {ijk}");
                    let world = (p_to_world * (l.as_dvec3() + 0.5).extend(1.0)).truncate();
                    assert!(close(world, dense_centre(g, &dense, d)), "voxel {ijk}");
                }
            }
        }
        let sparse = read_vdb_grid(&file, None, VdbGridKind::Scalar, "t").unwrap();
        assert!(bricks.bricks.len() <= 27 * sparse.brick_count());
    }
}
