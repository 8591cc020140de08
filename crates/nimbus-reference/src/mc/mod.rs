//! An independent brute-force Monte Carlo reference for multiple scattering in
//! homogeneous box media, in f64 on the CPU.
//!
//! This is the oracle for the renderer's multiple-scattering (K > 1) box pass, where the
//! quadrature reference ([`crate::quadrature`]) stops at single scattering. It shares no
//! algorithm with the GPU passes (no distance sampling over the whole volume, no ratio
//! estimators, no majorants) and no code with them: it is the plainest analog path
//! tracer that estimates the model below, with the crate's own small f64 routines
//! (`common`): random numbers, sampling, ray–quad and ray–sphere tests shared with the
//! grid oracle, and only the oriented box's slab test, the gobo test and the phase
//! function shared with the quadrature reference, whose ray–shape intersections are
//! its own.
//!
//! # Model
//!
//! The same as the renderer's box pass and [`crate::quadrature`]:
//!
//! - **Media**: homogeneous boxes, world = center + R·local, R =
//!   `rotation_xyz_deg(rotation_deg)`, local ∈ [−size/2, size/2], and homogeneous
//!   convex polyhedra (the half-spaces n·x <= d of their f32 planes); scalar σt, σs =
//!   albedo·σt per RGB channel, Henyey–Greenstein phase p(cosθ) with θ the angle between
//!   the travel directions before and after scattering. Disjoint; vacuum elsewhere; no
//!   refraction at boundaries.
//! - **Shapes**: opaque two-sided Lambertian quads, oriented boxes and spheres with RGB
//!   albedo (0 = black occluder).
//! - **Lights**: directional lights (travel direction ω, irradiance E, optional convex
//!   gobo), and an environment L_env(d): a constant radiance, or an equirectangular
//!   map times `radiance · scale` looked up at its nearest texel (`EnvMap::lookup`, the
//!   mapping of the scene format). The environment is seen by rays that escape and
//!   lights the media and the shapes.
//!
//! The radiance along a camera ray is the sum over k = 1..K (K = `max_bounces`) of the
//! light (the suns' and the environment's) that scattered exactly k times — a
//! scattering is a real collision in a medium or a reflection off a shape — plus the
//! environment seen through the media by the camera ray itself.
//!
//! # Estimator
//!
//! Each path starts on the camera ray with throughput β = 1 and repeats:
//!
//! 1. Find the nearest shape hit t_S, then sample a free-flight distance by analog
//!    tracking: walk the ray's in-medium spans in order, in each draw an exponential
//!    distance with rate σt, and stop at the first that lands inside its span before t_S.
//! 2. **Medium collision** at x (the k-th scattering): β ← β·albedo (σs/σt, the
//!    collision estimator's weight), then next-event estimation to every directional
//!    light, L += β · p(ω·(−d)) · E · V_ω(x) · T_ω(x), where d is the direction the path
//!    travelled from the camera into x (light travelling along ω is scattered into −d).
//!    Stop if k = K, else continue from x in a direction sampled from the HG lobe
//!    around d (weight 1).
//! 3. **Shape hit** at x (the k-th scattering): β ← β·albedo, then L += β/π ·
//!    max(0, n·(−ω)) · E · V_ω(x) · T_ω(x) with n facing the incoming ray. Stop if k = K,
//!    else continue in a cosine-distributed direction around n (weight 1, the albedo is
//!    already in β).
//! 4. **Escape**: add β·L_env(d), d the direction of the ray that escaped (k = 0: the
//!    camera ray sees the environment's background, a map interpolated between texel
//!    centres as the renderer shows it; k ≥ 1: the environment's light, the nearest
//!    texel, scattered k times). After the K-th scattering a path under a non-black environment traces
//!    one more free flight in its sampled direction: it adds β·L_env(d) if it escapes
//!    and nothing if it collides or meets a shape.
//!
//! V_ω is the gobo mask times shape visibility towards −ω, T_ω = exp(−Σ σt·ℓ) the
//! transmittance through every medium to infinity. The suns' light of order k is added
//! at the k-th scattering by next-event estimation; the environment's only by analog
//! escape (no next-event estimation, no importance sampling of the map: independent of
//! the renderer's environment sampling, and noisy for small bright sources). So a path
//! with at most K scatterings estimates exactly orders 1..K; no Russian roulette, no
//! path is cut early except when β is exactly 0.
//!
//! Every path has its own random stream (xoshiro256** seeded through SplitMix64 from
//! the seed and the path's index), so results are bit-for-bit deterministic for a seed,
//! whatever the thread count, and runs with different K but the same seed use common
//! random numbers: each path's K = 1 estimate is a prefix of its K = 4 estimate.
//!
//! Under an albedo-1 medium and a constant environment L with nothing else, every path
//! escapes with β = 1 unless it scatters more than K times: the furnace, L exactly.

mod tracer;

use anyhow::ensure;
use glam::DVec3;
use nimbus_scene::Scene;

use crate::common::estimate::{check_paths, check_render, render_paths, unit_ray, PathSums};
pub use crate::common::estimate::{McEstimate, McImage};
use tracer::{Sums, Tracer};

/// Settings of a Monte Carlo reference run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct McOptions {
    /// K, the most scattering events on a path, ≥ 1 (1 = single scattering).
    pub max_bounces: u32,
    /// Paths per ray ([`radiance_mc`]) or per pixel ([`render_mc`]), ≥ 2.
    pub paths: u32,
    /// Random seed; same seed, same scene, same result.
    pub seed: u64,
}

/// The oracle's name in errors.
const WHAT: &str = "Monte Carlo reference";

/// The radiance (W/(m²·sr), RGB) reaching `origin` along the camera ray origin + t·dir,
/// t ≥ 0, with up to `opts.max_bounces` scatterings, from `opts.paths` independent
/// paths. `dir` need not be normalized. The scene's own `max_bounces` is ignored.
pub fn radiance_mc(
    scene: &Scene,
    origin: DVec3,
    dir: DVec3,
    opts: &McOptions,
) -> anyhow::Result<McEstimate> {
    check_options(opts)?;
    let d = unit_ray(origin, dir, WHAT)?;
    let tracer = Tracer::new(scene)?;
    Ok(tracer.radiance(origin, d, opts).estimate())
}

/// Renders the scene's frame 0: mean and standard error per pixel, `width * height`
/// each, row-major from the top left. Each pixel averages `opts.paths` paths; path i
/// goes through stratum i mod footprint² of a footprint × footprint grid over the
/// pixel, jittered uniformly within it (box filter), so `opts.paths` must be a multiple
/// of footprint². `footprint = 0` sends every path through the pixel centre (the
/// radiance there, as `[render] pixel_jitter = false`). The standard error treats the
/// paths as independent, which overestimates it slightly under stratification. Rows
/// are shared among `available_parallelism` threads; the result does not depend on
/// the thread count.
pub fn render_mc(scene: &Scene, opts: &McOptions, footprint: u32) -> anyhow::Result<McImage> {
    check_options(opts)?;
    check_render(scene, opts.paths, footprint, WHAT)?;
    let tracer = Tracer::new(scene)?;
    Ok(render_paths(
        scene,
        opts.paths,
        opts.seed,
        footprint,
        |sums: &mut Sums, o, d, rng| {
            let (l, segments) = tracer.trace_path(o, d, opts.max_bounces, rng);
            sums.add(l, segments);
        },
    ))
}

fn check_options(opts: &McOptions) -> anyhow::Result<()> {
    ensure!(
        opts.max_bounces >= 1,
        "{WHAT}: max_bounces must be at least 1"
    );
    check_paths(opts.paths, WHAT)
}

#[cfg(test)]
mod tests;
