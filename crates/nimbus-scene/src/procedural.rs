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

use glam::Vec3;

use crate::volume::VoxelGrid;

/// SplitMix64 finalizer: a well-mixed 64-bit hash step (with the golden-ratio increment
/// added first, so `mix(s)` is the SplitMix64 output for the state s + γ).
pub(crate) fn mix(mut x: u64) -> u64 {
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

/// Fractal value noise in [0, 1) at `p` (any units; lattice spacing 1 / `base_frequency`):
/// `octaves` octaves, lacunarity 2, gain 0.5, deterministic for `seed` on every platform
/// (the noise of the procedural cloud, on layers of its own). For the volume generators
/// in `examples/`.
pub fn fbm_noise(seed: u64, octaves: u32, base_frequency: f64, p: [f64; 3]) -> f64 {
    fbm(seed, 1000, octaves, base_frequency, p)
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

/// The unit direction towards a sun at `elevation` above the horizon and `azimuth`
/// from −Z towards +X (radians), in the environment map's frame (+Y up).
pub fn sun_direction(elevation: f32, azimuth: f32) -> Vec3 {
    Vec3::new(
        elevation.cos() * azimuth.sin(),
        elevation.sin(),
        -elevation.cos() * azimuth.cos(),
    )
}

/// A daylight sky for benchmarks, as `w` x `h` equirectangular texels (row-major, the
/// mapping of [`crate::EnvMap`]: −Z the centre column, +Y the top row): a smooth
/// horizon-to-zenith gradient over a dark ground, and a sun of angular `diameter`
/// (radians) towards `sun` (need not be normalized) whose texels alone give an
/// irradiance of `sun_irradiance` W/m² at normal incidence — the small, very bright
/// source that decides an environment map's importance sampling.
pub fn daylight_sky(
    w: usize,
    h: usize,
    sun: Vec3,
    diameter: f64,
    sun_irradiance: f64,
) -> Vec<[f32; 3]> {
    let sun = sun.normalize_or(Vec3::Y);
    let half = diameter / 2.0;
    let sun_solid_angle = 2.0 * std::f64::consts::PI * (1.0 - half.cos());
    let sun_radiance = (sun_irradiance / sun_solid_angle.max(1e-12)) as f32;
    let sun_colour = Vec3::new(1.0, 0.92, 0.8);
    let zenith = Vec3::new(0.12, 0.2, 0.3);
    let horizon = Vec3::new(0.35, 0.4, 0.45);
    let ground = Vec3::new(0.08, 0.07, 0.06);
    let cos_half = half.cos() as f32;
    let mut texels = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            // The direction through the texel centre.
            let d = crate::envmap::uv_to_direction(
                (x as f64 + 0.5) / w as f64,
                (y as f64 + 0.5) / h as f64,
            )
            .as_vec3();
            let mut c = if d.y >= 0.0 {
                let glow = 0.18 * d.dot(sun).max(0.0).powi(8);
                horizon.lerp(zenith, d.y.powf(0.4)) + glow * sun_colour
            } else {
                ground
            };
            if d.dot(sun) >= cos_half {
                c += sun_radiance * sun_colour;
            }
            texels.push(c.to_array());
        }
    }
    texels
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Irradiance at normal incidence towards `n` from equirectangular `texels`.
    fn irradiance(texels: &[[f32; 3]], w: usize, h: usize, n: Vec3) -> f64 {
        let mut e = 0.0;
        for y in 0..h {
            let (t0, t1) = (
                std::f64::consts::PI * y as f64 / h as f64,
                std::f64::consts::PI * (y + 1) as f64 / h as f64,
            );
            let d_omega = 2.0 * std::f64::consts::PI / w as f64 * (t0.cos() - t1.cos());
            for x in 0..w {
                let d = crate::envmap::uv_to_direction(
                    (x as f64 + 0.5) / w as f64,
                    (y as f64 + 0.5) / h as f64,
                )
                .as_vec3();
                let l = f64::from(texels[y * w + x][1]);
                e += l * f64::from(d.dot(n).max(0.0)) * d_omega;
            }
        }
        e
    }

    /// The sun's texels give the irradiance asked for (green channel: the sun colour's
    /// is 0.92), within the map's discretization of a 1.5-degree disc, towards the sun's
    /// direction, which the mapping places where EnvMap expects it; everything finite
    /// and non-negative.
    #[test]
    fn daylight_sky_sun_gives_its_irradiance() {
        let (w, h) = (1024, 512);
        let sun = Vec3::new(0.3, 0.6, -0.5).normalize();
        let diameter = 1.5f64.to_radians();
        let with = daylight_sky(w, h, sun, diameter, 20.0);
        let without = daylight_sky(w, h, sun, diameter, 0.0);
        assert!(with.iter().flatten().all(|c| c.is_finite() && *c >= 0.0));
        let e_sun = irradiance(&with, w, h, sun) - irradiance(&without, w, h, sun);
        assert!(
            (e_sun / (20.0 * 0.92) - 1.0).abs() < 0.15,
            "sun irradiance {e_sun}"
        );
        // Looking away from the sun, its texels add nothing.
        let away = irradiance(&with, w, h, -sun) - irradiance(&without, w, h, -sun);
        assert!(away.abs() < 1e-9, "{away}");
        // The brightest texel is where EnvMap's mapping puts the sun.
        let brightest = (0..w * h)
            .max_by(|&a, &b| with[a][1].total_cmp(&with[b][1]))
            .unwrap_or(0);
        let (u, v) = crate::envmap::direction_to_uv(sun.as_dvec3());
        let (x, y) = ((u * w as f64) as usize, (v * h as f64) as usize);
        assert!(
            (brightest % w).abs_diff(x) <= 3 && (brightest / w).abs_diff(y) <= 3,
            "brightest texel {} vs the sun's ({x}, {y})",
            brightest
        );
    }

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
