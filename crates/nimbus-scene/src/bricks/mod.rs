//! Sparse voxel grids as 8³ bricks: the form every density, emission and derived level
//! takes on its way to the GPU (bricks in an atlas behind a two-level indirection, as
//! GVDB and NanoVDB do), whether it came from a dense file, the procedural cloud or
//! OpenVDB. Memory follows the stored bricks: 4 bytes of indirection per node of 8³
//! bricks of the bounding box, and 2 KiB per node that holds a brick ([`indirection`]).
//!
//! # Index spaces
//! A [`BrickGrid`] holds values on an integer **lattice**: lattice point `l` is where a
//! value sits; between lattice points the field is trilinear. Coordinates are *primed*:
//! shifted by [`BrickGrid::origin`] (a multiple of 8) so that every brick coordinate is
//! ≥ 0, brick `b` holding lattice points `8b ..= 8b + 7` per axis.
//!
//! - **Lattice clamp**: a lookup at `l` reads `clamp(l, lattice_min, lattice_max)`;
//!   lattice points no brick holds are 0.
//! - **p-space**: the continuous index space of the shaders, `p = l + 0.5` at lattice
//!   point `l` (so a voxel of a cell-centred grid is the unit cell `[i, i + 1]`). The
//!   field fills the p-space box `index_min ..= index_max` and is 0 outside it.
//!
//! A dense `type = "grid"` of dims `n` is lattice `0 ..= n − 1` with the box `[0, n]`:
//! within half a voxel of a face the clamp makes the density constant, as
//! docs/scene-format.md says. An OpenVDB grid with active voxels in `bmin ..= bmax` is lattice
//! `bmin − 1 ..= bmax + 1` (one layer of background around the active voxels, where
//! trilinear filtering reaches) with the box `[bmin − 1, bmax + 1] + 0.5`: nothing
//! clamps inside it.
//!
//! # Levels derived per brick
//! [`BrickGrid::mip`] (averages of existing 2×2×2 children, as
//! [`VoxelGrid::mip_chain`]), [`BrickGrid::min_mip`], [`BrickGrid::conservative`]
//! (Volumetric ReSTIR's piecewise-constant grid, as
//! [`VoxelGrid::conservative_piecewise_constant`]) and [`BrickGrid::super_voxels`] (the
//! baseline's min / max / mean per 8³ block, as [`VoxelGrid::super_voxels`]) give, for a
//! dense grid, bit for bit what the dense functions give (`tests.rs` checks it), and
//! touch only bricks near stored ones.

mod build;
mod derive;
pub mod indirection;
mod load;
mod march;
mod precision;
#[cfg(test)]
mod tests;

pub use indirection::Indirection;

pub use build::{
    procedural_cloud_brick_may_be_nonzero, procedural_cloud_super_voxel_may_be_nonzero,
    procedural_super_voxel_test, BrickTopology,
};
pub use march::{march_errors, MARCH_ERROR_SEGMENTS};
pub use precision::effective_sigma_t;

use anyhow::{bail, Result};
use glam::{DMat4, DVec3, IVec3};

#[allow(unused_imports)]
use crate::volume::VoxelGrid;

/// Edge of a brick in lattice points.
pub const BRICK_EDGE: i32 = 8;
/// Lattice points in a brick.
pub const BRICK_POINTS: usize = 512;
/// Edge of a brick's slot in an atlas: the brick and one apron layer on its high side,
/// so that every dual cell `[l, l + 1]³` with `l` in the brick reads one slot.
pub const SLOT_EDGE: i32 = 9;
/// Texels in a slot.
pub const SLOT_TEXELS: usize = 729;
/// An indirection entry without a brick.
pub const NO_BRICK: u32 = u32::MAX;

/// A sparse grid of 8³ bricks; see the module docs for its index spaces.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BrickGrid {
    /// Absolute lattice coordinates of primed lattice point 0 (a multiple of 8).
    pub origin: IVec3,
    /// Primed lattice clamp range (inclusive, ≥ 0).
    pub lattice_min: IVec3,
    pub lattice_max: IVec3,
    /// Bricks per axis of the indirection: `lattice_max / 8 + 1`.
    pub brick_dims: [u32; 3],
    /// The p-space box the field fills (0 outside).
    pub index_min: DVec3,
    pub index_max: DVec3,
    /// Values per lattice point (1, or 3 for velocity and coloured emission).
    pub channels: u32,
    /// Per brick of `brick_dims`: its index in `bricks`, or [`NO_BRICK`].
    pub indirection: Indirection,
    /// Primed coordinates of the stored bricks, in storage order.
    pub bricks: Vec<IVec3>,
    /// `BRICK_POINTS · channels` values per stored brick, x fastest, channels
    /// interleaved. Points outside the lattice range hold 0 and are never read.
    pub values: Vec<f32>,
    /// The OpenVDB grid's own index-to-world transform (absolute lattice coordinates to
    /// world, before the scene's `to_world`), when the grid came from a `.vdb` file.
    pub file_transform: Option<DMat4>,
}

/// Floor division of every component by 2^`shift`.
pub fn shr(v: IVec3, shift: u32) -> IVec3 {
    IVec3::new(v.x >> shift, v.y >> shift, v.z >> shift)
}

/// Index of point `local` (each 0..8) inside a brick.
pub fn point_index(local: IVec3) -> usize {
    (local.x + BRICK_EDGE * (local.y + BRICK_EDGE * local.z)) as usize
}

impl BrickGrid {
    /// An empty grid (no bricks) over the primed lattice range `lattice_min ..=
    /// lattice_max` and p-space box `index_min ..= index_max`. Refuses a top table of
    /// more than [`indirection::MAX_TOP_CELLS`] entries before allocating it.
    pub fn empty(
        origin: IVec3,
        lattice_min: IVec3,
        lattice_max: IVec3,
        index_min: DVec3,
        index_max: DVec3,
        channels: u32,
    ) -> Result<BrickGrid> {
        if lattice_min.min_element() < 0 || (lattice_max - lattice_min).min_element() < 0 {
            bail!("internal: brick lattice range {lattice_min} ..= {lattice_max} is invalid");
        }
        let brick_dims = (shr(lattice_max, 3) + 1).to_array().map(|d| d as u32);
        let indirection = Indirection::new(brick_dims)?;
        Ok(BrickGrid {
            origin,
            lattice_min,
            lattice_max,
            brick_dims,
            index_min,
            index_max,
            channels,
            indirection,
            bricks: Vec::new(),
            values: Vec::new(),
            file_transform: None,
        })
    }

    /// Stored bricks.
    pub fn brick_count(&self) -> usize {
        self.bricks.len()
    }

    /// Values per brick.
    pub fn brick_len(&self) -> usize {
        BRICK_POINTS * self.channels as usize
    }

    /// Whether brick `b` lies inside `brick_dims`.
    pub fn contains_brick(&self, b: IVec3) -> bool {
        self.indirection.contains(b)
    }

    /// The storage index of brick `b`, if it is stored.
    pub fn find(&self, b: IVec3) -> Option<usize> {
        let at = self.indirection.get(b);
        (at != NO_BRICK).then_some(at as usize)
    }

    /// The values of stored brick `i`.
    pub fn brick_values(&self, i: usize) -> &[f32] {
        let n = self.brick_len();
        &self.values[i * n..(i + 1) * n]
    }

    /// Appends brick `b` (not stored yet, inside `brick_dims`) with `values`
    /// (`brick_len` of them).
    pub fn push_brick(&mut self, b: IVec3, values: &[f32]) -> Result<()> {
        if !self.contains_brick(b) {
            bail!(
                "internal: brick {b} outside the indirection {:?}",
                self.brick_dims
            );
        }
        if self.indirection.get(b) != NO_BRICK || values.len() != self.brick_len() {
            bail!("internal: brick {b} stored twice or with the wrong size");
        }
        self.indirection.set(b, self.bricks.len() as u32)?;
        self.bricks.push(b);
        self.values.extend_from_slice(values);
        Ok(())
    }

    /// Whether primed lattice point `l` lies inside the clamp range.
    pub fn in_range(&self, l: IVec3) -> bool {
        l.cmpge(self.lattice_min).all() && l.cmple(self.lattice_max).all()
    }

    /// Channel `c` at primed lattice point `l`, without clamping: 0 where no brick holds it.
    pub fn get_channel(&self, l: IVec3, c: u32) -> f32 {
        match self.find(shr(l, 3)) {
            Some(i) => {
                let local = l & IVec3::splat(BRICK_EDGE - 1);
                self.values[i * self.brick_len()
                    + point_index(local) * self.channels as usize
                    + c as usize]
            }
            None => 0.0,
        }
    }

    /// Channel 0 at primed lattice point `l`, without clamping.
    pub fn get(&self, l: IVec3) -> f32 {
        self.get_channel(l, 0)
    }

    /// Channel `c` at `clamp(l, lattice_min, lattice_max)`: what every lookup reads.
    pub fn get_clamped(&self, l: IVec3, c: u32) -> f32 {
        self.get_channel(l.clamp(self.lattice_min, self.lattice_max), c)
    }

    /// Trilinear interpolation of channel 0 at p-space point `p` (lattice point `l` at
    /// `l + 0.5`), clamped to the lattice range like every lookup; a NaN coordinate acts
    /// as the range's low end. The f64 reference of the shaders' lookup.
    pub fn trilinear(&self, p: DVec3) -> f64 {
        self.trilinear_channel(p, 0)
    }

    /// [`BrickGrid::trilinear`] of channel `c`.
    pub fn trilinear_channel(&self, p: DVec3, c: u32) -> f64 {
        let mut lo = [0i32; 3];
        let mut hi = [0i32; 3];
        let mut t = [0f64; 3];
        for axis in 0..3 {
            let (a, b) = (self.lattice_min[axis], self.lattice_max[axis]);
            // `max` first: f64::max ignores NaN.
            let c = p[axis].max(f64::from(a) + 0.5).min(f64::from(b) + 0.5) - 0.5;
            let base = (c.floor() as i32).clamp(a, b);
            lo[axis] = base;
            hi[axis] = (base + 1).min(b);
            t[axis] = c - f64::from(base);
        }
        let ends = [lo, hi];
        crate::volume::trilinear(
            |[x, y, z]| {
                let l = IVec3::new(ends[x][0], ends[y][1], ends[z][2]);
                f64::from(self.get_channel(l, c))
            },
            t,
        )
    }

    /// The largest value of channel 0 and the primed lattice point holding it (0 and
    /// `lattice_min` for an empty grid).
    pub fn max_value(&self) -> (f32, IVec3) {
        let mut best = (0.0f32, self.lattice_min);
        let ch = self.channels as usize;
        for (i, b) in self.bricks.iter().enumerate() {
            for (n, v) in self.brick_values(i).chunks_exact(ch).enumerate() {
                if v[0] > best.0 {
                    let n = n as i32;
                    let local = IVec3::new(n & 7, (n >> 3) & 7, n >> 6);
                    best = (v[0], *b * BRICK_EDGE + local);
                }
            }
        }
        best
    }

    /// The largest value of any channel and the absolute lattice point holding it (0 and
    /// the lattice minimum for an empty grid).
    pub fn max_any_channel(&self) -> (f32, IVec3) {
        let mut best = (0.0f32, self.lattice_min);
        let ch = self.channels as usize;
        for (i, b) in self.bricks.iter().enumerate() {
            for (n, v) in self.brick_values(i).chunks_exact(ch).enumerate() {
                let m = v.iter().fold(0.0f32, |a, &x| a.max(x));
                if m > best.0 {
                    let n = n as i32;
                    let local = IVec3::new(n & 7, (n >> 3) & 7, n >> 6);
                    best = (m, *b * BRICK_EDGE + local);
                }
            }
        }
        (best.0, best.1 + self.origin)
    }

    /// Host bytes held: values, brick coordinates and the indirection.
    pub fn memory_bytes(&self) -> u64 {
        (self.values.len() * 4 + self.bricks.len() * 12 + self.indirection.len() * 4) as u64
    }

    /// The slot texels of brick `b` (stored or not): `SLOT_EDGE`³ points from `8b`,
    /// x fastest, each `get_clamped` of its lattice point times `scale`, channels
    /// interleaved, appended to `out`.
    pub fn slot_texels(&self, b: IVec3, scale: f32, out: &mut Vec<f32>) {
        let base = b * BRICK_EDGE;
        let ch = self.channels;
        // The brick's own points straight from storage when nothing clamps.
        let own = self.find(b);
        let inner_ok = self.in_range(base) && self.in_range(base + IVec3::splat(BRICK_EDGE));
        for z in 0..SLOT_EDGE {
            for y in 0..SLOT_EDGE {
                for x in 0..SLOT_EDGE {
                    let local = IVec3::new(x, y, z);
                    let l = base + local;
                    let apron = x == BRICK_EDGE || y == BRICK_EDGE || z == BRICK_EDGE;
                    for c in 0..ch {
                        let v = match own {
                            Some(i) if inner_ok && !apron => {
                                self.values[i * self.brick_len()
                                    + point_index(local) * ch as usize
                                    + c as usize]
                            }
                            _ => self.get_clamped(l, c),
                        };
                        out.push(v * scale);
                    }
                }
            }
        }
    }

    /// The coarsest mip level that still changes the grid: the smallest `l` whose lattice
    /// range `lattice_min >> l ..= lattice_max >> l` is a single point (for a dense grid
    /// ⌈log2(largest dim)⌉).
    pub fn last_level(&self) -> u32 {
        let mut l = 0;
        while shr(self.lattice_min, l) != shr(self.lattice_max, l) && l < 31 {
            l += 1;
        }
        l
    }

    /// The inclusive range of lattice points of brick `b` inside the clamp range.
    pub fn brick_range(&self, b: IVec3) -> (IVec3, IVec3) {
        let base = b * BRICK_EDGE;
        (
            base.max(self.lattice_min),
            (base + IVec3::splat(BRICK_EDGE - 1)).min(self.lattice_max),
        )
    }
}
