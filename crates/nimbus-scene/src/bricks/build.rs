//! Building a [`BrickGrid`]: from a dense grid, streamed from z-slabs of a file (8
//! layers at a time, never the whole grid), brick by brick from the procedural cloud,
//! and from an OpenVDB [`SparseGrid`] (its leaves become bricks without a copy, its
//! tiles are expanded); and the brick sets alone ([`BrickTopology`]), which the memory
//! guard reads before anything is allocated.

use anyhow::{anyhow, bail, Result};
use glam::{DVec3, IVec3};

use super::{shr, BrickGrid, BRICK_EDGE, BRICK_POINTS};
use crate::cumulus::Cumulus;
use crate::types::ProceduralKind;
use crate::vdb::{SparseGrid, LEAF_DIM};
use crate::volume::VoxelGrid;

/// Which bricks a grid will store (an upper bound where the data is not read), its
/// lattice and box: what the memory guard needs, without the values.
#[derive(Clone, Debug, PartialEq)]
pub struct BrickTopology {
    pub origin: IVec3,
    pub lattice_min: IVec3,
    pub lattice_max: IVec3,
    pub index_min: DVec3,
    pub index_max: DVec3,
    pub channels: u32,
    /// Primed brick coordinates, each once.
    pub bricks: Vec<IVec3>,
}

impl BrickTopology {
    /// Bricks per axis of the indirection.
    pub fn brick_dims(&self) -> [u32; 3] {
        (shr(self.lattice_max, 3) + 1).to_array().map(|d| d as u32)
    }

    /// Entries of the indirection of these bricks: one per brick of the box where that
    /// is one-level, else the top table and a leaf table per node, an upper bound for the
    /// grid's and its atlas layout's (whose slots also hold the low-side neighbours of
    /// stored bricks). The nodes are counted in a set of nodes (1/512 of the bricks).
    pub fn cells(&self) -> u64 {
        use super::indirection::{dense_cells, entries_for, MAX_DENSE_CELLS};
        let dims = self.brick_dims();
        if dense_cells(dims) <= MAX_DENSE_CELLS {
            return dense_cells(dims);
        }
        let mut nodes = std::collections::HashSet::new();
        for b in &self.bricks {
            let (lo, hi) = (shr((*b - 1).max(IVec3::ZERO), 3), shr(*b, 3));
            for z in lo.z..=hi.z {
                for y in lo.y..=hi.y {
                    for x in lo.x..=hi.x {
                        nodes.insert(IVec3::new(x, y, z));
                    }
                }
            }
        }
        entries_for(dims, nodes.len() as u64)
    }

    /// The topology of a dense grid of `dims` whose stored bricks are `bricks`.
    pub fn dense(dims: [u32; 3], channels: u32, bricks: Vec<IVec3>) -> BrickTopology {
        let n = IVec3::from_array(dims.map(|d| d as i32));
        BrickTopology {
            origin: IVec3::ZERO,
            lattice_min: IVec3::ZERO,
            lattice_max: n - 1,
            index_min: DVec3::ZERO,
            index_max: n.as_dvec3(),
            channels,
            bricks,
        }
    }

    /// An empty [`BrickGrid`] with this lattice and box.
    pub fn grid(&self) -> Result<BrickGrid> {
        BrickGrid::empty(
            self.origin,
            self.lattice_min,
            self.lattice_max,
            self.index_min,
            self.index_max,
            self.channels,
        )
    }
}

/// Why a value cannot be a voxel of a grid, if it cannot: not finite, or negative where
/// `non_negative`.
fn bad_value(v: f32, non_negative: bool) -> Option<&'static str> {
    if !v.is_finite() {
        Some("is not finite")
    } else if non_negative && v < 0.0 {
        Some("is negative (densities and emission must be >= 0)")
    } else {
        None
    }
}

/// The brick coordinates of a dense grid of `dims`, z slowest.
fn dense_bricks(dims: [u32; 3]) -> impl Iterator<Item = IVec3> {
    let [bx, by, bz] = dims.map(|d| d.div_ceil(BRICK_EDGE as u32) as i32);
    (0..bz).flat_map(move |z| (0..by).flat_map(move |y| (0..bx).map(move |x| IVec3::new(x, y, z))))
}

impl BrickGrid {
    /// The bricks of a dense grid (cell-centred, clamped at its faces: lattice
    /// `0 ..= n − 1`, box `[0, n]`); all-zero bricks are dropped.
    pub fn from_dense(grid: &VoxelGrid) -> Result<BrickGrid> {
        let dims = grid.dims;
        let ch = grid.channels as usize;
        let mut out = BrickTopology::dense(dims, grid.channels, Vec::new()).grid()?;
        let mut values = vec![0f32; BRICK_POINTS * ch];
        for b in dense_bricks(dims) {
            let (lo, hi) = out.brick_range(b);
            values.iter_mut().for_each(|v| *v = 0.0);
            let mut any = false;
            for k in lo.z..=hi.z {
                for j in lo.y..=hi.y {
                    for i in lo.x..=hi.x {
                        let src = grid.index(i as u32, j as u32, k as u32) * ch;
                        let dst = super::point_index(IVec3::new(i, j, k) - b * BRICK_EDGE) * ch;
                        values[dst..dst + ch].copy_from_slice(&grid.data[src..src + ch]);
                        any |= grid.data[src..src + ch].iter().any(|v| *v != 0.0);
                    }
                }
            }
            if any {
                out.push_brick(b, &values)?;
            }
        }
        Ok(out)
    }

    /// A dense grid of `dims` read in z-slabs of 8 layers: `fill(z0, layers, slab)`
    /// writes `nx · ny · layers · channels` values (x fastest, then y, then z) into
    /// `slab`. Every value is checked (finite; ≥ 0 when `non_negative`), errors naming
    /// `name` and the voxel. All-zero bricks are dropped. Peak memory: one slab plus
    /// the bricks kept.
    pub fn from_slabs(
        dims: [u32; 3],
        channels: u32,
        name: &str,
        non_negative: bool,
        mut fill: impl FnMut(u32, u32, &mut [f32]) -> Result<()>,
    ) -> Result<BrickGrid> {
        let [nx, ny, nz] = dims.map(|d| d as usize);
        let ch = channels as usize;
        let mut out = BrickTopology::dense(dims, channels, Vec::new()).grid()?;
        let layers_max = BRICK_EDGE as usize;
        let mut slab = Vec::new();
        slab.try_reserve_exact(nx * ny * layers_max * ch)
            .map_err(|e| {
                anyhow!("{name}: cannot allocate a slab of {nx} x {ny} x 8 voxels: {e}")
            })?;
        let mut values = vec![0f32; BRICK_POINTS * ch];
        for bz in 0..nz.div_ceil(layers_max) {
            let z0 = bz * layers_max;
            let layers = layers_max.min(nz - z0);
            slab.clear();
            slab.resize(nx * ny * layers * ch, 0.0);
            fill(z0 as u32, layers as u32, &mut slab)?;
            if let Some(at) = slab
                .iter()
                .position(|v| bad_value(*v, non_negative).is_some())
            {
                let value = slab[at];
                let voxel = at / ch;
                let (i, j, k) = (voxel % nx, (voxel / nx) % ny, z0 + voxel / (nx * ny));
                let channel = if ch > 1 {
                    format!(" channel {}", at % ch)
                } else {
                    String::new()
                };
                let problem = bad_value(value, non_negative).unwrap_or("");
                bail!("{name}: voxel ({i}, {j}, {k}){channel}: value {value} {problem}");
            }
            for by in 0..ny.div_ceil(layers_max) {
                for bx in 0..nx.div_ceil(layers_max) {
                    let b = IVec3::new(bx as i32, by as i32, bz as i32);
                    let (lo, hi) = out.brick_range(b);
                    values.iter_mut().for_each(|v| *v = 0.0);
                    let mut any = false;
                    for k in lo.z..=hi.z {
                        for j in lo.y..=hi.y {
                            let row = ((k as usize - z0) * ny + j as usize) * nx;
                            for i in lo.x..=hi.x {
                                let src = (row + i as usize) * ch;
                                let local = IVec3::new(i, j, k) - b * BRICK_EDGE;
                                let dst = super::point_index(local) * ch;
                                values[dst..dst + ch].copy_from_slice(&slab[src..src + ch]);
                                any |= slab[src..src + ch].iter().any(|v| *v != 0.0);
                            }
                        }
                    }
                    if any {
                        out.push_brick(b, &values)?;
                    }
                }
            }
        }
        Ok(out)
    }

    /// The procedural cloud of `kind` (see [`crate::procedural_cloud`] and
    /// [`crate::procedural_cumulus`]), generated brick by brick: bricks its bound leaves
    /// out are never evaluated. Bit-identical to [`BrickGrid::from_dense`] of the dense
    /// cloud.
    pub fn procedural(dims: [u32; 3], seed: u64, kind: ProceduralKind) -> Result<BrickGrid> {
        match kind {
            ProceduralKind::Cloud => BrickGrid::procedural_cloud(dims, seed),
            ProceduralKind::Cumulus => BrickGrid::procedural_cumulus(dims, seed),
        }
    }

    /// The cumulus of `dims`, brick by brick.
    fn procedural_cumulus(dims: [u32; 3], seed: u64) -> Result<BrickGrid> {
        let mut out = BrickTopology::dense(dims, 1, Vec::new()).grid()?;
        let mut brick = vec![0f32; BRICK_POINTS];
        Cumulus::new(dims, seed).for_each_block(BRICK_EDGE, |lo, hi, values| {
            if values.iter().all(|v| *v == 0.0) {
                return Ok(());
            }
            brick.iter_mut().for_each(|v| *v = 0.0);
            let b = lo / BRICK_EDGE;
            let mut n = 0;
            for k in lo.z..=hi.z {
                for j in lo.y..=hi.y {
                    for i in lo.x..=hi.x {
                        brick[super::point_index(IVec3::new(i, j, k) - lo)] = values[n];
                        n += 1;
                    }
                }
            }
            out.push_brick(b, &brick)
        })?;
        Ok(out)
    }

    /// The procedural `"cloud"` of `dims`, brick by brick.
    pub fn procedural_cloud(dims: [u32; 3], seed: u64) -> Result<BrickGrid> {
        let mut out = BrickTopology::dense(dims, 1, Vec::new()).grid()?;
        let mut values = vec![0f32; BRICK_POINTS];
        for b in dense_bricks(dims) {
            if !procedural_cloud_brick_may_be_nonzero(dims, b) {
                continue;
            }
            let (lo, hi) = out.brick_range(b);
            values.iter_mut().for_each(|v| *v = 0.0);
            let mut any = false;
            for k in lo.z..=hi.z {
                for j in lo.y..=hi.y {
                    for i in lo.x..=hi.x {
                        let v =
                            crate::procedural::cloud_voxel(dims, seed, [i, j, k].map(|c| c as u32));
                        values[super::point_index(IVec3::new(i, j, k) - b * BRICK_EDGE)] = v;
                        any |= v != 0.0;
                    }
                }
            }
            if any {
                out.push_brick(b, &values)?;
            }
        }
        Ok(out)
    }

    /// An OpenVDB grid's bricks (moved, not copied) and its active tiles expanded into
    /// bricks, over lattice `bmin − 1 ..= bmax + 1` of its active bounding box. Inactive
    /// voxels are the background, which must be 0 (an error names the file and grid
    /// otherwise); values must be ≥ 0 when `non_negative`. `what` names the use.
    pub fn from_vdb(grid: SparseGrid, what: &str, non_negative: bool) -> Result<BrickGrid> {
        let name = format!("{what}: {}: grid \"{}\"", grid.file.display(), grid.name);
        let topo = vdb_topology(&grid, &name)?;
        let ch = grid.channels();
        let mut out = topo.grid().map_err(|e| anyhow!("{name}: {e:#}"))?;
        out.file_transform = Some(grid.index_to_world);
        let SparseGrid {
            brick_origins,
            values,
            tiles,
            ..
        } = grid;
        for (n, origin) in brick_origins.iter().enumerate() {
            let b = shr(*origin - out.origin, 3);
            if !out.contains_brick(b) {
                bail!("internal: {name}: leaf {origin} outside its bounding box");
            }
            out.indirection.set(b, n as u32)?;
            out.bricks.push(b);
        }
        out.values = values;
        for (i, b) in out.bricks.iter().enumerate() {
            let brick = &out.values[i * BRICK_POINTS * ch..(i + 1) * BRICK_POINTS * ch];
            if let Some(at) = brick
                .iter()
                .position(|v| bad_value(*v, non_negative).is_some())
            {
                let p = (at / ch) as i32;
                let ijk = out.origin + *b * BRICK_EDGE + IVec3::new(p & 7, (p >> 3) & 7, p >> 6);
                let problem = bad_value(brick[at], non_negative).unwrap_or("");
                bail!("{name}: voxel {ijk}: value {} {problem}", brick[at]);
            }
        }
        let mut tile_values = vec![0f32; BRICK_POINTS * ch];
        for t in &tiles {
            let value = &t.value[..ch];
            if let Some(v) = value
                .iter()
                .find(|v| bad_value(**v, non_negative).is_some())
            {
                let problem = bad_value(*v, non_negative).unwrap_or("");
                bail!(
                    "{name}: the active tile of {}³ voxels at {}: value {v} {problem}",
                    t.edge,
                    t.origin
                );
            }
            for p in tile_values.chunks_exact_mut(ch) {
                p.copy_from_slice(value);
            }
            let bricks = (t.edge / LEAF_DIM as u32) as i32;
            let first = shr(t.origin - out.origin, 3);
            for z in 0..bricks {
                for y in 0..bricks {
                    for x in 0..bricks {
                        out.push_brick(first + IVec3::new(x, y, z), &tile_values)?;
                    }
                }
            }
        }
        Ok(out)
    }
}

/// The lattice, box and bricks of an OpenVDB grid (see [`BrickGrid::from_vdb`]).
fn vdb_topology(grid: &SparseGrid, name: &str) -> Result<BrickTopology> {
    let ch = grid.channels();
    if grid.background[..ch].iter().any(|v| *v != 0.0) {
        bail!(
            "{name}: its background (the value of inactive voxels) is {:?}; Nimbus reads \
             inactive voxels as empty, so it must be 0 (a level set's background is its \
             narrow-band width: convert it to a fog volume first)",
            &grid.background[..ch]
        );
    }
    let Some((bmin, bmax)) = grid.active_bbox else {
        bail!("{name}: the grid has no active voxels");
    };
    let mut bricks: Vec<IVec3> = Vec::new();
    let topo = BrickTopology::vdb(bmin, bmax, ch as u32, Vec::new());
    for o in &grid.brick_origins {
        bricks.push(shr(*o - topo.origin, 3));
    }
    for t in &grid.tiles {
        let n = (t.edge / LEAF_DIM as u32) as i32;
        let first = shr(t.origin - topo.origin, 3);
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    bricks.push(first + IVec3::new(x, y, z));
                }
            }
        }
    }
    Ok(BrickTopology { bricks, ..topo })
}

impl BrickTopology {
    /// The lattice and box of an OpenVDB grid whose active voxels span `bmin ..= bmax`
    /// (absolute index coordinates), with `bricks` (primed).
    pub fn vdb(bmin: IVec3, bmax: IVec3, channels: u32, bricks: Vec<IVec3>) -> BrickTopology {
        let lo = bmin - 1;
        let hi = bmax + 1;
        let origin = shr(lo, 3) * BRICK_EDGE;
        BrickTopology {
            origin,
            lattice_min: lo - origin,
            lattice_max: hi - origin,
            index_min: (lo - origin).as_dvec3() + 0.5,
            index_max: (hi - origin).as_dvec3() + 0.5,
            channels,
            bricks,
        }
    }

    /// The topology of the procedural cloud: the bricks its envelope may reach (an upper
    /// bound of what [`BrickGrid::procedural_cloud`] stores).
    pub fn procedural_cloud(dims: [u32; 3]) -> BrickTopology {
        let bricks = dense_bricks(dims)
            .filter(|b| procedural_cloud_brick_may_be_nonzero(dims, *b))
            .collect();
        BrickTopology::dense(dims, 1, bricks)
    }

    /// The topology of a procedural cloud of `kind`: the bricks its bound may reach.
    pub fn procedural(dims: [u32; 3], seed: u64, kind: ProceduralKind) -> BrickTopology {
        match kind {
            ProceduralKind::Cloud => BrickTopology::procedural_cloud(dims),
            ProceduralKind::Cumulus => {
                let shape = Cumulus::shape(dims, seed);
                let bricks = dense_bricks(dims)
                    .filter(|b| {
                        shape.may_be_nonzero(*b * BRICK_EDGE, *b * BRICK_EDGE + BRICK_EDGE - 1)
                    })
                    .collect();
                BrickTopology::dense(dims, 1, bricks)
            }
        }
    }

    /// The topology of a dense grid streamed by `fill` as in
    /// [`BrickGrid::from_slabs`]: exactly the bricks with a non-zero value.
    pub fn scan_slabs(
        dims: [u32; 3],
        channels: u32,
        mut fill: impl FnMut(u32, u32, &mut [f32]) -> Result<()>,
    ) -> Result<BrickTopology> {
        let [nx, ny, nz] = dims.map(|d| d as usize);
        let ch = channels as usize;
        let e = BRICK_EDGE as usize;
        let (bx, by) = (nx.div_ceil(e), ny.div_ceil(e));
        let mut slab = Vec::new();
        slab.try_reserve_exact(nx * ny * e * ch)
            .map_err(|err| anyhow!("cannot allocate a slab of {nx} x {ny} x 8 voxels: {err}"))?;
        let mut bricks = Vec::new();
        let mut seen = vec![false; bx * by];
        for bz in 0..nz.div_ceil(e) {
            let z0 = bz * e;
            let layers = e.min(nz - z0);
            slab.clear();
            slab.resize(nx * ny * layers * ch, 0.0);
            fill(z0 as u32, layers as u32, &mut slab)?;
            seen.iter_mut().for_each(|s| *s = false);
            for (n, v) in slab.chunks_exact(ch).enumerate() {
                if v.iter().any(|x| *x != 0.0) {
                    let (i, j) = (n % nx, (n / nx) % ny);
                    seen[(j / e) * bx + i / e] = true;
                }
            }
            for (n, s) in seen.iter().enumerate() {
                if *s {
                    bricks.push(IVec3::new((n % bx) as i32, (n / bx) as i32, bz as i32));
                }
            }
        }
        Ok(BrickTopology::dense(dims, channels, bricks))
    }
}

/// Whether brick `b` of a procedural cloud of `dims` may hold a non-zero voxel: its voxel
/// centres reach where the density can be positive (see `procedural.rs`). The density
/// is `2.5 (envelope (0.3 + 0.9 detail) − 0.45)` with detail ≤ 1, so it is positive only
/// where envelope > 0.375; both smoothstep factors of the envelope are ≤ 1, so each must
/// exceed 0.375, i.e. its argument t > 0.4155 (3t² − 2t³ = 0.375 at t = 0.41548). Hence
/// 1 − r_displaced > 0.3 · 0.4155 with |displacement| ≤ 0.2: normalized radius r < 1.0754
/// about the cloud's centre; and y > 0.22 + 0.06 · 0.4155 = 0.2449 above the floor. (The
/// looser r < 1.2 of `procedural.rs` is where it stops evaluating.) The bound is tested
/// against the dense cloud in `bricks/tests.rs`.
pub fn procedural_cloud_brick_may_be_nonzero(dims: [u32; 3], b: IVec3) -> bool {
    procedural_cloud_points_may_be_nonzero(dims, b * BRICK_EDGE, b * BRICK_EDGE + BRICK_EDGE - 1)
}

/// Whether the super-voxel of brick `b` of a procedural cloud may have a positive maximum
/// (see [`BrickGrid::super_voxels`]): some lattice point of `8b − 1 ..= 8b + 8` may be
/// non-zero (the bound of [`procedural_cloud_brick_may_be_nonzero`]). The bricks for which
/// this holds bound the density's atlas slots.
pub fn procedural_cloud_super_voxel_may_be_nonzero(dims: [u32; 3], b: IVec3) -> bool {
    procedural_cloud_points_may_be_nonzero(dims, b * BRICK_EDGE - 1, b * BRICK_EDGE + BRICK_EDGE)
}

/// The super-voxels of a procedural grid that may have a positive maximum, as
/// [`procedural_cloud_super_voxel_may_be_nonzero`] for every kind: `test(b)` for each
/// brick `b`.
pub fn procedural_super_voxel_test(
    dims: [u32; 3],
    seed: u64,
    kind: ProceduralKind,
) -> impl Fn(IVec3) -> bool {
    let shape = (kind == ProceduralKind::Cumulus).then(|| Cumulus::shape(dims, seed));
    move |b| match &shape {
        None => procedural_cloud_super_voxel_may_be_nonzero(dims, b),
        Some(s) => s.may_be_nonzero(b * BRICK_EDGE - 1, b * BRICK_EDGE + BRICK_EDGE),
    }
}

/// Whether a voxel of `first ..= last` (clamped to the grid) may be non-zero.
fn procedural_cloud_points_may_be_nonzero(dims: [u32; 3], first: IVec3, last: IVec3) -> bool {
    const CENTER: [f64; 3] = [0.5, 0.40, 0.5];
    const RADII: [f64; 3] = [0.42, 0.32, 0.42];
    let mut r2 = 0.0;
    let mut top = 0.0;
    for axis in 0..3 {
        let n = f64::from(dims[axis]);
        let first = f64::from(first[axis].max(0));
        let last = f64::from(last[axis]).min(n - 1.0);
        let (lo, hi) = ((first + 0.5) / n, (last + 0.5) / n);
        let d = (CENTER[axis].clamp(lo, hi) - CENTER[axis]) / RADII[axis];
        r2 += d * d;
        if axis == 1 {
            top = hi;
        }
    }
    r2.sqrt() < MAX_R && top > MIN_Y
}

/// Normalized radius beyond which the procedural cloud is 0 (rounded up).
const MAX_R: f64 = 1.0755;
/// Normalized height below which the procedural cloud is 0 (rounded down).
const MIN_Y: f64 = 0.2448;
