//! Writes the animated plume behind `assets/scenes/plume-anim.toml`: four density frames
//! and the velocity field that carries each frame to the next, as Mitsuba `.vol` files:
//!
//! ```sh
//! cargo run --release --example make_plume            # into assets/volumes/
//! cargo run --release --example make_plume -- OUT_DIR
//! cargo run --release --example make_plume -- target/plume 256   # at 256³, with a scene
//! cargo run --release --example make_plume -- target/plume 64 96  # 96 frames: a benchmark
//! ```
//!
//! With a third argument F (2 ..= 1024, default 4), F density frames are written, and at
//! a resolution other than 32 also `plume-motion-N.toml`: issue 26's animated-plume motion
//! benchmark (the paper's Fig. 4, bottom) at 320x240 under a still camera, sun and sky,
//! the density swapped every frame and the velocity guiding ReSTIR's reprojection. Its
//! `nimbus study --per-frame` window starts after ReSTIR's warm-up (80 frames at Q = 20),
//! so give F >= 96; past the fourth frame a source at the stem's base keeps the plume
//! rising (without it the plume leaves the box by frame 40). Every frame stays resident in the baseline (about F · N³ · 4 bytes).
//!
//! With a resolution N other than 32, the same plume is written at N³ with turbulent
//! detail the 32³ grid cannot hold (the density times 0.45 + 0.9 · fractal noise of
//! 4 octaves from 14 per metre, clamped), and `plume-anim-N.toml` next to it renders
//! it at 640x360 (the committed 32³ assets keep their exact values).
//!
//! - `plume-f0.vol` .. `plume-f3.vol`: 32³ voxels, 1 channel, density in [0, 1]: a
//!   smooth stem rising into a rounded head, with three lobes around the vertical axis
//!   so that the swirl shows. Exactly 0 outside a compact support that stays at least
//!   three voxels away from every face in every frame.
//! - `plume-velocity.vol`: 32³ voxels, 3 channels, in metres per frame (world units of
//!   the scene's bounds [-0.5, 0.5]³): upward, 0.025 m/frame in the core falling to
//!   0.015 outside, plus a swirl about the vertical axis through the centre (at most
//!   0.06 rad/frame). Both parts depend on the distance to the axis only, so the field
//!   is divergence-free.
//!
//! Frame f + 1 is frame f advected semi-Lagrangian by the velocity:
//! d_{f+1}(x) = d_f(x − v(x)) at every voxel centre x, with the trilinear lookup of
//! `VoxelGrid::sample_trilinear` (clamped at the faces) and the f32 values exactly as
//! written, so a reader can recompute each frame from the previous file
//! (`crates/nimbus-scene/tests/suite/assets.rs` does).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use glam::Vec3;
use nimbus_scene::VoxelGrid;

/// Voxels per axis of the committed assets.
const N_ASSETS: u32 = 32;
/// Density frames written.
const FRAMES: usize = 4;
/// The medium's bounds in the scene (written into the .vol headers too).
const BOUNDS_MIN: Vec3 = Vec3::splat(-0.5);
const BOUNDS_MAX: Vec3 = Vec3::splat(0.5);

/// World position (m) of the centre of voxel `index`.
fn voxel_centre(n: u32, index: [u32; 3]) -> [f64; 3] {
    let mut p = [0.0; 3];
    for axis in 0..3 {
        let lo = f64::from(BOUNDS_MIN[axis]);
        let hi = f64::from(BOUNDS_MAX[axis]);
        p[axis] = lo + (f64::from(index[axis]) + 0.5) / f64::from(n) * (hi - lo);
    }
    p
}

/// Compact smooth bump: (1 − r²)³ for r < 1, else 0.
fn bump(r2: f64) -> f64 {
    if r2 >= 1.0 {
        0.0
    } else {
        let t = 1.0 - r2;
        t * t * t
    }
}

fn smoothstep(edge0: f64, edge1: f64, x: f64) -> f64 {
    let t = ((x - edge0) / (edge1 - edge0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Density of the first frame at world position `p` (m).
fn plume_density([x, y, z]: [f64; 3]) -> f64 {
    let r2_xz = x * x + z * z;
    // Head: an ellipsoid above the centre.
    let head = bump(r2_xz / (0.24 * 0.24) + y * y / (0.15 * 0.15));
    // Stem: widening upwards from y = -0.38 into the head, fading in at the bottom.
    let stem = if (-0.38..0.05).contains(&y) {
        let t = (y + 0.38) / 0.43;
        let radius = 0.06 + 0.1 * t;
        0.8 * bump(r2_xz / (radius * radius)) * smoothstep(-0.38, -0.3, y)
    } else {
        0.0
    };
    // Three lobes about the vertical axis, twisting with height.
    let lobes = 0.8 + 0.2 * (3.0 * z.atan2(x) + 6.0 * y).cos();
    ((1.0 - (1.0 - head) * (1.0 - stem)) * lobes).clamp(0.0, 1.0)
}

/// Velocity (m/frame) at world position `p`.
fn plume_velocity([x, _, z]: [f64; 3]) -> [f64; 3] {
    let r2 = x * x + z * z;
    let up = 0.02 * (0.75 + 0.5 * (-r2 / 0.03).exp());
    let swirl = 0.06 * (-r2 / 0.05).exp(); // rad/frame, counter-clockwise seen from +Y
    [swirl * z, up, -swirl * x]
}

/// The source that keeps a benchmark's plume rising (more frames than the committed
/// four): a disc of radius 0.16 m below y = -0.15 m, puffing with a period of 16 frames,
/// with fractal detail that rises 0.02 m per frame, taken where it is denser than what
/// the advection brought. Without it the plume
/// leaves the box by frame 40 and a study's window (frames 80..) renders an empty box.
fn feed(density: &mut VoxelGrid, frame: usize) {
    let n = density.dims[0];
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let p = voxel_centre(n, [i, j, k]);
                if p[1] >= -0.15 {
                    continue;
                }
                let r2_xz = p[0] * p[0] + p[2] * p[2];
                let puff = 0.7 + 0.3 * (std::f64::consts::TAU * frame as f64 / 16.0).sin();
                let base = puff * bump(r2_xz / (0.16 * 0.16)) * smoothstep(-0.42, -0.3, p[1]);
                let rise = [p[0], p[1] - 0.02 * frame as f64, p[2]];
                let detail = 0.45 + 0.9 * nimbus_scene::fbm_noise(11, 4, 14.0, rise);
                let d = (base * detail).clamp(0.0, 1.0) as f32;
                let at = ((k * n + j) * n + i) as usize;
                density.data[at] = density.data[at].max(d);
            }
        }
    }
}

/// A grid of `channels` values per voxel from `f`, x fastest.
fn grid(n: u32, channels: u32, f: impl Fn([u32; 3]) -> Vec<f32>) -> VoxelGrid {
    let mut data = Vec::with_capacity((n * n * n * channels) as usize);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                data.extend(f([i, j, k]));
            }
        }
    }
    VoxelGrid {
        dims: [n; 3],
        channels,
        data,
    }
}

/// One semi-Lagrangian step: each voxel takes the trilinear density of `density` at
/// its centre minus its velocity (converted to voxel-index space).
fn advect(density: &VoxelGrid, velocity: &VoxelGrid) -> VoxelGrid {
    let n = density.dims[0];
    let scale: [f64; 3] = std::array::from_fn(|axis| {
        f64::from(n) / (f64::from(BOUNDS_MAX[axis]) - f64::from(BOUNDS_MIN[axis]))
    });
    grid(n, 1, |[i, j, k]| {
        let index = [i, j, k];
        let p: [f64; 3] = std::array::from_fn(|axis| {
            let v = f64::from(velocity.get_channel(i, j, k, axis as u32));
            f64::from(index[axis]) + 0.5 - v * scale[axis]
        });
        vec![density.sample_trilinear(p).clamp(0.0, 1.0) as f32]
    })
}

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let out_dir = match args.next() {
        Some(dir) => PathBuf::from(dir),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/volumes"),
    };
    let n: u32 = match args.next() {
        Some(text) => text
            .parse()
            .with_context(|| format!("N = {text:?}: expected voxels per axis"))?,
        None => N_ASSETS,
    };
    if !(8..=1024).contains(&n) {
        bail!("N = {n}: expected 8 ..= 1024 voxels per axis");
    }
    let frame_count: usize = match args.next() {
        Some(text) => text
            .parse()
            .ok()
            .filter(|f| (2..=1024).contains(f))
            .with_context(|| format!("F = {text:?}: expected 2 ..= 1024 frames"))?,
        None => FRAMES,
    };
    std::fs::create_dir_all(&out_dir)?;
    // File names: the committed ones at 32³, else with the resolution.
    let name = |stem: &str| {
        if n == N_ASSETS {
            format!("plume-{stem}.vol")
        } else {
            format!("plume-{n}-{stem}.vol")
        }
    };

    let velocity = grid(n, 3, |index| {
        plume_velocity(voxel_centre(n, index))
            .iter()
            .map(|&v| v as f32)
            .collect()
    });
    let mut density = grid(n, 1, |index| {
        let p = voxel_centre(n, index);
        let d = plume_density(p);
        let d = if n == N_ASSETS {
            d
        } else {
            (d * (0.45 + 0.9 * nimbus_scene::fbm_noise(11, 4, 14.0, p))).clamp(0.0, 1.0)
        };
        vec![d as f32]
    });
    let mut frames = Vec::new();
    for frame in 0..frame_count {
        if frame > 0 {
            density = advect(&density, &velocity);
            if frame_count > FRAMES {
                feed(&mut density, frame);
            }
        }
        let path = out_dir.join(name(&format!("f{frame}")));
        nimbus_scene::write_vol(&path, &density, BOUNDS_MIN, BOUNDS_MAX)?;
        let nonzero = density.data.iter().filter(|&&v| v > 0.0).count();
        let max = density.data.iter().copied().fold(0.0f32, f32::max);
        println!(
            "wrote {} ({n}x{n}x{n}, {nonzero} non-zero voxels, max {max:.3})",
            path.display()
        );
        frames.push(path);
    }
    let path = out_dir.join(name("velocity"));
    nimbus_scene::write_vol(&path, &velocity, BOUNDS_MIN, BOUNDS_MAX)?;
    println!("wrote {} ({n}x{n}x{n}, 3 channels)", path.display());
    if n != N_ASSETS {
        write_scene(&out_dir, n, &frames[..FRAMES.min(frames.len())], &path)?;
        if frames.len() > FRAMES {
            write_motion_scene(&out_dir, n, &frames, &path)?;
        }
    }
    Ok(())
}

/// `plume-motion-N.toml`: every density frame in turn under a still camera, sun and sky.
fn write_motion_scene(out_dir: &Path, n: u32, frames: &[PathBuf], velocity: &Path) -> Result<()> {
    let abs = |p: &Path| -> Result<String> {
        Ok(p.canonicalize()
            .with_context(|| format!("resolving {}", p.display()))?
            .display()
            .to_string())
    };
    let mut text = format!(
        "# Motion benchmark (issue 26): the animated plume at {n}^3, {count} density frames\n\
         # advected by its velocity, under a still camera, sun and sky (the paper's Fig. 4,\n\
         # bottom). Written by examples/make_plume.rs.\n\n\
         [render]\nwidth = 320\nheight = 240\nframes = {count}\nseed = 3\n\n\
         [camera]\nposition = [0.0, 0.15, 2.0]\nlook_at = [0.0, 0.0, 0.0]\nhorizontal_fov_deg = 50\n\n\
         [[light]]\ntype = \"directional\"\ndirection = [0.5, -0.6, -0.6]\nirradiance = [5.0, 4.7, 4.2]\n\n\
         [[light]]\ntype = \"environment\"\nradiance = [0.25, 0.35, 0.55]\n\n\
         [[medium]]\ntype = \"grid\"\nbounds_min = [-0.5, -0.5, -0.5]\nbounds_max = [0.5, 0.5, 0.5]\n\
         density = {{ file = \"{}\" }}\nvelocity = {{ file = \"{}\" }}\n\
         density_scale = 20.0\nalbedo = 0.9\ng = 0.3\n",
        abs(&frames[0])?,
        abs(velocity)?,
        count = frames.len(),
    );
    for (f, path) in frames.iter().enumerate().skip(1) {
        text += &format!(
            "\n[[medium.frame]]\nframe = {f}\ndensity = {{ file = \"{}\" }}\n",
            abs(path)?
        );
    }
    text += "\n[integrator]\nmax_bounces = 3\n";
    let path = out_dir.join(format!("plume-motion-{n}.toml"));
    std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    println!("wrote {}", path.display());
    Ok(())
}

/// `plume-anim-N.toml`: the committed plume-anim.toml at 640x360, reading these files.
fn write_scene(out_dir: &Path, n: u32, frames: &[PathBuf], velocity: &Path) -> Result<()> {
    let template = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenes/plume-anim.toml");
    let mut text = std::fs::read_to_string(template)
        .with_context(|| format!("reading {template}"))?
        .replace("width = 96", "width = 640")
        .replace("height = 72", "height = 360");
    let abs = |p: &Path| -> Result<String> {
        Ok(p.canonicalize()
            .with_context(|| format!("resolving {}", p.display()))?
            .display()
            .to_string())
    };
    for (f, path) in frames.iter().enumerate() {
        text = text.replace(&format!("../volumes/plume-f{f}.vol"), &abs(path)?);
    }
    text = text.replace("../volumes/plume-velocity.vol", &abs(velocity)?);
    if text.contains("../volumes/") {
        bail!("{template}: a volume path this generator does not write");
    }
    let path = out_dir.join(format!("plume-anim-{n}.toml"));
    std::fs::write(
        &path,
        format!("# plume-anim.toml at {n}^3, written by examples/make_plume.rs.\n{text}"),
    )
    .with_context(|| format!("writing {}", path.display()))?;
    println!("wrote {}", path.display());
    Ok(())
}
