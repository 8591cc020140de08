//! The tree of one grid: topology (root → 32³ internal → 16³ internal → 8³ leaf, with
//! child and value masks and tiles) and then the leaf buffers, streamed node by node
//! (OpenVDB `tree/RootNode.h`, `InternalNode.h`, `LeafNode.h`, `io/Compression.h`).
//!
//! Only the masks of the leaves are held between the two passes (76 bytes a leaf);
//! leaf values go straight into the grid's brick buffer, whose size is checked
//! against [`MAX_GRID_VALUES`] before it is allocated.

use std::io::{Read, Seek};

use anyhow::{bail, Context, Result};
use glam::IVec3;

use super::input::Input;
use super::{
    blosc, SparseGrid, ValueType, VdbTile, BRICK_VOXELS, LEAF_DIM, MAX_ACTIVE_VOXELS,
    MAX_GRID_VALUES,
};

/// `io::COMPRESS_*` flags (per grid since file version 222).
pub const COMPRESS_ZIP: u32 = 0x1;
pub const COMPRESS_ACTIVE_MASK: u32 = 0x2;
pub const COMPRESS_BLOSC: u32 = 0x4;
const COMPRESS_KNOWN: u32 = COMPRESS_ZIP | COMPRESS_ACTIVE_MASK | COMPRESS_BLOSC;

/// Per-node mask-compression metadata (`io/Compression.h`); 0 and 1 (inactive values
/// are +background or -background, no selection mask) need nothing more read.
const NO_MASK_AND_ONE_INACTIVE_VAL: u8 = 2;
const MASK_AND_NO_INACTIVE_VALS: u8 = 3;
const MASK_AND_ONE_INACTIVE_VAL: u8 = 4;
const MASK_AND_TWO_INACTIVE_VALS: u8 = 5;
const NO_MASK_AND_ALL_VALS: u8 = 6;

/// Edge lengths (log2) of the standard 5-4-3 tree: a root child spans 2^12 voxels, an
/// upper internal node's child 2^7, a lower internal node's child (a leaf) 2^3.
const ROOT_CHILD_LOG2: u32 = 12;

/// How the values of one grid are stored.
#[derive(Clone, Copy, Debug)]
pub struct Encoding {
    pub value: ValueType,
    /// The descriptor's `_HalfFloat` suffix: node values of float / double types are
    /// stored as 16-bit halves (root values and inactive values stay full size).
    pub save_half: bool,
    pub compression: u32,
}

impl Encoding {
    pub fn check(&self) -> Result<()> {
        if self.compression & !COMPRESS_KNOWN != 0 {
            bail!(
                "unknown compression flags 0x{:x} (known: zip 0x1, active mask 0x2, blosc 0x4)",
                self.compression
            );
        }
        Ok(())
    }

    fn channels(&self) -> usize {
        self.value.channels()
    }

    /// Bytes of one full-size value (root background and tiles, inactive values).
    fn native_size(&self) -> usize {
        self.value.scalar_bytes() * self.channels()
    }

    /// `HalfReader<isReal>`: only real types saved as half go through the half path,
    /// which stores nothing at all for an empty array.
    fn half_reader(&self) -> bool {
        self.save_half
            && matches!(
                self.value,
                ValueType::Float | ValueType::Double | ValueType::Vec3Float | ValueType::Vec3Double
            )
    }

    /// Bytes of one value inside a node's value array.
    fn stored_size(&self) -> usize {
        if self.half_reader() {
            2 * self.channels()
        } else {
            self.native_size()
        }
    }

    /// Decodes `bytes` (values of `scalar` bytes per channel) into f32 channels.
    fn decode(&self, bytes: &[u8], scalar: usize, out: &mut Vec<f32>) {
        out.clear();
        for c in bytes.chunks_exact(scalar) {
            out.push(match scalar {
                2 => half::f16::from_bits(u16::from_le_bytes([c[0], c[1]])).to_f32(),
                4 => f32::from_le_bytes([c[0], c[1], c[2], c[3]]),
                _ => f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]) as f32,
            });
        }
    }

    fn read_native<R: Read + Seek>(&self, input: &mut Input<R>, what: &str) -> Result<[f32; 3]> {
        let bytes = input.bytes(self.native_size() as u64, what)?;
        let mut v = Vec::with_capacity(3);
        self.decode(&bytes, self.value.scalar_bytes(), &mut v);
        let mut out = [0.0; 3];
        out[..v.len()].copy_from_slice(&v);
        Ok(out)
    }
}

struct LeafTopo {
    origin: IVec3,
    mask: [u64; 8],
}

struct RootChild {
    origin: IVec3,
    /// The range of this child's leaves in `Topology::leaves`.
    leaves: std::ops::Range<usize>,
}

struct Topology {
    background: [f32; 3],
    leaves: Vec<LeafTopo>,
    root_children: Vec<RootChild>,
    tiles: Vec<VdbTile>,
    active_voxels: u64,
}

/// Reads the tree at the input's position (just after the transform) into `grid`.
pub fn read_tree<R: Read + Seek>(
    input: &mut Input<R>,
    enc: &Encoding,
    grid: &mut SparseGrid,
) -> Result<()> {
    enc.check()?;
    let topo = read_topology(input, enc)?;
    grid.background = topo.background;
    check_finite(&topo.background, enc.channels(), || {
        "the background value".to_string()
    })?;
    read_buffers(input, enc, topo, grid)
}

/// The topology of the tree at the input's position (just after the transform), without
/// its leaf values: background, leaf origins with their active masks, active tiles, the
/// active bounding box and voxel count.
pub fn read_topology_only<R: Read + Seek>(
    input: &mut Input<R>,
    enc: &Encoding,
) -> Result<super::VdbTopology> {
    enc.check()?;
    let topo = read_topology(input, enc)?;
    check_finite(&topo.background, enc.channels(), || {
        "the background value".to_string()
    })?;
    let mut bbox: Option<(IVec3, IVec3)> = None;
    let mut grow = |lo: IVec3, hi: IVec3| {
        bbox = Some(match bbox {
            None => (lo, hi),
            Some((a, b)) => (a.min(lo), b.max(hi)),
        });
    };
    for leaf in &topo.leaves {
        for n in ones(&leaf.mask) {
            let ijk = leaf.origin + local(n, 3);
            grow(ijk, ijk);
        }
    }
    for t in &topo.tiles {
        grow(t.origin, t.origin + IVec3::splat(t.edge as i32 - 1));
    }
    Ok(super::VdbTopology {
        background: topo.background,
        leaf_origins: topo.leaves.iter().map(|l| l.origin).collect(),
        tiles: topo.tiles,
        active_bbox: bbox,
        active_voxels: topo.active_voxels,
    })
}

pub(super) fn check_limits(enc: &Encoding, leaves: usize, active: u64) -> Result<()> {
    let values = leaves as u64 * BRICK_VOXELS as u64 * enc.channels() as u64;
    if values > MAX_GRID_VALUES {
        bail!(
            "the grid has at least {leaves} leaf nodes ({values} float32 values), over \
             the limit of 2^31 values (8 GiB)"
        );
    }
    if active > MAX_ACTIVE_VOXELS {
        bail!(
            "the grid has at least {active} active voxels (tiles included), over the \
             limit of 2^31"
        );
    }
    Ok(())
}

fn read_topology<R: Read + Seek>(input: &mut Input<R>, enc: &Encoding) -> Result<Topology> {
    let buffer_count = input.i32("the tree's buffer count")?;
    if buffer_count != 1 {
        bail!("the tree has {buffer_count} buffers; only single-buffer trees are supported");
    }
    let background = enc.read_native(input, "the background value")?;
    let num_tiles = input.u32("the root tile count")?;
    let num_children = input.u32("the root child count")?;
    let mut topo = Topology {
        background,
        leaves: Vec::new(),
        root_children: Vec::new(),
        tiles: Vec::new(),
        active_voxels: 0,
    };
    let align = |ijk: IVec3, what: &str| -> Result<()> {
        let mask = (1 << ROOT_CHILD_LOG2) - 1;
        if ijk.to_array().iter().any(|v| v & mask != 0) {
            bail!("corrupt file: {what} origin {ijk} is not a multiple of 4096");
        }
        Ok(())
    };
    for _ in 0..num_tiles {
        let ijk = read_ijk(input, "a root tile")?;
        let value = enc.read_native(input, "a root tile value")?;
        let active = input.u8("a root tile's active flag")?;
        if active != 0 {
            align(ijk, "a root tile")?;
            add_tile(&mut topo, enc, ijk, ROOT_CHILD_LOG2, value)?;
        }
    }
    let mut seen = std::collections::HashSet::new();
    for _ in 0..num_children {
        let origin = read_ijk(input, "a root child")?;
        align(origin, "a root child")?;
        if !seen.insert(origin.to_array()) {
            bail!("corrupt file: two root children at {origin}");
        }
        let first = topo.leaves.len();
        read_internal(input, enc, &mut topo, origin, 5)
            .with_context(|| format!("in the node at {origin}"))?;
        let leaves = first..topo.leaves.len();
        topo.root_children.push(RootChild { origin, leaves });
    }
    Ok(topo)
}

fn read_ijk<R: Read + Seek>(input: &mut Input<R>, what: &str) -> Result<IVec3> {
    Ok(IVec3::new(
        input.i32(what)?,
        input.i32(what)?,
        input.i32(what)?,
    ))
}

fn add_tile(
    topo: &mut Topology,
    enc: &Encoding,
    origin: IVec3,
    log2: u32,
    value: [f32; 3],
) -> Result<()> {
    let edge = 1u32 << log2;
    check_finite(&value, enc.channels(), || {
        format!("the active tile of {edge}³ voxels at {origin}")
    })?;
    topo.active_voxels += 1u64 << (3 * log2);
    check_limits(enc, topo.leaves.len(), topo.active_voxels)?;
    topo.tiles.push(VdbTile {
        origin,
        edge,
        value,
    });
    Ok(())
}

/// Local coordinates of bit `n` in a node of edge `2^log2` (z fastest, as OpenVDB).
fn local(n: usize, log2: u32) -> IVec3 {
    let d = (1usize << log2) - 1;
    IVec3::new(
        (n >> (2 * log2)) as i32,
        ((n >> log2) & d) as i32,
        (n & d) as i32,
    )
}

fn read_mask<R: Read + Seek>(input: &mut Input<R>, words: usize, what: &str) -> Result<Vec<u64>> {
    let bytes = input.bytes(words as u64 * 8, what)?;
    Ok(bytes
        .chunks_exact(8)
        .map(|c| u64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
        .collect())
}

/// The set bits of a node mask, in increasing order.
fn ones(mask: &[u64]) -> impl Iterator<Item = usize> + '_ {
    mask.iter().enumerate().flat_map(|(w, &word)| {
        let mut rest = word;
        std::iter::from_fn(move || {
            (rest != 0).then(|| {
                let b = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                w * 64 + b
            })
        })
    })
}

fn bit(mask: &[u64], n: usize) -> bool {
    mask[n >> 6] >> (n & 63) & 1 != 0
}

/// An internal node of edge `2^log2` children (5: 32³, whose children are 16³ nodes;
/// 4: 16³, whose children are leaves).
fn read_internal<R: Read + Seek>(
    input: &mut Input<R>,
    enc: &Encoding,
    topo: &mut Topology,
    origin: IVec3,
    log2: u32,
) -> Result<()> {
    let size = 1usize << (3 * log2);
    let child_log2 = if log2 == 5 { 7 } else { 3 };
    let child_mask = read_mask(input, size / 64, "an internal node's child mask")?;
    let value_mask = read_mask(input, size / 64, "an internal node's value mask")?;
    let mut values = Vec::new();
    read_active_values(input, enc, size, &value_mask, &mut values)?;
    let ch = enc.channels();
    // Active tiles: value-mask bits without a child.
    for (k, n) in ones(&value_mask).enumerate() {
        if !bit(&child_mask, n) {
            let mut value = [0.0; 3];
            value[..ch].copy_from_slice(&values[k * ch..(k + 1) * ch]);
            let ijk = origin + (local(n, log2) << child_log2);
            add_tile(topo, enc, ijk, child_log2, value)?;
        }
    }
    drop(values);
    for n in ones(&child_mask) {
        let child = origin + (local(n, log2) << child_log2);
        if log2 == 5 {
            read_internal(input, enc, topo, child, 4)?;
        } else {
            let words = read_mask(input, 8, "a leaf's value mask")?;
            let mut mask = [0u64; 8];
            mask.copy_from_slice(&words);
            topo.active_voxels += mask.iter().map(|w| u64::from(w.count_ones())).sum::<u64>();
            topo.leaves.push(LeafTopo {
                origin: child,
                mask,
            });
            check_limits(enc, topo.leaves.len(), topo.active_voxels)?;
        }
    }
    Ok(())
}

/// `io::readCompressedValues` for a node of `count` values: puts the values of the
/// active positions (the set bits of `value_mask`, in order) in `out` as f32
/// channels. This reader gives inactive voxels the background, so the inactive
/// values and the selection mask that mask compression stores are skipped.
/// Metadata 0 and 1 (inactive values are +background or -background, no selection
/// mask) have nothing more to skip.
fn read_active_values<R: Read + Seek>(
    input: &mut Input<R>,
    enc: &Encoding,
    count: usize,
    value_mask: &[u64],
    out: &mut Vec<f32>,
) -> Result<()> {
    let meta = input.u8("a node's compression metadata")?;
    if meta > NO_MASK_AND_ALL_VALS {
        bail!(
            "corrupt file: unknown node compression metadata {meta} at byte {}",
            input.pos() - 1
        );
    }
    let inactive_values = match meta {
        NO_MASK_AND_ONE_INACTIVE_VAL | MASK_AND_ONE_INACTIVE_VAL => 1,
        MASK_AND_TWO_INACTIVE_VALS => 2,
        _ => 0,
    };
    input.skip(
        (inactive_values * enc.native_size()) as u64,
        "a node's inactive values",
    )?;
    if matches!(
        meta,
        MASK_AND_NO_INACTIVE_VALS | MASK_AND_ONE_INACTIVE_VAL | MASK_AND_TWO_INACTIVE_VALS
    ) {
        input.skip(count as u64 / 8, "a node's selection mask")?;
    }
    let active = value_mask
        .iter()
        .map(|w| w.count_ones() as usize)
        .sum::<usize>();
    let masked = enc.compression & COMPRESS_ACTIVE_MASK != 0 && meta != NO_MASK_AND_ALL_VALS;
    let stored = if masked { active } else { count };
    let stored_size = enc.stored_size();
    let bytes = if enc.half_reader() && stored == 0 {
        Vec::new()
    } else {
        read_data(input, enc.compression, stored * stored_size)?
    };
    if masked {
        // Only the active values were stored.
        enc.decode(&bytes, stored_size / enc.channels(), out);
    } else {
        out.clear();
        out.reserve(active * enc.channels());
        let mut one = Vec::with_capacity(3);
        for n in ones(value_mask) {
            enc.decode(
                &bytes[n * stored_size..(n + 1) * stored_size],
                stored_size / enc.channels(),
                &mut one,
            );
            out.extend_from_slice(&one);
        }
    }
    Ok(())
}

/// `io::readData`: `expected` bytes, raw or as one zip / Blosc chunk (an i64 size,
/// negative for a chunk stored uncompressed, then the bytes).
fn read_data<R: Read + Seek>(
    input: &mut Input<R>,
    compression: u32,
    expected: usize,
) -> Result<Vec<u8>> {
    if compression & (COMPRESS_BLOSC | COMPRESS_ZIP) == 0 {
        return input.bytes(expected as u64, "node values");
    }
    let at = input.pos();
    let size = input.i64("a compressed chunk's size")?;
    if size <= 0 {
        if size.unsigned_abs() != expected as u64 {
            bail!(
                "corrupt file: uncompressed chunk at byte {at} has {} bytes, expected {expected}",
                size.unsigned_abs()
            );
        }
        return input.bytes(expected as u64, "node values");
    }
    // OpenVDB stores a chunk compressed only when that is smaller than the raw bytes
    // (Blosc adds at most 16 bytes of header); anything much larger is corruption.
    let limit = expected as u64 + expected as u64 / 8 + 1024;
    if size as u64 > limit {
        bail!("corrupt file: compressed chunk at byte {at} claims {size} bytes for {expected} bytes of values");
    }
    let packed = input.bytes(size as u64, "a compressed chunk")?;
    if compression & COMPRESS_BLOSC != 0 {
        blosc::decompress(&packed, expected).with_context(|| format!("blosc chunk at byte {at}"))
    } else {
        unzip(&packed, expected).with_context(|| format!("zip chunk at byte {at}"))
    }
}

/// zlib `uncompress` as OpenVDB checks it: exactly `expected` bytes come out.
fn unzip(packed: &[u8], expected: usize) -> Result<Vec<u8>> {
    let mut out = vec![0u8; expected];
    let mut z = flate2::Decompress::new(true);
    z.decompress(packed, &mut out, flate2::FlushDecompress::Finish)
        .map_err(|e| anyhow::anyhow!("zlib: {e}"))?;
    if z.total_out() != expected as u64 {
        bail!(
            "zlib data decoded to {} bytes, expected {expected}",
            z.total_out()
        );
    }
    Ok(out)
}

fn fmt_value(v: &[f32]) -> String {
    match v {
        [x] => format!("{x}"),
        _ => format!("{v:?}"),
    }
}

fn check_finite(v: &[f32; 3], ch: usize, what: impl FnOnce() -> String) -> Result<()> {
    if v[..ch].iter().all(|x| x.is_finite()) {
        return Ok(());
    }
    bail!(
        "{} is {} (values must be finite; a double too large for f32 reads as inf)",
        what(),
        fmt_value(&v[..ch])
    )
}

/// The leaf buffers, in the order OpenVDB writes them: root children sorted by origin
/// (x, then y, then z: `std::map<Coord>`), depth first below each.
fn read_buffers<R: Read + Seek>(
    input: &mut Input<R>,
    enc: &Encoding,
    mut topo: Topology,
    grid: &mut SparseGrid,
) -> Result<()> {
    let ch = enc.channels();
    // Bricks end up sorted by (z, y, x) of their origin, for lookups.
    let mut order: Vec<usize> = (0..topo.leaves.len()).collect();
    order.sort_unstable_by_key(|&i| {
        let o = topo.leaves[i].origin;
        (o.z, o.y, o.x)
    });
    let mut slot = vec![0usize; order.len()];
    for (rank, &i) in order.iter().enumerate() {
        slot[i] = rank;
    }
    let brick_len = BRICK_VOXELS * ch;
    grid.brick_origins = order.iter().map(|&i| topo.leaves[i].origin).collect();
    grid.brick_masks = order.iter().map(|&i| topo.leaves[i].mask).collect();
    grid.values = Vec::new();
    grid.values
        .try_reserve_exact(order.len() * brick_len)
        .map_err(|_| anyhow::anyhow!("{} leaf bricks do not fit in memory here", order.len()))?;
    grid.values.resize(order.len() * brick_len, 0.0);
    drop(order);

    topo.root_children
        .sort_by_key(|c| (c.origin.x, c.origin.y, c.origin.z));
    let mut values = Vec::new();
    let mut bbox: Option<(IVec3, IVec3)> = None;
    for child in &topo.root_children {
        for i in child.leaves.clone() {
            let leaf = &topo.leaves[i];
            let origin = leaf.origin;
            input
                .skip(64, "a leaf's value mask")
                .and_then(|_| read_active_values(input, enc, BRICK_VOXELS, &leaf.mask, &mut values))
                .with_context(|| format!("in the leaf at {origin}"))?;
            let dest = &mut grid.values[slot[i] * brick_len..(slot[i] + 1) * brick_len];
            for v in dest.chunks_exact_mut(ch) {
                v.copy_from_slice(&topo.background[..ch]);
            }
            for (k, n) in ones(&leaf.mask).enumerate() {
                let l = local(n, 3);
                let d = (l.x + LEAF_DIM * (l.y + LEAF_DIM * l.z)) as usize * ch;
                let v = &values[k * ch..(k + 1) * ch];
                let ijk = origin + l;
                if !v.iter().all(|x| x.is_finite()) {
                    bail!("voxel {ijk} is {} (values must be finite)", fmt_value(v));
                }
                dest[d..d + ch].copy_from_slice(v);
                bbox = Some(match bbox {
                    None => (ijk, ijk),
                    Some((lo, hi)) => (lo.min(ijk), hi.max(ijk)),
                });
            }
        }
    }
    for t in &topo.tiles {
        let hi = t.origin + IVec3::splat(t.edge as i32 - 1);
        bbox = Some(match bbox {
            None => (t.origin, hi),
            Some((lo, h)) => (lo.min(t.origin), h.max(hi)),
        });
    }
    topo.tiles
        .sort_by_key(|t| (t.edge, t.origin.z, t.origin.y, t.origin.x));
    grid.tiles = topo.tiles;
    grid.active_bbox = bbox;
    grid.active_voxels = topo.active_voxels;
    Ok(())
}
