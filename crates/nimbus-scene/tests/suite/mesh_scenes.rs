//! `[[shape]] type = "mesh"` in scene files: the mesh is loaded, placed and given its
//! BVH when the scene loads, shared among copies of the scene, and every error names
//! the scene file, the shape, the field and the mesh file.

use std::sync::Arc;

use glam::Vec3;
use nimbus_scene::{load, Shape};

use crate::common::*;

/// A unit cube centred on the origin as OBJ quads (fanned into 12 triangles).
const CUBE_OBJ: &str = "v -0.5 -0.5 -0.5\nv 0.5 -0.5 -0.5\nv -0.5 0.5 -0.5\nv 0.5 0.5 -0.5\n\
v -0.5 -0.5 0.5\nv 0.5 -0.5 0.5\nv -0.5 0.5 0.5\nv 0.5 0.5 0.5\n\
f 1 5 7 3\nf 2 4 8 6\nf 1 2 6 5\nf 3 7 8 4\nf 1 3 4 2\nf 5 6 8 7\n";

fn scene_with(dir: &TempDir, shape: &str) -> anyhow::Result<nimbus_scene::Scene> {
    let path = dir.write("scene.toml", format!("{CAMERA}{shape}").as_bytes());
    load(&path)
}

#[test]
fn a_mesh_shape_loads_placed_with_its_bvh() {
    let dir = TempDir::new("mesh-shape");
    dir.write("meshes/cube.obj", CUBE_OBJ.as_bytes());
    let scene = scene_with(
        &dir,
        "[[shape]]\ntype = \"mesh\"\nfile = \"meshes/cube.obj\"\nalbedo = 0.5\n\
         to_world = { scale = [2, 1, 1], rotate_deg = [0, 90, 0], translate = [0, 1, 0] }\n",
    )
    .unwrap();
    let [Shape::Mesh { mesh, albedo, .. }] = scene.shapes.as_slice() else {
        panic!("one mesh shape expected, got {:?}", scene.shapes);
    };
    assert_eq!(*albedo, Vec3::splat(0.5));
    assert_eq!(mesh.triangle_count(), 12);
    assert_eq!(mesh.file, dir.0.join("meshes/cube.obj"));
    // Scaled by 2 along x, then turned 90° about y: the long axis lies along z.
    let (lo, hi) = mesh.bounds();
    let expect_lo = Vec3::new(-0.5, 0.5, -1.0);
    let expect_hi = Vec3::new(0.5, 1.5, 1.0);
    assert!(
        (lo - expect_lo).abs().max_element() < 1e-6 && (hi - expect_hi).abs().max_element() < 1e-6,
        "bounds {lo} .. {hi}"
    );
    assert!(!mesh.bvh.nodes().is_empty());
    // Copies of the scene share the mesh.
    let copy = scene.clone();
    let Shape::Mesh { mesh: shared, .. } = &copy.shapes[0] else {
        unreachable!()
    };
    assert!(Arc::ptr_eq(mesh, shared));
    assert_eq!(scene, copy);
    // The default albedo is 0 and the default placement the identity.
    let plain = scene_with(
        &dir,
        "[[shape]]\ntype = \"mesh\"\nfile = \"meshes/cube.obj\"\n",
    )
    .unwrap();
    let [Shape::Mesh { mesh, albedo, .. }] = plain.shapes.as_slice() else {
        panic!("one mesh shape expected");
    };
    assert_eq!(*albedo, Vec3::ZERO);
    assert_eq!(mesh.bounds(), (Vec3::splat(-0.5), Vec3::splat(0.5)));
}

#[test]
fn bad_mesh_shapes_name_the_scene_the_shape_the_field_and_the_mesh_file() {
    let dir = TempDir::new("mesh-bad");
    let scene = dir.0.join("scene.toml").display().to_string();
    let table = "[[shape]] #1 (type = \"mesh\")";
    let check = |shape: &str, needles: &[&str]| {
        let error = format!("{:#}", scene_with(&dir, shape).unwrap_err());
        let mut all = vec![scene.as_str(), table];
        all.extend_from_slice(needles);
        assert_contains(&error, &all);
    };
    // A missing file.
    check(
        "[[shape]]\ntype = \"mesh\"\nfile = \"gone.obj\"\n",
        &["field `file`", "file not found", "gone.obj"],
    );
    // No file at all, and a file that is no mesh format.
    check(
        "[[shape]]\ntype = \"mesh\"\n",
        &["field `file`", "missing required field"],
    );
    dir.write("cube.stl", b"solid");
    check(
        "[[shape]]\ntype = \"mesh\"\nfile = \"cube.stl\"\n",
        &["field `file`", "cube.stl", ".obj or .ply"],
    );
    // A NaN vertex, named by the file's own index.
    dir.write("nan.obj", b"v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n");
    let nan = dir.0.join("nan.obj").display().to_string();
    check(
        "[[shape]]\ntype = \"mesh\"\nfile = \"nan.obj\"\n",
        &["field `file`", &nan, "vertex 3"],
    );
    // An index out of range, with its line.
    dir.write("range.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    check(
        "[[shape]]\ntype = \"mesh\"\nfile = \"range.obj\"\n",
        &[
            "field `file`",
            "range.obj",
            "face #1 (line 4)",
            "out of range",
        ],
    );
    // A bad placement names its own table and field.
    dir.write("cube.obj", CUBE_OBJ.as_bytes());
    check(
        "[[shape]]\ntype = \"mesh\"\nfile = \"cube.obj\"\nto_world = { scale = [1, 0, 1] }\n",
        &["> to_world", "field `scale`", "non-zero"],
    );
    // Emission: negative or NaN is refused naming the field (an emitting mesh is fine).
    check(
        "[[shape]]\ntype = \"mesh\"\nfile = \"cube.obj\"\nemission = [1, -1, 0]\n",
        &["field `emission`", "must be >= 0"],
    );
    check(
        "[[shape]]\ntype = \"mesh\"\nfile = \"cube.obj\"\nemission = nan\n",
        &["field `emission`", "finite"],
    );
    let emitting = scene_with(
        &dir,
        "[[shape]]\ntype = \"mesh\"\nfile = \"cube.obj\"\nemission = [1, 2, 3]\n",
    )
    .unwrap();
    assert_eq!(emitting.shapes[0].emission(), Vec3::new(1.0, 2.0, 3.0));
}
