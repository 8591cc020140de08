//! A dense grid in bricks is the dense grid: every lookup and every derived level equals
//! the dense function's, bit for bit, on grids with odd dims, empty regions and bricks
//! that clamp.

use glam::{DVec3, IVec3};

use super::*;
use crate::precision::grid_effective_sigma_t;
use crate::volume::VoxelGrid;

/// A grid of `dims` with a blob of pseudo-random values, zero elsewhere (so some bricks
/// are empty and some are cut by the blob's edge).
fn blob(dims: [u32; 3], seed: u32) -> VoxelGrid {
    let mut state = seed.wrapping_mul(747_796_405).wrapping_add(1);
    let mut data = Vec::new();
    let c = dims.map(|d| f64::from(d) * 0.4);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                state = state.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
                let r = [i, j, k]
                    .iter()
                    .zip(c)
                    .map(|(&x, c)| (f64::from(x) - c) / c)
                    .map(|d| d * d)
                    .sum::<f64>();
                let v = if r < 0.6 {
                    (state >> 8) as f32 / (1u32 << 24) as f32
                } else {
                    0.0
                };
                // Some exact zeros inside, some hot values.
                data.push(if state.is_multiple_of(7) {
                    0.0
                } else if state.is_multiple_of(97) {
                    v * 50.0
                } else {
                    v
                });
            }
        }
    }
    VoxelGrid {
        dims,
        channels: 1,
        data,
    }
}

fn grids() -> Vec<VoxelGrid> {
    vec![
        blob([19, 13, 11], 1),
        blob([8, 16, 9], 2),
        blob([3, 2, 1], 3),
        blob([1, 1, 1], 9),
        crate::procedural_cloud([40, 24, 33], 5),
    ]
}

fn dense_points(dims: [u32; 3]) -> impl Iterator<Item = (u32, u32, u32)> {
    let [nx, ny, nz] = dims;
    (0..nz).flat_map(move |k| (0..ny).flat_map(move |j| (0..nx).map(move |i| (i, j, k))))
}

fn at(i: u32, j: u32, k: u32) -> IVec3 {
    IVec3::new(i as i32, j as i32, k as i32)
}

#[test]
fn lookups_and_trilinear_match_the_dense_grid() {
    for g in grids() {
        let b = BrickGrid::from_dense(&g).unwrap();
        for (i, j, k) in dense_points(g.dims) {
            assert_eq!(b.get(at(i, j, k)), g.get(i, j, k));
        }
        // Clamped lookups beyond the faces read the outermost values.
        let n = IVec3::from_array(g.dims.map(|d| d as i32));
        assert_eq!(
            b.get_clamped(n + 3, 0),
            g.get(g.dims[0] - 1, g.dims[1] - 1, g.dims[2] - 1)
        );
        assert_eq!(b.get_clamped(IVec3::splat(-2), 0), g.get(0, 0, 0));
        for s in 0..200 {
            let p = DVec3::new(
                f64::from(s) * 0.173 % (f64::from(g.dims[0]) + 1.0) - 0.5,
                f64::from(s) * 0.311 % (f64::from(g.dims[1]) + 1.0) - 0.5,
                f64::from(s) * 0.097 % (f64::from(g.dims[2]) + 1.0) - 0.5,
            );
            assert_eq!(b.trilinear(p), g.sample_trilinear(p.to_array()), "{p}");
        }
        // Slot texels: 9³ clamped lookups from the brick's first point.
        let mut texels = Vec::new();
        let Some(&brick) = b.bricks.get(b.bricks.len() / 2) else {
            continue;
        };
        b.slot_texels(brick, 2.0, &mut texels);
        assert_eq!(texels.len(), SLOT_TEXELS);
        for z in 0..SLOT_EDGE {
            for y in 0..SLOT_EDGE {
                for x in 0..SLOT_EDGE {
                    let l = brick * BRICK_EDGE + IVec3::new(x, y, z);
                    let n = (x + SLOT_EDGE * (y + SLOT_EDGE * z)) as usize;
                    assert_eq!(texels[n], 2.0 * b.get_clamped(l, 0));
                }
            }
        }
    }
}

#[test]
fn streamed_and_procedural_bricks_equal_the_dense_bricks() {
    for g in grids() {
        let dense = BrickGrid::from_dense(&g).unwrap();
        let [nx, ny, _] = g.dims.map(|d| d as usize);
        let streamed = BrickGrid::from_slabs(g.dims, 1, "test", true, |z0, layers, out| {
            let start = z0 as usize * nx * ny;
            out.copy_from_slice(&g.data[start..start + layers as usize * nx * ny]);
            Ok(())
        })
        .unwrap();
        assert_eq!(streamed, dense);
        let topo = BrickTopology::scan_slabs(g.dims, 1, |z0, layers, out| {
            let start = z0 as usize * nx * ny;
            out.copy_from_slice(&g.data[start..start + layers as usize * nx * ny]);
            Ok(())
        })
        .unwrap();
        let mut stored = dense.bricks.clone();
        stored.sort_unstable_by_key(|b| (b.z, b.y, b.x));
        assert_eq!(topo.bricks, stored);
    }
    let dims = [40, 24, 33];
    let cloud = BrickGrid::procedural_cloud(dims, 5).unwrap();
    assert_eq!(
        cloud,
        BrickGrid::from_dense(&crate::procedural_cloud(dims, 5)).unwrap()
    );
    let bound = BrickTopology::procedural_cloud(dims);
    assert!(cloud.bricks.iter().all(|b| bound.bricks.contains(b)));
}

/// The cumulus brick by brick equals the dense cumulus, and its topology and super-voxel
/// bounds (from its puffs, not sampled) hold what it stores.
#[test]
fn the_procedural_cumulus_bricks_equal_the_dense_ones_within_their_bounds() {
    use crate::types::ProceduralKind::Cumulus;
    for (dims, seed) in [([64, 40, 64], 7), ([40, 24, 33], 2), ([23, 48, 17], 3)] {
        let cumulus = BrickGrid::procedural(dims, seed, Cumulus).unwrap();
        let dense = BrickGrid::from_dense(&crate::procedural_cumulus(dims, seed)).unwrap();
        assert_eq!(cumulus, dense, "{dims:?}");
        assert!(!cumulus.bricks.is_empty(), "{dims:?}");
        let bound = BrickTopology::procedural(dims, seed, Cumulus);
        assert!(cumulus.bricks.iter().all(|b| bound.bricks.contains(b)));
        let super_voxel = super::procedural_super_voxel_test(dims, seed, Cumulus);
        for (b, _) in cumulus.super_voxels() {
            assert!(super_voxel(b), "{dims:?} seed {seed}: super-voxel {b}");
        }
    }
}

/// The procedural cloud's brick bound (derived from the density formula, not sampled)
/// holds every non-zero voxel of dense clouds of several sizes and seeds.
#[test]
fn the_procedural_cloud_bound_holds_every_non_zero_voxel() {
    for (dims, seed) in [([40, 24, 33], 1), ([64, 40, 64], 7), ([23, 48, 17], 3)] {
        for seed in [seed, seed + 10, seed + 20] {
            let g = crate::procedural_cloud(dims, seed);
            let bricks = BrickGrid::from_dense(&g).unwrap();
            for (b, _) in bricks.super_voxels() {
                assert!(
                    procedural_cloud_super_voxel_may_be_nonzero(dims, b),
                    "{dims:?} seed {seed}: super-voxel {b}"
                );
            }
            for (i, j, k) in dense_points(dims) {
                if g.get(i, j, k) != 0.0 {
                    let b = at(i, j, k) / BRICK_EDGE;
                    assert!(
                        procedural_cloud_brick_may_be_nonzero(dims, b),
                        "{dims:?} seed {seed}: voxel ({i}, {j}, {k})"
                    );
                }
            }
        }
    }
}

#[test]
fn bad_values_are_refused_naming_the_voxel() {
    let mut g = blob([9, 9, 9], 4);
    g.data[3 + 9 * (4 + 9 * 5)] = -1.0;
    let e = BrickGrid::from_slabs(g.dims, 1, "f.raw", true, |z0, layers, out| {
        let start = z0 as usize * 81;
        out.copy_from_slice(&g.data[start..start + layers as usize * 81]);
        Ok(())
    })
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "f.raw: voxel (3, 4, 5): value -1 is negative (densities and emission must be >= 0)"
    );
}

#[test]
fn mips_and_conservative_levels_match_the_dense_functions() {
    for g in grids() {
        let b = BrickGrid::from_dense(&g).unwrap();
        let pc = g.conservative_piecewise_constant();
        let bpc = b.conservative().unwrap();
        for (i, j, k) in dense_points(g.dims) {
            assert_eq!(bpc.get(at(i, j, k)).to_bits(), pc.get(i, j, k).to_bits());
        }
        for level in 1..=3 {
            let dense = pc.mip_level(level);
            let sparse = bpc.mip_level(level).unwrap();
            assert_eq!(
                sparse.lattice_max,
                IVec3::from_array(dense.dims.map(|d| d as i32)) - 1,
                "level {level}"
            );
            for (i, j, k) in dense_points(dense.dims) {
                assert_eq!(
                    sparse.get(at(i, j, k)).to_bits(),
                    dense.get(i, j, k).to_bits()
                );
            }
        }
        // Minimum pyramid and the excess the ReSTIR level choice reads.
        let (mean, min) = (g.mip_level(1), g.min_downsample());
        let (bmean, bmin) = (b.mip().unwrap(), b.min_mip().unwrap());
        for (i, j, k) in dense_points(min.dims) {
            assert_eq!(bmin.get(at(i, j, k)), min.get(i, j, k));
        }
        let dense_excess = mean
            .data
            .iter()
            .zip(&min.data)
            .map(|(m, lo)| f64::from(m - lo))
            .fold(0.0, f64::max);
        assert_eq!(bmean.max_excess_over(&bmin), dense_excess);
    }
}

#[test]
fn super_voxels_match_the_dense_super_voxels() {
    for g in grids() {
        let b = BrickGrid::from_dense(&g).unwrap();
        let dense = g.super_voxels(8);
        let sparse = b.super_voxels();
        let mut count = 0;
        for k in 0..dense.dims[2] {
            for j in 0..dense.dims[1] {
                for i in 0..dense.dims[0] {
                    let n = dense.index(i, j, k);
                    let found = sparse.iter().find(|(c, _)| *c == at(i, j, k));
                    if dense.max[n] > 0.0 {
                        let (_, v) = found.expect("a super-voxel with density");
                        assert_eq!(*v, [dense.min[n], dense.max[n], dense.avg[n]]);
                        count += 1;
                    } else {
                        assert!(found.is_none());
                    }
                }
            }
        }
        assert_eq!(count, sparse.len());
    }
}

#[test]
fn effective_extinction_matches_the_dense_rule() {
    for g in grids() {
        let b = BrickGrid::from_dense(&g).unwrap();
        for (scale, voxel) in [(1.0, [0.1, 0.2, 0.05]), (300.0, [0.01, 0.01, 0.01])] {
            let dense = grid_effective_sigma_t(&g, scale, voxel).0;
            assert_eq!(effective_sigma_t(&b, scale, voxel).0, dense);
        }
    }
}

#[test]
fn neighbourhood_max_and_max_mips_match_the_dense_grid() {
    for g in grids() {
        let b = BrickGrid::from_dense(&g).unwrap();
        let mut dense = g.neighbourhood_max();
        let mut bricks = b.neighbourhood_max().unwrap();
        loop {
            for (i, j, k) in dense_points(dense.dims) {
                assert_eq!(bricks.get(at(i, j, k)), dense.get(i, j, k), "{:?}", g.dims);
            }
            let floored = b.max_with_scaled(&bricks, 0.25).unwrap();
            if bricks.lattice_min == b.lattice_min && bricks.lattice_max == b.lattice_max {
                for (i, j, k) in dense_points(dense.dims) {
                    let want = g.get(i, j, k).max(0.25 * dense.get(i, j, k));
                    assert_eq!(floored.get(at(i, j, k)), want);
                }
            }
            if dense.dims == [1, 1, 1] {
                break;
            }
            dense = dense.max_downsample();
            bricks = bricks.max_mip().unwrap();
        }
    }
}
