//! The levels derived from a [`BrickGrid`], brick by brick: mips (mean and minimum), the
//! conservative piecewise-constant grid of Volumetric ReSTIR and the baseline's
//! super-voxel bounds. Each visits only bricks near stored ones; for a dense grid each
//! gives bit for bit what the dense function of [`crate::VoxelGrid`] gives (same
//! neighbourhoods, same f64 summation order).

use std::collections::HashSet;
use std::ops::RangeInclusive;

use anyhow::Result;
use glam::IVec3;

use super::{point_index, shr, BrickGrid, BRICK_EDGE, BRICK_POINTS};
use crate::volume::conservative_average;

/// How [`BrickGrid::reduce_with`] combines a point's children.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Reduce {
    Mean,
    Min,
    Max,
}

/// `bricks` each once, sorted by (z, y, x).
fn sorted_unique(bricks: impl IntoIterator<Item = IVec3>) -> Vec<IVec3> {
    let mut out: Vec<IVec3> = bricks
        .into_iter()
        .collect::<HashSet<_>>()
        .into_iter()
        .collect();
    out.sort_unstable_by_key(|b| (b.z, b.y, b.x));
    out
}

/// The bricks `b + (x, y, z)`, each offset in `reach`, of every brick `b` of `grid`
/// that lie inside its indirection, each once, sorted by (z, y, x).
fn around(grid: &BrickGrid, reach: RangeInclusive<i32>) -> Vec<IVec3> {
    let mut near = Vec::new();
    for b in &grid.bricks {
        for z in reach.clone() {
            for y in reach.clone() {
                for x in reach.clone() {
                    let n = *b + IVec3::new(x, y, z);
                    if grid.contains_brick(n) {
                        near.push(n);
                    }
                }
            }
        }
    }
    sorted_unique(near)
}

/// Bricks of `grid` and their 26 neighbours inside its indirection, each once, sorted
/// by (z, y, x).
fn dilated(grid: &BrickGrid) -> Vec<IVec3> {
    around(grid, -1..=1)
}

/// The 10³ lattice points `8b − 1 ..= 8b + 8` around brick `b` (channel 0, 0 where no
/// brick holds them) and whether each lies inside the clamp range; x fastest.
fn neighbourhood(grid: &BrickGrid, b: IVec3, values: &mut [f32; 1000], inside: &mut [bool; 1000]) {
    let base = b * BRICK_EDGE - 1;
    for z in 0..10 {
        for y in 0..10 {
            for x in 0..10 {
                let l = base + IVec3::new(x, y, z);
                let n = hood_index(IVec3::new(x, y, z));
                inside[n] = grid.in_range(l);
                values[n] = if inside[n] { grid.get(l) } else { 0.0 };
            }
        }
    }
}

/// Index into a [`neighbourhood`] of the point `h` (each 0..10) from its corner.
fn hood_index(h: IVec3) -> usize {
    (h.x + 10 * (h.y + 10 * h.z)) as usize
}

/// The [`neighbourhood`] of one brick at a time, gathered again when the brick changes.
struct Hood {
    brick: Option<IVec3>,
    values: [f32; 1000],
    inside: [bool; 1000],
}

impl Hood {
    fn new() -> Self {
        Self {
            brick: None,
            values: [0.0; 1000],
            inside: [false; 1000],
        }
    }

    fn of(&mut self, grid: &BrickGrid, b: IVec3) -> &Self {
        if self.brick != Some(b) {
            neighbourhood(grid, b, &mut self.values, &mut self.inside);
            self.brick = Some(b);
        }
        self
    }
}

/// The loop every derived level shares: for each brick `b` of `bricks` (sorted by (z,
/// y, x)) and each lattice point `l` of `b` inside `out`'s range, `point(b, l, dst)`
/// writes `l`'s `out.channels` values into `dst` (zero until then). Bricks that come out
/// all zero are not stored.
fn derive(
    mut out: BrickGrid,
    bricks: Vec<IVec3>,
    mut point: impl FnMut(IVec3, IVec3, &mut [f32]),
) -> Result<BrickGrid> {
    let ch = out.channels as usize;
    let mut values = vec![0f32; BRICK_POINTS * ch];
    for b in bricks {
        let (lo, hi) = out.brick_range(b);
        values.fill(0.0);
        let mut any = false;
        for k in lo.z..=hi.z {
            for j in lo.y..=hi.y {
                for i in lo.x..=hi.x {
                    let l = IVec3::new(i, j, k);
                    let at = point_index(l - b * BRICK_EDGE) * ch;
                    let dst = &mut values[at..at + ch];
                    point(b, l, dst);
                    any |= dst.iter().any(|v| *v != 0.0);
                }
            }
        }
        if any {
            out.push_brick(b, &values)?;
        }
    }
    Ok(out)
}

impl BrickGrid {
    /// An empty grid of `channels` over this grid's lattice range and box.
    fn same_lattice(&self, channels: u32) -> Result<BrickGrid> {
        BrickGrid::empty(
            self.origin,
            self.lattice_min,
            self.lattice_max,
            self.index_min,
            self.index_max,
            channels,
        )
    }

    /// The conservative piecewise-constant grid of Volumetric ReSTIR sec. 4.1 (see
    /// [`crate::VoxelGrid::conservative_piecewise_constant`]): each lattice point keeps
    /// its own value (channel 0), a zero takes the average of its 26 neighbours inside the
    /// lattice range (zeros included), rounded up to the smallest positive f32 rather
    /// than to 0. Bricks that come out all zero are not stored.
    pub fn conservative(&self) -> Result<BrickGrid> {
        let mut hood = Hood::new();
        derive(self.same_lattice(1)?, dilated(self), |b, l, dst| {
            let hood = hood.of(self, b);
            let local = l - b * BRICK_EDGE;
            let at = |d: IVec3| hood_index(local + 1 + d);
            let own = hood.values[at(IVec3::ZERO)];
            dst[0] = if own != 0.0 {
                own
            } else {
                let mut sum = 0f64;
                let mut count = 0u32;
                for dz in -1..=1 {
                    for dy in -1..=1 {
                        for dx in -1..=1 {
                            let d = IVec3::new(dx, dy, dz);
                            if d != IVec3::ZERO && hood.inside[at(d)] {
                                sum += f64::from(hood.values[at(d)]);
                                count += 1;
                            }
                        }
                    }
                }
                conservative_average(sum, count)
            };
        })
    }

    /// One mip level down (see [`crate::VoxelGrid::mip_chain`]): lattice range halved
    /// (floor), each point the average of its existing 2×2×2 children (those inside this
    /// grid's range), per channel. The box is halved too. All-zero bricks are dropped.
    pub fn mip(&self) -> Result<BrickGrid> {
        self.reduce(false)
    }

    /// One level of a minimum pyramid: each point the minimum of its existing children
    /// (channel 0; where no brick holds a child it is 0).
    pub fn min_mip(&self) -> Result<BrickGrid> {
        self.reduce(true)
    }

    /// One level of a maximum pyramid (see [`crate::VoxelGrid::max_downsample`]): each
    /// point the maximum of its existing children (channel 0; values are ≥ 0, so a child
    /// no brick holds, 0, never raises it).
    pub fn max_mip(&self) -> Result<BrickGrid> {
        self.reduce_with(Reduce::Max)
    }

    /// The largest value of each lattice point's 3×3×3 neighbourhood inside the lattice
    /// range (channel 0; see [`crate::VoxelGrid::neighbourhood_max`]). Bricks that come
    /// out all zero are not stored.
    pub fn neighbourhood_max(&self) -> Result<BrickGrid> {
        let mut hood = Hood::new();
        derive(self.same_lattice(1)?, dilated(self), |b, l, dst| {
            let hood = hood.of(self, b);
            let local = l - b * BRICK_EDGE;
            let mut m = 0f32;
            for dz in 0..3 {
                for dy in 0..3 {
                    for dx in 0..3 {
                        let n = hood_index(local + IVec3::new(dx, dy, dz));
                        if hood.inside[n] {
                            m = m.max(hood.values[n]);
                        }
                    }
                }
            }
            dst[0] = m;
        })
    }

    /// Per lattice point (channel 0) `max(self, factor · other)`, `other` a grid of the
    /// same lattice (0 where it stores no brick).
    pub fn max_with_scaled(&self, other: &BrickGrid, factor: f32) -> Result<BrickGrid> {
        let all = sorted_unique(self.bricks.iter().chain(&other.bricks).copied());
        derive(self.same_lattice(1)?, all, |_, l, dst| {
            dst[0] = self.get(l).max(factor * other.get(l));
        })
    }

    /// [`BrickGrid::mip`] `level` times (a copy of this grid at level 0).
    pub fn mip_level(&self, level: u32) -> Result<BrickGrid> {
        let mut g = self.clone();
        for _ in 0..level {
            g = g.mip()?;
        }
        Ok(g)
    }

    fn reduce(&self, minimum: bool) -> Result<BrickGrid> {
        self.reduce_with(if minimum { Reduce::Min } else { Reduce::Mean })
    }

    fn reduce_with(&self, mode: Reduce) -> Result<BrickGrid> {
        let minimum = mode != Reduce::Mean;
        let ch = if minimum { 1 } else { self.channels as usize };
        let out = BrickGrid::empty(
            self.origin,
            shr(self.lattice_min, 1),
            shr(self.lattice_max, 1),
            self.index_min * 0.5,
            self.index_max * 0.5,
            ch as u32,
        )?;
        let parents = sorted_unique(self.bricks.iter().map(|b| shr(*b, 1)));
        let mut sum = vec![0f64; ch];
        derive(out, parents, |_, parent, dst| {
            let first = parent * 2;
            let c_lo = first.max(self.lattice_min);
            let c_hi = (first + 1).min(self.lattice_max);
            sum.iter_mut().for_each(|s| *s = 0.0);
            let mut count = 0u32;
            let mut m = if mode == Reduce::Max {
                f32::NEG_INFINITY
            } else {
                f32::INFINITY
            };
            for kk in c_lo.z..=c_hi.z {
                for jj in c_lo.y..=c_hi.y {
                    for ii in c_lo.x..=c_hi.x {
                        let l = IVec3::new(ii, jj, kk);
                        if mode == Reduce::Max {
                            m = m.max(self.get(l));
                        } else if minimum {
                            m = m.min(self.get(l));
                        } else {
                            for (c, s) in sum.iter_mut().enumerate() {
                                *s += f64::from(self.get_channel(l, c as u32));
                            }
                        }
                        count += 1;
                    }
                }
            }
            if minimum {
                dst[0] = if count == 0 { 0.0 } else { m };
            } else if count > 0 {
                for (d, s) in dst.iter_mut().zip(&sum) {
                    *d = (s / f64::from(count)) as f32;
                }
            }
        })
    }

    /// The super-voxels of the baseline (Volumetric ReSTIR sec. 6; see
    /// [`crate::VoxelGrid::super_voxels`]) with the bricks' own edge: super-voxel `b`
    /// covers the p-space block `[8b, 8b + 8]` (clipped to the box) and gets the min and
    /// max of every lattice point whose trilinear support reaches it (`8b − 1 ..= 8b + 8`,
    /// clamped) and the exact mean of the trilinear field over it. Only super-voxels
    /// with a positive max are returned, sorted by (z, y, x): elsewhere the density is 0.
    pub fn super_voxels(&self) -> Vec<(IVec3, [f32; 3])> {
        let mut out = Vec::new();
        let mut hood = Hood::new();
        for b in dilated(self) {
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            let hood = hood.of(self, b);
            // Per axis: the lattice range reaching the block, and each point's weight
            // integral over the block divided by its length.
            let mut ranges: [(i32, Vec<f64>); 3] = Default::default();
            for (axis, range) in ranges.iter_mut().enumerate() {
                let (lmin, lmax) = (self.lattice_min[axis], self.lattice_max[axis]);
                let block = f64::from(b[axis] * BRICK_EDGE);
                let a = block.max(self.index_min[axis]);
                let z = (block + f64::from(BRICK_EDGE)).min(self.index_max[axis]);
                let first = (b[axis] * BRICK_EDGE - 1).max(lmin);
                let last = (b[axis] * BRICK_EDGE + BRICK_EDGE).min(lmax);
                let len = z - a;
                let weights = (first..=last)
                    .map(|m| {
                        if len > 0.0 {
                            weight_integral(lmin, lmax, m, a, z) / len
                        } else {
                            0.0
                        }
                    })
                    .collect();
                *range = (first, weights);
            }
            let mut mean = 0f64;
            let base = b * BRICK_EDGE - 1;
            for (dz, fz) in ranges[2].1.iter().enumerate() {
                for (dy, fy) in ranges[1].1.iter().enumerate() {
                    for (dx, fx) in ranges[0].1.iter().enumerate() {
                        let l = IVec3::new(
                            ranges[0].0 + dx as i32,
                            ranges[1].0 + dy as i32,
                            ranges[2].0 + dz as i32,
                        ) - base;
                        let v = hood.values[hood_index(l)];
                        lo = lo.min(v);
                        hi = hi.max(v);
                        mean += f64::from(v) * fx * fy * fz;
                    }
                }
            }
            if hi > 0.0 {
                out.push((b, [lo, hi, (mean as f32).clamp(lo, hi)]));
            }
        }
        out
    }

    /// The bricks whose slot (the brick and its apron: `SLOT_EDGE`³ clamped lookups from
    /// `8b`, every channel) holds a non-zero value, sorted by (z, y, x): the bricks an
    /// atlas needs so that every dual cell with a non-zero corner reads a slot.
    pub fn slot_bricks(&self) -> Vec<IVec3> {
        let mut out = around(self, -1..=0);
        let mut texels = Vec::new();
        out.retain(|b| {
            texels.clear();
            self.slot_texels(*b, 1.0, &mut texels);
            texels.iter().any(|v| *v != 0.0)
        });
        out
    }

    /// The largest `self − min` (f32 differences) over the lattice points of this grid's
    /// bricks, `min` a grid of the same level (0 where it stores no brick).
    pub fn max_excess_over(&self, min: &BrickGrid) -> f64 {
        let mut best = 0f64;
        let ch = self.channels as usize;
        for (i, b) in self.bricks.iter().enumerate() {
            let (lo, hi) = self.brick_range(*b);
            let values = self.brick_values(i);
            for k in lo.z..=hi.z {
                for j in lo.y..=hi.y {
                    for x in lo.x..=hi.x {
                        let l = IVec3::new(x, j, k);
                        let m = values[point_index(l - *b * BRICK_EDGE) * ch];
                        best = best.max(f64::from(m - min.get(l)));
                    }
                }
            }
        }
        best
    }
}

/// The 1D clamped-linear weight of lattice point `m` (range `lo ..= hi`) at p-space
/// coordinate `x`: the hat centred at m + 0.5, flat to the range's ends beyond them.
fn weight_1d(lo: i32, hi: i32, m: i32, x: f64) -> f64 {
    let c = x.clamp(f64::from(lo) + 0.5, f64::from(hi) + 0.5);
    (1.0 - (c - (f64::from(m) + 0.5)).abs()).max(0.0)
}

/// ∫ₐᵇ weight_1d(lo, hi, m, x) dx, exact: the weight is linear between its breakpoints,
/// so the trapezoid rule on those pieces is exact.
fn weight_integral(lo: i32, hi: i32, m: i32, a: f64, b: f64) -> f64 {
    let mf = f64::from(m);
    let mut points = vec![a, b];
    for p in [
        mf - 0.5,
        mf + 0.5,
        mf + 1.5,
        f64::from(lo) + 0.5,
        f64::from(hi) + 0.5,
    ] {
        if p > a && p < b {
            points.push(p);
        }
    }
    points.sort_by(f64::total_cmp);
    points
        .windows(2)
        .map(|w| (w[1] - w[0]) * 0.5 * (weight_1d(lo, hi, m, w[0]) + weight_1d(lo, hi, m, w[1])))
        .sum()
}
