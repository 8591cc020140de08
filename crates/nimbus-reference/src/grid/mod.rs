//! An independent brute-force Monte Carlo reference for heterogeneous (voxel-grid)
//! media, in f64 on the CPU.
//!
//! This is the oracle for the renderer's baseline grid integrator. It shares no
//! algorithm with the GPU passes: free flights are sampled by **delta tracking** with a
//! single global majorant per grid (the largest σt anywhere in it), and shadow-ray
//! transmittance is estimated by **ratio tracking** with the same global majorant — no
//! super-voxels, no decomposition tracking, no closed-form or quadrature transmittance.
//! Geometry, random numbers and sampling are the crate's small f64 routines (`common`),
//! shared with [`crate::mc`], whose [`McEstimate`] it returns.
//!
//! # Model
//!
//! - **Media** (disjoint; vacuum elsewhere; no refraction):
//!   - grid media: the axis-aligned box `bounds_min .. bounds_max`; a point x maps to
//!     voxel-index space p = (x − bounds_min)/size · dims and σt(x) = `density_scale` ·
//!     [`sample_trilinear`](nimbus_scene::VoxelGrid::sample_trilinear)\(p)
//!     (cell-centred, clamped near faces). At frame 0 the density is the last
//!     `[[medium.frame]]` with `frame` = 0, else `density`. σs = albedo·σt, σa =
//!     (1 − albedo)·σt per channel. Optional emission Le(x) = `emission_scale` ·
//!     trilinear(emission grid, its own index space), with the absorbed-emission
//!     convention: σa·Le is the emitted power density.
//!   - box media: homogeneous, as in [`crate::mc`].
//!   - HG phase p(cosθ), θ between the travel directions before and after scattering.
//! - **Shapes**: opaque two-sided Lambertian quads, oriented boxes, spheres and triangle
//!   meshes; any may emit (`emission` Le, an area light): a quad towards edge_u × edge_v,
//!   a mesh triangle towards its counter-clockwise normal, a box or a sphere outwards.
//!   Camera rays see Le (bounce 0 only); the surface still reflects by its albedo.
//! - **Lights**:
//!   - directional (travel direction ω, irradiance E, optional convex gobo);
//!   - point (intensity I in W/sr): I/r²;
//!   - sphere (an opaque emitting sphere of radiance L): lit through NEE only; it
//!     also occludes every other light's shadow rays and ends any path that hits it;
//!     a camera ray that reaches it sees L (bounce 0 only);
//!   - environment (constant radiance, or an EXR map times `radiance·scale`): lit
//!     through NEE only (a map's nearest texel); camera rays that escape see it (bounce
//!     0 only; a map interpolated between texel centres, the renderer's background).
//!
//! # Estimator
//!
//! Each path starts on the camera ray with throughput β = 1 and repeats, with k the
//! number of scatterings so far:
//!
//! 1. Find the nearest shape or sphere-light hit t_S, then sample a free flight up to
//!    t_S: walk the ray's in-medium spans in order of entry; in a box draw an
//!    exponential with rate σt; in a grid run delta tracking with majorant σ̄ (tentative
//!    steps of rate σ̄, accept at y with probability σt(y)/σ̄). The first accepted
//!    collision inside its span wins.
//! 2. **Medium collision** at x (the (k+1)-th scattering; k ← k + 1): if the grid
//!    emits, L += β·(1 − albedo)·Le(x) (collision estimator of ∫T σa Le); then β ←
//!    β·albedo and, for every light, L += β · p(l·d) · Lᵢ(x, l)/pdf(l), where d is the
//!    direction the path travelled into x and l the sampled direction towards the
//!    light (light travelling along −l scatters into −d: cosθ = (−l)·(−d)). Stop if
//!    k = K, else continue from x in an HG-sampled direction around d.
//! 3. **Shape hit** (k ← k + 1): β ← β·albedo, NEE with β/π · max(0, n·l) (n facing
//!    the incoming ray), stop if k = K, else continue cosine-distributed around n.
//! 4. **Sphere light hit**: add β·L if k = 0; stop. (An emitting shape hit adds β·Le
//!    if k = 0, then goes on as a shape hit.)
//! 5. **Escape**: add β·L_env(d) if k = 0; stop.
//!
//! NEE per light: directional l = −ω (pdf δ); point l towards it, I/r²; sphere: l
//! uniform in the cone the sphere subtends (pdf 1/(2π(1 − cosθmax)), no NEE from
//! inside the sphere); environment: l from [`EnvSampler`](nimbus_scene::EnvSampler)
//! (map) or uniform on the sphere (constant); emitting shapes: one sample for all of
//! them, a piece by power and a point uniformly in area on it (`area`), Le·cos_l/d²
//! over its area pdf, shapes blocking only short of the point. Every NEE is multiplied by V (shapes and other sphere lights
//! closer than the light) and by a ratio-tracking estimate of T (Π over tentative
//! collisions of 1 − σt/σ̄ in grids, exp(−σt·ℓ) in boxes).
//!
//! So a path with K scatterings estimates the light that scattered 1..K times; the
//! emission term at the k-th collision (k = 1..K) is light emitted in the medium that
//! then scattered k − 1 more times before reaching the camera, i.e. emission is counted
//! for 0..K−1 scatterings after emission. Each light contributes once per vertex
//! (NEE), never again by a path that escapes or hits a sphere light after scattering.
//! No Russian roulette; with albedo 1, a constant environment L and K → ∞ the answer
//! is L (the furnace; truncation at K leaves out the paths with more than K
//! collisions).
//!
//! Every path has its own xoshiro256** stream seeded through SplitMix64 from the seed
//! and the path's index, so results are bit-for-bit deterministic whatever the thread
//! count.

mod area;
mod lights;
mod media;
mod tracer;

use anyhow::ensure;
use glam::DVec3;
use nimbus_scene::Scene;

use crate::common::estimate::{check_paths, check_render, render_paths, unit_ray, Moments};
pub use crate::common::estimate::{McEstimate, McImage};
use tracer::Tracer;

/// Settings of a grid Monte Carlo reference run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GridOptions {
    /// K, the most scattering events on a path, 1 ..= 1024.
    pub max_bounces: u32,
    /// Paths per ray ([`radiance_grid_mc`]) or per pixel ([`render_grid_mc`]), ≥ 2.
    pub paths: u32,
    /// Random seed; same seed, same scene, same result.
    pub seed: u64,
}

/// The oracle's name in errors.
const WHAT: &str = "grid Monte Carlo reference";

/// The radiance (W/(m²·sr), RGB) reaching `origin` along origin + t·dir, t ≥ 0, with
/// up to `opts.max_bounces` scatterings, from `opts.paths` independent paths. `dir`
/// need not be normalized. The scene's own `max_bounces` is ignored.
pub fn radiance_grid_mc(
    scene: &Scene,
    origin: DVec3,
    dir: DVec3,
    opts: &GridOptions,
) -> anyhow::Result<McEstimate> {
    check_options(opts)?;
    let d = unit_ray(origin, dir, WHAT)?;
    let tracer = Tracer::new(scene)?;
    Ok(tracer.radiance(origin, d, opts).estimate())
}

/// Renders the scene's frame 0: mean and standard error per pixel, row-major from the
/// top left, exactly like [`crate::mc::render_mc`]: path i of a pixel goes
/// through stratum i mod footprint² of a footprint × footprint grid, jittered (box
/// filter; `opts.paths` must be a multiple of footprint²); footprint 0 shoots every
/// path through the pixel centre.
pub fn render_grid_mc(
    scene: &Scene,
    opts: &GridOptions,
    footprint: u32,
) -> anyhow::Result<McImage> {
    check_options(opts)?;
    check_render(scene, opts.paths, footprint, WHAT)?;
    let tracer = Tracer::new(scene)?;
    Ok(render_paths(
        scene,
        opts.paths,
        opts.seed,
        footprint,
        |sums: &mut Moments, o, d, rng| {
            sums.add(tracer.trace_path(o, d, opts.max_bounces, rng));
        },
    ))
}

fn check_options(opts: &GridOptions) -> anyhow::Result<()> {
    ensure!(
        (1..=1024).contains(&opts.max_bounces),
        "{WHAT}: max_bounces must be in 1..=1024, got {}",
        opts.max_bounces
    );
    check_paths(opts.paths, WHAT)
}

#[cfg(test)]
mod tests;
