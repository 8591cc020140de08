//! Writes a pyro explosion at any resolution: a billowing fireball of smoke (twelve
//! puffs around a core and up a rising column, each crowned by six smaller billows)
//! whose hot inside glows as a blackbody, as Mitsuba `.vol` files, together with a scene
//! file that renders it with Volumetric ReSTIR at 640x360, sitting in a layer of ground
//! fog on a dark ground:
//!
//! ```sh
//! cargo run --release --example make_explosion -- target/explosion 256
//! ```
//! writes `target/explosion/explosion-256-density.vol`, `explosion-256-temperature.vol`
//! and `explosion-256.toml` (N defaults to 128).
//!
//! - Density in [0, 1] over the box [-1, 1]³ (m): s, how deep a point lies inside the
//!   union of the puffs (1 − distance / radius of the nearest-centred one), displaced by
//!   low-frequency noise (billows), its outer shell eroded by high-frequency noise
//!   (ragged smoke), then a smooth step over s in [0, 0.2] times detail noise. Exactly
//!   0 on the outermost voxel layer and wherever no puff reaches (most of the box).
//! - Temperature (unitless, as simulation tools write it; the scene maps it to
//!   1200 + 900 · value kelvin): up to 1.5 at the core falling to 0 at 0.75 m, broken up
//!   by noise, and only inside the smoke, not in its outer shell, so the fire glows
//!   through where the smoke is thin. The scene's `temperature` turns it into blackbody
//!   radiance (absorbed-emission convention: σa · Le is the emitted power), so the fire
//!   is white-yellow where hottest and dull red at its edges.
//!
//! The same explosion at every resolution: shapes and noise live in world coordinates,
//! so finer grids resolve finer detail of the same fireball.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use glam::Vec3;
use nimbus_scene::{fbm_noise, VoxelGrid};

const BOUNDS_MIN: Vec3 = Vec3::splat(-1.0);
const BOUNDS_MAX: Vec3 = Vec3::splat(1.0);
const SEED: u64 = 23;

/// A puff: centre and radius (m).
struct Puff {
    c: [f64; 3],
    r: f64,
}

/// The core, eight puffs around it and a column rising out of it.
fn puffs() -> Vec<Puff> {
    let mut p = vec![Puff {
        c: [0.0, -0.15, 0.0],
        r: 0.45,
    }];
    for i in 0..8 {
        let a = f64::from(i) * std::f64::consts::TAU / 8.0 + 0.3;
        let up = if i % 2 == 0 { 0.12 } else { -0.05 };
        p.push(Puff {
            c: [0.38 * a.cos(), -0.15 + up, 0.38 * a.sin()],
            r: 0.26 + 0.04 * f64::from(i % 3),
        });
    }
    for (y, r) in [(0.3, 0.28), (0.55, 0.3), (0.75, 0.22)] {
        p.push(Puff {
            c: [0.04 * y, y, -0.03 * y],
            r,
        });
    }
    p
}

fn smoothstep(edge0: f64, edge1: f64, x: f64) -> f64 {
    let t = ((x - edge0) / (edge1 - edge0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// The puffs with their billows: each puff of [`puffs`] crowned by six puffs of 0.4 its
/// radius on its surface (upward-biased directions from a hash), the cauliflower
/// sub-structure of a fireball's smoke.
fn billowed(puffs: Vec<Puff>) -> Vec<Puff> {
    let mut out = Vec::with_capacity(puffs.len() * 7);
    let mut n = 0u64;
    let mut unit = || {
        n += 1;
        let h = mix(SEED ^ mix(n));
        (h >> 11) as f64 / (1u64 << 53) as f64
    };
    for puff in &puffs {
        for _ in 0..6 {
            let y = -0.3 + 1.3 * unit();
            let angle = std::f64::consts::TAU * unit();
            let ring = (1.0 - y * y).max(0.0).sqrt();
            let d = [ring * angle.cos(), y, ring * angle.sin()];
            let r = puff.r * (0.35 + 0.15 * unit());
            out.push(Puff {
                c: [0, 1, 2].map(|a| puff.c[a] + d[a] * puff.r * 0.85),
                r,
            });
        }
    }
    let mut all = puffs;
    all.extend(out);
    all
}

/// SplitMix64's finalizer.
fn mix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

/// (density, temperature) at world point `p`, given [`billowed`] puffs (the first is
/// the core).
fn explosion(puffs: &[Puff], p: [f64; 3]) -> (f32, f32) {
    // How deep inside the union of puffs: 1 at a centre, 0 on a surface.
    let mut s = f64::MIN;
    for puff in puffs {
        s = s.max(1.0 - distance(p, puff.c) / puff.r);
    }
    if s <= -0.2 {
        return (0.0, 0.0);
    }
    // Billows at the scale of the crowning puffs, then the thin shell eroded into
    // ragged smoke by finer noise.
    let s1 = s + 0.4 * (fbm_noise(SEED, 3, 4.0, p) - 0.5);
    if s1 <= 0.0 {
        return (0.0, 0.0);
    }
    let erosion = 0.3 * (1.0 - fbm_noise(SEED + 1, 4, 14.0, p)) * (1.0 - smoothstep(0.0, 0.35, s1));
    let s2 = s1 - erosion;
    if s2 <= 0.0 {
        return (0.0, 0.0);
    }
    let detail = fbm_noise(SEED + 3, 3, 10.0, p);
    let density = (smoothstep(0.0, 0.2, s2) * (0.55 + 0.7 * detail)).clamp(0.0, 1.0);
    // Heat: strongest at the core, in noisy pockets, and inside the smoke rather than in
    // its outer shell, so the fire glows through where the smoke is thin.
    let core = distance(p, puffs[0].c);
    let heat = fbm_noise(SEED + 2, 3, 6.0, p);
    let temperature =
        (smoothstep(0.75, 0.0, core) * (0.3 + 1.4 * heat) * smoothstep(0.05, 0.35, s2))
            .clamp(0.0, 1.5);
    (density as f32, temperature as f32)
}

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let out_dir = PathBuf::from(args.next().unwrap_or_else(|| "target/explosion".into()));
    let n: u32 = match args.next() {
        Some(text) => text
            .parse()
            .with_context(|| format!("N = {text:?}: expected voxels per axis"))?,
        None => 128,
    };
    if !(8..=1024).contains(&n) {
        bail!("N = {n}: expected 8 ..= 1024 voxels per axis");
    }
    std::fs::create_dir_all(&out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    let puffs = billowed(puffs());
    let voxels = (n as usize).pow(3);
    let (mut density, mut temperature) = (Vec::with_capacity(voxels), Vec::with_capacity(voxels));
    let size = f64::from(BOUNDS_MAX.x - BOUNDS_MIN.x);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let border = [i, j, k].iter().any(|&c| c == 0 || c + 1 == n);
                let p = [i, j, k]
                    .map(|c| f64::from(BOUNDS_MIN.x) + (f64::from(c) + 0.5) / f64::from(n) * size);
                let (d, t) = if border {
                    (0.0, 0.0)
                } else {
                    explosion(&puffs, p)
                };
                density.push(d);
                temperature.push(t);
            }
        }
    }
    let nonzero = density.iter().filter(|&&v| v > 0.0).count();
    let grid = |data| VoxelGrid {
        dims: [n; 3],
        channels: 1,
        data,
    };
    let density_path = out_dir.join(format!("explosion-{n}-density.vol"));
    let temperature_path = out_dir.join(format!("explosion-{n}-temperature.vol"));
    nimbus_scene::write_vol(&density_path, &grid(density), BOUNDS_MIN, BOUNDS_MAX)?;
    nimbus_scene::write_vol(
        &temperature_path,
        &grid(temperature),
        BOUNDS_MIN,
        BOUNDS_MAX,
    )?;
    println!(
        "wrote {} and {} ({n}^3, {nonzero} non-zero voxels, {:.1} % of the box)",
        density_path.display(),
        temperature_path.display(),
        100.0 * nonzero as f64 / voxels as f64
    );
    let scene_path = out_dir.join(format!("explosion-{n}.toml"));
    let abs = |p: &PathBuf| -> Result<String> {
        Ok(p.canonicalize()
            .with_context(|| format!("resolving {}", p.display()))?
            .display()
            .to_string())
    };
    let scene = format!(
        r#"# A pyro explosion ({n}^3 voxels), written by examples/make_explosion.rs.
# Smoke that absorbs half of what it scatters glows as a blackbody where it is hot
# (1200 + 900 x temperature kelvin; absorbed emission: sigma_a * Le), sitting in a
# layer of ground fog (a box medium overlapping the grid) on a dark ground, under a
# dim dusk sky and a low sun.

[render]
width = 640
height = 360
frames = 16
seed = 5

[camera]
position = [0.4, 0.35, 4.4]
look_at = [0.0, 0.05, 0.0]
horizontal_fov_deg = 45

[[light]]
type = "directional"
direction = [0.7, -0.35, -0.6]
irradiance = [1.2, 1.0, 0.85]

[[light]]
type = "environment"
radiance = [0.04, 0.05, 0.08]

[[medium]]
type = "grid"
bounds_min = [-1.0, -1.0, -1.0]
bounds_max = [1.0, 1.0, 1.0]
density = {{ file = "{}" }}
density_scale = 30.0
albedo = [0.55, 0.5, 0.45]
g = 0.3
temperature = {{ file = "{}" }}
temperature_offset = 1200.0
temperature_scale = 900.0
blackbody_scale = 0.05

[[medium]]
type = "box"
center = [0.0, -0.9, 0.0]
size = [8.0, 0.5, 8.0]
sigma_t = 0.3
albedo = [0.85, 0.87, 0.9]
g = 0.5

[[shape]]
type = "quad"
corner = [-4.0, -1.15, 4.0]
edge_u = [8.0, 0.0, 0.0]
edge_v = [0.0, 0.0, -8.0]
albedo = [0.18, 0.16, 0.14]

[integrator]
volume = "restir"
max_bounces = 4
"#,
        abs(&density_path)?,
        abs(&temperature_path)?
    );
    std::fs::write(&scene_path, scene)
        .with_context(|| format!("writing {}", scene_path.display()))?;
    println!("wrote {}", scene_path.display());
    Ok(())
}
