//! An independent brute-force Monte Carlo reference for heterogeneous (voxel-grid)
//! media, in f64 on the CPU.
//!
//! This is the oracle for the renderer's baseline grid integrator. It shares no
//! algorithm with the GPU passes: free flights are sampled by **delta tracking** with a
//! single global majorant per grid (the largest σt anywhere in it), and shadow-ray
//! transmittance is estimated by **ratio tracking** with the same global majorant — no
//! super-voxels, no decomposition tracking, no closed-form or quadrature transmittance.
//! Geometry, random numbers and sampling are small f64 routines shared only with
//! [`crate::mc`] (in `reference_common`), whose public
//! [`McEstimate`] it returns.
//!
//! # Model
//!
//! - **Media** (disjoint; vacuum elsewhere; no refraction):
//!   - grid media: the axis-aligned box `bounds_min .. bounds_max`; a point x maps to
//!     voxel-index space p = (x − bounds_min)/size · dims and σt(x) = `density_scale` ·
//!     [`VoxelGrid::sample_trilinear`]\(p) (cell-centred, clamped near faces). At
//!     frame 0 the density is the last `[[medium.frame]]` with `frame` = 0, else
//!     `density`. σs = albedo·σt, σa = (1 − albedo)·σt per channel. Optional emission
//!     Le(x) = `emission_scale` · trilinear(emission grid, its own index space), with
//!     the absorbed-emission convention: σa·Le is the emitted power density.
//!   - box media: homogeneous, as in [`crate::mc`].
//!   - HG phase p(cosθ), θ between the travel directions before and after scattering.
//! - **Shapes**: opaque two-sided Lambertian quads, oriented boxes and spheres.
//! - **Lights**:
//!   - directional (travel direction ω, irradiance E, optional convex gobo);
//!   - point (intensity I in W/sr): I/r²;
//!   - sphere (an opaque emitting sphere of radiance L): lit through NEE only; it
//!     also occludes every other light's shadow rays and ends any path that hits it;
//!     a camera ray that reaches it sees L (bounce 0 only);
//!   - environment (constant radiance, or an EXR map times `radiance·scale`): lit
//!     through NEE only; camera rays that escape see it (bounce 0 only).
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
//! 4. **Sphere light hit**: add β·L if k = 0; stop.
//! 5. **Escape**: add β·L_env(d) if k = 0; stop.
//!
//! NEE per light: directional l = −ω (pdf δ); point l towards it, I/r²; sphere: l
//! uniform in the cone the sphere subtends (pdf 1/(2π(1 − cosθmax)), no NEE from
//! inside the sphere); environment: l from [`EnvSampler`] (map) or uniform on the
//! sphere (constant). Every NEE is multiplied by V (shapes and other sphere lights
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

use std::f64::consts::PI;

use anyhow::{bail, ensure, Context};
use glam::{DMat3, DVec3};
use nimbus_scene::{load_grid, EnvMap, EnvSampler, GridMedium, Light, Medium, Scene, VoxelGrid};

use crate::common::{
    check_render, direction_around, hit_sphere, phase_hg, radiance_paths, render_paths,
    sample_cosine, sample_hg, sample_sphere, surface_offset, GoboF64, Moments, OrientedBox, Rng,
    Surface,
};
use crate::mc::{McEstimate, McImage};

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

/// Paths per work item of [`radiance_grid_mc`].
const CHUNK_PATHS: u32 = 1024;

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
    let d = dir.normalize_or_zero();
    ensure!(
        d != DVec3::ZERO && d.is_finite() && origin.is_finite(),
        "grid Monte Carlo reference: bad camera ray origin {origin}, direction {dir}"
    );
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
    check_render(scene, opts.paths, footprint, "grid Monte Carlo reference")?;
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
        "grid Monte Carlo reference: max_bounces must be in 1..=1024, got {}",
        opts.max_bounces
    );
    ensure!(
        opts.paths >= 2,
        "grid Monte Carlo reference: at least 2 paths are needed for a standard error, \
         got {}",
        opts.paths
    );
    Ok(())
}

/// A grid medium in f64 with its grids loaded.
struct GridF64 {
    bounds: OrientedBox,
    lo: DVec3,
    size: DVec3,
    density: VoxelGrid,
    density_scale: f64,
    /// σ̄ = density_scale · max voxel ≥ every trilinear σt in the grid.
    majorant: f64,
    /// Emission grid and `emission_scale`.
    emission: Option<(VoxelGrid, DVec3)>,
}

impl GridF64 {
    fn index_space(&self, x: DVec3, dims: [u32; 3]) -> [f64; 3] {
        let p = (x - self.lo) / self.size;
        [
            p.x * f64::from(dims[0]),
            p.y * f64::from(dims[1]),
            p.z * f64::from(dims[2]),
        ]
    }

    fn sigma_t(&self, x: DVec3) -> f64 {
        self.density_scale
            * self
                .density
                .sample_trilinear(self.index_space(x, self.density.dims))
    }

    fn emission(&self, x: DVec3) -> DVec3 {
        match &self.emission {
            None => DVec3::ZERO,
            Some((grid, scale)) => *scale * grid.sample_trilinear(self.index_space(x, grid.dims)),
        }
    }
}

enum MediumKind {
    Homogeneous { bounds: OrientedBox, sigma_t: f64 },
    Grid(GridF64),
}

struct MediumF64 {
    kind: MediumKind,
    albedo: DVec3,
    g: f64,
}

impl MediumF64 {
    fn span(&self, o: DVec3, d: DVec3, t_max: f64) -> Option<(f64, f64)> {
        match &self.kind {
            MediumKind::Homogeneous { bounds, sigma_t } => {
                if *sigma_t > 0.0 {
                    bounds.span(o, d, 0.0, t_max)
                } else {
                    None
                }
            }
            MediumKind::Grid(grid) => {
                if grid.majorant > 0.0 {
                    grid.bounds.span(o, d, 0.0, t_max)
                } else {
                    None
                }
            }
        }
    }

    /// A collision on (t0, t1) of o + t·d: exponential in a box, delta tracking with
    /// the global majorant in a grid.
    fn sample_collision(&self, o: DVec3, d: DVec3, t0: f64, t1: f64, rng: &mut Rng) -> Option<f64> {
        match &self.kind {
            MediumKind::Homogeneous { sigma_t, .. } => {
                let t = t0 + rng.exponential(*sigma_t);
                (t < t1).then_some(t)
            }
            MediumKind::Grid(grid) => {
                let mut t = t0;
                loop {
                    t += rng.exponential(grid.majorant);
                    if t >= t1 {
                        return None;
                    }
                    if rng.uniform() * grid.majorant < grid.sigma_t(o + t * d) {
                        return Some(t);
                    }
                }
            }
        }
    }

    /// An unbiased estimate of the transmittance over (t0, t1): exact in a box, ratio
    /// tracking with the global majorant in a grid.
    fn transmittance(&self, o: DVec3, d: DVec3, t0: f64, t1: f64, rng: &mut Rng) -> f64 {
        match &self.kind {
            MediumKind::Homogeneous { sigma_t, .. } => (-sigma_t * (t1 - t0)).exp(),
            MediumKind::Grid(grid) => {
                let mut t = t0;
                let mut tr = 1.0;
                loop {
                    t += rng.exponential(grid.majorant);
                    if t >= t1 {
                        return tr;
                    }
                    tr *= 1.0 - grid.sigma_t(o + t * d) / grid.majorant;
                    if tr <= 0.0 {
                        return 0.0;
                    }
                }
            }
        }
    }
}

enum Environment {
    Constant(DVec3),
    Map { map: EnvMap, sampler: EnvSampler },
}

impl Environment {
    fn radiance(&self, d: DVec3) -> DVec3 {
        match self {
            Self::Constant(l) => *l,
            Self::Map { map, .. } => {
                let [r, g, b] = map.lookup(d);
                DVec3::new(f64::from(r), f64::from(g), f64::from(b))
            }
        }
    }
}

enum LightF64 {
    Directional {
        omega: DVec3,
        irradiance: DVec3,
        gobo: Option<GoboF64>,
    },
    Point {
        position: DVec3,
        intensity: DVec3,
    },
    Sphere {
        center: DVec3,
        radius: f64,
        radiance: DVec3,
    },
    Environment(Environment),
}

/// One NEE sample: unit direction towards the light, distance to it (∞ for distant
/// lights), the light's contribution divided by the sampling pdf, and the index of
/// the sphere light sampled (not an occluder of itself).
struct LightSample {
    l: DVec3,
    distance: f64,
    weight: DVec3,
    sphere: Option<usize>,
}

struct Tracer {
    media: Vec<MediumF64>,
    surfaces: Vec<Surface>,
    lights: Vec<LightF64>,
}

/// The density source of a grid medium at frame 0.
fn frame0_density(m: &GridMedium) -> &nimbus_scene::GridSource {
    m.frames
        .iter()
        .rev()
        .find(|f| f.frame == 0)
        .map_or(&m.density, |f| &f.density)
}

/// Loaded grids of one grid medium: density and optional emission.
type LoadedGrid = (VoxelGrid, Option<VoxelGrid>);

impl Tracer {
    /// Loads every grid (once) and builds the tracer.
    fn new(scene: &Scene) -> anyhow::Result<Self> {
        let source = scene.source.display();
        let mut grids = Vec::new();
        for (i, medium) in scene.media.iter().enumerate() {
            grids.push(match medium {
                Medium::Box(_) => None,
                Medium::Grid(m) => {
                    let what = format!("{source}: [[medium]] #{}", i + 1);
                    let density = load_grid(frame0_density(m), 1, &format!("{what} > density"))?;
                    let emission = m
                        .emission
                        .as_ref()
                        .map(|e| load_grid(e, 1, &format!("{what} > emission")))
                        .transpose()?;
                    Some((density, emission))
                }
            });
        }
        let mut environments = Vec::new();
        for (i, light) in scene.lights.iter().enumerate() {
            if let Light::Environment {
                radiance,
                file: Some(file),
                scale,
            } = light
            {
                let map = EnvMap::load_exr(file, *radiance * *scale)
                    .with_context(|| format!("{source}: light {}", i + 1))?;
                environments.push((i, map));
            }
        }
        Self::with_grids(scene, grids, environments)
    }

    /// Builds the tracer from grids already loaded (`grids[i]` for medium i, `None` for
    /// boxes) and environment maps already loaded (light index, map).
    fn with_grids(
        scene: &Scene,
        grids: Vec<Option<LoadedGrid>>,
        mut maps: Vec<(usize, EnvMap)>,
    ) -> anyhow::Result<Self> {
        let source = scene.source.display();
        ensure!(grids.len() == scene.media.len(), "grid count mismatch");
        let mut media = Vec::new();
        for (i, (medium, loaded)) in scene.media.iter().zip(grids).enumerate() {
            media.push(match (medium, loaded) {
                (Medium::Box(m), _) => MediumF64 {
                    kind: MediumKind::Homogeneous {
                        bounds: OrientedBox::from_scene(m.center, m.size, m.rotation_deg),
                        sigma_t: f64::from(m.sigma_t),
                    },
                    albedo: m.albedo.as_dvec3(),
                    g: f64::from(m.g),
                },
                (Medium::Grid(m), Some((density, emission))) => {
                    let (lo, hi) = (m.bounds_min.as_dvec3(), m.bounds_max.as_dvec3());
                    ensure!(
                        hi.cmpgt(lo).all(),
                        "{source}: medium {i}: empty grid bounds {lo} .. {hi}"
                    );
                    let density_scale = f64::from(m.density_scale);
                    let max_voxel = density
                        .data
                        .iter()
                        .step_by(density.channels as usize)
                        .fold(0f64, |a, &v| a.max(f64::from(v)));
                    MediumF64 {
                        kind: MediumKind::Grid(GridF64 {
                            bounds: OrientedBox::new(
                                0.5 * (lo + hi),
                                0.5 * (hi - lo),
                                DMat3::IDENTITY,
                            ),
                            lo,
                            size: hi - lo,
                            density,
                            density_scale,
                            majorant: density_scale * max_voxel,
                            emission: emission.map(|e| (e, m.emission_scale.as_dvec3())),
                        }),
                        albedo: m.albedo.as_dvec3(),
                        g: f64::from(m.g),
                    }
                }
                (Medium::Grid(_), None) => bail!("{source}: medium {i}: grid not loaded"),
            });
        }

        let surfaces = scene.shapes.iter().map(Surface::from_shape).collect();

        let mut lights = Vec::new();
        for (i, light) in scene.lights.iter().enumerate() {
            lights.push(match light {
                Light::Directional {
                    direction,
                    irradiance,
                    gobo,
                } => LightF64::Directional {
                    omega: direction.as_dvec3().normalize(),
                    irradiance: irradiance.as_dvec3(),
                    gobo: gobo.as_ref().map(|g| GoboF64::new(*direction, g)),
                },
                Light::Point {
                    position,
                    intensity,
                } => LightF64::Point {
                    position: position.as_dvec3(),
                    intensity: intensity.as_dvec3(),
                },
                Light::Sphere {
                    center,
                    radius,
                    radiance,
                } => LightF64::Sphere {
                    center: center.as_dvec3(),
                    radius: f64::from(*radius),
                    radiance: radiance.as_dvec3(),
                },
                Light::Environment {
                    radiance,
                    file: None,
                    scale,
                } => LightF64::Environment(Environment::Constant(
                    radiance.as_dvec3() * scale.as_dvec3(),
                )),
                Light::Environment { file: Some(f), .. } => {
                    let Some(k) = maps.iter().position(|(j, _)| *j == i) else {
                        bail!("{source}: light {}: {} not loaded", i + 1, f.display());
                    };
                    let (_, map) = maps.swap_remove(k);
                    let sampler = EnvSampler::new(&map);
                    LightF64::Environment(Environment::Map { map, sampler })
                }
            });
        }
        Ok(Self {
            media,
            surfaces,
            lights,
        })
    }

    /// The nearest shape hit (t, normal, albedo) or sphere-light hit (t, radiance) of
    /// o + t·d, t > 0.
    fn nearest_hit(&self, o: DVec3, d: DVec3) -> Option<(f64, Hit)> {
        let mut best: Option<(f64, Hit)> = None;
        for surface in &self.surfaces {
            if let Some((t, n)) = surface.hit(o, d) {
                if best.as_ref().is_none_or(|(tb, _)| t < *tb) {
                    best = Some((t, Hit::Surface(n, surface.albedo)));
                }
            }
        }
        for light in &self.lights {
            if let LightF64::Sphere {
                center,
                radius,
                radiance,
            } = *light
            {
                if let Some(t) = hit_sphere(center, radius, o, d) {
                    if best.as_ref().is_none_or(|(tb, _)| t < *tb) {
                        best = Some((t, Hit::Emitter(radiance)));
                    }
                }
            }
        }
        best
    }

    /// Whether a shape or a sphere light other than `except` lies on o + t·l,
    /// 0 < t < t_max.
    fn occluded(&self, o: DVec3, l: DVec3, t_max: f64, except: Option<usize>) -> bool {
        if self
            .surfaces
            .iter()
            .any(|s| s.hit(o, l).is_some_and(|(t, _)| t < t_max))
        {
            return true;
        }
        self.lights
            .iter()
            .enumerate()
            .any(|(i, light)| match *light {
                LightF64::Sphere { center, radius, .. } if Some(i) != except => {
                    hit_sphere(center, radius, o, l).is_some_and(|t| t < t_max)
                }
                _ => false,
            })
    }

    /// Delta-tracked free flight up to `t_max`: the first collision (t, medium).
    fn sample_collision(
        &self,
        o: DVec3,
        d: DVec3,
        t_max: f64,
        rng: &mut Rng,
    ) -> Option<(f64, usize)> {
        let mut spans: Vec<(f64, f64, usize)> = self
            .media
            .iter()
            .enumerate()
            .filter_map(|(i, m)| m.span(o, d, t_max).map(|(a, b)| (a, b, i)))
            .collect();
        spans.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (t0, t1, i) in spans {
            if let Some(t) = self.media[i].sample_collision(o, d, t0, t1, rng) {
                return Some((t, i));
            }
        }
        None
    }

    /// V·T towards a light at distance `t_max` (∞ for distant lights): 0 if occluded,
    /// else the product of every medium's transmittance estimate.
    fn visibility(
        &self,
        o: DVec3,
        l: DVec3,
        t_max: f64,
        except: Option<usize>,
        rng: &mut Rng,
    ) -> f64 {
        if self.occluded(o, l, t_max, except) {
            return 0.0;
        }
        let mut tr = 1.0;
        for m in &self.media {
            if let Some((a, b)) = m.span(o, l, t_max) {
                tr *= m.transmittance(o, l, a, b, rng);
                if tr <= 0.0 {
                    return 0.0;
                }
            }
        }
        tr
    }

    /// One NEE sample of light `i` from x (before visibility), or None when it
    /// contributes nothing.
    fn sample_light(&self, i: usize, x: DVec3, rng: &mut Rng) -> Option<LightSample> {
        match &self.lights[i] {
            LightF64::Directional {
                omega,
                irradiance,
                gobo,
            } => {
                if gobo.as_ref().is_some_and(|g| !g.lets_through(x)) {
                    return None;
                }
                Some(LightSample {
                    l: -*omega,
                    distance: f64::INFINITY,
                    weight: *irradiance,
                    sphere: None,
                })
            }
            LightF64::Point {
                position,
                intensity,
            } => {
                let to = *position - x;
                let r2 = to.length_squared();
                if r2 <= 0.0 {
                    return None;
                }
                let r = r2.sqrt();
                Some(LightSample {
                    l: to / r,
                    distance: r,
                    weight: *intensity / r2,
                    sphere: None,
                })
            }
            LightF64::Sphere {
                center,
                radius,
                radiance,
            } => {
                let to = *center - x;
                let dc = to.length();
                if dc <= *radius {
                    return None;
                }
                let axis = to / dc;
                let sin2_max = (radius / dc).powi(2);
                let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
                // 1 − cosθmax without cancellation.
                let one_minus = sin2_max / (1.0 + cos_max);
                let (u1, u2) = (rng.uniform(), rng.uniform());
                let cos_theta = 1.0 - u1 * one_minus;
                let l = direction_around(axis, cos_theta, u2);
                let distance = hit_sphere(*center, *radius, x, l).unwrap_or(dc * cos_theta);
                Some(LightSample {
                    l,
                    distance,
                    weight: *radiance * (2.0 * PI * one_minus),
                    sphere: Some(i),
                })
            }
            LightF64::Environment(env) => {
                let (l, pdf) = match env {
                    Environment::Constant(_) => (sample_sphere(rng), 1.0 / (4.0 * PI)),
                    Environment::Map { sampler, .. } => {
                        sampler.sample([rng.uniform(), rng.uniform()])
                    }
                };
                if pdf <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    l,
                    distance: f64::INFINITY,
                    weight: env.radiance(l) / pdf,
                    sphere: None,
                })
            }
        }
    }

    /// Σ over lights of one NEE sample: weight · f(l) · V · T, with `f` the phase
    /// function or BRDF·cosine of the direction towards the light.
    fn direct(&self, x: DVec3, f: impl Fn(DVec3) -> f64, rng: &mut Rng) -> DVec3 {
        let mut sum = DVec3::ZERO;
        for i in 0..self.lights.len() {
            let Some(s) = self.sample_light(i, x, rng) else {
                continue;
            };
            let fl = f(s.l);
            if fl <= 0.0 || s.weight == DVec3::ZERO {
                continue;
            }
            let v = self.visibility(x, s.l, s.distance, s.sphere, rng);
            sum += s.weight * fl * v;
        }
        sum
    }

    /// One path from o along unit d with at most `k_max` scatterings.
    fn trace_path(&self, o: DVec3, d: DVec3, k_max: u32, rng: &mut Rng) -> DVec3 {
        let (mut x, mut d) = (o, d);
        let mut beta = DVec3::ONE;
        let mut radiance = DVec3::ZERO;
        let mut scatterings = 0;
        loop {
            let hit = self.nearest_hit(x, d);
            let t_hit = hit.as_ref().map_or(f64::INFINITY, |(t, _)| *t);
            if let Some((t, i)) = self.sample_collision(x, d, t_hit, rng) {
                let medium = &self.media[i];
                let p = x + t * d;
                if let MediumKind::Grid(grid) = &medium.kind {
                    if grid.emission.is_some() {
                        radiance += beta * (DVec3::ONE - medium.albedo) * grid.emission(p);
                    }
                }
                beta *= medium.albedo;
                scatterings += 1;
                if beta == DVec3::ZERO {
                    break;
                }
                let g = medium.g;
                radiance += beta * self.direct(p, |l| phase_hg(l.dot(d), g), rng);
                if scatterings == k_max {
                    break;
                }
                d = sample_hg(d, g, rng);
                x = p;
            } else {
                match hit {
                    Some((t, Hit::Surface(normal, albedo))) => {
                        let p = x + t * d;
                        let n = if normal.dot(d) < 0.0 { normal } else { -normal };
                        let p = p + surface_offset(p) * n;
                        beta *= albedo;
                        scatterings += 1;
                        if beta == DVec3::ZERO {
                            break;
                        }
                        radiance += beta * self.direct(p, |l| n.dot(l).max(0.0) / PI, rng);
                        if scatterings == k_max {
                            break;
                        }
                        d = sample_cosine(n, rng);
                        x = p;
                    }
                    Some((_, Hit::Emitter(l))) => {
                        if scatterings == 0 {
                            radiance += beta * l;
                        }
                        break;
                    }
                    None => {
                        if scatterings == 0 {
                            for light in &self.lights {
                                if let LightF64::Environment(env) = light {
                                    radiance += beta * env.radiance(d);
                                }
                            }
                        }
                        break;
                    }
                }
            }
        }
        radiance
    }

    /// `opts.paths` paths along one ray, in chunks shared among threads; path i uses
    /// stream i of the seed; chunks are merged in order.
    fn radiance(&self, o: DVec3, d: DVec3, opts: &GridOptions) -> Moments {
        radiance_paths(
            opts.paths,
            opts.seed,
            CHUNK_PATHS,
            |sums: &mut Moments, rng| {
                sums.add(self.trace_path(o, d, opts.max_bounces, rng));
            },
        )
    }
}

enum Hit {
    /// A shape: unit normal (either side) and albedo.
    Surface(DVec3, DVec3),
    /// A sphere light's radiance.
    Emitter(DVec3),
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use glam::Vec3;
    use nimbus_scene::{BoxMedium, GridSource, Shape};

    use super::*;
    use crate::mc::{radiance_mc, McOptions};

    fn scene(media: Vec<Medium>, shapes: Vec<Shape>, lights: Vec<Light>) -> Scene {
        crate::common::test_scene(media, shapes, lights, (4, 3), 30.0)
    }

    fn grid_medium(lo: Vec3, hi: Vec3, density_scale: f32, albedo: Vec3, g: f32) -> GridMedium {
        GridMedium {
            bounds_min: lo,
            bounds_max: hi,
            density: GridSource::ProceduralCloud {
                dims: [16, 16, 16],
                noise_seed: 7,
            },
            density_scale,
            albedo,
            g,
            emission: None,
            emission_scale: Vec3::ONE,
            velocity: None,
            frames: Vec::new(),
        }
    }

    fn constant_grid(dims: [u32; 3], value: f32) -> VoxelGrid {
        let n = dims.iter().map(|&d| d as usize).product();
        VoxelGrid {
            dims,
            channels: 1,
            data: vec![value; n],
        }
    }

    /// A tracer for `s` whose grid media all use the given grids (in order).
    fn tracer(s: &Scene, mut grids: Vec<LoadedGrid>) -> Tracer {
        grids.reverse();
        let loaded = s
            .media
            .iter()
            .map(|m| match m {
                Medium::Box(_) => None,
                Medium::Grid(_) => grids.pop(),
            })
            .collect();
        Tracer::with_grids(s, loaded, Vec::new()).unwrap()
    }

    fn run(t: &Tracer, o: DVec3, d: DVec3, k: u32, paths: u32, seed: u64) -> McEstimate {
        let opts = GridOptions {
            max_bounces: k,
            paths,
            seed,
        };
        t.radiance(o, d.normalize(), &opts).estimate()
    }

    /// |mc − expected| ≤ k·SE + 1e-12·|expected| per channel.
    fn assert_within(mc: &McEstimate, expected: [f64; 3], k: f64, what: &str) {
        for (c, e) in expected.into_iter().enumerate() {
            let (m, se) = (mc.mean[c], mc.std_error[c]);
            println!(
                "{what}, channel {c}: MC {m:.6} ± {se:.6}, expected {e:.6} ({:.2} SE)",
                (m - e) / se
            );
            assert!(
                (m - e).abs() <= k * se + 1e-12 * e.abs(),
                "{what}, channel {c}: MC {m:e} ± {se:e}, expected {e:e} ({:.2} SE)",
                (m - e) / se
            );
        }
    }

    fn sun(direction: Vec3, irradiance: Vec3) -> Light {
        Light::Directional {
            direction: direction.normalize(),
            irradiance,
            gobo: None,
        }
    }

    fn constant_env(radiance: Vec3) -> Light {
        Light::Environment {
            radiance,
            file: None,
            scale: Vec3::ONE,
        }
    }

    /// ∫ σt along o + t·d, t ∈ [a, b], by composite Simpson on `n` (even) pieces.
    fn optical_depth(grid: &GridF64, o: DVec3, d: DVec3, a: f64, b: f64, n: u32) -> f64 {
        let h = (b - a) / f64::from(n);
        let f = |i: u32| grid.sigma_t(o + (a + f64::from(i) * h) * d);
        let mut sum = f(0) + f(n);
        for i in 1..n {
            sum += if i % 2 == 1 { 4.0 } else { 2.0 } * f(i);
        }
        sum * h / 3.0
    }

    #[test]
    fn constant_grid_matches_the_box_reference() {
        // The same homogeneous medium as a box (reference_mc, analog tracking, exact
        // shadow transmittance) and as a constant grid (delta + ratio tracking), over a
        // floor, lit by a sun.
        let (center, size) = (Vec3::new(0.1, -0.1, 0.0), Vec3::new(2.0, 1.5, 1.0));
        let (albedo, g, sigma) = (Vec3::new(0.9, 0.5, 0.25), 0.4, 1.5);
        let boxed = Medium::Box(BoxMedium {
            center,
            size,
            rotation_deg: Vec3::ZERO,
            sigma_t: sigma,
            albedo,
            g,
        });
        let gridded = Medium::Grid(grid_medium(
            center - 0.5 * size,
            center + 0.5 * size,
            sigma,
            albedo,
            g,
        ));
        let floor = Shape::Quad {
            corner: Vec3::new(-4.0, -1.0, 4.0),
            edge_u: Vec3::new(8.0, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, -8.0),
            albedo: Vec3::splat(0.7),
        };
        let light = sun(Vec3::new(0.3, -1.0, 0.4), Vec3::new(2.0, 1.5, 1.0));
        let box_scene = scene(vec![boxed], vec![floor.clone()], vec![light.clone()]);
        let grid_scene = scene(vec![gridded], vec![floor], vec![light]);
        let t = tracer(&grid_scene, vec![(constant_grid([5, 4, 3], 1.0), None)]);
        let origin = DVec3::new(0.0, 0.3, 5.0);
        for (j, target) in [DVec3::new(0.1, -0.1, 0.0), DVec3::new(0.8, -0.9, 0.6)]
            .into_iter()
            .enumerate()
        {
            for k in [1, 3] {
                let seed = 10 * j as u64 + u64::from(k);
                let paths = 100_000;
                let mc = run(&t, origin, target - origin, k, paths, seed);
                let opts = McOptions {
                    max_bounces: k,
                    paths,
                    seed: seed + 100,
                };
                let r = radiance_mc(&box_scene, origin, target - origin, &opts).unwrap();
                for c in 0..3 {
                    let se = (mc.std_error[c].powi(2) + r.std_error[c].powi(2)).sqrt();
                    let z = (mc.mean[c] - r.mean[c]) / se;
                    println!(
                        "target {j}, K = {k}, channel {c}: grid {:.6} ± {:.6}, box {:.6} ± {:.6} ({z:.2} SE)",
                        mc.mean[c], mc.std_error[c], r.mean[c], r.std_error[c]
                    );
                    assert!(
                        z.abs() <= 4.0,
                        "target {j}, K = {k}, channel {c}: {z:.2} SE"
                    );
                }
            }
        }
    }

    #[test]
    fn white_furnace_in_a_cloud() {
        // Albedo 1 in a constant environment of radiance 1, lit only through NEE: the
        // sum over orders is 1 everywhere. K = 64 leaves out paths with more than 64
        // collisions: at this optical thickness (max σt = 10 over 2 m) no path of 400k reached
        // 64 collisions (K = 64 and K = 256 gave identical bits).
        let cloud = grid_medium(Vec3::splat(-1.0), Vec3::ONE, 10.0, Vec3::ONE, 0.5);
        let s = scene(
            vec![Medium::Grid(cloud)],
            Vec::new(),
            vec![constant_env(Vec3::ONE)],
        );
        let t = Tracer::new(&s).unwrap();
        let rays = [
            (
                "outside",
                DVec3::new(0.0, 0.2, 5.0),
                DVec3::new(0.0, -0.04, -1.0),
            ),
            (
                "inside",
                DVec3::new(0.0, 0.2, 0.9),
                DVec3::new(0.0, -0.04, -1.0),
            ),
        ];
        for (i, (name, o, d)) in rays.into_iter().enumerate() {
            let mc = run(&t, o, d, 64, 20_000, 40 + i as u64);
            assert_within(&mc, [1.0; 3], 4.0, &format!("furnace, camera {name}"));
            // Not trivially 1: single scattering plus the env seen through the cloud
            // is well below 1.
            let k1 = run(&t, o, d, 1, 20_000, 40 + i as u64);
            println!("furnace, camera {name}: K = 1 gives {:.4}", k1.mean[0]);
            assert!(k1.mean[0] < 0.8, "{name}: {:?}", k1.mean);
        }
    }

    #[test]
    fn heterogeneous_tracking_matches_quadrature_transmittance() {
        // An absorbing cloud (albedo 0): a camera ray through it sees the constant
        // environment times exp(−∫σt) (delta tracking), and a floor outside it lit by
        // a point light through it is albedo/π · I cosθ/r² · exp(−∫σt) (ratio tracking).
        let (lo, hi) = (Vec3::new(-1.0, -0.5, -1.0), Vec3::new(1.0, 1.5, 1.0));
        let cloud = grid_medium(lo, hi, 3.0, Vec3::ZERO, 0.0);
        let floor = Shape::Quad {
            corner: Vec3::new(-4.0, -1.0, 4.0),
            edge_u: Vec3::new(8.0, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, -8.0),
            albedo: Vec3::splat(0.6),
        };
        let light_pos = DVec3::new(0.2, 3.0, -0.1);
        let point = Light::Point {
            position: light_pos.as_vec3(),
            intensity: Vec3::new(3.0, 2.0, 1.0),
        };
        let s = scene(
            vec![Medium::Grid(cloud)],
            vec![floor],
            vec![point, constant_env(Vec3::new(1.0, 0.5, 0.25))],
        );
        let t = Tracer::new(&s).unwrap();
        let MediumKind::Grid(grid) = &t.media[0].kind else {
            unreachable!()
        };

        // Camera ray through the cloud to the sky (misses the floor).
        let (o, d) = (
            DVec3::new(-3.0, 0.3, 4.0),
            DVec3::new(3.1, 0.35, -4.0).normalize(),
        );
        let (a, b) = grid.bounds.span(o, d, 0.0, f64::INFINITY).unwrap();
        let tau = optical_depth(grid, o, d, a, b, 20_000);
        assert!(tau > 0.5, "{tau}");
        // The floor is lit too (env NEE): keep the ray above it (it escapes upwards).
        assert!(d.y > 0.0);
        let mc = run(&t, o, d, 1, 100_000, 50);
        let e = (-tau).exp();
        assert_within(
            &mc,
            [e, 0.5 * e, 0.25 * e],
            4.0,
            "camera ray through the cloud",
        );

        // A floor point whose shadow ray to the light crosses the cloud, seen from a
        // camera that does not; env NEE lights the floor too, so remove the env.
        let s2 = scene(s.media.clone(), s.shapes.clone(), vec![s.lights[0].clone()]);
        let t2 = Tracer::new(&s2).unwrap();
        let p = DVec3::new(0.0, -1.0, 0.1);
        let cam = DVec3::new(0.0, -0.6, 5.0);
        assert!(grid
            .bounds
            .span(cam, (p - cam).normalize(), 0.0, (p - cam).length())
            .is_none());
        let to_light = light_pos - p;
        let (r, l) = (to_light.length(), to_light.normalize());
        let (a, b) = grid.bounds.span(p, l, 0.0, r).unwrap();
        let tau = optical_depth(grid, p, l, a, b, 20_000);
        assert!(tau > 0.5, "{tau}");
        let geometric = 0.6 / PI * l.y / (r * r) * (-tau).exp();
        let mc = run(&t2, cam, p - cam, 1, 100_000, 51);
        assert_within(
            &mc,
            [3.0 * geometric, 2.0 * geometric, geometric],
            4.0,
            "point light through the cloud",
        );
    }

    #[test]
    fn point_and_sphere_lights_match_closed_forms() {
        // A thin absorbing layer (σt = 0.2, albedo 0) around camera and lights; a
        // Lambertian floor below it at y = −1, the layer's bottom at y = −0.9.
        let layer = grid_medium(
            Vec3::new(-5.0, -0.9, -5.0),
            Vec3::new(5.0, 3.0, 8.0),
            0.2,
            Vec3::ZERO,
            0.0,
        );
        let floor = Shape::Quad {
            corner: Vec3::new(-4.0, -1.0, 4.0),
            edge_u: Vec3::new(8.0, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, -8.0),
            albedo: Vec3::splat(0.6),
        };
        let (cam, p) = (DVec3::new(0.0, 0.5, 3.0), DVec3::new(0.1, -1.0, -0.2));
        // The length of a segment from y0 to y1 above y = −0.9, per unit length.
        let inside = |y0: f64, y1: f64| (y1.max(-0.9) - y0.max(-0.9)).abs() / (y1 - y0).abs();
        let t_cam = (-0.2 * (cam - p).length() * inside(-1.0, 0.5)).exp();

        let light_pos = DVec3::new(0.3, 1.0, 0.2);
        let point = Light::Point {
            position: light_pos.as_vec3(),
            intensity: Vec3::new(2.0, 1.0, 0.5),
        };
        let s = scene(
            vec![Medium::Grid(layer.clone())],
            vec![floor.clone()],
            vec![point],
        );
        let t = tracer(&s, vec![(constant_grid([4, 4, 4], 1.0), None)]);
        let to = light_pos - p;
        let (r, l) = (to.length(), to.normalize());
        let t_shadow = (-0.2 * r * inside(-1.0, 1.0)).exp();
        let e = 0.6 / PI * l.y / (r * r) * t_shadow * t_cam;
        let mc = run(&t, cam, p - cam, 1, 100_000, 60);
        assert_within(&mc, [2.0 * e, e, 0.5 * e], 4.0, "point light");

        // Sphere light in vacuum: radiance of the floor = albedo · L · (R/d)² · cosθ
        // (a sphere wholly above the horizon), and the camera sees L directly.
        let (center, radius) = (DVec3::new(0.3, 0.6, 0.2), 0.4);
        let sphere = Light::Sphere {
            center: center.as_vec3(),
            radius: radius as f32,
            radiance: Vec3::new(5.0, 3.0, 1.0),
        };
        let s = scene(Vec::new(), vec![floor.clone()], vec![sphere.clone()]);
        let t = tracer(&s, Vec::new());
        let to = center - p;
        let (dist, axis) = (to.length(), to.normalize());
        let e = 0.6 * (radius / dist).powi(2) * axis.y;
        let mc = run(&t, cam, p - cam, 1, 100_000, 61);
        assert_within(&mc, [5.0 * e, 3.0 * e, e], 4.0, "sphere light on the floor");
        // Seen directly through the absorbing layer (deterministic: SE 0 but exact).
        let s = scene(vec![Medium::Grid(layer)], vec![floor], vec![sphere]);
        let t = tracer(&s, vec![(constant_grid([4, 4, 4], 1.0), None)]);
        let near = center.z + radius; // the sphere's front at x = 0.3, y = 0.6
        let o = DVec3::new(0.3, 0.6, 7.0);
        let tr = (-0.2 * (o.z - near)).exp();
        let mc = run(&t, o, DVec3::NEG_Z, 1, 100_000, 62);
        assert_within(
            &mc,
            [5.0 * tr, 3.0 * tr, tr],
            4.0,
            "sphere light seen directly",
        );
    }

    #[test]
    fn emission_only_is_le_times_one_minus_transmittance() {
        let mut m = grid_medium(Vec3::splat(-1.0), Vec3::ONE, 1.2, Vec3::ZERO, 0.0);
        m.emission = Some(GridSource::ProceduralCloud {
            dims: [2, 2, 2],
            noise_seed: 0,
        });
        m.emission_scale = Vec3::new(0.5, 1.0, 2.0);
        let le = m.emission_scale.as_dvec3();
        let (o, d) = (DVec3::new(0.2, -0.1, 5.0), DVec3::NEG_Z);
        let one_minus_t = 1.0 - (-1.2f64 * 2.0).exp();
        for albedo in [0.0f32, 0.3] {
            m.albedo = Vec3::splat(albedo);
            let s = scene(vec![Medium::Grid(m.clone())], Vec::new(), Vec::new());
            let t = tracer(
                &s,
                vec![(
                    constant_grid([3, 3, 3], 1.0),
                    Some(constant_grid([2, 2, 2], 1.0)),
                )],
            );
            // K = 1: emission at the first collision only, (1 − albedo)·Le·(1 − T).
            let mc = run(&t, o, d, 1, 100_000, 70);
            let expected = (le * (1.0 - f64::from(albedo)) * one_minus_t).to_array();
            assert_within(&mc, expected, 4.0, &format!("emission, albedo {albedo}"));
        }
    }

    #[test]
    fn results_are_deterministic_and_options_checked() {
        let mut cloud = grid_medium(Vec3::splat(-1.0), Vec3::ONE, 3.0, Vec3::splat(0.8), 0.3);
        cloud.emission = Some(GridSource::ProceduralCloud {
            dims: [8, 8, 8],
            noise_seed: 3,
        });
        let s = scene(
            vec![Medium::Grid(cloud)],
            vec![Shape::Sphere {
                center: Vec3::new(0.0, -2.0, 0.0),
                radius: 0.8,
                albedo: Vec3::splat(0.5),
            }],
            vec![
                sun(Vec3::new(0.2, -1.0, 0.1), Vec3::ONE),
                Light::Point {
                    position: Vec3::new(1.5, 1.5, 1.0),
                    intensity: Vec3::ONE,
                },
                Light::Sphere {
                    center: Vec3::new(-1.5, 1.5, 0.0),
                    radius: 0.3,
                    radiance: Vec3::ONE,
                },
                constant_env(Vec3::splat(0.2)),
            ],
        );
        let opts = GridOptions {
            max_bounces: 4,
            paths: 64,
            seed: 5,
        };
        let (mean, se) = render_grid_mc(&s, &opts, 2).unwrap();
        assert_eq!((mean.len(), se.len()), (12, 12));
        assert_eq!(render_grid_mc(&s, &opts, 2).unwrap(), (mean.clone(), se));
        assert!(mean.iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
        let (o, d) = (DVec3::new(0.0, 0.0, 5.0), DVec3::new(0.05, 0.02, -1.0));
        let a = radiance_grid_mc(&s, o, d, &opts).unwrap();
        assert_eq!(a, radiance_grid_mc(&s, o, d, &opts).unwrap());
        let other = GridOptions { seed: 6, ..opts };
        assert_ne!(a, radiance_grid_mc(&s, o, d, &other).unwrap());

        let bad_k = GridOptions {
            max_bounces: 0,
            ..opts
        };
        assert!(radiance_grid_mc(&s, o, d, &bad_k).is_err());
        let one_path = GridOptions { paths: 1, ..opts };
        assert!(radiance_grid_mc(&s, o, d, &one_path).is_err());
        assert!(radiance_grid_mc(&s, o, DVec3::ZERO, &opts).is_err());
        assert!(render_grid_mc(&s, &opts, 3).is_err());
        let mut missing = s.clone();
        missing.lights.push(Light::Environment {
            radiance: Vec3::ONE,
            file: Some(PathBuf::from("/nonexistent/sky.exr")),
            scale: Vec3::ONE,
        });
        assert!(radiance_grid_mc(&missing, o, d, &opts).is_err());
    }
}
