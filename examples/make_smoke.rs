//! Writes a column of smoke rising out of ground fog, for the gallery (issue 27): the
//! smoke as a Mitsuba `.vol` file and a scene that renders it at 640x360 with the
//! baseline path tracer:
//!
//! ```sh
//! cargo run --release --example make_smoke -- target/smoke 192
//! ```
//! writes `target/smoke/smoke-192.vol` and `smoke-fog-192.toml` (N defaults to 128).
//!
//! The smoke fills the box [-1.5, 0, -1.5] .. [1.5, 3, 1.5] (m), y up, built as smoke
//! simulations look: a chain of puffs along a centre line that rises from a source near
//! the ground and bends downwind (+x), each puff wider than the one below it (the
//! column entrains air as it rises), with smaller puffs budding off its sides; the
//! union's surface displaced by low-frequency noise (billows) and eroded by
//! high-frequency noise, more so higher up, where the smoke thins and breaks into wisps.
//! Density in [0, 1] falls with height (dilution); exactly 0 on the outermost voxel
//! layer. The same smoke at every resolution: shapes and noise live in world
//! coordinates.
//!
//! The scene sets it in ground fog: three overlapping box media (extinctions add) that
//! thin upwards, on a ground, under a low sun from behind on the left, whose light the
//! smoke shadows through the fog, and a constant sky.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use glam::Vec3;
use nimbus_scene::{fbm_noise, VoxelGrid};

const BOUNDS_MIN: Vec3 = Vec3::new(-1.5, 0.0, -1.5);
const BOUNDS_MAX: Vec3 = Vec3::new(1.5, 3.0, 1.5);
const SEED: u64 = 41;

/// A sphere of smoke (m) and the height fraction t of the centre line it sits on.
struct Puff {
    c: [f64; 3],
    r: f64,
    t: f64,
}

/// A value in [0, 1) from a hash of `n` (splitmix64).
fn unit(n: u64) -> f64 {
    let mut x = n.wrapping_add(SEED).wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^= x >> 31;
    (x >> 11) as f64 / (1u64 << 53) as f64
}

fn smoothstep(edge0: f64, edge1: f64, x: f64) -> f64 {
    let t = ((x - edge0) / (edge1 - edge0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// The centre line at height fraction t: from the source at 0.12 m up to 2.45 m,
/// bending downwind.
fn centre(t: f64) -> [f64; 3] {
    [-0.45 + 0.85 * t * t, 0.12 + 2.33 * t, 0.1 - 0.25 * t]
}

/// The column's radius at height fraction t.
fn radius(t: f64) -> f64 {
    0.13 + 0.5 * t
}

/// The puffs: along the centre line at 0.55 radii apart, jittered sideways, each with
/// two smaller puffs budding off it.
fn puffs() -> Vec<Puff> {
    let mut out = Vec::new();
    let mut t = 0.0;
    let mut n = 0u64;
    let mut next = || {
        n += 1;
        unit(n)
    };
    while t <= 1.0 {
        let r = radius(t);
        let c = centre(t);
        let jitter = [next() - 0.5, 0.0, next() - 0.5].map(|v| v * 0.5 * r);
        let main = Puff {
            c: [0, 1, 2].map(|a| c[a] + jitter[a]),
            r: r * (0.85 + 0.3 * next()),
            t,
        };
        for _ in 0..2 {
            let angle = std::f64::consts::TAU * next();
            let up = 0.4 * (next() - 0.3);
            let d = [angle.cos(), up, angle.sin()];
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            out.push(Puff {
                c: [0, 1, 2].map(|a| main.c[a] + d[a] / len * 0.75 * main.r),
                r: main.r * (0.45 + 0.2 * next()),
                t,
            });
        }
        out.push(main);
        t += 0.55 * r / 2.33;
    }
    out
}

/// Smoke density at world position `p`, given the puffs.
fn smoke(puffs: &[Puff], p: [f64; 3]) -> f32 {
    let mut s = f64::MIN;
    let mut t = 0.0;
    for puff in puffs {
        let d =
            ((p[0] - puff.c[0]).powi(2) + (p[1] - puff.c[1]).powi(2) + (p[2] - puff.c[2]).powi(2))
                .sqrt();
        let v = 1.0 - d / puff.r;
        if v > s {
            s = v;
            t = puff.t;
        }
    }
    if s <= -0.25 {
        return 0.0;
    }
    // Billows: the surface displaced by low-frequency noise.
    let s1 = s + 0.45 * (fbm_noise(SEED, 3, 2.2, p) - 0.5);
    if s1 <= 0.0 {
        return 0.0;
    }
    // Wisps: high-frequency erosion of the outer shell, deeper higher up.
    let erosion = (0.25 + 0.45 * t) * (1.0 - fbm_noise(SEED + 1, 4, 9.0, p));
    let s2 = s1 - erosion * (1.0 - smoothstep(0.0, 0.45, s1));
    let dilution = 1.0 - 0.6 * t;
    (smoothstep(0.0, 0.3, s2) * dilution) as f32
}

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let out_dir = PathBuf::from(args.next().unwrap_or_else(|| "target/smoke".to_string()));
    let n: u32 = match args.next() {
        Some(text) => text.parse().context("N must be a whole number")?,
        None => 128,
    };
    if !(16..=512).contains(&n) {
        bail!("N = {n}: give a resolution in 16 ..= 512");
    }
    std::fs::create_dir_all(&out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    let puffs = puffs();
    let size = BOUNDS_MAX - BOUNDS_MIN;
    let nn = n as usize;
    let mut data = vec![0f32; nn * nn * nn];
    let mut filled = 0usize;
    for k in 1..nn - 1 {
        for j in 1..nn - 1 {
            for i in 1..nn - 1 {
                let p = [i, j, k].map(|v| (v as f64 + 0.5) / f64::from(n));
                let p = [0, 1, 2].map(|a| f64::from(BOUNDS_MIN[a]) + p[a] * f64::from(size[a]));
                let v = smoke(&puffs, p);
                filled += usize::from(v > 0.0);
                data[(k * nn + j) * nn + i] = v;
            }
        }
    }
    let grid = VoxelGrid {
        dims: [n; 3],
        channels: 1,
        data,
    };
    let path = out_dir.join(format!("smoke-{n}.vol"));
    nimbus_scene::write_vol(&path, &grid, BOUNDS_MIN, BOUNDS_MAX)?;
    println!(
        "wrote {} ({n}^3, {} puffs, {filled} non-zero voxels, {:.1} % of the box)",
        path.display(),
        puffs.len(),
        100.0 * filled as f64 / grid.data.len() as f64
    );
    write_scene(&out_dir, n, &path)
}

/// `smoke-fog-N.toml`: the smoke in ground fog.
fn write_scene(out_dir: &Path, n: u32, density: &Path) -> Result<()> {
    let density = density
        .canonicalize()
        .with_context(|| format!("resolving {}", density.display()))?;
    let text = format!(
        r#"# A column of smoke rising out of ground fog ({n}^3 voxels), written by
# examples/make_smoke.rs: grey smoke (albedo 0.55) bending downwind as it rises and
# thins, its base hidden in fog (three overlapping box media, extinctions add:
# sigma_t 0.22 per metre below 0.35 m, 0.1 up to 0.8 m, 0.04 up to 1.4 m), on a ground, under a low sun from
# behind on the left and a constant sky. Baseline path tracer.

[render]
width = 640
height = 360
spp = 128
seed = 7

[camera]
position = [-0.3, 1.05, 6.5]
look_at = [0.25, 1.5, 0.0]
horizontal_fov_deg = 50

[[light]]
type = "directional"
direction = [0.75, -0.32, 0.58]
irradiance = [6.0, 4.9, 3.6]

[[light]]
type = "environment"
radiance = [0.16, 0.21, 0.32]

[[medium]]
type = "grid"
density = {{ file = "{}" }}
density_scale = 12.0
albedo = 0.55
g = 0.35

[[medium]]
type = "box"
center = [0.0, 0.7, 0.0]
size = [60.0, 1.4, 60.0]
sigma_t = 0.04
albedo = 0.9
g = 0.6

[[medium]]
type = "box"
center = [0.0, 0.4, 0.0]
size = [60.0, 0.8, 60.0]
sigma_t = 0.06
albedo = 0.9
g = 0.6

[[medium]]
type = "box"
center = [0.0, 0.175, 0.0]
size = [60.0, 0.35, 60.0]
sigma_t = 0.12
albedo = 0.9
g = 0.6

[[shape]]
type = "quad"
corner = [-30.0, 0.0, 30.0]
edge_u = [60.0, 0.0, 0.0]
edge_v = [0.0, 0.0, -60.0]
albedo = [0.3, 0.28, 0.22]

[integrator]
volume = "baseline"
max_bounces = 4
"#,
        density.display()
    );
    let path = out_dir.join(format!("smoke-fog-{n}.toml"));
    std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    println!("wrote {}", path.display());
    Ok(())
}
