//! OpenVDB (`.vdb`) reader: one grid of a file into a [`SparseGrid`] of 8³ bricks (the
//! tree's leaf nodes) and constant tiles, so memory follows the active voxels.
//!
//! Written from OpenVDB's own sources (`io/Archive.cc`, `io/GridDescriptor.cc`,
//! `io/Compression.{h,cc}`, `tree/{Root,Internal,Leaf}Node.h`, `math/Maps.h`) and c-blosc
//! 1.x's `blosc.c` / `blosclz.c`, in safe Rust: zlib through `flate2`, lz4 through
//! `lz4_flex`, Blosc's container and blosclz decoded here (`vdb/blosc.rs`).
//!
//! # Supported
//! - File format versions 222 (OpenVDB 3.0, 2014) to 225 (OpenVDB 13; 10 to 12 write
//!   224): what Houdini, Blender, EmberGen and OpenVDB's tools write. Files with grid
//!   offsets (everything written to a file rather than a pipe).
//! - Grids `Tree_<T>_5_4_3` (the standard root → 32³ → 16³ → 8³ tree) with `T` one of
//!   `float`, `double`, `half` (OpenVDB 13's half grids), `vec3s`, `vec3d`; values are
//!   widened or narrowed to f32 (a double beyond f32's range is an error, as inf).
//! - The `_HalfFloat` option (float / vec3 node values stored as 16-bit halves).
//! - Compression per grid: none, zip (zlib), Blosc (c-blosc 1.x with the blosclz, lz4,
//!   lz4hc or zlib codec, with or without byte shuffle), each with or without
//!   OpenVDB's active-mask compression (all seven per-node modes; chunks stored
//!   uncompressed inside a compressed grid, too).
//! - Transforms `AffineMap`, `UnitaryMap`, `ScaleMap`, `UniformScaleMap`,
//!   `TranslationMap`, `ScaleTranslateMap`, `UniformScaleTranslateMap`, as an affine
//!   [`glam::DMat4`]; tiles at every level; grid instancing (a grid sharing another's
//!   tree); duplicate grid names (the first is taken).
//! - Any grid class: level sets read like fog volumes ([`SparseGrid::grid_class`] tells
//!   them apart). Of the grid metadata only `class` is read; the rest is skipped.
//!
//! # Not supported (each a clear error)
//! File versions before 222 or after 225, streams without grid offsets,
//! `NonlinearFrustumMap` and unknown maps, degenerate (singular or non-finite)
//! transforms, point data / point index / integer / bool / mask / string grids, trees
//! other than 5-4-3, multi-buffer trees, Blosc with snappy / zstd / bit-shuffle,
//! unknown compression flags.
//!
//! # What the grid holds
//! - Bricks: one per leaf node, in [`SparseGrid::brick_origins`] (sorted by z, then y,
//!   then x of the origin), [`SparseGrid::brick_masks`] (the active-voxel masks, bit
//!   `x·64 + y·8 + z` as in OpenVDB) and [`SparseGrid::values`]: 512 voxels per brick,
//!   **x fastest, then y, then z** ([`SparseGrid::brick_voxel_index`]), channels
//!   interleaved. Inactive voxels inside a brick hold the background value
//!   (docs/scene-format.md: inactive voxels are the background); OpenVDB's stored inactive
//!   values are skipped.
//! - Tiles: active constant regions of internal nodes (edge 8 or 128 voxels) and of the
//!   root (4096, which is always over the voxel limit below). Inactive tiles are
//!   background and are dropped.
//! - Voxel `(i, j, k)`'s value sits at `index_to_world · (i, j, k, 1)` (OpenVDB's
//!   node-centred convention).
//!
//! # Limits and checks
//! Reading streams node by node: the topology pass keeps each leaf's origin and mask
//! (76 bytes), then the leaf values go straight into one buffer whose size is checked
//! first. Refused before allocating: more than [`MAX_ACTIVE_VOXELS`] active voxels
//! (tiles included), or bricks holding more than [`MAX_GRID_VALUES`] f32 values (8 GiB).
//! Active values (voxels and tiles) and the background must be finite: the error names
//! the voxel and its value. Every count and size in the file is checked against the
//! bytes the file still has, so a truncated or corrupt file is an error, never a panic
//! or a huge allocation.
//!
//! # Tests
//! `tests/suite/vdb.rs` compares the reader, voxel for voxel, with what OpenVDB 10 reads back
//! from files it wrote (`tools/make_test_vdbs.py`); the unit tests here cover what
//! OpenVDB 10's Python module cannot write, and truncate and byte-flip real files.

mod blosc;
mod dense;
mod file;
mod input;
mod tree;

use std::fmt;
use std::fs::File;
use std::io::{Read, Seek};
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Result};
use glam::{DMat4, IVec3};

use crate::volume::MAX_GRID_VALUES;
pub(crate) use dense::load_window;
use file::Descriptor;
use input::Input;

/// Edge of a brick (an OpenVDB leaf node) in voxels.
pub const LEAF_DIM: i32 = 8;
/// Voxels in a brick.
pub const BRICK_VOXELS: usize = 512;
/// The most active voxels (tiles counted by their volume) a grid may have.
pub const MAX_ACTIVE_VOXELS: u64 = 1 << 31;

/// The value type of a grid as stored in the file (all are read as f32).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ValueType {
    Float,
    Half,
    Double,
    Vec3Float,
    Vec3Double,
}

impl ValueType {
    /// 1 for scalars, 3 for vectors.
    pub fn channels(self) -> usize {
        match self {
            Self::Float | Self::Half | Self::Double => 1,
            _ => 3,
        }
    }

    /// Bytes of one channel of the native type.
    pub fn scalar_bytes(self) -> usize {
        match self {
            Self::Half => 2,
            Self::Float | Self::Vec3Float => 4,
            Self::Double | Self::Vec3Double => 8,
        }
    }

    /// OpenVDB's name: `float`, `half`, `double`, `vec3s`, `vec3d`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Float => "float",
            Self::Half => "half",
            Self::Double => "double",
            Self::Vec3Float => "vec3s",
            Self::Vec3Double => "vec3d",
        }
    }
}

/// The grid's `class` metadata.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GridClass {
    FogVolume,
    LevelSet,
    Staggered,
    Unknown,
}

/// What the caller needs, for choosing and checking the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VdbGridKind {
    /// `float`, `half` or `double` (density, scalar emission).
    Scalar,
    /// `vec3s` or `vec3d` (velocity, coloured emission).
    Vec3,
    /// Either.
    Any,
}

impl VdbGridKind {
    fn accepts(self, t: ValueType) -> bool {
        match self {
            Self::Scalar => t.channels() == 1,
            Self::Vec3 => t.channels() == 3,
            Self::Any => true,
        }
    }

    fn describe(self) -> &'static str {
        match self {
            Self::Scalar => "scalar grid (float, half or double)",
            Self::Vec3 => "vec3 grid (vec3s or vec3d)",
            Self::Any => "scalar or vec3 grid",
        }
    }
}

/// One grid of a file, as [`list_grids`] gives it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VdbGridInfo {
    pub name: String,
    /// OpenVDB's value type name (`float`, `vec3s`, `bool`, `ptdataidx32`, ...) or the
    /// whole tree type when the tree is not a 5-4-3 tree.
    pub type_name: String,
    /// `Some` for the types this reader reads.
    pub value_type: Option<ValueType>,
    pub saved_as_half: bool,
}

impl fmt::Display for VdbGridInfo {
    /// `density (float)`, `vel (vec3s, saved as half)`, `points (point data)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = match self.type_name.as_str() {
            "ptdataidx32" | "ptdataidx64" => "point data",
            "ptidx32" | "ptidx64" => "point index",
            other => other,
        };
        let half = if self.saved_as_half {
            ", saved as half"
        } else {
            ""
        };
        write!(f, "{} ({kind}{half})", self.name)
    }
}

/// An active tile: a constant cube of `edge`³ voxels from `origin` (inclusive).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VdbTile {
    pub origin: IVec3,
    /// 8 (a tile of a 16³ node), 128 (of a 32³ node) or 4096 (of the root).
    pub edge: u32,
    /// Scalars in `value[0]`, the other channels 0.
    pub value: [f32; 3],
}

/// One grid read from a `.vdb` file: bricks (leaf nodes) and tiles, in index space.
#[derive(Clone, Debug)]
pub struct SparseGrid {
    pub file: PathBuf,
    /// The file format version (222..=225) and the OpenVDB version that wrote it.
    pub file_version: u32,
    pub library_version: (u32, u32),
    pub name: String,
    pub value_type: ValueType,
    /// The file stored node values as 16-bit halves (`_HalfFloat`).
    pub saved_as_half: bool,
    pub grid_class: GridClass,
    /// The OpenVDB map the transform came from, e.g. `ScaleTranslateMap`.
    pub map_type: String,
    /// Index space to world space (column vectors): voxel `(i, j, k)` sits at
    /// `index_to_world · (i, j, k, 1)`.
    pub index_to_world: DMat4,
    /// Scalars in `background[0]`, the other channels 0.
    pub background: [f32; 3],
    /// Inclusive index-space bounds of the active voxels and tiles; `None` when the
    /// grid has none.
    pub active_bbox: Option<(IVec3, IVec3)>,
    /// Active voxels, tiles counted by their volume.
    pub active_voxels: u64,
    /// Origins (multiples of 8) of the bricks, sorted by (z, y, x).
    pub brick_origins: Vec<IVec3>,
    /// Active-voxel masks of the bricks: bit `x·64 + y·8 + z` (OpenVDB's order) of the
    /// 512-bit mask, as 8 words.
    pub brick_masks: Vec<[u64; 8]>,
    /// `BRICK_VOXELS · channels` values per brick, x fastest within a brick, channels
    /// interleaved; inactive voxels hold the background.
    pub values: Vec<f32>,
    /// Active tiles, sorted by (edge, z, y, x).
    pub tiles: Vec<VdbTile>,
}

impl SparseGrid {
    pub fn channels(&self) -> usize {
        self.value_type.channels()
    }

    pub fn brick_count(&self) -> usize {
        self.brick_origins.len()
    }

    /// Index of voxel `(x, y, z)` (each 0..8) inside a brick's 512 voxels.
    pub fn brick_voxel_index(x: i32, y: i32, z: i32) -> usize {
        (x + LEAF_DIM * (y + LEAF_DIM * z)) as usize
    }

    /// The values of brick `b` (`512 · channels`).
    pub fn brick(&self, b: usize) -> &[f32] {
        let n = BRICK_VOXELS * self.channels();
        &self.values[b * n..(b + 1) * n]
    }

    /// Whether voxel `(x, y, z)` of brick `b` is active.
    pub fn brick_voxel_active(&self, b: usize, x: i32, y: i32, z: i32) -> bool {
        let n = ((x << 6) | (y << 3) | z) as usize;
        self.brick_masks[b][n >> 6] >> (n & 63) & 1 != 0
    }

    /// The value at index `ijk` and whether it is active: a brick's voxel, else an
    /// active tile's value, else the background. O(log bricks + log tiles).
    pub fn value_at(&self, ijk: IVec3) -> ([f32; 3], bool) {
        let ch = self.channels();
        let origin = ijk & IVec3::splat(!(LEAF_DIM - 1));
        let key = |o: &IVec3| (o.z, o.y, o.x);
        if let Ok(b) = self.brick_origins.binary_search_by_key(&key(&origin), key) {
            let l = ijk - origin;
            let at = Self::brick_voxel_index(l.x, l.y, l.z) * ch;
            let mut v = [0.0; 3];
            v[..ch].copy_from_slice(&self.brick(b)[at..at + ch]);
            return (v, self.brick_voxel_active(b, l.x, l.y, l.z));
        }
        for edge in [8u32, 128, 4096] {
            let origin = ijk & IVec3::splat(!(edge as i32 - 1));
            let tile_key = |t: &VdbTile| (t.edge, t.origin.z, t.origin.y, t.origin.x);
            if let Ok(t) = self
                .tiles
                .binary_search_by_key(&(edge, origin.z, origin.y, origin.x), tile_key)
            {
                return (self.tiles[t].value, true);
            }
        }
        (self.background, false)
    }

    /// Bytes held by the bricks and tiles.
    pub fn memory_bytes(&self) -> usize {
        self.values.len() * 4
            + self.brick_origins.len() * std::mem::size_of::<IVec3>()
            + self.brick_masks.len() * 64
            + self.tiles.len() * std::mem::size_of::<VdbTile>()
    }
}

/// A grid's tree without its leaf values ([`read_vdb_topology`]): enough to place the
/// grid and to know which bricks it stores before reading them.
#[derive(Clone, Debug)]
pub struct VdbTopology {
    /// Scalars in `background[0]`, the other channels 0.
    pub background: [f32; 3],
    /// Origins of the leaf nodes (bricks), in file order.
    pub leaf_origins: Vec<IVec3>,
    /// Active tiles.
    pub tiles: Vec<VdbTile>,
    /// Inclusive index-space bounds of the active voxels and tiles.
    pub active_bbox: Option<(IVec3, IVec3)>,
    pub active_voxels: u64,
}

/// What [`read_vdb_topology`] returns: the grid's identity, transform and topology.
#[derive(Clone, Debug)]
pub struct VdbGridHeader {
    pub file: PathBuf,
    pub name: String,
    pub value_type: ValueType,
    pub saved_as_half: bool,
    pub grid_class: GridClass,
    pub map_type: String,
    pub index_to_world: DMat4,
    pub topology: VdbTopology,
}

/// Reads one grid of a `.vdb` file as [`read_vdb_grid`] does, but stops after the tree's
/// topology: no leaf values are read or decompressed (tiles of internal nodes are).
/// Errors are [`read_vdb_grid`]'s.
pub fn read_vdb_topology(
    path: &Path,
    grid: Option<&str>,
    kind: VdbGridKind,
    what: &str,
) -> Result<VdbGridHeader> {
    let what = prefix(what);
    let mut input = open(path, &what)?;
    let file_err = |e: anyhow::Error| anyhow!("{what}{}: {e:#}", path.display());
    file::read_header(&mut input).map_err(file_err)?;
    file::read_meta(&mut input).map_err(file_err)?;
    let descs = file::read_descriptors(&mut input).map_err(file_err)?;
    let desc = select(&descs, grid, kind).map_err(file_err)?;
    let grid_err =
        |e: anyhow::Error| anyhow!("{what}{}: grid \"{}\": {e:#}", path.display(), desc.name);
    let value_type = check_type(desc, kind).map_err(grid_err)?;
    let read = |input: &mut Input<_>| -> Result<VdbGridHeader> {
        // An instance's tree is its parent's (see `read_grid`).
        let tree_desc = if desc.instance_parent.is_empty() {
            desc
        } else {
            descs
                .iter()
                .find(|d| d.unique_name == desc.instance_parent)
                .ok_or_else(|| {
                    anyhow!(
                        "its instance parent \"{}\" is not in the file",
                        desc.instance_parent
                    )
                })?
        };
        input.seek(desc.grid_pos)?;
        input.u32("the grid's compression flags")?;
        let meta = file::read_meta(input)?;
        let (map_type, index_to_world) = file::read_transform(input)?;
        input.seek(tree_desc.grid_pos)?;
        let compression = input.u32("the grid's compression flags")?;
        file::read_meta(input)?;
        file::read_transform(input)?;
        let enc = tree::Encoding {
            value: value_type,
            save_half: tree_desc.save_half,
            compression,
        };
        let topology = tree::read_topology_only(input, &enc)?;
        Ok(VdbGridHeader {
            file: path.to_path_buf(),
            name: desc.name.clone(),
            value_type,
            saved_as_half: desc.save_half,
            grid_class: file::grid_class(&meta),
            map_type,
            index_to_world,
            topology,
        })
    };
    read(&mut input).map_err(grid_err)
}

/// `"{what}: "`, or nothing when `what` is empty.
fn prefix(what: &str) -> String {
    if what.is_empty() {
        String::new()
    } else {
        format!("{what}: ")
    }
}

/// Opens `path`; errors read "{prefix}{path}: cannot open VDB file: ...".
fn open(path: &Path, prefix: &str) -> Result<Input<std::io::BufReader<File>>> {
    let file = File::open(path)
        .map_err(|e| anyhow!("{prefix}{}: cannot open VDB file: {e}", path.display()))?;
    Input::open(file).map_err(|e| anyhow!("{prefix}{}: cannot read: {e}", path.display()))
}

/// Header, file metadata and grid descriptors.
fn read_directory<R: Read + Seek>(input: &mut Input<R>) -> Result<Vec<Descriptor>> {
    file::read_header(input)?;
    file::read_meta(input)?;
    file::read_descriptors(input)
}

fn info(d: &Descriptor) -> VdbGridInfo {
    VdbGridInfo {
        name: d.name.clone(),
        type_name: d.type_name.clone(),
        value_type: d.value_type(),
        saved_as_half: d.save_half,
    }
}

fn grid_list(descs: &[Descriptor]) -> String {
    if descs.is_empty() {
        return "the file has no grids".to_string();
    }
    let names: Vec<String> = descs.iter().map(|d| info(d).to_string()).collect();
    format!("the file has grids: {}", names.join(", "))
}

/// Lists the grids of a `.vdb` file (names and types) without reading their trees.
pub fn list_grids(path: &Path) -> Result<Vec<VdbGridInfo>> {
    let mut input = open(path, "")?;
    let descs = read_directory(&mut input).map_err(|e| anyhow!("{}: {e:#}", path.display()))?;
    Ok(descs.iter().map(info).collect())
}

/// Picks the grid: the one named `grid`, else the file's only grid of `kind`, else
/// (for scalars) the one named "density".
fn select<'a>(
    descs: &'a [Descriptor],
    grid: Option<&str>,
    kind: VdbGridKind,
) -> Result<&'a Descriptor> {
    if let Some(name) = grid {
        return descs
            .iter()
            .find(|d| d.name == name)
            .or_else(|| descs.iter().find(|d| d.unique_name == name))
            .ok_or_else(|| anyhow!("no grid named \"{name}\"; {}", grid_list(descs)));
    }
    let matching: Vec<&Descriptor> = descs
        .iter()
        .filter(|d| d.value_type().is_some_and(|t| kind.accepts(t)))
        .collect();
    if let [only] = matching.as_slice() {
        return Ok(only);
    }
    if kind != VdbGridKind::Vec3 {
        if let Some(d) = descs.iter().find(|d| d.name == "density") {
            return Ok(d);
        }
    }
    if matching.is_empty() {
        bail!("the file has no {}; {}", kind.describe(), grid_list(descs));
    }
    bail!(
        "the file has {} grids of the kind needed ({}) and none named \"density\"; name one \
         with `grid = \"...\"`; {}",
        matching.len(),
        kind.describe(),
        grid_list(descs)
    )
}

/// The descriptor's value type, or why it cannot be read as `kind`.
fn check_type(d: &Descriptor, kind: VdbGridKind) -> Result<ValueType> {
    let needed = kind.describe();
    if !d.tree_543 {
        bail!(
            "its tree type {} is not supported (only OpenVDB's standard 5-4-3 trees); \
             a {needed} is needed",
            d.type_name
        );
    }
    match (d.value_type(), d.type_name.as_str()) {
        (Some(t), _) if kind.accepts(t) => Ok(t),
        (Some(t), _) => bail!("it holds {} values; a {needed} is needed", t.name()),
        (None, "ptdataidx32" | "ptdataidx64") => {
            bail!("it is a point data grid (particles, not voxels); a {needed} is needed")
        }
        (None, "ptidx32" | "ptidx64") => bail!("it is a point index grid; a {needed} is needed"),
        (None, other) => {
            bail!("it holds {other} values, which Nimbus does not read; a {needed} is needed")
        }
    }
}

/// Reads one grid of the `.vdb` file at `path` into a [`SparseGrid`].
///
/// `grid` names the grid; `None` picks the file's only grid of `kind`, else (unless
/// `kind` is [`VdbGridKind::Vec3`]) the grid named "density". `what` names the use in
/// messages (e.g. `"scene.toml: [[medium]] #1 > density"`); every error names `what`,
/// the file and, once chosen, the grid:
///
/// ```text
/// scene.toml: [[medium]] #1 > density: clouds/x.vdb: no grid named "dens"; the file has grids: density (float), vel (vec3s)
/// ```
pub fn read_vdb_grid(
    path: &Path,
    grid: Option<&str>,
    kind: VdbGridKind,
    what: &str,
) -> Result<SparseGrid> {
    let mut input = open(path, &prefix(what))?;
    read_from(&mut input, path, grid, kind, what)
}

/// [`read_vdb_grid`] on any seekable input; `path` only names it.
fn read_from<R: Read + Seek>(
    input: &mut Input<R>,
    path: &Path,
    grid: Option<&str>,
    kind: VdbGridKind,
    what: &str,
) -> Result<SparseGrid> {
    let what = prefix(what);
    let file_err = |e: anyhow::Error| anyhow!("{what}{}: {e:#}", path.display());
    let header = file::read_header(input).map_err(file_err)?;
    file::read_meta(input).map_err(file_err)?;
    let descs = file::read_descriptors(input).map_err(file_err)?;
    let desc = select(&descs, grid, kind).map_err(file_err)?;
    let grid_err =
        |e: anyhow::Error| anyhow!("{what}{}: grid \"{}\": {e:#}", path.display(), desc.name);
    let value_type = check_type(desc, kind).map_err(grid_err)?;
    let mut grid = read_grid(input, &descs, desc, value_type, path).map_err(grid_err)?;
    grid.file_version = header.file_version;
    grid.library_version = header.library;
    Ok(grid)
}

fn read_grid<R: Read + Seek>(
    input: &mut Input<R>,
    descs: &[Descriptor],
    desc: &Descriptor,
    value_type: ValueType,
    path: &Path,
) -> Result<SparseGrid> {
    input.seek(desc.grid_pos)?;
    let compression = input.u32("the grid's compression flags")?;
    let meta = file::read_meta(input)?;
    let (map_type, index_to_world) = file::read_transform(input)?;
    let mut grid = SparseGrid {
        file: path.to_path_buf(),
        file_version: 0,
        library_version: (0, 0),
        name: desc.name.clone(),
        value_type,
        saved_as_half: desc.save_half,
        grid_class: file::grid_class(&meta),
        map_type,
        index_to_world,
        background: [0.0; 3],
        active_bbox: None,
        active_voxels: 0,
        brick_origins: Vec::new(),
        brick_masks: Vec::new(),
        values: Vec::new(),
        tiles: Vec::new(),
    };
    let mut enc = tree::Encoding {
        value: value_type,
        save_half: desc.save_half,
        compression,
    };
    if !desc.instance_parent.is_empty() {
        // An instance shares its parent's tree (written once, with the parent).
        let parent = descs
            .iter()
            .find(|d| d.unique_name == desc.instance_parent)
            .ok_or_else(|| {
                anyhow!(
                    "its instance parent \"{}\" is not in the file",
                    desc.instance_parent
                )
            })?;
        if !parent.instance_parent.is_empty() || parent.value_type() != Some(value_type) {
            bail!(
                "its instance parent \"{}\" is itself an instance or of another type",
                parent.name
            );
        }
        input.seek(parent.grid_pos)?;
        enc.compression = input.u32("the parent grid's compression flags")?;
        enc.save_half = parent.save_half;
        file::read_meta(input)?;
        file::read_transform(input)?;
    }
    tree::read_tree(input, &enc, &mut grid)?;
    if desc.instance_parent.is_empty() && input.pos() > desc.end_pos {
        bail!(
            "corrupt file: the grid's data runs to byte {}, past its end at {}",
            input.pos(),
            desc.end_pos
        );
    }
    Ok(grid)
}

#[cfg(test)]
mod tests;
