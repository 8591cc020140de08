//! How much transmittance a coarser mip level loses when it is ray marched: the measure
//! by which Volumetric ReSTIR's levels are chosen from a volume's content.
//!
//! The target functions of ReSTIR's reuse passes (and the next-event transmittance of
//! its candidates) ray march the averaged mip `L` of the density, midpoint samples one
//! level-`L` voxel diagonal apart (sec. 5.1). Final shading divides the path's true
//! contribution by that target, so every segment multiplies the estimate by
//! `T / T~ = exp(τ~ − τ)`: an error in optical depth that no amount of reuse averages
//! away. How large it is depends on the content, not on the resolution: a cloud whose
//! detail spans many voxels loses nothing at mip 1 or 2, one with voxel-scale noise
//! loses a lot (measured: ln T/T~ spread 0.25–0.28 at mip 1 on the 64³ study cloud).
//!
//! [`march_errors`] measures it directly: segments start at points drawn in proportion
//! to the density inside the stored bricks (where walks collide), leave in uniformly
//! random directions to the end of the grid (where next-event and scattered rays go),
//! and each level's marched optical depth is compared with a fine integral of the full
//! trilinear field. Errors are weighted by the segment's true transmittance, since a
//! segment that carries no light cannot disturb an estimate.

use glam::DVec3;

use super::{BrickGrid, BRICK_EDGE};

/// Segments of [`march_errors`]'s default measurement.
pub const MARCH_ERROR_SEGMENTS: usize = 768;
/// Optical depth past which a segment is not followed further: its light is below
/// e^-30 of what enters it, and its weight in the measure with it.
const DEPTH_OF_NO_CONCERN: f64 = 30.0;

/// The transmittance-weighted RMS error of the optical depth that ray marching each mip
/// level gives, for levels `0..=max_level` (index = level), against a fine integral of
/// `density`'s trilinear field (steps of a quarter of the smallest voxel edge).
///
/// `voxel` is the world size of one voxel per axis and `scale` the density scale
/// (σ_t = scale × density), so optical depths are in the renderer's units. Segments start
/// at `segments` points drawn inside the stored bricks (a uniformly chosen brick, then a
/// point in it with probability proportional to the density over the brick's largest
/// value) and run in uniformly random world directions to the end of the grid's box. The
/// same `seed` gives the same result. A grid without density gives zeros.
pub fn march_errors(
    density: &BrickGrid,
    voxel: [f64; 3],
    scale: f64,
    max_level: u32,
    segments: usize,
    seed: u64,
) -> anyhow::Result<Vec<f64>> {
    let mut mips = vec![density.clone()];
    for level in 1..=max_level {
        let next = if level <= density.last_level() {
            mips[mips.len() - 1].mip()?
        } else {
            mips[mips.len() - 1].clone()
        };
        mips.push(next);
    }
    let levels = mips.len();
    let mut sum_w = 0.0;
    let mut sum_sq = vec![0.0; levels];
    // (NaN scales measure nothing either.)
    if density.bricks.is_empty() || scale.is_nan() || scale <= 0.0 {
        return Ok(sum_sq);
    }
    let voxel = DVec3::from(voxel);
    let diagonal = voxel.length();
    let fine = 0.25 * voxel.min_element();
    // The world box in p-space units is the grid's index box.
    let (lo, hi) = (density.index_min, density.index_max);
    let mut rng = SplitMix(seed);
    let brick_max: Vec<f32> = (0..density.bricks.len())
        .map(|i| {
            density
                .brick_values(i)
                .iter()
                .fold(0.0f32, |m, &v| m.max(v))
        })
        .collect();
    let mut drawn = 0;
    // Rejection sampling inside bricks; bounded so that a grid of isolated specks ends.
    let mut tries = 0;
    while drawn < segments && tries < 64 * segments {
        tries += 1;
        let i = (rng.next() * density.bricks.len() as f64) as usize % density.bricks.len();
        if brick_max[i] <= 0.0 || brick_max[i].is_nan() {
            continue;
        }
        let b = density.bricks[i];
        let corner = (b * BRICK_EDGE).as_dvec3() + DVec3::splat(0.5);
        let p0 = corner + DVec3::new(rng.next(), rng.next(), rng.next()) * f64::from(BRICK_EDGE);
        if !(p0.cmpge(lo).all() && p0.cmple(hi).all()) {
            continue;
        }
        if rng.next() * f64::from(brick_max[i]) >= density.trilinear(p0) {
            continue;
        }
        drawn += 1;
        // A uniformly random world direction and its rate of change in p-space.
        let z = 2.0 * rng.next() - 1.0;
        let phi = std::f64::consts::TAU * rng.next();
        let r = (1.0 - z * z).max(0.0).sqrt();
        let w = DVec3::new(r * phi.cos(), r * phi.sin(), z);
        let dp = w / voxel;
        // World length to the box's exit.
        let mut len = f64::INFINITY;
        for a in 0..3 {
            if dp[a] > 0.0 {
                len = len.min((hi[a] - p0[a]) / dp[a]);
            } else if dp[a] < 0.0 {
                len = len.min((lo[a] - p0[a]) / dp[a]);
            }
        }
        if len <= 0.0 || !len.is_finite() {
            continue;
        }
        // The fine integral, stopped where the segment no longer carries light.
        let n = (len / fine).ceil().max(1.0) as usize;
        let dt = len / n as f64;
        let mut tau = 0.0;
        let mut end = len;
        for j in 0..n {
            tau += scale * density.trilinear(p0 + dp * ((j as f64 + 0.5) * dt)) * dt;
            if tau > DEPTH_OF_NO_CONCERN {
                end = (j + 1) as f64 * dt;
                break;
            }
        }
        if tau > DEPTH_OF_NO_CONCERN {
            continue;
        }
        let weight = (-tau).exp();
        sum_w += weight;
        for (level, mip) in mips.iter().enumerate() {
            let factor = f64::from(1u32 << level.min(31));
            let step = diagonal * factor;
            let n = (end / step).ceil().max(1.0) as usize;
            let dt = end / n as f64;
            let mut marched = 0.0;
            for j in 0..n {
                let p = p0 + dp * ((j as f64 + 0.5) * dt);
                marched += mip.trilinear(p / factor);
            }
            let err = scale * marched * dt - tau;
            sum_sq[level] += weight * err * err;
        }
    }
    if sum_w > 0.0 {
        for s in &mut sum_sq {
            *s = (*s / sum_w).sqrt();
        }
    }
    Ok(sum_sq)
}

/// SplitMix64 (Steele, Lea and Flood 2014) on the procedural noise's finalizer: a small
/// deterministic generator for the measurement's draws, uniform doubles in [0, 1).
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> f64 {
        // mix(s) finalizes s + γ, the next state's output.
        let z = crate::procedural::mix(self.0);
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        (z >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::VoxelGrid;

    fn grid(dims: [u32; 3], mut f: impl FnMut(u32, u32, u32) -> f32) -> BrickGrid {
        let mut data = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    data.push(f(i, j, k));
                }
            }
        }
        BrickGrid::from_dense(&VoxelGrid {
            dims,
            channels: 1,
            data,
        })
        .unwrap()
    }

    #[test]
    fn a_constant_grid_loses_nothing_at_any_level() {
        let g = grid([32, 32, 32], |_, _, _| 0.5);
        let e = march_errors(&g, [0.1; 3], 4.0, 3, 256, 1).unwrap();
        assert_eq!(e.len(), 4);
        for (level, err) in e.iter().enumerate() {
            assert!(*err < 1e-9, "level {level}: {err}");
        }
    }

    #[test]
    fn voxel_scale_noise_is_lost_by_coarse_levels_and_smooth_ramps_are_not() {
        // Independent values per voxel: averaging 2x2x2 blocks changes every segment's
        // depth; a ramp over the whole grid is linear, which every mip keeps (up to the
        // clamped border).
        let mut state = 12345u32;
        let noise = grid([32, 32, 32], |_, _, _| {
            state = state.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
            (state >> 8) as f32 / (1u32 << 24) as f32
        });
        let ramp = grid([32, 32, 32], |i, _, _| 0.2 + i as f32 / 32.0);
        let e_noise = march_errors(&noise, [0.05; 3], 2.0, 2, 512, 7).unwrap();
        let e_ramp = march_errors(&ramp, [0.05; 3], 2.0, 2, 512, 7).unwrap();
        eprintln!("noise {e_noise:?} ramp {e_ramp:?}");
        assert!(e_noise[1] > 2.0 * e_noise[0], "{e_noise:?}");
        assert!(e_noise[2] > e_noise[1], "{e_noise:?}");
        assert!(e_ramp[2] < 0.25 * e_noise[1], "{e_ramp:?} vs {e_noise:?}");
    }

    #[test]
    fn an_empty_grid_and_the_same_seed() {
        let empty = grid([16, 16, 16], |_, _, _| 0.0);
        assert_eq!(
            march_errors(&empty, [0.1; 3], 1.0, 2, 64, 3).unwrap(),
            vec![0.0; 3]
        );
        let g = grid([16, 16, 16], |i, j, k| ((i * 7 + j * 3 + k) % 5) as f32);
        let a = march_errors(&g, [0.1; 3], 1.0, 2, 64, 3).unwrap();
        assert_eq!(a, march_errors(&g, [0.1; 3], 1.0, 2, 64, 3).unwrap());
    }

    #[test]
    #[ignore = "prints the measure of the study and bench clouds"]
    fn print_the_clouds() {
        for (dims, extent) in [
            ([64u32, 40, 64], [2.0, 1.2, 2.0]),
            ([256, 160, 256], [2.0, 1.2, 2.0]),
        ] {
            let g = BrickGrid::procedural_cloud(dims, 7).unwrap();
            let voxel = [0, 1, 2].map(|a| extent[a] / f64::from(dims[a]));
            let t = std::time::Instant::now();
            let e = march_errors(&g, voxel, 24.0, 3, MARCH_ERROR_SEGMENTS, 1).unwrap();
            eprintln!("{dims:?}: {e:?} in {:?}", t.elapsed());
        }
    }
}
