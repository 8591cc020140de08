//! The deterministic procedural cloud behind `procedural = "cloud"`.
//!
//! # Construction
//! All arithmetic is integer hashing plus IEEE-754 basic operations in f64 (`+ − × ÷`,
//! `sqrt`, `floor`, comparisons), which are correctly rounded on every platform, so a
//! given `(dims, seed)` produces bit-identical grids everywhere. No `sin`/`exp`/`pow`.
//!
//! Voxel (i, j, k) is evaluated at its centre in normalized coordinates
//! `p = ((i, j, k) + 0.5) / dims` ∈ (0, 1)³ (+Y is up, as in the scene format):
//! 1. **Noise**: 3D *value noise* — a hash of (lattice point, octave, seed) gives a
//!    value in [0, 1) at every integer lattice point, blended with the quintic
//!    smoothstep 6t⁵ − 15t⁴ + 10t³ per axis. Five octaves of fractal Brownian motion
//!    (base frequency 5 per unit, lacunarity 2, gain 0.5), normalized to [0, 1].
//!    A separate 2-octave low-frequency noise (frequency 3) displaces the envelope.
//! 2. **Envelope**: an ellipsoid centred at (0.5, 0.40, 0.5) with radii
//!    (0.42, 0.32, 0.42), whose normalized radius is displaced by the low-frequency noise
//!    (±0.2, the billowy top and sides) and then cut by a soft floor: a smoothstep from
//!    y = 0.22 to 0.28 (a flat-ish base). The envelope is 1 deep inside, falling to 0
//!    (cubic smoothstep) over the outer 30 % of the (displaced) radius.
//! 3. **Density**: detail = clamp(3 · (fbm − 0.5) + 0.5, 0, 1) (contrast-stretched
//!    noise), density = clamp(2.5 · (envelope · (0.3 + 0.9 · detail) − 0.45), 0, 1): the
//!    threshold leaves empty pockets inside the cloud where the noise is low, and
//!    everything outside the envelope is exactly 0.
//! 4. The outermost layer of voxels on every face is forced to exactly 0 (which the
//!    envelope already gives for grids larger than about 8 voxels per axis).
//!
//! At 64³, 7–12 % of the voxels are non-zero depending on the seed (seed 0: 12.1 %).

use crate::volume::VoxelGrid;

/// SplitMix64 finalizer: a well-mixed 64-bit hash step.
fn mix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// A value in [0, 1) for the lattice point (x, y, z) of noise layer `layer`.
fn lattice(seed: u64, layer: u64, x: i64, y: i64, z: i64) -> f64 {
    let mut h = mix(seed ^ mix(layer));
    h = mix(h ^ x as u64);
    h = mix(h ^ y as u64);
    h = mix(h ^ z as u64);
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Quintic smoothstep 6t⁵ − 15t⁴ + 10t³ for t in [0, 1].
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// Cubic smoothstep of x between `edge0` and `edge1`, clamped to [0, 1].
fn smoothstep(edge0: f64, edge1: f64, x: f64) -> f64 {
    let t = ((x - edge0) / (edge1 - edge0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Value noise in [0, 1) at `p` (lattice units).
fn value_noise(seed: u64, layer: u64, p: [f64; 3]) -> f64 {
    let fl = p.map(f64::floor);
    let cell = fl.map(|v| v as i64);
    let t = [fade(p[0] - fl[0]), fade(p[1] - fl[1]), fade(p[2] - fl[2])];
    let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
    let v =
        |dx: i64, dy: i64, dz: i64| lattice(seed, layer, cell[0] + dx, cell[1] + dy, cell[2] + dz);
    let x00 = lerp(v(0, 0, 0), v(1, 0, 0), t[0]);
    let x10 = lerp(v(0, 1, 0), v(1, 1, 0), t[0]);
    let x01 = lerp(v(0, 0, 1), v(1, 0, 1), t[0]);
    let x11 = lerp(v(0, 1, 1), v(1, 1, 1), t[0]);
    lerp(lerp(x00, x10, t[1]), lerp(x01, x11, t[1]), t[2])
}

/// Fractal Brownian motion of value noise, normalized to [0, 1).
fn fbm(seed: u64, first_layer: u64, octaves: u32, base_frequency: f64, p: [f64; 3]) -> f64 {
    let mut sum = 0.0;
    let mut norm = 0.0;
    let mut amplitude = 1.0;
    let mut frequency = base_frequency;
    for octave in 0..octaves {
        let q = p.map(|c| c * frequency);
        sum += amplitude * value_noise(seed, first_layer + u64::from(octave), q);
        norm += amplitude;
        amplitude *= 0.5;
        frequency *= 2.0;
    }
    sum / norm
}

/// Density in [0, 1] of the cloud at normalized position `p` ∈ [0, 1]³.
fn cloud_density(seed: u64, p: [f64; 3]) -> f64 {
    const CENTER: [f64; 3] = [0.5, 0.40, 0.5];
    const RADII: [f64; 3] = [0.42, 0.32, 0.42];
    let mut r2 = 0.0;
    for axis in 0..3 {
        let d = (p[axis] - CENTER[axis]) / RADII[axis];
        r2 += d * d;
    }
    let r = r2.sqrt();
    // Outside the largest possible displaced envelope (and below the floor): empty.
    if r >= 1.2 || p[1] <= 0.22 {
        return 0.0;
    }
    let displacement = 0.4 * (fbm(seed, 100, 2, 3.0, p) - 0.5);
    let r_displaced = r - displacement;
    let envelope = smoothstep(0.0, 0.3, 1.0 - r_displaced) * smoothstep(0.22, 0.28, p[1]);
    if envelope <= 0.0 {
        return 0.0;
    }
    let noise = fbm(seed, 0, 5, 5.0, p);
    let detail = ((noise - 0.5) * 3.0 + 0.5).clamp(0.0, 1.0);
    (2.5 * (envelope * (0.3 + 0.9 * detail) - 0.45)).clamp(0.0, 1.0)
}

/// A deterministic cumulus-like cloud of `dims` voxels, densities in [0, 1], exactly 0
/// on the outermost voxel layer and outside the envelope; see the module docs for the
/// construction. Bit-identical for the same `(dims, seed)` on every platform.
///
/// Allocates `dims` product f32s; callers with untrusted dims should go through
/// [`crate::load_grid`], which applies the memory guard first.
pub fn procedural_cloud(dims: [u32; 3], seed: u64) -> VoxelGrid {
    // (Kept as its own loop, not through `cloud_voxel`: the golden checksum pins it.)
    let [nx, ny, nz] = dims.map(|d| d as usize);
    let mut data = vec![0f32; nx * ny * nz];
    for k in 1..nz.saturating_sub(1) {
        for j in 1..ny.saturating_sub(1) {
            for i in 1..nx.saturating_sub(1) {
                let p = [
                    (i as f64 + 0.5) / nx as f64,
                    (j as f64 + 0.5) / ny as f64,
                    (k as f64 + 0.5) / nz as f64,
                ];
                data[(k * ny + j) * nx + i] = cloud_density(seed, p) as f32;
            }
        }
    }
    VoxelGrid {
        dims,
        channels: 1,
        data,
    }
}

/// Voxel `ijk` of [`procedural_cloud`]`(dims, seed)`, alone: 0 on the outermost layer.
pub(crate) fn cloud_voxel(dims: [u32; 3], seed: u64, ijk: [u32; 3]) -> f32 {
    if (0..3).any(|a| ijk[a] == 0 || ijk[a] + 1 >= dims[a]) {
        return 0.0;
    }
    let p = [0, 1, 2].map(|a| (f64::from(ijk[a]) + 0.5) / f64::from(dims[a]));
    cloud_density(seed, p) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn helpers_hit_their_endpoints() {
        assert_eq!(fade(0.0), 0.0);
        assert_eq!(fade(1.0), 1.0);
        assert_eq!(smoothstep(0.2, 0.4, 0.1), 0.0);
        assert_eq!(smoothstep(0.2, 0.4, 0.5), 1.0);
        for x in [-3.7, 0.0, 1.5, 123.25] {
            let v = value_noise(5, 1, [x, 0.5 * x, -x]);
            assert!((0.0..1.0).contains(&v));
        }
        // Value noise interpolates the lattice values exactly at lattice points.
        assert_eq!(value_noise(9, 2, [3.0, -4.0, 5.0]), lattice(9, 2, 3, -4, 5));
    }

    /// Golden checksum: the cloud must be bit-identical on every platform and build.
    /// If the construction is changed on purpose, update the constant.
    #[test]
    fn golden_checksum() {
        let grid = procedural_cloud([20, 16, 24], 42);
        let checksum = grid
            .data
            .iter()
            .fold(0u64, |h, v| mix(h ^ u64::from(v.to_bits())));
        let nonzero = grid.data.iter().filter(|&&v| v > 0.0).count();
        assert_eq!((checksum, nonzero), (554_231_826_767_120_010, 878));
    }
}
