//! Voxel grids (CPU side): loading with validation, trilinear lookup, and the derived
//! structures the renderer uploads — mip pyramid, conservative piecewise-constant grid
//! and super-voxel majorants.
//!
//! Index space: voxel (i, j, k) is the cell [i, i+1] × [j, j+1] × [k, k+1] with its
//! centre at (i, j, k) + 0.5; a point `x` of the medium's box maps to
//! `(x − bounds_min) / size · dims`.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};

use crate::cumulus::procedural_cumulus;
use crate::files::{file_size, read_vol_header, VolEncoding, VOL_HEADER_BYTES};
use crate::procedural::procedural_cloud;
use crate::types::{GridMedium, GridSource, ProceduralKind};

/// Most f32 values (voxels × channels) in one loaded grid: 2^31, i.e. 8 GiB of data.
pub const MAX_GRID_VALUES: u64 = 1 << 31;

/// Super-voxel edge length in voxels used by the baseline (Volumetric ReSTIR sec. 6).
pub const SUPER_VOXEL_FACTOR: u32 = 8;

/// A dense voxel grid: x fastest, then y, then z, channels interleaved per voxel, so
/// value (i, j, k, c) = `data[((k·ny + j)·nx + i)·channels + c]`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VoxelGrid {
    pub dims: [u32; 3],
    pub channels: u32,
    pub data: Vec<f32>,
}

/// Per-super-voxel bounds of the trilinear density (see [`VoxelGrid::super_voxels`]);
/// x fastest, then y, then z.
#[derive(Clone, Debug, PartialEq)]
pub struct SuperVoxels {
    /// Super-voxels per axis: ceil(dims / factor).
    pub dims: [u32; 3],
    /// Edge length in voxels.
    pub factor: u32,
    /// Lower bound of the trilinear density over the super-voxel's region.
    pub min: Vec<f32>,
    /// Upper bound (majorant) of the trilinear density over the region.
    pub max: Vec<f32>,
    /// Exact mean of the trilinear density over the region.
    pub avg: Vec<f32>,
}

impl SuperVoxels {
    /// Linear index of super-voxel (i, j, k).
    pub fn index(&self, i: u32, j: u32, k: u32) -> usize {
        let [nx, ny, _] = self.dims.map(|d| d as usize);
        (k as usize * ny + j as usize) * nx + i as usize
    }
}

impl VoxelGrid {
    /// Number of voxels, nx·ny·nz.
    pub fn voxel_count(&self) -> usize {
        self.dims.iter().map(|&d| d as usize).product()
    }

    /// Linear voxel index of (i, j, k): (k·ny + j)·nx + i. The voxel's first channel
    /// is `data[index · channels]`.
    pub fn index(&self, i: u32, j: u32, k: u32) -> usize {
        let [nx, ny, _] = self.dims.map(|d| d as usize);
        (k as usize * ny + j as usize) * nx + i as usize
    }

    /// Channel 0 of voxel (i, j, k) (the density of a scalar grid).
    pub fn get(&self, i: u32, j: u32, k: u32) -> f32 {
        self.data[self.index(i, j, k) * self.channels as usize]
    }

    /// Channel `c` of voxel (i, j, k).
    pub fn get_channel(&self, i: u32, j: u32, k: u32, c: u32) -> f32 {
        self.data[self.index(i, j, k) * self.channels as usize + c as usize]
    }

    /// Trilinear interpolation of channel 0 at `p` in voxel-index space (centres at
    /// i + 0.5), as docs/scene-format.md specifies: each coordinate is first clamped to
    /// [0.5, n − 0.5], so within half a voxel of a face (and outside the grid) the
    /// value is that of the outermost centres. A NaN coordinate acts as 0.5.
    pub fn sample_trilinear(&self, p: [f64; 3]) -> f64 {
        self.sample_trilinear_channel(p, 0)
    }

    /// [`VoxelGrid::sample_trilinear`] of channel `c`.
    pub fn sample_trilinear_channel(&self, p: [f64; 3], c: u32) -> f64 {
        let mut lo = [0u32; 3];
        let mut hi = [0u32; 3];
        let mut t = [0f64; 3];
        for axis in 0..3 {
            let n = self.dims[axis];
            // `max` first: f64::max ignores NaN.
            let c = p[axis].max(0.5).min(f64::from(n) - 0.5) - 0.5;
            let base = (c.floor() as u32).min(n - 1);
            lo[axis] = base;
            hi[axis] = (base + 1).min(n - 1);
            t[axis] = c - f64::from(base);
        }
        let ends = [lo, hi];
        trilinear(
            |[x, y, z]| f64::from(self.get_channel(ends[x][0], ends[y][1], ends[z][2], c)),
            t,
        )
    }

    /// The mip pyramid: level 0 is a copy of this grid; each next level has
    /// ceil(n / 2) voxels per axis (at least 1), each the average of its existing
    /// 2×2×2 children (fewer at odd edges: only children inside the finer level are
    /// averaged), per channel. The chain ends with the 1×1×1 level, so it has
    /// 1 + ceil(log2(max dim)) levels (13 at most for dims up to 4096).
    pub fn mip_chain(&self) -> Vec<VoxelGrid> {
        let mut chain = vec![self.clone()];
        while let Some(last) = chain.last().filter(|g| g.dims != [1, 1, 1]) {
            let next = downsample(last);
            chain.push(next);
        }
        chain
    }

    /// Level `level` of [`VoxelGrid::mip_chain`] (level 0 is `self`, borrowed), clamped
    /// at the 1×1×1 level, without keeping the levels in between: peak memory is this
    /// grid plus two levels below it.
    pub fn mip_level(&self, level: u32) -> std::borrow::Cow<'_, VoxelGrid> {
        let mut current = std::borrow::Cow::Borrowed(self);
        for _ in 0..level {
            if current.dims == [1, 1, 1] {
                break;
            }
            current = std::borrow::Cow::Owned(downsample(&current));
        }
        current
    }

    /// One step of a minimum pyramid: ceil(n/2) per axis, each value the minimum of the
    /// existing 2×2×2 children (channel 0; the result has one channel).
    pub fn min_downsample(&self) -> VoxelGrid {
        self.reduce_downsample(f32::min, f32::INFINITY)
    }

    /// One step of a maximum pyramid, like [`VoxelGrid::min_downsample`].
    pub fn max_downsample(&self) -> VoxelGrid {
        self.reduce_downsample(f32::max, f32::NEG_INFINITY)
    }

    fn reduce_downsample(&self, op: fn(f32, f32) -> f32, start: f32) -> VoxelGrid {
        let dims = self.dims.map(|n| n.div_ceil(2).max(1));
        let mut data = Vec::with_capacity(dims.iter().map(|&d| d as usize).product());
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let mut m = start;
                    for kk in (2 * k)..(2 * k + 2).min(self.dims[2]) {
                        for jj in (2 * j)..(2 * j + 2).min(self.dims[1]) {
                            for ii in (2 * i)..(2 * i + 2).min(self.dims[0]) {
                                m = op(m, self.get(ii, jj, kk));
                            }
                        }
                    }
                    data.push(m);
                }
            }
        }
        VoxelGrid {
            dims,
            channels: 1,
            data,
        }
    }

    /// The largest value of each voxel's 3×3×3 neighbourhood (clipped at the faces),
    /// channel 0: a bound of the trilinear density anywhere in the voxel's cell.
    pub fn neighbourhood_max(&self) -> VoxelGrid {
        let [nx, ny, nz] = self.dims.map(|d| d as usize);
        let mut out: Vec<f32> = (0..nx * ny * nz)
            .map(|v| self.data[v * self.channels as usize])
            .collect();
        // Separable: a 3-wide running maximum along x, then y, then z.
        let strides = [1usize, nx, nx * ny];
        let counts = [nx, ny, nz];
        for axis in 0..3 {
            let (stride, n) = (strides[axis], counts[axis]);
            let src = out.clone();
            for (v, value) in out.iter_mut().enumerate() {
                let c = (v / stride) % n;
                if c > 0 {
                    *value = value.max(src[v - stride]);
                }
                if c + 1 < n {
                    *value = value.max(src[v + stride]);
                }
            }
        }
        VoxelGrid {
            dims: self.dims,
            channels: 1,
            data: out,
        }
    }

    /// The conservative piecewise-constant grid of Volumetric ReSTIR sec. 4.1, for
    /// regular tracking: each voxel keeps its own (nearest) density, and a voxel whose
    /// density is 0 takes the average density of its neighbours — all 26 voxels of
    /// its 3×3×3 neighbourhood that lie inside the grid (the paper's "average density
    /// of their neighbors", zeros included in the average).
    ///
    /// Why 26 and not 6: the trilinear density anywhere in cell (i, j, k) (a closed
    /// cell, including its faces and corners) is a convex combination of voxels of the
    /// 3×3×3 block around it, and near a corner the diagonal neighbour has positive
    /// weight. With non-negative densities the 26-average is > 0 exactly when some
    /// neighbour is > 0, so σ* > 0 wherever the trilinear σ > 0 anywhere in the cell.
    /// A 6-neighbourhood would miss density leaking in from edge/corner neighbours.
    ///
    /// Uses channel 0 (meant for scalar density grids, which loading guarantees are
    /// non-negative); the result has one channel.
    pub fn conservative_piecewise_constant(&self) -> VoxelGrid {
        let [nx, ny, nz] = self.dims;
        let mut data = Vec::with_capacity(self.voxel_count());
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let own = self.get(i, j, k);
                    if own != 0.0 {
                        data.push(own);
                        continue;
                    }
                    let mut sum = 0f64;
                    let mut count = 0u32;
                    for kk in k.saturating_sub(1)..=(k + 1).min(nz - 1) {
                        for jj in j.saturating_sub(1)..=(j + 1).min(ny - 1) {
                            for ii in i.saturating_sub(1)..=(i + 1).min(nx - 1) {
                                if (ii, jj, kk) != (i, j, k) {
                                    sum += f64::from(self.get(ii, jj, kk));
                                    count += 1;
                                }
                            }
                        }
                    }
                    data.push(conservative_average(sum, count));
                }
            }
        }
        VoxelGrid {
            dims: self.dims,
            channels: 1,
            data,
        }
    }

    /// Super-voxels of `factor`³ voxels (8 in the paper; a `factor` of 0 acts as 1).
    /// Super-voxel (I, J, K) covers the voxel cells I·f .. min((I+1)·f, n) per axis.
    ///
    /// `min` / `max` bound the *trilinear* density over that whole region: they are
    /// the min / max over every voxel whose trilinear support overlaps it, i.e. the
    /// covered voxels plus a one-voxel apron (clamped to the grid). `avg` is the exact
    /// mean of the trilinear density over the region (the trilinear field is separable
    /// into per-axis piecewise-linear weights, which are integrated exactly), so
    /// min ≤ avg ≤ max. Uses channel 0.
    pub fn super_voxels(&self, factor: u32) -> SuperVoxels {
        let f = factor.max(1);
        let sdims = self.dims.map(|n| n.div_ceil(f));
        let count = sdims.iter().map(|&d| d as usize).product();
        let mut out = SuperVoxels {
            dims: sdims,
            factor: f,
            min: Vec::with_capacity(count),
            max: Vec::with_capacity(count),
            avg: Vec::with_capacity(count),
        };
        // Per axis and super-voxel: the voxel range [first, last] of the apron and
        // each of those voxels' weight integral over the region, divided by its length.
        let axis_weights: Vec<Vec<(u32, Vec<f64>)>> = (0..3)
            .map(|axis| {
                let n = self.dims[axis];
                (0..sdims[axis])
                    .map(|s| {
                        let a = s * f;
                        let b = ((s + 1) * f).min(n);
                        let first = a.saturating_sub(1);
                        let last = b.min(n - 1);
                        let len = f64::from(b - a);
                        let w = (first..=last)
                            .map(|m| weight_integral(n, m, f64::from(a), f64::from(b)) / len)
                            .collect();
                        (first, w)
                    })
                    .collect()
            })
            .collect();
        for sk in 0..sdims[2] {
            let (z0, wz) = &axis_weights[2][sk as usize];
            for sj in 0..sdims[1] {
                let (y0, wy) = &axis_weights[1][sj as usize];
                for si in 0..sdims[0] {
                    let (x0, wx) = &axis_weights[0][si as usize];
                    let mut lo = f32::INFINITY;
                    let mut hi = f32::NEG_INFINITY;
                    let mut mean = 0f64;
                    for (dz, &fz) in wz.iter().enumerate() {
                        for (dy, &fy) in wy.iter().enumerate() {
                            for (dx, &fx) in wx.iter().enumerate() {
                                let v = self.get(x0 + dx as u32, y0 + dy as u32, z0 + dz as u32);
                                lo = lo.min(v);
                                hi = hi.max(v);
                                mean += f64::from(v) * fx * fy * fz;
                            }
                        }
                    }
                    out.min.push(lo);
                    out.max.push(hi);
                    out.avg.push((mean as f32).clamp(lo, hi));
                }
            }
        }
        out
    }
}

/// The 1D clamped-linear interpolation weight of voxel `m` (of `n`) at coordinate `x`
/// (index space): the hat centred at m + 0.5, extended flat to the faces for the
/// outermost voxels (the half-voxel clamp).
fn weight_1d(n: u32, m: u32, x: f64) -> f64 {
    let c = x.clamp(0.5, f64::from(n) - 0.5);
    (1.0 - (c - (f64::from(m) + 0.5)).abs()).max(0.0)
}

/// ∫ₐᵇ weight_1d(n, m, x) dx, exact: the weight is linear between the breakpoints
/// m − 0.5, m + 0.5, m + 1.5 (and the clamp points 0.5, n − 0.5), so the trapezoid
/// rule on those pieces is exact.
fn weight_integral(n: u32, m: u32, a: f64, b: f64) -> f64 {
    let mf = f64::from(m);
    let mut points = vec![a, b];
    for p in [mf - 0.5, mf + 0.5, mf + 1.5, 0.5, f64::from(n) - 0.5] {
        if p > a && p < b {
            points.push(p);
        }
    }
    points.sort_by(f64::total_cmp);
    points
        .windows(2)
        .map(|w| (w[1] - w[0]) * 0.5 * (weight_1d(n, m, w[0]) + weight_1d(n, m, w[1])))
        .sum()
}

/// One mip step: ceil(n/2) per axis, averaging the existing 2×2×2 children.
fn downsample(g: &VoxelGrid) -> VoxelGrid {
    let dims = g.dims.map(|n| n.div_ceil(2).max(1));
    let ch = g.channels as usize;
    let mut data = Vec::with_capacity(dims.iter().map(|&d| d as usize).product::<usize>() * ch);
    let mut sum = vec![0f64; ch];
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                sum.iter_mut().for_each(|s| *s = 0.0);
                let mut count = 0u32;
                for kk in (2 * k)..(2 * k + 2).min(g.dims[2]) {
                    for jj in (2 * j)..(2 * j + 2).min(g.dims[1]) {
                        for ii in (2 * i)..(2 * i + 2).min(g.dims[0]) {
                            let base = g.index(ii, jj, kk) * ch;
                            for (c, s) in sum.iter_mut().enumerate() {
                                *s += f64::from(g.data[base + c]);
                            }
                            count += 1;
                        }
                    }
                }
                data.extend(sum.iter().map(|s| (s / f64::from(count)) as f32));
            }
        }
    }
    VoxelGrid {
        dims,
        channels: g.channels,
        data,
    }
}

/// Trilinear blend of the 8 corner values `corner([x, y, z])` (each index 0 for the low
/// end of its axis, 1 for the high end) at fractions `t`: along x, then y, then z. The
/// one blend of [`VoxelGrid::sample_trilinear_channel`] and
/// [`crate::BrickGrid::trilinear_channel`], so the two agree bit for bit.
pub(crate) fn trilinear(corner: impl Fn([usize; 3]) -> f64, t: [f64; 3]) -> f64 {
    let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
    let x00 = lerp(corner([0, 0, 0]), corner([1, 0, 0]), t[0]);
    let x10 = lerp(corner([0, 1, 0]), corner([1, 1, 0]), t[0]);
    let x01 = lerp(corner([0, 0, 1]), corner([1, 0, 1]), t[0]);
    let x11 = lerp(corner([0, 1, 1]), corner([1, 1, 1]), t[0]);
    lerp(lerp(x00, x10, t[1]), lerp(x01, x11, t[1]), t[2])
}

/// The value the conservative piecewise-constant grid gives a zero point: the average
/// `sum / count` of its neighbours (0 without any), rounded to f32 but never from a
/// positive average down to 0 (the smallest positive f32 instead). Shared by the dense
/// and the brick grid.
pub(crate) fn conservative_average(sum: f64, count: u32) -> f32 {
    let avg = if count == 0 {
        0.0
    } else {
        sum / f64::from(count)
    };
    let value = avg as f32;
    if avg > 0.0 && value <= 0.0 {
        f32::from_bits(1)
    } else {
        value
    }
}

/// The number of f32 values of a raw grid file (`GridSource::Raw`) of `dims` ×
/// `channels`, after checking the memory guard ([`check_grid_memory`]) and that the
/// file holds exactly that many little-endian float32s. Errors name `what` and the file.
pub(crate) fn check_raw_file(
    file: &Path,
    dims: [u32; 3],
    channels: u32,
    what: &str,
) -> Result<usize> {
    let values = check_grid_memory(dims, channels, what)?;
    let size = file_size(file).map_err(|m| anyhow!("{what}: {m}"))?;
    let expected = values as u64 * 4;
    if size != expected {
        bail!(
            "{what}: {}: expected {expected} bytes ({} x {} x {} voxels x {channels} \
             channel(s) x 4 bytes of float32), found {size} bytes",
            file.display(),
            dims[0],
            dims[1],
            dims[2]
        );
    }
    Ok(values)
}

/// The number of f32 values a `dims` × `channels` grid holds, or an error (naming
/// `what`) if a dimension is 0 or it exceeds [`MAX_GRID_VALUES`] (8 GiB of f32). Checked
/// before anything is allocated or read.
pub fn check_grid_memory(dims: [u32; 3], channels: u32, what: &str) -> Result<usize> {
    if dims.contains(&0) || channels == 0 {
        bail!(
            "{what}: a grid of {} x {} x {} voxels with {channels} channel(s) is empty",
            dims[0],
            dims[1],
            dims[2]
        );
    }
    let values = dims.iter().map(|&d| u64::from(d)).product::<u64>() * u64::from(channels);
    if values > MAX_GRID_VALUES {
        bail!(
            "{what}: {} x {} x {} voxels x {channels} channel(s) = {values} float32 values \
             ({:.1} GiB) exceeds the limit of 2^31 values (8 GiB)",
            dims[0],
            dims[1],
            dims[2],
            values as f64 * 4.0 / (1u64 << 30) as f64
        );
    }
    usize::try_from(values)
        .map_err(|_| anyhow!("{what}: {values} float32 values do not fit in memory here"))
}

/// Loads a grid. `channels` says what it holds: 1 for a scalar grid (density or
/// emission: every value must be finite and >= 0), 3 for a velocity grid (finite, any
/// sign). `what` names the grid in messages, e.g. `"scenes/a.toml: [[medium]] #2 >
/// density"`.
///
/// - `Raw`: little-endian float32, exactly nx·ny·nz·channels·4 bytes.
/// - `MitsubaVol`: the header is read and checked with [`read_vol_header`]; its
///   channel count must equal `channels`.
/// - `ProceduralCloud`: [`procedural_cloud`] (scalar only).
/// - `Vdb`: the grid's values in its [`crate::VdbWindow`] (a float or half grid for 1
///   channel, a vec3 grid for 3, its vectors mapped by the window's `vector_map`).
///
/// The memory guard ([`check_grid_memory`]) runs before any allocation. Errors name the
/// file and, for bad values, the voxel (i, j, k), channel and value.
pub fn load_grid(source: &GridSource, channels: u32, what: &str) -> Result<VoxelGrid> {
    if channels != 1 && channels != 3 {
        bail!("{what}: grids have 1 (density, emission) or 3 (velocity) channels, not {channels}");
    }
    let grid = match source {
        GridSource::Raw { file, dims } => {
            let values = check_raw_file(file, *dims, channels, what)?;
            let data =
                read_values(file, 0, values, VolEncoding::F32).with_context(|| what.to_string())?;
            VoxelGrid {
                dims: *dims,
                channels,
                data,
            }
        }
        GridSource::MitsubaVol { file } => {
            let header = read_vol_header(file).with_context(|| what.to_string())?;
            if header.channels != channels {
                bail!(
                    "{what}: {}: .vol file has {} channel(s), expected {channels}",
                    file.display(),
                    header.channels
                );
            }
            let values = check_grid_memory(header.dims, channels, what)
                .with_context(|| format!("{what}: {}", file.display()))?;
            let data = read_values(file, VOL_HEADER_BYTES, values, header.encoding)
                .with_context(|| what.to_string())?;
            VoxelGrid {
                dims: header.dims,
                channels,
                data,
            }
        }
        GridSource::ProceduralCloud {
            dims,
            noise_seed,
            kind,
        } => {
            if channels != 1 {
                bail!("{what}: a procedural cloud has 1 channel, {channels} were expected");
            }
            check_grid_memory(*dims, 1, what)?;
            match kind {
                ProceduralKind::Cloud => procedural_cloud(*dims, *noise_seed),
                ProceduralKind::Cumulus => procedural_cumulus(*dims, *noise_seed),
            }
        }
        GridSource::Vdb { file, grid, window } => {
            check_grid_memory(
                window.dims,
                channels,
                &format!("{what}: {}", file.display()),
            )?;
            crate::vdb::load_window(file, grid.as_deref(), window, channels, what)?
        }
    };
    let name = match source {
        GridSource::Raw { file, .. }
        | GridSource::MitsubaVol { file }
        | GridSource::Vdb { file, .. } => file.display().to_string(),
        GridSource::ProceduralCloud { .. } => "procedural cloud".to_string(),
    };
    validate_values(&grid, &name, channels == 1).with_context(|| what.to_string())?;
    Ok(grid)
}

impl GridSource {
    /// The grid's dims without reading its values: `dims` of raw and procedural grids,
    /// the header's of `.vol` files (read and checked with [`read_vol_header`]), the
    /// window's of OpenVDB grids ([`crate::VdbWindow`]).
    pub fn dims(&self) -> Result<[u32; 3]> {
        match self {
            GridSource::Raw { dims, .. } | GridSource::ProceduralCloud { dims, .. } => Ok(*dims),
            GridSource::MitsubaVol { file } => Ok(read_vol_header(file)?.dims),
            GridSource::Vdb { window, .. } => Ok(window.dims),
        }
    }
}

/// Checks that every grid in `grids` (`(what, dims)` pairs, `what` naming the grid as
/// in [`load_grid`]) has the dims of the first; the error names the first that
/// differs, the first grid, and both dims.
pub fn check_same_dims(grids: &[(&str, [u32; 3])]) -> Result<()> {
    let Some(&(first_what, first)) = grids.first() else {
        return Ok(());
    };
    for &(what, dims) in &grids[1..] {
        if dims != first {
            bail!(
                "{what}: {} x {} x {} voxels differs from {first_what}'s {} x {} x {}; \
                 these grids must have the same dims",
                dims[0],
                dims[1],
                dims[2],
                first[0],
                first[1],
                first[2]
            );
        }
    }
    Ok(())
}

impl GridMedium {
    /// The dims shared by the base density, every `[[medium.frame]]` density and the
    /// velocity grid, or an error naming the first that differs (see
    /// [`check_same_dims`]). Reads `.vol` headers only. `what` names the medium, e.g.
    /// `"scenes/a.toml: [[medium]] #1"`.
    ///
    /// The scene format lets these grids differ; a renderer that swaps frames in place
    /// or reprojects with the velocity in the density's voxel space calls this after
    /// [`crate::load`]. Grids read later with [`load_grid`] should be compared again
    /// (each [`VoxelGrid`]'s `dims` with [`check_same_dims`]): files can change in
    /// between.
    pub fn animation_dims(&self, what: &str) -> Result<[u32; 3]> {
        let mut grids = Vec::with_capacity(self.frames.len() + 2);
        for (i, source) in self.density_sources().enumerate() {
            let name = match i {
                0 => format!("{what} > density"),
                i => format!(
                    "{what} > [[medium.frame]] (frame {}) > density",
                    self.frames[i - 1].frame
                ),
            };
            let dims = source.dims().with_context(|| name.clone())?;
            grids.push((name, dims));
        }
        if let Some(velocity) = &self.velocity {
            let name = format!("{what} > velocity");
            let dims = velocity.dims().with_context(|| name.clone())?;
            grids.push((name, dims));
        }
        let refs: Vec<(&str, [u32; 3])> = grids.iter().map(|(n, d)| (n.as_str(), *d)).collect();
        check_same_dims(&refs)?;
        Ok(grids[0].1)
    }
}

/// Reads `count` values of `encoding` from `path` starting at byte `offset`.
fn read_values(path: &Path, offset: u64, count: usize, encoding: VolEncoding) -> Result<Vec<f32>> {
    let mut data = Vec::new();
    data.try_reserve_exact(count).map_err(|e| {
        anyhow!(
            "{}: cannot allocate {count} float32 values: {e}",
            path.display()
        )
    })?;
    let mut file = File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    file.seek(SeekFrom::Start(offset))
        .with_context(|| format!("cannot seek in {}", path.display()))?;
    let mut reader = BufReader::new(file);
    let size = encoding.bytes() as usize;
    let mut chunk = vec![0u8; 1 << 20];
    let mut decoded = vec![0f32; chunk.len() / size];
    while data.len() < count {
        let n = (count - data.len()).min(decoded.len());
        let bytes = &mut chunk[..n * size];
        reader.read_exact(bytes).with_context(|| {
            format!(
                "{}: file ended after {} of {count} {} values",
                path.display(),
                data.len(),
                encoding.name()
            )
        })?;
        encoding.decode(bytes, &mut decoded[..n]);
        data.extend_from_slice(&decoded[..n]);
    }
    Ok(data)
}

/// Every value finite; and >= 0 when `non_negative`. Errors name `name`, the voxel and
/// the value.
fn validate_values(grid: &VoxelGrid, name: &str, non_negative: bool) -> Result<()> {
    let ch = grid.channels as usize;
    let bad = grid
        .data
        .iter()
        .position(|v| !v.is_finite() || (non_negative && *v < 0.0));
    let Some(at) = bad else {
        return Ok(());
    };
    let value = grid.data[at];
    let voxel = at / ch;
    let [nx, ny, _] = grid.dims.map(|d| d as usize);
    let (i, j, k) = (voxel % nx, (voxel / nx) % ny, voxel / (nx * ny));
    let channel = if ch > 1 {
        format!(" channel {}", at % ch)
    } else {
        String::new()
    };
    let problem = if value.is_finite() {
        "is negative (densities and emission must be >= 0)"
    } else {
        "is not finite"
    };
    bail!("{name}: voxel ({i}, {j}, {k}){channel}: value {value} {problem}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_partition_unity_and_integrate_exactly() {
        for n in [1u32, 2, 5, 9] {
            // Weights sum to 1 everywhere, including the clamped half-voxels.
            for step in 0..=(n * 16) {
                let x = f64::from(step) / 16.0;
                let sum: f64 = (0..n).map(|m| weight_1d(n, m, x)).sum();
                assert!((sum - 1.0).abs() < 1e-12, "n {n} x {x}: {sum}");
            }
            // So the integrals over any interval sum to its length.
            for (a, b) in [(0.0, f64::from(n)), (0.25, 0.75), (0.0, 1.0)] {
                let b = b.min(f64::from(n));
                let total: f64 = (0..n).map(|m| weight_integral(n, m, a, b)).sum();
                assert!((total - (b - a)).abs() < 1e-12);
            }
        }
        // Interior hat integrated over its own cell: 3/4 (1 − 2·(1/2·1/2·1/2)).
        assert!((weight_integral(5, 2, 2.0, 3.0) - 0.75).abs() < 1e-12);
        // The outermost voxel over its cell: flat half + linear half = 0.5 + 0.375.
        assert!((weight_integral(5, 0, 0.0, 1.0) - 0.875).abs() < 1e-12);
    }

    #[test]
    fn memory_guard_limits() {
        assert_eq!(
            check_grid_memory([1024, 1024, 2048], 1, "g").unwrap(),
            1 << 31
        );
        assert!(check_grid_memory([1024, 1024, 2048], 3, "g").is_err());
        let e = check_grid_memory([0, 4, 4], 1, "g").unwrap_err();
        assert!(format!("{e}").contains("empty"));
        assert!(load_grid(
            &GridSource::ProceduralCloud {
                dims: [4, 4, 4],
                noise_seed: 0,
                kind: Default::default(),
            },
            3,
            "v"
        )
        .is_err());
    }
}
