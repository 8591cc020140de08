//! The deterministic procedural cumulus behind `procedural = "cumulus"`: a cumulus
//! congestus with a flat base, cauliflower towers and wispy edges, the way production
//! cloud generators build one (a hierarchy of puffs for the billows, Worley noise for
//! their sub-structure and for the erosion of the edges; Schneider's *Nubis* and
//! Bouthors' cumulus models).
//!
//! # Construction
//! As for the `"cloud"` kind, all arithmetic is integer hashing plus IEEE-754 basic
//! operations in f64 (`+ − × ÷`, `sqrt`, `floor`, comparisons), so a `(dims, seed)`
//! gives bit-identical grids on every platform.
//!
//! Voxel (i, j, k) is evaluated at its centre p = ((i, j, k) + 0.5) / dims, in the
//! isotropic frame q = (p − ½) · dims / max(dims) (so noise cells are round in voxels):
//! the box's half extents there are H = dims / (2 max(dims)), +Y up.
//! 1. **Puffs** (spheres, all inside the box): seven trunk puffs on the base (one tall
//!    one in the middle, six on a ring), each crowned by five half-size puffs on its
//!    upper hemisphere, and each upward-facing one of those by four more at half size
//!    again: the billows of a cumulus's top, in three generations. The shape value is
//!    s(q) = max over puffs of 1 − |q − c| / r (positive inside a puff).
//! 2. **Billows**: inverted Worley noise W (1 − the distance to the nearest feature
//!    point, three octaves, a 64³ tileable table sampled trilinearly) displaces the
//!    surface: s₁ = s + 0.3 · (W(q · 5) − 0.5).
//! 3. **Erosion**: a finer Worley octave set eats the thin outer shell, more so low in
//!    the cloud, which leaves wisps at the edges and a ragged underside:
//!    s₂ = s₁ − 0.22 · (1 + 1.5 · (1 − smoothstep(0, 0.25, h))) · (1 − W(q · 17)) ·
//!    (1 − smoothstep(0, 0.25, s₁)), h the height fraction from the base.
//! 4. **Density** = smoothstep(0, 0.14, s₂) · smoothstep(0, 0.03, h) (a flat base),
//!    in [0, 1]; exactly 0 below the base, outside every puff's 1.15 radii and on the
//!    outermost voxel layer.

use glam::IVec3;

use crate::procedural::mix;
use crate::volume::VoxelGrid;

/// Texels per axis of the tileable Worley table.
const TEX: usize = 64;
/// Worley cells per table period of each octave, and their weights.
const OCTAVES: [(usize, f64); 3] = [(4, 0.625), (8, 0.25), (16, 0.125)];
/// Billow noise: table periods per unit of q, and the displacement's amplitude.
const BILLOW_FREQUENCY: f64 = 5.0;
const BILLOW: f64 = 0.3;
/// Erosion noise: table periods per unit of q, and the erosion's depth.
const DETAIL_FREQUENCY: f64 = 17.0;
const EROSION: f64 = 0.22;
/// s₁ = s + BILLOW (W − ½) ≥ s − BILLOW / 2 and the erosion only lowers it, so the
/// density is 0 where s ≤ −BILLOW / 2, i.e. |q − c| ≥ (1 + BILLOW / 2) r for every puff.
const REACH: f64 = 1.0 + BILLOW / 2.0;

/// A sphere of the puff hierarchy, in q.
#[derive(Clone, Copy, Debug)]
struct Puff {
    c: [f64; 3],
    r: f64,
}

/// The cumulus of one `(dims, seed)`: its puffs and its noise table.
pub(crate) struct Cumulus {
    dims: [u32; 3],
    /// max(dims): p → q scale is dims / max(dims).
    max_dim: f64,
    /// Height of the flat base and of the top, in q.
    base: f64,
    top: f64,
    puffs: Vec<Puff>,
    /// The inverted-Worley fBm table, TEX³ values in [0, 1], x fastest.
    noise: Vec<f32>,
}

/// A value in [0, 1) from a hash of the arguments.
fn unit(seed: u64, a: u64, b: u64) -> f64 {
    let h = mix(mix(seed ^ mix(a)) ^ b);
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

fn smoothstep(edge0: f64, edge1: f64, x: f64) -> f64 {
    let t = ((x - edge0) / (edge1 - edge0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// The puff hierarchy of `seed` inside half extents `h` (q), from base to top.
fn puffs(seed: u64, h: [f64; 3], base: f64, top: f64) -> Vec<Puff> {
    let height = top - base;
    let width = h[0].min(h[2]);
    let mut out = Vec::new();
    let mut n = 0u64;
    let mut next = || {
        n += 1;
        unit(seed, 7, n)
    };
    // Generation 0: a tall middle puff and a ring of six around it, their centres low
    // enough that the base cuts them flat: the wide, flat-bottomed body.
    let mut trunk = vec![Puff {
        c: [0.0, base + 0.40 * height, 0.0],
        r: 0.38 * height,
    }];
    for i in 0..6 {
        let angle = (f64::from(i) + 0.4 * next()) * std::f64::consts::TAU / 6.0;
        let (s, c) = (sin(angle), cos(angle));
        let ring = width * (0.30 + 0.14 * next());
        let r = height * (0.24 + 0.10 * next());
        trunk.push(Puff {
            c: [ring * c, base + 0.3 * r, ring * s],
            r,
        });
    }
    out.extend(&trunk);
    // Generations 1 and 2: puffs at half size on the upper hemisphere of their parent.
    let mut parents = trunk;
    for (generation, children) in [(1u32, 5u32), (2, 4)] {
        let mut next_parents = Vec::new();
        for parent in &parents {
            for _ in 0..children {
                // A direction on the upper hemisphere, biased upwards (y in [0.2, 1]).
                let y = 0.2 + 0.8 * next();
                let angle = std::f64::consts::TAU * next();
                let ring = (1.0 - y * y).max(0.0).sqrt();
                let d = [ring * cos(angle), y, ring * sin(angle)];
                let r = parent.r * (0.45 + 0.15 * next());
                let dist = parent.r * (0.7 + 0.15 * next());
                let child = Puff {
                    c: [0, 1, 2].map(|a| parent.c[a] + d[a] * dist),
                    r,
                };
                out.push(child);
                if generation == 1 && y > 0.45 {
                    next_parents.push(child);
                }
            }
        }
        parents = next_parents;
    }
    // Everything inside the box with its noise reach, a voxel-ish margin to spare: pull
    // the whole hierarchy towards the base's centre until it fits.
    let limit = [h[0] * 0.97, top, h[2] * 0.97];
    let mut fit: f64 = 1.0;
    for p in &out {
        for (a, lim) in limit.iter().enumerate() {
            let extent = if a == 1 {
                (p.c[1] - base) + REACH * p.r
            } else {
                p.c[a].abs() + REACH * p.r
            };
            let room = if a == 1 { lim - base } else { *lim };
            if extent > room {
                fit = fit.min(room / extent);
            }
        }
    }
    for p in &mut out {
        p.c = [p.c[0] * fit, base + (p.c[1] - base) * fit, p.c[2] * fit];
        p.r *= fit;
    }
    out
}

/// Sine and cosine by their Taylor series after reduction to [−π, π] (basic operations
/// only, so the puffs are bit-identical on every platform; accurate to ~1e-12).
fn sin(x: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    let x = x - tau * ((x + std::f64::consts::PI) / tau).floor();
    let x2 = x * x;
    let mut term = x;
    let mut sum = x;
    for k in 1..12 {
        term *= -x2 / f64::from((2 * k) * (2 * k + 1));
        sum += term;
    }
    sum
}

fn cos(x: f64) -> f64 {
    sin(x + std::f64::consts::FRAC_PI_2)
}

/// The tileable inverted-Worley fBm table of `seed`, normalized to [0, 1].
fn worley_table(seed: u64) -> Vec<f32> {
    let mut table = vec![0f64; TEX * TEX * TEX];
    for (octave, &(cells, weight)) in OCTAVES.iter().enumerate() {
        // One feature point per cell, at a hashed position inside it.
        let feature = |c: [usize; 3], axis: u64| {
            let id = ((c[2] * cells + c[1]) * cells + c[0]) as u64;
            unit(seed, 1000 + octave as u64 * 3 + axis, id)
        };
        let mut points = vec![[0f64; 3]; cells * cells * cells];
        for k in 0..cells {
            for j in 0..cells {
                for i in 0..cells {
                    let c = [i, j, k];
                    points[(k * cells + j) * cells + i] =
                        [0, 1, 2].map(|a| c[a] as f64 + feature(c, a as u64));
                }
            }
        }
        let scale = cells as f64 / TEX as f64;
        for z in 0..TEX {
            for y in 0..TEX {
                for x in 0..TEX {
                    let p = [x, y, z].map(|t| (t as f64 + 0.5) * scale);
                    let cell = p.map(|v| v.floor() as i64);
                    let mut best = f64::MAX;
                    for dz in -1..=1 {
                        for dy in -1..=1 {
                            for dx in -1..=1 {
                                let n = [cell[0] + dx, cell[1] + dy, cell[2] + dz];
                                // Wrap the cell for the table's period, keep the offset.
                                let w = n.map(|v| v.rem_euclid(cells as i64) as usize);
                                let f = points[(w[2] * cells + w[1]) * cells + w[0]];
                                let mut d2 = 0.0;
                                for a in 0..3 {
                                    let d = (n[a] - w[a] as i64) as f64 + f[a] - p[a];
                                    d2 += d * d;
                                }
                                best = best.min(d2);
                            }
                        }
                    }
                    table[(z * TEX + y) * TEX + x] += weight * (1.0 - best.sqrt().min(1.0));
                }
            }
        }
    }
    let (lo, hi) = table
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    let span = (hi - lo).max(1e-12);
    table.iter().map(|&v| ((v - lo) / span) as f32).collect()
}

impl Cumulus {
    pub(crate) fn new(dims: [u32; 3], seed: u64) -> Cumulus {
        Cumulus {
            noise: worley_table(seed),
            ..Cumulus::shape(dims, seed)
        }
    }

    /// The puffs alone (no noise table): enough for [`Cumulus::may_be_nonzero`].
    pub(crate) fn shape(dims: [u32; 3], seed: u64) -> Cumulus {
        let (max_dim, h, base, top) = Self::frame(dims);
        Cumulus {
            dims,
            max_dim,
            base,
            top,
            puffs: puffs(seed, h, base, top),
            noise: Vec::new(),
        }
    }

    /// max(dims), the half extents H in q, and the heights of the base and the top.
    fn frame(dims: [u32; 3]) -> (f64, [f64; 3], f64, f64) {
        let max_dim = f64::from(dims.into_iter().max().unwrap_or(1).max(1));
        let h = dims.map(|d| f64::from(d) / (2.0 * max_dim));
        (max_dim, h, -0.72 * h[1], 0.94 * h[1])
    }

    /// The q of voxel `ijk`'s centre.
    fn q(&self, ijk: IVec3) -> [f64; 3] {
        [0, 1, 2].map(|a| {
            let n = f64::from(self.dims[a]);
            ((f64::from(ijk[a]) + 0.5) / n - 0.5) * n / self.max_dim
        })
    }

    /// The indices of the puffs whose reach meets the voxel centres of `lo ..= hi`.
    fn puffs_near(&self, lo: IVec3, hi: IVec3) -> Vec<usize> {
        if lo.cmpgt(hi).any() {
            return Vec::new();
        }
        let (a, b) = (self.q(lo), self.q(hi));
        if b[1] <= self.base {
            return Vec::new();
        }
        (0..self.puffs.len())
            .filter(|&i| {
                let p = self.puffs[i];
                let mut d2 = 0.0;
                for axis in 0..3 {
                    let d = p.c[axis].clamp(a[axis], b[axis]) - p.c[axis];
                    d2 += d * d;
                }
                d2 < (REACH * p.r) * (REACH * p.r)
            })
            .collect()
    }

    /// Whether a voxel of `first ..= last` (clamped to the grid, the outermost layer
    /// excluded) may be non-zero: some puff reaches it above the base.
    pub(crate) fn may_be_nonzero(&self, first: IVec3, last: IVec3) -> bool {
        let d = IVec3::from_array(self.dims.map(|v| v as i32));
        !self
            .puffs_near(first.max(IVec3::ONE), last.min(d - 2))
            .is_empty()
    }

    /// The noise table at `q · frequency` (periods), trilinear, wrapping.
    fn noise(&self, q: [f64; 3], frequency: f64) -> f64 {
        let t = q.map(|v| v * frequency * TEX as f64 - 0.5);
        let f = t.map(f64::floor);
        let w = [0, 1, 2].map(|a| t[a] - f[a]);
        let i0 = f.map(|v| (v as i64).rem_euclid(TEX as i64) as usize);
        let i1 = i0.map(|v| (v + 1) % TEX);
        let at = |x: usize, y: usize, z: usize| f64::from(self.noise[(z * TEX + y) * TEX + x]);
        let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
        let x00 = lerp(at(i0[0], i0[1], i0[2]), at(i1[0], i0[1], i0[2]), w[0]);
        let x10 = lerp(at(i0[0], i1[1], i0[2]), at(i1[0], i1[1], i0[2]), w[0]);
        let x01 = lerp(at(i0[0], i0[1], i1[2]), at(i1[0], i0[1], i1[2]), w[0]);
        let x11 = lerp(at(i0[0], i1[1], i1[2]), at(i1[0], i1[1], i1[2]), w[0]);
        lerp(lerp(x00, x10, w[1]), lerp(x01, x11, w[1]), w[2])
    }

    /// The density of voxel `ijk` given the puffs that may reach it.
    fn density(&self, ijk: IVec3, near: &[usize]) -> f32 {
        let d = IVec3::from_array(self.dims.map(|v| v as i32));
        if ijk.cmplt(IVec3::ONE).any() || ijk.cmpge(d - 1).any() {
            return 0.0;
        }
        let q = self.q(ijk);
        let h = (q[1] - self.base) / (self.top - self.base);
        if h <= 0.0 {
            return 0.0;
        }
        let mut s = f64::MIN;
        for &i in near {
            let p = self.puffs[i];
            let d2: f64 = q.iter().zip(p.c).map(|(q, c)| (q - c) * (q - c)).sum();
            s = s.max(1.0 - d2.sqrt() / p.r);
        }
        if s <= -BILLOW / 2.0 {
            return 0.0;
        }
        let s1 = s + BILLOW * (self.noise(q, BILLOW_FREQUENCY) - 0.5);
        if s1 <= 0.0 {
            return 0.0;
        }
        let low = 1.0 + 1.5 * (1.0 - smoothstep(0.0, 0.25, h));
        let erosion = EROSION
            * low
            * (1.0 - self.noise(q, DETAIL_FREQUENCY))
            * (1.0 - smoothstep(0.0, 0.25, s1));
        let s2 = s1 - erosion;
        (smoothstep(0.0, 0.14, s2) * smoothstep(0.0, 0.03, h)) as f32
    }

    /// The values of the bricks of edge `edge` voxels, one at a time: `visit(lo, hi,
    /// values)` gets each brick whose puffs may reach it, values x fastest over
    /// `lo ..= hi`.
    pub(crate) fn for_each_block<E>(
        &self,
        edge: i32,
        mut visit: impl FnMut(IVec3, IVec3, &[f32]) -> Result<(), E>,
    ) -> Result<(), E> {
        let d = IVec3::from_array(self.dims.map(|v| v as i32));
        let blocks = (d + edge - 1) / edge;
        let mut values = Vec::new();
        for bz in 0..blocks.z {
            for by in 0..blocks.y {
                for bx in 0..blocks.x {
                    let lo = IVec3::new(bx, by, bz) * edge;
                    let hi = (lo + edge - 1).min(d - 1);
                    let near = self.puffs_near(lo.max(IVec3::ONE), hi.min(d - 2));
                    if near.is_empty() {
                        continue;
                    }
                    values.clear();
                    for k in lo.z..=hi.z {
                        for j in lo.y..=hi.y {
                            for i in lo.x..=hi.x {
                                values.push(self.density(IVec3::new(i, j, k), &near));
                            }
                        }
                    }
                    visit(lo, hi, &values)?;
                }
            }
        }
        Ok(())
    }
}

/// The cumulus of `dims` voxels as a dense grid (densities in [0, 1]), bit-identical
/// for the same `(dims, seed)` on every platform; see the module docs.
///
/// Allocates `dims` product f32s; callers with untrusted dims should go through
/// [`crate::load_grid`], which applies the memory guard first.
pub fn procedural_cumulus(dims: [u32; 3], seed: u64) -> VoxelGrid {
    let cumulus = Cumulus::new(dims, seed);
    let [nx, ny, nz] = dims.map(|d| d as usize);
    let mut data = vec![0f32; nx * ny * nz];
    let Ok(()) = cumulus.for_each_block(8, |lo, hi, values| {
        let mut n = 0;
        for k in lo.z..=hi.z {
            for j in lo.y..=hi.y {
                for i in lo.x..=hi.x {
                    data[(k as usize * ny + j as usize) * nx + i as usize] = values[n];
                    n += 1;
                }
            }
        }
        Ok::<(), std::convert::Infallible>(())
    });
    VoxelGrid {
        dims,
        channels: 1,
        data,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sine_and_cosine_match_the_library() {
        for i in -40..40 {
            let x = f64::from(i) * 0.37;
            assert!((sin(x) - x.sin()).abs() < 1e-10, "sin {x}");
            assert!((cos(x) - x.cos()).abs() < 1e-10, "cos {x}");
        }
    }

    #[test]
    fn the_table_tiles_and_spans_zero_to_one() {
        let c = Cumulus::new([16, 16, 16], 3);
        let (lo, hi) = c
            .noise
            .iter()
            .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        assert_eq!((lo, hi), (0.0, 1.0));
        // One period apart: the same value.
        for p in [[0.1, 0.2, 0.3], [0.77, 0.01, 0.5]] {
            let a = c.noise(p, 1.0);
            let b = c.noise([p[0] + 1.0, p[1] - 1.0, p[2] + 2.0], 1.0);
            assert!((a - b).abs() < 1e-9, "{a} {b}");
        }
    }

    #[test]
    fn puffs_stay_inside_the_box_above_the_base() {
        for dims in [[256, 160, 256], [64, 64, 64], [100, 40, 70]] {
            let (_, h, base, top) = Cumulus::frame(dims);
            let c = Cumulus::new(dims, 11);
            for p in &c.puffs {
                assert!(p.c[1] > base, "{p:?}");
                assert!(p.c[1] + REACH * p.r <= top + 1e-9, "{dims:?} {p:?}");
                for a in [0, 2] {
                    assert!(p.c[a].abs() + REACH * p.r <= h[a] + 1e-9, "{dims:?} {p:?}");
                }
            }
        }
    }

    /// Degenerate and extreme boxes: no panic, every value finite in [0, 1], zero on
    /// the outermost layer, and the puffs (scaled to fit) inside the box.
    #[test]
    fn extreme_dims_stay_finite_and_inside() {
        for dims in [
            [1, 1, 1],
            [2, 2, 2],
            [3, 3, 3],
            [2, 300, 2],
            [300, 2, 300],
            [5, 200, 40],
        ] {
            let grid = procedural_cumulus(dims, 1);
            assert!(grid
                .data
                .iter()
                .all(|v| v.is_finite() && (0.0..=1.0).contains(v)));
            for (n, v) in grid.data.iter().enumerate() {
                let (x, y, z) = (
                    n as u32 % dims[0],
                    (n as u32 / dims[0]) % dims[1],
                    n as u32 / (dims[0] * dims[1]),
                );
                let edge = [x, y, z]
                    .iter()
                    .zip(dims)
                    .any(|(&c, d)| c == 0 || c + 1 == d);
                assert!(!edge || *v == 0.0, "{dims:?}: voxel ({x}, {y}, {z}) = {v}");
            }
            let c = Cumulus::shape(dims, 1);
            assert!(
                c.puffs.iter().all(|p| p.r > 0.0 && p.r.is_finite()),
                "{dims:?}"
            );
        }
    }

    #[test]
    fn the_bound_holds_and_the_cloud_fills_a_sensible_fraction() {
        let dims = [64, 40, 64];
        let grid = procedural_cumulus(dims, 7);
        let c = Cumulus::new(dims, 7);
        let all: Vec<usize> = (0..c.puffs.len()).collect();
        let mut filled = 0usize;
        for k in 0..dims[2] as i32 {
            for j in 0..dims[1] as i32 {
                for i in 0..dims[0] as i32 {
                    let ijk = IVec3::new(i, j, k);
                    let v = c.density(ijk, &all);
                    let n = ((k * dims[1] as i32 + j) * dims[0] as i32 + i) as usize;
                    assert_eq!(v, grid.data[n], "{ijk}");
                    assert!((0.0..=1.0).contains(&v));
                    if v > 0.0 {
                        filled += 1;
                        assert!(c.may_be_nonzero(ijk, ijk), "{ijk}");
                    }
                }
            }
        }
        let fraction = filled as f64 / grid.data.len() as f64;
        assert!((0.04..0.4).contains(&fraction), "{fraction}");
    }
}
