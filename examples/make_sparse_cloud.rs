//! Writes a mostly empty cloud (a cluster of noisy puffs filling ~0.2 % of its box) as
//! raw float32 at any resolution, one z-layer at a time (the host never holds the grid),
//! together with a scene file that renders it. The same cloud at every resolution: puffs
//! and noise live in normalized box coordinates. The generator behind the scale
//! measurements of `docs/volumes.md`:
//!
//! ```sh
//! cargo run --release --example make_sparse_cloud -- target/sparse-cloud 512
//! ```
//! writes `target/sparse-cloud/cloud-512.raw` and `cloud-512.toml`.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;

use anyhow::{bail, Context, Result};

/// A spherical puff in normalized coordinates.
struct Puff {
    c: [f64; 3],
    r: f64,
}

/// A 64-bit mix (splitmix64).
fn mix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

fn unit(x: u64) -> f64 {
    (mix(x) >> 11) as f64 / (1u64 << 53) as f64
}

/// Trilinear value noise in [0, 1) at `p` (lattice units).
fn value_noise(seed: u64, p: [f64; 3]) -> f64 {
    let f = p.map(f64::floor);
    let t = [0, 1, 2].map(|a| {
        let x = p[a] - f[a];
        x * x * (3.0 - 2.0 * x)
    });
    let v = |dx: i64, dy: i64, dz: i64| {
        let (i, j, k) = (f[0] as i64 + dx, f[1] as i64 + dy, f[2] as i64 + dz);
        unit(
            seed ^ mix((i as u64).wrapping_mul(73_856_093)
                ^ (j as u64).wrapping_mul(19_349_663)
                ^ (k as u64).wrapping_mul(83_492_791)),
        )
    };
    let l = |a: f64, b: f64, t: f64| a + (b - a) * t;
    let x00 = l(v(0, 0, 0), v(1, 0, 0), t[0]);
    let x10 = l(v(0, 1, 0), v(1, 1, 0), t[0]);
    let x01 = l(v(0, 0, 1), v(1, 0, 1), t[0]);
    let x11 = l(v(0, 1, 1), v(1, 1, 1), t[0]);
    l(l(x00, x10, t[1]), l(x01, x11, t[1]), t[2])
}

/// Three octaves of value noise, normalized to [0, 1).
fn fbm(seed: u64, p: [f64; 3]) -> f64 {
    let (mut sum, mut norm, mut amp, mut freq) = (0.0, 0.0, 1.0, 24.0);
    for o in 0..3 {
        sum += amp * value_noise(seed.wrapping_add(o), p.map(|c| c * freq));
        norm += amp;
        amp *= 0.5;
        freq *= 2.0;
    }
    sum / norm
}

fn puffs(seed: u64) -> Vec<Puff> {
    // A flat cluster of 60 puffs around the box centre.
    (0..60u64)
        .map(|i| {
            let u = |k: u64| unit(seed ^ mix(i * 8 + k));
            let c = [
                0.5 + 0.16 * (2.0 * u(0) - 1.0),
                0.5 + 0.05 * (2.0 * u(1) - 1.0),
                0.5 + 0.16 * (2.0 * u(2) - 1.0),
            ];
            Puff {
                c,
                r: 0.012 + 0.022 * u(3),
            }
        })
        .collect()
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() != 2 {
        bail!("usage: make_sparse_cloud OUT_DIR N");
    }
    let dir = PathBuf::from(&args[0]);
    let n: u32 = args[1]
        .parse()
        .with_context(|| format!("N ({:?}) is not a positive integer", args[1]))?;
    if !(8..=4096).contains(&n) {
        bail!("N = {n} is outside 8 ..= 4096");
    }
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let seed = 11u64;
    let puffs = puffs(seed);
    let raw = dir.join(format!("cloud-{n}.raw"));
    let mut out = BufWriter::with_capacity(
        1 << 22,
        File::create(&raw).with_context(|| format!("cannot create {}", raw.display()))?,
    );
    let nn = n as usize;
    let mut layer = vec![0f32; nn * nn];
    let mut active = 0u64;
    let scale = f64::from(n);
    for k in 0..nn {
        layer.iter_mut().for_each(|v| *v = 0.0);
        let z = (k as f64 + 0.5) / scale;
        for p in &puffs {
            let dz = z - p.c[2];
            if dz.abs() >= p.r {
                continue;
            }
            let lo = |c: f64| (((c - p.r) * scale - 0.5).floor().max(0.0)) as usize;
            let hi = |c: f64| (((c + p.r) * scale + 0.5).ceil() as usize).min(nn - 1);
            for j in lo(p.c[1])..=hi(p.c[1]) {
                let y = (j as f64 + 0.5) / scale;
                for i in lo(p.c[0])..=hi(p.c[0]) {
                    let x = (i as f64 + 0.5) / scale;
                    let d = ((x - p.c[0]).powi(2) + (y - p.c[1]).powi(2) + dz * dz).sqrt() / p.r;
                    if d >= 1.0 {
                        continue;
                    }
                    let shape = (1.0 - d) * 2.0;
                    let v = (shape * (0.4 + 0.9 * fbm(seed, [x, y, z])) - 0.35).clamp(0.0, 1.0);
                    let cell = &mut layer[j * nn + i];
                    *cell = cell.max(v as f32);
                }
            }
        }
        active += layer.iter().filter(|v| **v > 0.0).count() as u64;
        for v in &layer {
            out.write_all(&v.to_le_bytes())?;
        }
    }
    out.flush()?;
    let toml = dir.join(format!("cloud-{n}.toml"));
    std::fs::write(
        &toml,
        format!(
            "# A mostly empty cloud of {n}^3 voxels (examples/make_sparse_cloud.rs).\n\n\
             [render]\nwidth = 160\nheight = 120\nframes = 4\nspp = 1\nseed = 2\n\n\
             [camera]\nposition = [0.0, 0.25, 0.75]\nlook_at = [0.0, 0.0, 0.0]\nhorizontal_fov_deg = 50\n\n\
             [[light]]\ntype = \"directional\"\ndirection = [0.6, -0.5, -0.6]\nirradiance = [6.0, 5.6, 5.0]\n\n\
             [[light]]\ntype = \"environment\"\nradiance = [0.25, 0.35, 0.55]\n\n\
             [[medium]]\ntype = \"grid\"\nbounds_min = [-1.0, -1.0, -1.0]\nbounds_max = [1.0, 1.0, 1.0]\n\
             density = {{ file = \"cloud-{n}.raw\", dims = [{n}, {n}, {n}] }}\n\
             density_scale = 400.0\nalbedo = 0.95\ng = 0.6\n\n\
             [integrator]\nvolume = \"baseline\"\nmax_bounces = 3\n"
        ),
    )?;
    println!(
        "wrote {} ({n}^3, {active} active voxels, {:.3} % of the box) and {}",
        raw.display(),
        100.0 * active as f64 / (f64::from(n).powi(3)),
        toml.display()
    );
    Ok(())
}
