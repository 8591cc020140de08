//! Loading triangle meshes: OBJ and PLY (ascii, binary little and big endian),
//! fanning, `to_world`, and every error the loader promises.

use std::path::{Path, PathBuf};

use glam::Vec3;
use nimbus_scene::{
    load_mesh, read_mesh, rotation_xyz_deg, LoadedMesh, MeshFormat, ToWorld, TriangleMesh,
    MAX_FACE_VERTICES, MAX_LINE_BYTES, MAX_MESH_TRIANGLES, MAX_MESH_VERTICES,
};

fn read(
    format: MeshFormat,
    name: &str,
    bytes: &[u8],
    to_world: &ToWorld,
) -> anyhow::Result<LoadedMesh> {
    let mut reader = bytes;
    read_mesh(&mut reader, format, name, to_world)
}

fn obj(text: &str) -> anyhow::Result<LoadedMesh> {
    read(
        MeshFormat::Obj,
        "m.obj",
        text.as_bytes(),
        &ToWorld::IDENTITY,
    )
}

fn ply(bytes: &[u8]) -> anyhow::Result<LoadedMesh> {
    read(MeshFormat::Ply, "m.ply", bytes, &ToWorld::IDENTITY)
}

#[track_caller]
fn ok(result: anyhow::Result<LoadedMesh>) -> LoadedMesh {
    match result {
        Ok(mesh) => mesh,
        Err(e) => panic!("mesh should load, got: {e:#}"),
    }
}

/// The message of an error that must happen; it must contain every needle.
#[track_caller]
fn err(result: anyhow::Result<LoadedMesh>, needles: &[&str]) -> String {
    let message = match result {
        Ok(mesh) => panic!("mesh should be rejected, loaded {mesh:?}"),
        Err(e) => format!("{e:#}"),
    };
    for needle in needles {
        assert!(
            message.contains(needle),
            "error message lacks {needle:?}:\n{message}"
        );
    }
    message
}

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

/// The unit square (two triangles from one quad) plus a triangle: the mesh the
/// OBJ and PLY fixtures below describe.
fn square_and_triangle() -> TriangleMesh {
    TriangleMesh {
        positions: vec![
            v(0., 0., 0.),
            v(1., 0., 0.),
            v(1., 1., 0.),
            v(0., 1., 0.),
            v(0., 0., 1.),
        ],
        indices: vec![[0, 1, 2], [0, 2, 3], [0, 4, 1]],
    }
}

#[test]
fn obj_reads_vertices_faces_and_ignores_the_rest() {
    let text = "# a comment\n\
                mtllib m.mtl\n\
                o thing\n\
                v 0 0 0\n\
                v 1 0 0 1.0\n\
                v 1 1 0 0.5 0.5 0.5\n\
                v 0 1 0\n\
                vt 0 0\n\
                vn 0 0 1\n\
                g part\n\
                usemtl red\n\
                s off\n\
                f 1/1/1 2/1/1 3//1 4\n\
                l 1 2 3\n\
                p 1\n\
                v 0 0 1\n\
                f -5 -1 2\n";
    let loaded = ok(obj(text));
    assert_eq!(loaded.mesh, square_and_triangle());
    assert_eq!(loaded.dropped_degenerate, 0);
}

#[test]
fn obj_forward_references_continuations_and_crlf() {
    let text =
        "f 1 2 \\\r\n 3 4\r\nv 0 0 0\r\nv 1 0 0\r\nv 1 1 0\r\nv 0 1 0\r\nv 0 0 1\r\nf 1 5 2\r\n";
    assert_eq!(ok(obj(text)).mesh, square_and_triangle());
}

const PLY_ASCII: &str = "ply\n\
    format ascii 1.0\n\
    comment extra properties and elements are skipped\n\
    obj_info made by hand\n\
    element vertex 5\n\
    property float nx\n\
    property double x\n\
    property float y\n\
    property list uchar float extra\n\
    property float z\n\
    property uchar red\n\
    element face 2\n\
    property uchar flags\n\
    property list uchar int vertex_indices\n\
    element edge 1\n\
    property int vertex1\n\
    property int vertex2\n\
    end_header\n\
    9 0 0 0 0 255\n\
    9 1 0 2 7.5 8.5 0 255\n\
    9 1 1 0 0 255\n\
    9 0 1 0 0 255\n\
    9 0 0 1 0.5 1 255\n\
    1 4 0 1 2 3\n\
    1 3 0 4 1\n\
    0 1\n";

#[test]
fn ply_ascii_reads_vertices_faces_and_skips_the_rest() {
    let loaded = ok(ply(PLY_ASCII.as_bytes()));
    assert_eq!(loaded.mesh, square_and_triangle());
    // An element without properties holds no data, whatever its count (read at once,
    // not counted through); a second `face` element is skipped like any other.
    let text = PLY_ASCII.replace(
        "end_header\n",
        "element nothing 4294967296\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n",
    );
    let text = format!("{text}3 0 1 2\n");
    assert_eq!(ok(ply(text.as_bytes())).mesh, square_and_triangle());
}

/// A PLY value to write in binary.
#[derive(Clone, Copy)]
enum Val {
    U8(u8),
    I8(i8),
    U16(u16),
    I32(i32),
    U32(u32),
    F32(f32),
    F64(f64),
}

fn encode(values: &[Val], big_endian: bool) -> Vec<u8> {
    let mut out = Vec::new();
    for &value in values {
        let mut bytes = match value {
            Val::U8(x) => vec![x],
            Val::I8(x) => x.to_le_bytes().to_vec(),
            Val::U16(x) => x.to_le_bytes().to_vec(),
            Val::I32(x) => x.to_le_bytes().to_vec(),
            Val::U32(x) => x.to_le_bytes().to_vec(),
            Val::F32(x) => x.to_le_bytes().to_vec(),
            Val::F64(x) => x.to_le_bytes().to_vec(),
        };
        if big_endian {
            bytes.reverse();
        }
        out.extend(bytes);
    }
    out
}

/// The square-and-triangle mesh as a binary PLY with mixed types.
fn binary_ply(big_endian: bool) -> Vec<u8> {
    let format = if big_endian {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let header = format!(
        "ply\r\nformat {format} 1.0\r\n\
         element vertex 5\r\n\
         property float x\r\nproperty double y\r\nproperty char tag\r\nproperty float z\r\n\
         element face 2\r\n\
         property list uchar uint16 vertex_index\r\nproperty int material\r\n\
         element material 1\r\n\
         property list uint uint32 stuff\r\n\
         end_header\r\n"
    );
    use Val::*;
    let mut values = Vec::new();
    for p in square_and_triangle().positions {
        values.extend([F32(p.x), F64(f64::from(p.y)), I8(-3), F32(p.z)]);
    }
    values.extend([U8(4), U16(0), U16(1), U16(2), U16(3), I32(7)]);
    values.extend([U8(3), U16(0), U16(4), U16(1), I32(-1)]);
    values.extend([U32(2), U32(10), U32(20)]);
    let mut bytes = header.into_bytes();
    bytes.extend(encode(&values, big_endian));
    bytes
}

#[test]
fn ply_binary_little_and_big_endian() {
    for big_endian in [false, true] {
        let loaded = ok(ply(&binary_ply(big_endian)));
        assert_eq!(
            loaded.mesh,
            square_and_triangle(),
            "big endian: {big_endian}"
        );
    }
}

#[test]
fn ply_truncated_binary_is_an_error() {
    let bytes = binary_ply(false);
    err(
        ply(&bytes[..bytes.len() - 5]),
        &["m.ply", "material", "unexpected end of file"],
    );
    err(
        ply(&bytes[..bytes.len() - 28]),
        &["m.ply", "face #1", "unexpected end of file"],
    );
}

#[test]
fn files_on_disk_and_extensions() {
    let from_obj = ok(load_mesh(&data("tetra.obj"), &ToWorld::IDENTITY));
    let from_ply = ok(load_mesh(&data("tetra.ply"), &ToWorld::IDENTITY));
    assert_eq!(from_obj, from_ply);
    assert_eq!(from_obj.mesh.triangle_count(), 4);
    // Every face points away from the centroid (outward, counter-clockwise).
    let centre = Vec3::splat(0.25);
    for i in 0..4 {
        let [a, b, c] = from_obj.mesh.triangle(i).unwrap_or_default();
        assert!(
            (b - a).cross(c - a).dot(a - centre) > 0.0,
            "face {i} points inwards"
        );
    }
    assert_eq!(
        MeshFormat::from_path(Path::new("a/B.PLY")).ok(),
        Some(MeshFormat::Ply)
    );
    assert_eq!(
        MeshFormat::from_path(Path::new("b.Obj")).ok(),
        Some(MeshFormat::Obj)
    );
    err(
        load_mesh(Path::new("scenes/bunny.stl"), &ToWorld::IDENTITY),
        &["scenes/bunny.stl", "unknown mesh file extension"],
    );
    err(
        load_mesh(Path::new("scenes/noext"), &ToWorld::IDENTITY),
        &["scenes/noext", "unknown mesh file extension"],
    );
    err(
        load_mesh(&data("missing.obj"), &ToWorld::IDENTITY),
        &["missing.obj", "not found"],
    );
}

#[test]
fn to_world_scales_then_rotates_x_y_z_then_translates() {
    let tri = "v 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n";
    let place = |to_world: ToWorld| {
        ok(read(MeshFormat::Obj, "t.obj", tri.as_bytes(), &to_world))
            .mesh
            .positions
    };
    // Scale before rotation: x is doubled, then turned onto y.
    let p = place(ToWorld {
        scale: v(2., 1., 1.),
        rotate_deg: v(0., 0., 90.),
        translate: v(0., 0., 5.),
    });
    let expected = [v(0., 2., 5.), v(-1., 0., 5.), v(0., 0., 6.)];
    for (got, want) in p.iter().zip(expected) {
        assert!(got.abs_diff_eq(want, 1e-6), "{got} != {want}");
    }
    // X before Y: +y turns to +z about X, then to +x about Y (Y first would give +z).
    let p = place(ToWorld {
        rotate_deg: v(90., 90., 0.),
        ..ToWorld::IDENTITY
    });
    assert!(p[1].abs_diff_eq(v(1., 0., 0.), 1e-6), "{}", p[1]);
    // The same matrix as boxes use, for an arbitrary rotation.
    let to_world = ToWorld {
        scale: v(0.5, 2., 3.),
        rotate_deg: v(10., -35., 70.),
        translate: v(1., 2., 3.),
    };
    let r = rotation_xyz_deg(to_world.rotate_deg);
    for (got, local) in place(to_world)
        .iter()
        .zip([v(1., 0., 0.), v(0., 1., 0.), v(0., 0., 1.)])
    {
        let want = r * (to_world.scale * local) + to_world.translate;
        assert!(got.abs_diff_eq(want, 1e-6), "{got} != {want}");
    }
}

#[test]
fn mirroring_keeps_the_facing_side() {
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"; // normal +z
    for scale in [v(-1., 1., 1.), v(1., -2., 1.), v(-1., -1., -1.)] {
        let to_world = ToWorld {
            scale,
            ..ToWorld::IDENTITY
        };
        let mesh = ok(read(MeshFormat::Obj, "t.obj", tri.as_bytes(), &to_world)).mesh;
        let [a, b, c] = mesh.triangle(0).unwrap_or_default();
        let normal = (b - a).cross(c - a).normalize();
        // The object-space normal (0,0,1) carried by the mirror (inverse transpose).
        let want = (Vec3::Z / scale).normalize();
        assert!(
            normal.abs_diff_eq(want, 1e-6),
            "scale {scale}: normal {normal}, want {want}"
        );
    }
}

#[test]
fn bad_to_world_is_an_error() {
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let load = |to_world: ToWorld| read(MeshFormat::Obj, "t.obj", tri.as_bytes(), &to_world);
    err(
        load(ToWorld {
            scale: v(1., 0., 1.),
            ..ToWorld::IDENTITY
        }),
        &["t.obj", "scale", "non-zero"],
    );
    err(
        load(ToWorld {
            translate: v(f32::NAN, 0., 0.),
            ..ToWorld::IDENTITY
        }),
        &["t.obj", "finite"],
    );
    let huge = "v 0 0 0\nv 1e30 0 0\nv 0 1 0\nf 1 2 3\n";
    let big = ToWorld {
        scale: Vec3::splat(1e10),
        ..ToWorld::IDENTITY
    };
    err(
        read(MeshFormat::Obj, "h.obj", huge.as_bytes(), &big),
        &["h.obj", "vertex 2", "not finite after to_world"],
    );
}

#[test]
fn obj_syntax_errors_name_the_line() {
    err(
        obj("v 0 0 0\nv 1 2\n"),
        &["m.obj", "line 2", "vertex 2", "needs 3 coordinates"],
    );
    err(
        obj("v 0 x 0\n"),
        &["m.obj", "line 1", "`x` is not a number"],
    );
    err(
        obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n"),
        &["face #1 (line 4)", "at least 3 vertices, got 2"],
    );
    err(
        obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 two 3\n"),
        &["face #1 (line 4)", "`two` is not a vertex index"],
    );
    err(
        obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"),
        &["face #1 (line 4)", "vertex index 0"],
    );
    err(
        obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n"),
        &["face #1 (line 4)", "relative vertex index -4"],
    );
    err(
        obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n"),
        &[
            "m.obj",
            "face #2 (line 5)",
            "vertex index 9 is out of range",
            "3 vertices",
        ],
    );
    err(
        obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999\n"),
        &["face #1 (line 4)", "out of range"],
    );
}

#[test]
fn non_finite_vertices_are_errors() {
    err(
        obj("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n"),
        &["m.obj", "line 2", "vertex 2 is not finite"],
    );
    err(
        obj("v 0 0 0\nv 0 -inf 0\nv 0 1 0\nf 1 2 3\n"),
        &["line 2", "not finite"],
    );
    err(obj("v 0 0 1e39\n"), &["line 1", "not finite"]);
    let text = PLY_ASCII.replace("9 1 1 0 0 255", "9 1 nan 0 0 255");
    err(ply(text.as_bytes()), &["m.ply", "vertex 2", "not finite"]);
    let text = PLY_ASCII.replace("9 1 1 0 0 255", "9 1e300 1 0 0 255");
    err(
        ply(text.as_bytes()),
        &["m.ply", "vertex 2", "not finite as f32"],
    );
}

#[test]
fn ply_header_errors() {
    err(ply(b"plx\n"), &["m.ply", "not a PLY file"]);
    err(
        ply(b"ply\nelement vertex 0\nend_header\n"),
        &["m.ply", "no `format` line"],
    );
    err(
        ply(b"ply\nformat ascii 2.0\n"),
        &["m.ply", "header line 2", "unsupported version"],
    );
    err(
        ply(b"ply\nformat binary_middle_endian 1.0\n"),
        &["header line 2", "unknown format"],
    );
    err(
        ply(b"ply\nformat ascii 1.0\nelement vertex 3\n"),
        &["no `end_header`"],
    );
    err(
        ply(b"ply\nformat ascii 1.0\nproperty float x\nend_header\n"),
        &["header line 3", "before any `element`"],
    );
    err(
        ply(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n"),
        &["header line 4", "unknown type `quad`"],
    );
    err(
        ply(b"ply\nformat ascii 1.0\nelement vertex -1\nend_header\n"),
        &["header line 3", "bad count"],
    );
    err(
        ply(b"ply\nformat ascii 1.0\nwhat is this\nend_header\n"),
        &["header line 3", "unexpected"],
    );
    err(ply(b"ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n"), &["no `vertex` element"]);
    err(
        ply(b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n"),
        &["exactly one scalar property `z`"],
    );
    err(
        ply(b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty int vertex_indices\nend_header\n"),
        &["list property `vertex_indices`"],
    );
    err(
        ply(b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty list uchar float vertex_indices\nend_header\n"),
        &["integer type"],
    );
    err(
        ply(b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n"),
        &["m.ply", "no faces"],
    );
}

#[test]
fn ply_body_errors_name_the_element() {
    let text = PLY_ASCII.replace("1 3 0 4 1", "1 3 0 4 5");
    err(
        ply(text.as_bytes()),
        &[
            "m.ply",
            "face #2",
            "vertex index 5 is out of range",
            "5 vertices",
        ],
    );
    let text = PLY_ASCII.replace("1 3 0 4 1", "1 3 0 -4 1");
    err(
        ply(text.as_bytes()),
        &["face #2", "vertex index -4 is out of range"],
    );
    let text = PLY_ASCII.replace("1 3 0 4 1", "1 2 0 4");
    err(
        ply(text.as_bytes()),
        &["face #2", "at least 3 vertices, got 2"],
    );
    let text = PLY_ASCII.replace("9 1 1 0 0 255", "9 1 one 0 0 255");
    err(
        ply(text.as_bytes()),
        &["m.ply", "vertex 2", "`one` is not a valid float32"],
    );
    let text = PLY_ASCII.replace("1 3 0 4 1", "1 3 0 4.5 1");
    err(
        ply(text.as_bytes()),
        &["face #2", "`4.5` is not a valid int32"],
    );
    let text = PLY_ASCII.replace("0 1\n", "");
    err(
        ply(text.as_bytes()),
        &["element `edge` #1", "unexpected end of file"],
    );
}

#[test]
fn sizes_over_the_limits_are_refused_before_reading() {
    let header = |vertices: u64, faces: u64| {
        format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex {vertices}\nproperty float x\nproperty float y\nproperty float z\nelement face {faces}\nproperty list uchar int vertex_indices\nend_header\n"
        )
    };
    // No data follows: the header alone must be refused, before any allocation.
    err(
        ply(header(MAX_MESH_VERTICES + 1, 1).as_bytes()),
        &["m.ply", "`vertex` elements, more than the limit"],
    );
    err(
        ply(header(3, MAX_MESH_TRIANGLES + 1).as_bytes()),
        &["m.ply", "`face` elements, more than the limit"],
    );
    err(
        ply(header(u64::MAX, 1).as_bytes()),
        &["more than the limit"],
    );
    // Within the limits, the missing data is the error.
    err(
        ply(header(MAX_MESH_VERTICES, 1).as_bytes()),
        &["vertex 0", "unexpected end of file"],
    );
    // One face with too many vertices.
    let mut text = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nf");
    for _ in 0..=MAX_FACE_VERTICES {
        text.push_str(" 1");
    }
    err(obj(&text), &["face #1 (line 4)", "more than 4096 vertices"]);
    // A line that never ends.
    let long = format!("# {}", "x".repeat(MAX_LINE_BYTES));
    err(obj(&long), &["m.obj", "line 1 is longer than"]);
    err(
        ply(format!("ply\ncomment {}\n", "y".repeat(MAX_LINE_BYTES)).as_bytes()),
        &["m.ply", "line 2 is longer than"],
    );
}

#[test]
fn polygons_that_cannot_be_fanned_are_errors() {
    let base = "v 0 0 0\nv 2 0 0\nv 2 2 0\nv 1 0.5 0\nv 0 2 0\n";
    // A concave (arrowhead) quad as the second face.
    err(
        obj(&format!("{base}f 1 2 3\nf 1 2 3 4\n")),
        &["m.obj", "face #2 (line 7)", "concave at its vertex 4"],
    );
    // A convex pentagon is fine.
    let pentagon = "v 0 0 0\nv 2 0 0\nv 3 1 0\nv 1 3 0\nv -1 1 0\nf 1 2 3 4 5\n";
    assert_eq!(ok(obj(pentagon)).mesh.triangle_count(), 3);
    // A quad with one corner lifted by half its size.
    err(
        obj("v 0 0 0\nv 1 0 0\nv 1 1 0.5\nv 0 1 0\nf 1 2 3 4\n"),
        &["face #1 (line 5)", "not planar"],
    );
    let text = PLY_ASCII.replace("1 4 0 1 2 3", "1 4 0 2 1 3");
    err(
        ply(text.as_bytes()),
        &["m.ply", "face #1", "crosses itself"],
    );
}

#[test]
fn degenerate_triangles_are_dropped_and_counted() {
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nv 9 9 9\n\
                f 1 2 3\n\
                f 1 1 3\n\
                f 1 2 4\n\
                f 3 2 1\n";
    let loaded = ok(obj(text));
    assert_eq!(loaded.dropped_degenerate, 2);
    // The collinear vertex 4 and the unused vertex 5 are gone.
    assert_eq!(
        loaded.mesh.positions,
        vec![v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.)]
    );
    assert_eq!(loaded.mesh.indices, vec![[0, 1, 2], [2, 1, 0]]);
    // Identical positions under different indices are degenerate too.
    let loaded = ok(obj(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 0 0\nf 1 2 3\nf 1 2 4\n",
    ));
    assert_eq!(loaded.dropped_degenerate, 1);
}

#[test]
fn all_degenerate_and_empty_meshes_are_errors() {
    err(
        obj("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n"),
        &["m.obj", "all 2 triangles are degenerate"],
    );
    err(obj("v 0 0 0\nv 1 0 0\nv 2 0 0\n"), &["m.obj", "no faces"]);
    err(obj(""), &["m.obj", "no faces"]);
    let text = PLY_ASCII.replace("element face 2", "element face 0");
    let text = text.replace("1 4 0 1 2 3\n1 3 0 4 1\n", "");
    err(ply(text.as_bytes()), &["m.ply", "no faces"]);
}

#[test]
fn mesh_validate_and_helpers() {
    let mut mesh = square_and_triangle();
    assert!(mesh.validate().is_ok());
    assert_eq!(mesh.bounds(), Some((v(0., 0., 0.), v(1., 1., 1.))));
    mesh.indices.push([0, 1, 5]);
    assert!(mesh.validate().is_err());
    mesh.indices.pop();
    mesh.positions[1].x = f32::INFINITY;
    assert!(mesh.validate().is_err());
    assert!(TriangleMesh::default().validate().is_err());

    let sphere = TriangleMesh::uv_sphere(v(1., 2., 3.), 2.0, 16, 8);
    assert_eq!(sphere.triangle_count(), 2 * 16 * 7);
    assert!(sphere.validate().is_ok());
    for i in 0..sphere.triangle_count() {
        let [a, b, c] = sphere.triangle(i).unwrap_or_default();
        for p in [a, b, c] {
            assert!(((p - v(1., 2., 3.)).length() - 2.0).abs() < 1e-5);
        }
        let outward = (b - a).cross(c - a).dot((a + b + c) / 3.0 - v(1., 2., 3.));
        assert!(outward > 0.0, "sphere triangle {i} faces inwards");
    }
    let field = TriangleMesh::height_field(10, 4.0, 0.5, 7);
    assert_eq!(field.triangle_count(), 200);
    for i in 0..field.triangle_count() {
        let [a, b, c] = field.triangle(i).unwrap_or_default();
        assert!(
            (b - a).cross(c - a).y > 0.0,
            "height field triangle {i} faces down"
        );
    }
    let mut letters = TriangleMesh::cuboid(v(0., 0., 0.), v(1., 2., 3.));
    letters.append(&TriangleMesh::cuboid(v(2., 0., 0.), v(3., 1., 1.)));
    assert_eq!(letters.triangle_count(), 24);
    assert_eq!(letters.bounds(), Some((v(0., 0., 0.), v(3., 2., 3.))));
    for i in 0..12 {
        let [a, b, c] = letters.triangle(i).unwrap_or_default();
        let outward = (b - a)
            .cross(c - a)
            .dot((a + b + c) / 3.0 - v(0.5, 1., 1.5));
        assert!(outward > 0.0, "cuboid triangle {i} faces inwards");
    }
}
