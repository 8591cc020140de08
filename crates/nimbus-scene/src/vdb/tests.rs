//! Unit tests on synthetic files (a small writer below, following OpenVDB's layout)
//! for what OpenVDB 10's Python module cannot write: other maps, native half /
//! double / vec3d grids, rejected types and versions, every per-node compression
//! mode with explicit inactive values; and a fuzz-style test on real files.

use std::io::{Cursor, Write};
use std::path::Path;

use anyhow::Result;
use glam::{DMat4, DVec3, IVec3};

use super::input::Input;
use super::tree::{COMPRESS_ACTIVE_MASK, COMPRESS_BLOSC, COMPRESS_ZIP};
use super::*;

/// Little-endian byte writer.
#[derive(Default)]
struct W(Vec<u8>);

impl W {
    fn u8(&mut self, v: u8) -> &mut Self {
        self.0.push(v);
        self
    }
    fn u32(&mut self, v: u32) -> &mut Self {
        self.0.extend(v.to_le_bytes());
        self
    }
    fn i32(&mut self, v: i32) -> &mut Self {
        self.0.extend(v.to_le_bytes());
        self
    }
    fn i64(&mut self, v: i64) -> &mut Self {
        self.0.extend(v.to_le_bytes());
        self
    }
    fn f64(&mut self, v: f64) -> &mut Self {
        self.0.extend(v.to_le_bytes());
        self
    }
    fn s(&mut self, s: &str) -> &mut Self {
        self.u32(s.len() as u32);
        self.0.extend(s.as_bytes());
        self
    }
    fn raw(&mut self, b: &[u8]) -> &mut Self {
        self.0.extend(b);
        self
    }
}

/// One value of a synthetic grid's type.
#[derive(Clone, Copy)]
enum Ty {
    F32,
    F16,
    F64,
    Vec3F64,
}

impl Ty {
    fn bytes(self, v: f64) -> Vec<u8> {
        match self {
            Ty::F32 => (v as f32).to_le_bytes().to_vec(),
            Ty::F16 => half::f16::from_f64(v).to_le_bytes().to_vec(),
            Ty::F64 => v.to_le_bytes().to_vec(),
            Ty::Vec3F64 => [v, -v, 2.0 * v]
                .iter()
                .flat_map(|x| x.to_le_bytes())
                .collect(),
        }
    }
}

fn uniform_scale_map(s: f64) -> Vec<u8> {
    let mut w = W::default();
    w.s("UniformScaleMap");
    for v in [s, s, s, s, s, s, 1.0 / s, 1.0 / s, 1.0 / s] {
        w.f64(v);
    }
    for _ in 0..6 {
        w.f64(0.0);
    }
    w.0
}

/// A file of `grids`: (name, full type name, instance parent, body after the
/// descriptor).
fn vdb_file(version: u32, grids: &[(&str, &str, &str, Vec<u8>)]) -> Vec<u8> {
    let mut w = W::default();
    w.i64(0x5644_4220)
        .u32(version)
        .u32(10)
        .u32(0)
        .u8(1)
        .raw(&[b'0'; 36]);
    w.u32(0); // file metadata
    w.i32(grids.len() as i32);
    for (name, ty, parent, body) in grids {
        w.s(name).s(ty).s(parent);
        let grid_pos = w.0.len() as i64 + 24;
        let end = grid_pos + body.len() as i64;
        w.i64(grid_pos)
            .i64(if parent.is_empty() { grid_pos } else { 0 })
            .i64(end);
        w.raw(body);
    }
    w.0
}

/// Node values as `io::writeCompressedValues` lays them out after the metadata
/// byte: one raw, zip or (stored) Blosc chunk of `bytes`.
fn chunk(compression: u32, bytes: &[u8]) -> Vec<u8> {
    let mut w = W::default();
    if compression & COMPRESS_BLOSC != 0 {
        // A "memcpyed" Blosc buffer: header + raw bytes.
        let mut b = vec![2u8, 1, 0x02 | (1 << 5), 4];
        b.extend((bytes.len() as u32).to_le_bytes());
        b.extend((bytes.len() as u32).to_le_bytes());
        b.extend((bytes.len() as u32 + 16).to_le_bytes());
        b.extend(bytes);
        w.i64(b.len() as i64).raw(&b);
    } else if compression & COMPRESS_ZIP != 0 {
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
        z.write_all(bytes).unwrap();
        let packed = z.finish().unwrap();
        w.i64(packed.len() as i64).raw(&packed);
    } else {
        w.raw(bytes);
    }
    w.0
}

/// A tree with one 8³ leaf at `leaf` (in the root child at the origin): `leaf_mask`
/// active voxels, and the leaf's buffer bytes after its mask (`leaf_values`).
fn one_leaf_tree(
    ty: Ty,
    compression: u32,
    background: f64,
    leaf: IVec3,
    leaf_mask: [u64; 8],
    leaf_values: &[u8],
) -> Vec<u8> {
    let mut w = W::default();
    w.i32(1)
        .raw(&ty.bytes(background))
        .u32(0)
        .u32(1)
        .i32(0)
        .i32(0)
        .i32(0);
    // Upper (32³) and lower (16³) internal nodes: one child each, no active tiles.
    let nodes: [(usize, IVec3); 2] = [(5, leaf >> 7i32), (4, (leaf >> 3i32) & 15i32)];
    for (log2, l) in nodes {
        let size = 1usize << (3 * log2);
        let n = ((l.x as usize) << (2 * log2)) | ((l.y as usize) << log2) | l.z as usize;
        let mut child = vec![0u8; size / 8];
        child[n / 8] |= 1 << (n % 8);
        w.raw(&child).raw(&vec![0u8; size / 8]);
        // Values: metadata 0 (inactive = background); with mask compression, none.
        w.u8(0);
        let stored = if compression & COMPRESS_ACTIVE_MASK != 0 {
            0
        } else {
            size
        };
        let zeros: Vec<u8> = (0..stored).flat_map(|_| ty.bytes(background)).collect();
        w.raw(&chunk(compression, &zeros));
    }
    let mask: Vec<u8> = leaf_mask.iter().flat_map(|m| m.to_le_bytes()).collect();
    w.raw(&mask); // topology
    w.raw(&mask).raw(leaf_values); // buffers
    w.0
}

fn grid_body(compression: u32, map: &[u8], tree: &[u8]) -> Vec<u8> {
    let mut w = W::default();
    w.u32(compression).u32(0).raw(map).raw(tree);
    w.0
}

fn read_bytes(bytes: &[u8], grid: Option<&str>, kind: VdbGridKind) -> Result<SparseGrid> {
    let mut input = Input::new(Cursor::new(bytes), bytes.len() as u64);
    read_from(&mut input, Path::new("mem.vdb"), grid, kind, "test")
}

fn err(bytes: &[u8], grid: Option<&str>, kind: VdbGridKind) -> String {
    match read_bytes(bytes, grid, kind) {
        Ok(g) => panic!("should fail, read grid {:?}", g.name),
        Err(e) => format!("{e:#}"),
    }
}

#[track_caller]
fn assert_has(message: &str, needle: &str) {
    assert!(message.contains(needle), "{needle:?} not in:\n{message}");
}

/// A float grid with one leaf at (8, 16, 24): voxels 0 and 511 (OpenVDB order)
/// active with 0.5 and 2.0, mask-compressed (metadata 0, two stored values).
fn simple_file(compression: u32) -> Vec<u8> {
    let mut mask = [0u64; 8];
    mask[0] = 1;
    mask[7] = 1 << 63;
    let mut leaf = W::default();
    leaf.u8(0);
    let values: Vec<u8> = [0.5f32, 2.0].iter().flat_map(|v| v.to_le_bytes()).collect();
    leaf.raw(&chunk(compression, &values));
    let c = compression | COMPRESS_ACTIVE_MASK;
    let tree = one_leaf_tree(Ty::F32, c, 0.0, IVec3::new(8, 16, 24), mask, &leaf.0);
    let body = grid_body(c, &uniform_scale_map(0.5), &tree);
    vdb_file(224, &[("density", "Tree_float_5_4_3", "", body)])
}

#[test]
fn synthetic_file_reads_under_every_compression() {
    for compression in [
        0,
        COMPRESS_ZIP,
        COMPRESS_BLOSC,
        COMPRESS_ZIP | COMPRESS_BLOSC,
    ] {
        let g = read_bytes(&simple_file(compression), None, VdbGridKind::Scalar).unwrap();
        assert_eq!(g.brick_origins, [IVec3::new(8, 16, 24)]);
        assert_eq!(g.value_at(IVec3::new(8, 16, 24)), ([0.5, 0.0, 0.0], true));
        assert_eq!(g.value_at(IVec3::new(15, 23, 31)), ([2.0, 0.0, 0.0], true));
        assert_eq!(g.value_at(IVec3::new(9, 16, 24)), ([0.0; 3], false));
        assert_eq!(
            g.active_bbox,
            Some((IVec3::new(8, 16, 24), IVec3::new(15, 23, 31)))
        );
        assert_eq!(g.active_voxels, 2);
        assert_eq!(g.index_to_world, DMat4::from_scale(DVec3::splat(0.5)));
        // x fastest inside the brick: voxel (7, 7, 7) is the last value.
        assert_eq!(g.brick(0)[511], 2.0);
    }
}

/// Every per-node metadata mode (io/Compression.h), with its inactive values and
/// selection mask written out; background 0.25.
#[test]
fn every_mask_compression_mode() {
    let mut mask = [0u64; 8];
    mask[3] = 0b1011; // voxels 192, 193, 195 active
    let active: Vec<u8> = [1.0f32, 2.0, 3.0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    for meta in 0u8..=6 {
        for compression in [COMPRESS_ACTIVE_MASK, COMPRESS_ACTIVE_MASK | COMPRESS_ZIP] {
            let mut leaf = W::default();
            leaf.u8(meta);
            if matches!(meta, 2 | 4 | 5) {
                leaf.raw(&0.75f32.to_le_bytes());
            }
            if meta == 5 {
                leaf.raw(&(-0.75f32).to_le_bytes());
            }
            if matches!(meta, 3..=5) {
                leaf.raw(&[0xAA; 64]); // selection mask
            }
            if meta == 6 {
                // All 512 values stored; inactive ones arbitrary.
                let mut all: Vec<f32> = (0..512).map(|n| n as f32 * 0.001 - 9.0).collect();
                all[192] = 1.0;
                all[193] = 2.0;
                all[195] = 3.0;
                let bytes: Vec<u8> = all.iter().flat_map(|v| v.to_le_bytes()).collect();
                leaf.raw(&chunk(compression, &bytes));
            } else {
                leaf.raw(&chunk(compression, &active));
            }
            let tree = one_leaf_tree(Ty::F32, compression, 0.25, IVec3::ZERO, mask, &leaf.0);
            let body = grid_body(compression, &uniform_scale_map(1.0), &tree);
            let file = vdb_file(224, &[("d", "Tree_float_5_4_3", "", body)]);
            let g = read_bytes(&file, None, VdbGridKind::Scalar)
                .unwrap_or_else(|e| panic!("mode {meta}: {e:#}"));
            // Bits 192, 193, 195: x = 3, y = 0, z = 0, 1, 3.
            for (z, v) in [(0, 1.0), (1, 2.0), (3, 3.0)] {
                assert_eq!(
                    g.value_at(IVec3::new(3, 0, z)),
                    ([v, 0.0, 0.0], true),
                    "mode {meta}"
                );
            }
            // Inactive voxels read as the background.
            assert_eq!(g.value_at(IVec3::new(3, 0, 2)), ([0.25, 0.0, 0.0], false));
            assert_eq!(g.background[0], 0.25);
            assert!(g.brick(0).iter().filter(|&&v| v == 0.25).count() == 509);
        }
    }
}

#[test]
fn uncompressed_chunk_inside_a_compressed_grid() {
    // A negative chunk size: the bytes follow raw (OpenVDB does this when compressing
    // would not help).
    let mut mask = [0u64; 8];
    mask[0] = 1;
    let mut leaf = W::default();
    leaf.u8(0).i64(-4).raw(&7.0f32.to_le_bytes());
    let c = COMPRESS_BLOSC | COMPRESS_ACTIVE_MASK;
    let tree = one_leaf_tree(Ty::F32, c, 0.0, IVec3::ZERO, mask, &leaf.0);
    let file = vdb_file(
        224,
        &[(
            "d",
            "Tree_float_5_4_3",
            "",
            grid_body(c, &uniform_scale_map(1.0), &tree),
        )],
    );
    let g = read_bytes(&file, None, VdbGridKind::Scalar).unwrap();
    assert_eq!(g.value_at(IVec3::ZERO), ([7.0, 0.0, 0.0], true));
    // A wrong raw size is an error.
    let mut leaf = W::default();
    leaf.u8(0).i64(-8).raw(&[0; 8]);
    let tree = one_leaf_tree(Ty::F32, c, 0.0, IVec3::ZERO, mask, &leaf.0);
    let file = vdb_file(
        224,
        &[(
            "d",
            "Tree_float_5_4_3",
            "",
            grid_body(c, &uniform_scale_map(1.0), &tree),
        )],
    );
    assert_has(
        &err(&file, None, VdbGridKind::Scalar),
        "has 8 bytes, expected 4",
    );
}

/// A one-leaf grid of `ty` with all 512 voxels active (no mask compression), voxel
/// n holding `value(n)`.
fn dense_leaf_file(
    version: u32,
    type_name: &str,
    ty: Ty,
    half: bool,
    value: impl Fn(usize) -> f64,
) -> Vec<u8> {
    let mut leaf = W::default();
    leaf.u8(6);
    for n in 0..512 {
        let v = value(n);
        match (half, ty) {
            (true, Ty::Vec3F64) => {
                for x in [v, -v, 2.0 * v] {
                    leaf.raw(&half::f16::from_f64(x).to_le_bytes());
                }
            }
            (true, _) => {
                leaf.raw(&half::f16::from_f64(v).to_le_bytes());
            }
            (false, _) => {
                leaf.raw(&ty.bytes(v));
            }
        }
    }
    let mut w = W::default();
    // Internal nodes hold values of the stored size too (half when saved as half).
    let node_ty = if half { Ty::F16 } else { ty };
    w.i32(1)
        .raw(&ty.bytes(0.0))
        .u32(0)
        .u32(1)
        .i32(0)
        .i32(0)
        .i32(0);
    for log2 in [5usize, 4] {
        let size = 1usize << (3 * log2);
        let mut child = vec![0u8; size / 8];
        child[0] = 1;
        w.raw(&child).raw(&vec![0u8; size / 8]).u8(6);
        let per = if half && matches!(ty, Ty::Vec3F64) {
            3
        } else {
            1
        };
        for _ in 0..size * per {
            w.raw(&node_ty.bytes(0.0));
        }
    }
    w.raw(&[0xFF; 64]).raw(&[0xFF; 64]).raw(&leaf.0);
    let name = if half {
        format!("{type_name}_HalfFloat")
    } else {
        type_name.to_string()
    };
    let body = grid_body(0, &uniform_scale_map(1.0), &w.0);
    vdb_file(version, &[("g", &name, "", body)])
}

#[test]
fn native_half_double_and_vec3d_grids() {
    let value = |n: usize| (n % 37) as f64 * 0.125 - 2.0;
    let ijk = |n: usize| IVec3::new((n >> 6) as i32, ((n >> 3) & 7) as i32, (n & 7) as i32);
    // A native half grid (file version 225).
    let g = read_bytes(
        &dense_leaf_file(225, "Tree_half_5_4_3", Ty::F16, false, value),
        None,
        VdbGridKind::Scalar,
    )
    .unwrap();
    assert_eq!(g.value_type, ValueType::Half);
    for n in 0..512 {
        assert_eq!(g.value_at(ijk(n)).0[0], value(n) as f32);
    }
    // A double grid, saved full and as half.
    for half in [false, true] {
        let g = read_bytes(
            &dense_leaf_file(224, "Tree_double_5_4_3", Ty::F64, half, value),
            None,
            VdbGridKind::Scalar,
        )
        .unwrap();
        assert_eq!((g.value_type, g.saved_as_half), (ValueType::Double, half));
        assert_eq!(g.active_voxels, 512);
        for n in 0..512 {
            assert_eq!(g.value_at(ijk(n)), ([value(n) as f32, 0.0, 0.0], true));
        }
    }
    // vec3d, full and as half.
    for half in [false, true] {
        let g = read_bytes(
            &dense_leaf_file(224, "Tree_vec3d_5_4_3", Ty::Vec3F64, half, value),
            None,
            VdbGridKind::Vec3,
        )
        .unwrap();
        assert_eq!(g.value_type, ValueType::Vec3Double);
        for n in 0..512 {
            let v = value(n) as f32;
            assert_eq!(g.value_at(ijk(n)), ([v, -v, 2.0 * v], true));
        }
    }
    // A double beyond f32's range is reported as inf, naming the voxel.
    let e = err(
        &dense_leaf_file(224, "Tree_double_5_4_3", Ty::F64, false, |n| {
            if n == 9 {
                1e300
            } else {
                1.0
            }
        }),
        None,
        VdbGridKind::Scalar,
    );
    assert_has(&e, "test: mem.vdb: grid \"g\": voxel [0, 1, 1] is inf");
}

fn with_type(type_name: &str) -> Vec<u8> {
    let body = grid_body(0, &uniform_scale_map(1.0), &[]);
    vdb_file(224, &[("g", type_name, "", body)])
}

#[test]
fn unsupported_grid_types() {
    let e = err(
        &with_type("Tree_ptdataidx32_5_4_3"),
        Some("g"),
        VdbGridKind::Scalar,
    );
    assert_has(&e, "grid \"g\": it is a point data grid");
    let e = err(
        &with_type("Tree_int32_5_4_3"),
        Some("g"),
        VdbGridKind::Scalar,
    );
    assert_has(&e, "it holds int32 values, which Nimbus does not read");
    let e = err(&with_type("Tree_mask_5_4_3"), Some("g"), VdbGridKind::Any);
    assert_has(&e, "it holds mask values");
    let e = err(&with_type("Tree_float_4_3"), Some("g"), VdbGridKind::Scalar);
    assert_has(&e, "its tree type Tree_float_4_3 is not supported");
    // Without a name: no grid of the kind, and the listing names the point grid.
    let e = err(
        &with_type("Tree_ptdataidx32_5_4_3"),
        None,
        VdbGridKind::Scalar,
    );
    assert_has(
        &e,
        "the file has no scalar grid (float, half or double); the file has grids: g (point data)",
    );
}

#[test]
fn header_errors() {
    let good = simple_file(0);
    let mut bad = good.clone();
    bad[0] = b'X';
    assert_has(
        &err(&bad, None, VdbGridKind::Scalar),
        "test: mem.vdb: not a VDB file",
    );
    assert_has(
        &err(&good[..5], None, VdbGridKind::Scalar),
        "not a VDB file",
    );
    for (version, needle) in [
        (221, "older than 222"),
        (226, "newer than this reader knows"),
    ] {
        let mut bad = good.clone();
        bad[8..12].copy_from_slice(&u32::to_le_bytes(version));
        assert_has(&err(&bad, None, VdbGridKind::Scalar), needle);
    }
    let mut bad = good.clone();
    bad[20] = 0; // has-grid-offsets flag
    assert_has(&err(&bad, None, VdbGridKind::Scalar), "no grid offsets");
}

/// Replaces the first occurrence of `from` in `bytes` with `to` (same length).
fn patch(bytes: &[u8], from: &[u8], to: &[u8]) -> Vec<u8> {
    let at = bytes
        .windows(from.len())
        .position(|w| w == from)
        .expect("pattern");
    let mut out = bytes.to_vec();
    out[at..at + to.len()].copy_from_slice(to);
    out
}

#[test]
fn grid_errors() {
    let good = simple_file(0);
    // The compression flags are the first word of the grid, just before the metadata
    // count (0) and the map name.
    let mut pattern = (COMPRESS_ACTIVE_MASK).to_le_bytes().to_vec();
    pattern.extend(0u32.to_le_bytes());
    pattern.extend(15u32.to_le_bytes());
    let mut flags = 0x8u32.to_le_bytes().to_vec();
    flags.extend(&pattern[4..]);
    let e = err(&patch(&good, &pattern, &flags), None, VdbGridKind::Scalar);
    assert_has(&e, "grid \"density\": unknown compression flags 0x8");
    // Multi-buffer trees.
    let e = err(
        &patch(
            &good,
            b"\x01\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x01\x00\x00\x00",
            b"\x02\x00\x00\x00",
        ),
        None,
        VdbGridKind::Scalar,
    );
    assert_has(&e, "2 buffers");
    // Unknown node metadata.
    let mut mask = [0u64; 8];
    mask[0] = 1;
    let tree = one_leaf_tree(Ty::F32, COMPRESS_ACTIVE_MASK, 0.0, IVec3::ZERO, mask, &[9]);
    let file = vdb_file(
        224,
        &[(
            "d",
            "Tree_float_5_4_3",
            "",
            grid_body(COMPRESS_ACTIVE_MASK, &uniform_scale_map(1.0), &tree),
        )],
    );
    assert_has(
        &err(&file, None, VdbGridKind::Scalar),
        "in the leaf at [0, 0, 0]: corrupt file: unknown node compression metadata 9",
    );
    // A missing instance parent.
    let body = grid_body(0, &uniform_scale_map(1.0), &[]);
    let file = vdb_file(224, &[("d", "Tree_float_5_4_3", "nobody", body)]);
    assert_has(
        &err(&file, None, VdbGridKind::Scalar),
        "instance parent \"nobody\" is not in the file",
    );
}

fn root_tiles_tree(tiles: &[(IVec3, f32, bool)]) -> Vec<u8> {
    let mut w = W::default();
    w.i32(1)
        .raw(&0f32.to_le_bytes())
        .u32(tiles.len() as u32)
        .u32(0);
    for (ijk, v, active) in tiles {
        w.i32(ijk.x)
            .i32(ijk.y)
            .i32(ijk.z)
            .raw(&v.to_le_bytes())
            .u8(u8::from(*active));
    }
    w.0
}

#[test]
fn root_tiles() {
    let file = |tiles: &[(IVec3, f32, bool)]| {
        let body = grid_body(0, &uniform_scale_map(1.0), &root_tiles_tree(tiles));
        vdb_file(224, &[("d", "Tree_float_5_4_3", "", body)])
    };
    // Inactive root tiles are dropped; an empty grid has no bbox.
    let g = read_bytes(
        &file(&[(IVec3::new(4096, 0, 0), 5.0, false)]),
        None,
        VdbGridKind::Scalar,
    )
    .unwrap();
    assert_eq!(
        (g.active_voxels, g.active_bbox, g.tiles.len()),
        (0, None, 0)
    );
    // An active one is 2^36 voxels: refused.
    let e = err(
        &file(&[(IVec3::new(4096, 0, 0), 5.0, true)]),
        None,
        VdbGridKind::Scalar,
    );
    assert_has(&e, "over the limit of 2^31");
    let e = err(
        &file(&[(IVec3::new(4095, 0, 0), 5.0, true)]),
        None,
        VdbGridKind::Scalar,
    );
    assert_has(&e, "not a multiple of 4096");
}

#[test]
fn brick_limit_is_checked_before_allocating() {
    let enc = tree::Encoding {
        value: ValueType::Vec3Float,
        save_half: false,
        compression: 0,
    };
    let max = (MAX_GRID_VALUES / (BRICK_VOXELS as u64 * 3)) as usize;
    assert!(tree::check_limits(&enc, max, 0).is_ok());
    assert_has(
        &format!("{:#}", tree::check_limits(&enc, max + 1, 0).unwrap_err()),
        "limit of 2^31 values",
    );
    assert!(tree::check_limits(&enc, 0, MAX_ACTIVE_VOXELS + 1).is_err());
}

fn transform(bytes: &[u8]) -> Result<(String, DMat4)> {
    let mut input = Input::new(Cursor::new(bytes), bytes.len() as u64);
    file::read_transform(&mut input)
}

fn map(name: &str, values: &[f64]) -> Vec<u8> {
    let mut w = W::default();
    w.s(name);
    for v in values {
        w.f64(*v);
    }
    w.0
}

#[test]
fn every_linear_map() {
    let t = DVec3::new(1.0, -2.0, 3.5);
    let s = DVec3::new(0.5, 2.0, 4.0);
    let (name, m) = transform(&map("TranslationMap", &t.to_array())).unwrap();
    assert_eq!(
        (name.as_str(), m),
        ("TranslationMap", DMat4::from_translation(t))
    );
    let mut scale = s.to_array().to_vec();
    scale.extend([9.0; 12]); // voxel size and the cached inverses: ignored
    assert_eq!(
        transform(&map("ScaleMap", &scale)).unwrap().1,
        DMat4::from_scale(s)
    );
    let mut st = t.to_array().to_vec();
    st.extend(&scale);
    let want = DMat4::from_translation(t) * DMat4::from_scale(s);
    assert_eq!(transform(&map("ScaleTranslateMap", &st)).unwrap().1, want);
    assert_eq!(
        transform(&map("UniformScaleTranslateMap", &st)).unwrap().1,
        want
    );
    // Affine and unitary maps: OpenVDB's row-major, row-vector Mat4d.
    let rows = [
        [0.0, 1.0, 0.0, 0.0],
        [-2.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 3.0, 0.0],
        [5.0, 6.0, 7.0, 1.0],
    ];
    let flat: Vec<f64> = rows.iter().flatten().copied().collect();
    for name in ["AffineMap", "UnitaryMap"] {
        let m = transform(&map(name, &flat)).unwrap().1;
        // Index (1, 0, 0) goes to row 0 + translation.
        assert_eq!(m.transform_point3(DVec3::X), DVec3::new(5.0, 7.0, 7.0));
        assert_eq!(m.transform_point3(DVec3::Y), DVec3::new(3.0, 6.0, 7.0));
        assert_eq!(m.transform_point3(DVec3::ZERO), DVec3::new(5.0, 6.0, 7.0));
    }
    // Not affine, degenerate, frustum, unknown.
    let mut projective = flat.clone();
    projective[3] = 0.5;
    assert_has(
        &format!(
            "{:#}",
            transform(&map("AffineMap", &projective)).unwrap_err()
        ),
        "is not affine",
    );
    let mut flat_scale = scale.clone();
    flat_scale[1] = 0.0;
    assert_has(
        &format!(
            "{:#}",
            transform(&map("ScaleMap", &flat_scale)).unwrap_err()
        ),
        "degenerate",
    );
    let mut nan = t.to_array().to_vec();
    nan[0] = f64::NAN;
    assert_has(
        &format!("{:#}", transform(&map("TranslationMap", &nan)).unwrap_err()),
        "degenerate",
    );
    assert_has(
        &format!(
            "{:#}",
            transform(&map("NonlinearFrustumMap", &[])).unwrap_err()
        ),
        "frustum",
    );
    assert_has(
        &format!("{:#}", transform(&map("SkewMap", &[])).unwrap_err()),
        "\"SkewMap\" is not supported",
    );
}

/// Truncates and byte-flips real OpenVDB files at many positions: truncation is
/// always an error, a flip either an error or a grid, never a panic.
#[test]
fn truncated_and_flipped_files_never_panic() {
    let files: [(&str, &[u8], VdbGridKind); 7] = [
        (
            "float_blosc",
            include_bytes!("../../../../assets/test-vdb/float_blosc.vdb"),
            VdbGridKind::Scalar,
        ),
        (
            "half_zip",
            include_bytes!("../../../../assets/test-vdb/half_zip.vdb"),
            VdbGridKind::Scalar,
        ),
        (
            "vec3_blosc",
            include_bytes!("../../../../assets/test-vdb/vec3_blosc.vdb"),
            VdbGridKind::Vec3,
        ),
        (
            "inactive_modes",
            include_bytes!("../../../../assets/test-vdb/inactive_modes_blosc.vdb"),
            VdbGridKind::Scalar,
        ),
        (
            "levelset_blosc",
            include_bytes!("../../../../assets/test-vdb/levelset_blosc.vdb"),
            VdbGridKind::Scalar,
        ),
        (
            "tiles_blosc",
            include_bytes!("../../../../assets/test-vdb/tiles_blosc.vdb"),
            VdbGridKind::Scalar,
        ),
        (
            "multi",
            include_bytes!("../../../../assets/test-vdb/multi.vdb"),
            VdbGridKind::Any,
        ),
    ];
    let mut flips_ok = 0;
    let mut flips_err = 0;
    for (name, bytes, kind) in files {
        let grid = (kind == VdbGridKind::Any).then_some("density_copy");
        let read = |b: &[u8]| read_bytes(b, grid, kind);
        assert!(read(bytes).is_ok(), "{name}");
        // Every cut in the header, descriptors, metadata, transform and the start of
        // the topology, then every 31st byte and the last 200.
        let cuts = (0..bytes.len()).filter(|&n| n < 1000 || n % 31 == 0 || n + 200 > bytes.len());
        for cut in cuts {
            assert!(read(&bytes[..cut]).is_err(), "{name} cut at {cut} read");
        }
        let flips = (0..bytes.len()).filter(|&n| n < 1000 || n % 13 == 0);
        for at in flips {
            for flip in [0x01u8, 0x80, 0xFF] {
                let mut bad = bytes.to_vec();
                bad[at] ^= flip;
                match read(&bad) {
                    Ok(_) => flips_ok += 1,
                    Err(_) => flips_err += 1,
                }
                if at < 8 {
                    assert!(read(&bad).is_err(), "{name}: flip at {at} read");
                }
            }
        }
    }
    assert!(
        flips_err > 500 && flips_ok > 500,
        "{flips_ok} ok, {flips_err} errors"
    );
}
