//! An independent brute-force Monte Carlo reference for multiple scattering in
//! homogeneous box media, in f64 on the CPU.
//!
//! This is the oracle for the renderer's multiple-scattering (K > 1) box pass, where the
//! quadrature reference ([`crate::quadrature`]) stops at single scattering. It shares no
//! algorithm with the GPU passes (no distance sampling over the whole volume, no ratio
//! estimators, no majorants) and none of its geometry code with either: it is the
//! plainest analog path tracer that estimates the model below, with its own small f64
//! ray–box, ray–quad and ray–sphere tests and its own random number generator (in
//! `reference_common`, shared only with the grid oracle).
//!
//! # Model
//!
//! The same as the renderer's box pass and [`crate::quadrature`]:
//!
//! - **Media**: homogeneous boxes, world = center + R·local, R =
//!   `rotation_xyz_deg(rotation_deg)`, local ∈ [−size/2, size/2]; scalar σt, σs =
//!   albedo·σt per RGB channel, Henyey–Greenstein phase p(cosθ) with θ the angle between
//!   the travel directions before and after scattering. Disjoint; vacuum elsewhere; no
//!   refraction at boundaries.
//! - **Shapes**: opaque two-sided Lambertian quads, oriented boxes and spheres with RGB
//!   albedo (0 = black occluder).
//! - **Lights**: directional lights (travel direction ω, irradiance E, optional convex
//!   gobo), and constant environment radiance that only camera rays that escape see
//!   (it lights nothing).
//!
//! The radiance along a camera ray is the sum over k = 1..K (K = `max_bounces`) of the
//! light that scattered exactly k times — a scattering is a real collision in a medium
//! or a reflection off a shape — plus the environment seen through the media by the
//! camera ray itself.
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
//! 4. **Escape**: add the environment radiance only if k = 0 (the camera ray itself).
//!
//! V_ω is the gobo mask times shape visibility towards −ω, T_ω = exp(−Σ σt·ℓ) the
//! transmittance through every medium to infinity. The estimate of order k is added at
//! the k-th scattering, so a path with K scatterings estimates exactly orders 1..K; no
//! Russian roulette, no path is cut early except when β is exactly 0.
//!
//! Every path has its own random stream (xoshiro256** seeded through SplitMix64 from
//! the seed and the path's index), so results are bit-for-bit deterministic for a seed,
//! whatever the thread count, and runs with different K but the same seed use common
//! random numbers: each path's K = 1 estimate is a prefix of its K = 4 estimate.

use std::f64::consts::PI;

use anyhow::{bail, ensure};
use glam::DVec3;
use nimbus_scene::{Light, Medium, Scene};

use crate::common::{
    check_render, phase_hg, radiance_paths, render_paths, sample_cosine, sample_hg, surface_offset,
    GoboF64, Moments, OrientedBox, PathSums, Rng, Surface,
};

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

/// A Monte Carlo estimate: per-channel mean and standard error of the mean.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct McEstimate {
    pub mean: [f64; 3],
    /// sqrt(sample variance / paths).
    pub std_error: [f64; 3],
}

/// A rendered image: (mean, standard error) per pixel, row-major from the top left.
pub type McImage = (Vec<[f64; 3]>, Vec<[f64; 3]>);

/// Paths per work item of [`radiance_mc`] (the unit shared among threads).
const CHUNK_PATHS: u32 = 4096;

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
    let d = dir.normalize_or_zero();
    ensure!(
        d != DVec3::ZERO && d.is_finite() && origin.is_finite(),
        "Monte Carlo reference: bad camera ray origin {origin}, direction {dir}"
    );
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
    check_render(scene, opts.paths, footprint, "Monte Carlo reference")?;
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
        "Monte Carlo reference: max_bounces must be at least 1"
    );
    ensure!(
        opts.paths >= 2,
        "Monte Carlo reference: at least 2 paths are needed for a standard error, got {}",
        opts.paths
    );
    Ok(())
}

struct BoxMediumF64 {
    bounds: OrientedBox,
    sigma_t: f64,
    albedo: DVec3,
    g: f64,
}

struct Sun {
    /// Unit travel direction ω.
    omega: DVec3,
    irradiance: DVec3,
    gobo: Option<GoboF64>,
}

/// The scene in f64, checked against what the estimator models.
struct Tracer {
    media: Vec<BoxMediumF64>,
    surfaces: Vec<Surface>,
    suns: Vec<Sun>,
    environment: DVec3,
}

/// Running moments over paths, with the number of free-flight rays traced (camera ray
/// plus one per continued scattering).
#[derive(Clone, Copy, Default)]
struct Sums {
    moments: Moments,
    segments: u64,
}

impl Sums {
    fn add(&mut self, l: DVec3, segments: u32) {
        self.moments.add(l);
        self.segments += u64::from(segments);
    }
}

impl PathSums for Sums {
    fn merge(&mut self, other: &Sums) {
        if other.moments.n == 0 {
            return;
        }
        self.moments.merge(&other.moments);
        self.segments += other.segments;
    }

    fn estimate(&self) -> McEstimate {
        self.moments.estimate()
    }
}

impl Tracer {
    fn new(scene: &Scene) -> anyhow::Result<Self> {
        let source = scene.source.display();
        let mut media = Vec::new();
        for (i, medium) in scene.media.iter().enumerate() {
            let Medium::Box(m) = medium else {
                bail!(
                    "{source}: medium {i}: grid media are not supported by the Monte Carlo \
                     reference (homogeneous boxes only)"
                );
            };
            media.push(BoxMediumF64 {
                bounds: OrientedBox::from_scene(m.center, m.size, m.rotation_deg),
                sigma_t: f64::from(m.sigma_t),
                albedo: m.albedo.as_dvec3(),
                g: f64::from(m.g),
            });
        }

        let surfaces = scene.shapes.iter().map(Surface::from_shape).collect();

        let mut suns = Vec::new();
        let mut environment = DVec3::ZERO;
        for (i, light) in scene.lights.iter().enumerate() {
            match light {
                Light::Directional {
                    direction,
                    irradiance,
                    gobo,
                } => suns.push(Sun {
                    omega: direction.as_dvec3().normalize(),
                    irradiance: irradiance.as_dvec3(),
                    gobo: gobo.as_ref().map(|g| GoboF64::new(*direction, g)),
                }),
                Light::Environment {
                    radiance,
                    file: None,
                    scale,
                } => environment += radiance.as_dvec3() * scale.as_dvec3(),
                Light::Environment { file: Some(f), .. } => bail!(
                    "{source}: light {i}: environment maps ({}) are not supported by the \
                     Monte Carlo reference (constant radiance only)",
                    f.display()
                ),
                Light::Point { .. } => bail!(
                    "{source}: light {i}: point lights are not supported by the Monte Carlo \
                     reference"
                ),
                Light::Sphere { .. } => bail!(
                    "{source}: light {i}: sphere lights are not supported by the Monte \
                     Carlo reference"
                ),
            }
        }
        Ok(Self {
            media,
            surfaces,
            suns,
            environment,
        })
    }

    /// The nearest shape hit of o + t·d, t > 0: (t, unit normal, albedo).
    fn nearest_surface(&self, o: DVec3, d: DVec3) -> Option<(f64, DVec3, DVec3)> {
        let mut best: Option<(f64, DVec3, DVec3)> = None;
        for surface in &self.surfaces {
            if let Some((t, n)) = surface.hit(o, d) {
                if best.is_none_or(|(t_best, _, _)| t < t_best) {
                    best = Some((t, n, surface.albedo));
                }
            }
        }
        best
    }

    /// Analog free flight along o + t·d up to `t_max`: the in-medium spans in order of
    /// entry, an exponential distance with rate σt drawn in each; returns the first
    /// collision (t, medium) that lands inside its span.
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
            .filter_map(|(i, m)| m.bounds.span(o, d, 0.0, t_max).map(|(a, b)| (a, b, i)))
            .collect();
        spans.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (t0, t1, i) in spans {
            let sigma_t = self.media[i].sigma_t;
            if sigma_t <= 0.0 {
                continue;
            }
            // Exponential with rate σt; 1 − u ∈ (0, 1], so the log is finite.
            let t = t0 - (1.0 - rng.uniform()).ln() / sigma_t;
            if t < t1 {
                return Some((t, i));
            }
        }
        None
    }

    /// E·V_ω(x)·T_ω(x): the irradiance of `sun` reaching x (gobo, shadows, media).
    fn sunlight_at(&self, x: DVec3, sun: &Sun) -> DVec3 {
        if let Some(gobo) = &sun.gobo {
            if !gobo.lets_through(x) {
                return DVec3::ZERO;
            }
        }
        let towards = -sun.omega;
        if self.surfaces.iter().any(|s| s.hit(x, towards).is_some()) {
            return DVec3::ZERO;
        }
        let optical_depth: f64 = self
            .media
            .iter()
            .filter_map(|m| {
                let (a, b) = m.bounds.span(x, towards, 0.0, f64::INFINITY)?;
                Some(m.sigma_t * (b - a))
            })
            .sum();
        sun.irradiance * (-optical_depth).exp()
    }

    /// One path from o along unit d with at most `k_max` scatterings: its radiance
    /// estimate and the number of free-flight rays it traced.
    fn trace_path(&self, o: DVec3, d: DVec3, k_max: u32, rng: &mut Rng) -> (DVec3, u32) {
        let (mut x, mut d) = (o, d);
        let mut beta = DVec3::ONE;
        let mut radiance = DVec3::ZERO;
        let mut scatterings = 0;
        let mut segments = 0;
        loop {
            segments += 1;
            let surface = self.nearest_surface(x, d);
            let t_surface = surface.map_or(f64::INFINITY, |(t, _, _)| t);
            if let Some((t, i)) = self.sample_collision(x, d, t_surface, rng) {
                // Medium collision: weight σs/σt, NEE with the phase of ω → −d.
                let medium = &self.media[i];
                let p = x + t * d;
                beta *= medium.albedo;
                for sun in &self.suns {
                    let phase = phase_hg(sun.omega.dot(-d), medium.g);
                    radiance += beta * phase * self.sunlight_at(p, sun);
                }
                scatterings += 1;
                if scatterings == k_max || beta == DVec3::ZERO {
                    break;
                }
                d = sample_hg(d, medium.g, rng);
                x = p;
            } else if let Some((t, normal, albedo)) = surface {
                // Lambertian reflection: weight albedo, NEE with the cosine at the normal
                // facing the incoming ray.
                let p = x + t * d;
                let n = if normal.dot(d) < 0.0 { normal } else { -normal };
                let p = p + surface_offset(p) * n;
                beta *= albedo;
                for sun in &self.suns {
                    let cosine = n.dot(-sun.omega).max(0.0);
                    if cosine > 0.0 {
                        radiance += beta / PI * cosine * self.sunlight_at(p, sun);
                    }
                }
                scatterings += 1;
                if scatterings == k_max || beta == DVec3::ZERO {
                    break;
                }
                d = sample_cosine(n, rng);
                x = p;
            } else {
                // Escape: the environment counts only for the camera ray.
                if scatterings == 0 {
                    radiance += beta * self.environment;
                }
                break;
            }
        }
        (radiance, segments)
    }

    /// `opts.paths` paths along one camera ray, in chunks shared among threads; path i
    /// uses stream i of the seed, and chunks are merged in order.
    fn radiance(&self, o: DVec3, d: DVec3, opts: &McOptions) -> Sums {
        radiance_paths(
            opts.paths,
            opts.seed,
            CHUNK_PATHS,
            |sums: &mut Sums, rng| {
                let (l, segments) = self.trace_path(o, d, opts.max_bounces, rng);
                sums.add(l, segments);
            },
        )
    }
}

/// Camera rays of frame 0 in f64, with `CameraFrame::ray_direction`'s convention.
#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use glam::{Vec2, Vec3};
    use nimbus_scene::{BoxMedium, Gobo, GridMedium, GridSource, Shape};

    use super::*;
    use crate::quadrature::{self, ReferenceOptions};
    use crate::common::{rotation_f64, CameraRays};

    const QUADRATURE: ReferenceOptions = ReferenceOptions {
        rel_tol: 1e-9,
        footprint_samples: 1,
    };

    fn medium(center: Vec3, size: Vec3, rotation_deg: Vec3, sigma_t: f32, g: f32) -> BoxMedium {
        BoxMedium {
            center,
            size,
            rotation_deg,
            sigma_t,
            albedo: Vec3::new(0.9, 0.5, 0.25),
            g,
        }
    }

    fn scene(media: Vec<BoxMedium>, shapes: Vec<Shape>, lights: Vec<Light>) -> Scene {
        crate::common::test_scene(
            media.into_iter().map(Medium::Box).collect(),
            shapes,
            lights,
            (6, 4),
            40.0,
        )
    }

    fn sun(direction: Vec3, irradiance: Vec3) -> Light {
        Light::Directional {
            direction: direction.normalize(),
            irradiance,
            gobo: None,
        }
    }

    fn environment(radiance: Vec3) -> Light {
        Light::Environment {
            radiance,
            file: None,
            scale: Vec3::ONE,
        }
    }

    /// |mc − expected| ≤ k·SE + 1e-12·|expected| per channel (the slack covers rays
    /// whose estimate is deterministic, SE = 0).
    fn assert_within(mc: &McEstimate, expected: [f64; 3], k: f64, what: &str) {
        for (c, e) in expected.into_iter().enumerate() {
            let (m, se) = (mc.mean[c], mc.std_error[c]);
            assert!(
                (m - e).abs() <= k * se + 1e-12 * e.abs(),
                "{what}, channel {c}: MC {m:e} ± {se:e}, expected {e:e} ({:.2} SE)",
                (m - e) / se
            );
        }
    }

    #[test]
    fn rng_is_uniform_and_streams_differ() {
        let mut rng = Rng::new(7, 0);
        let n = 100_000;
        let (mut sum, mut sum_sq) = (0.0, 0.0);
        for _ in 0..n {
            let u = rng.uniform();
            assert!((0.0..1.0).contains(&u));
            sum += u;
            sum_sq += u * u;
        }
        let n = f64::from(n);
        // Mean 1/2 (SE 0.29/√n), second moment 1/3 (SE 0.30/√n).
        assert!((sum / n - 0.5).abs() < 5.0 * 0.29 / n.sqrt());
        assert!((sum_sq / n - 1.0 / 3.0).abs() < 5.0 * 0.30 / n.sqrt());
        let firsts: Vec<u64> = (0..4)
            .flat_map(|stream| {
                [
                    Rng::new(7, stream).next_u64(),
                    Rng::new(8, stream).next_u64(),
                ]
            })
            .collect();
        for (i, a) in firsts.iter().enumerate() {
            assert!(!firsts[i + 1..].contains(a), "streams repeat");
        }
    }

    #[test]
    fn phase_sampling_matches_the_hg_moments() {
        // HG's Legendre moments are g^l: E[μ] = g and E[μ²] = (1 + 2g²)/3; the cosine
        // lobe has E[cosθ] = 2/3.
        let n = 100_000;
        let axis = DVec3::new(0.3, -0.8, 0.52).normalize();
        let mut rng = Rng::new(1, 2);
        for g in [-0.7, 0.0, 0.3, 0.9] {
            let (mut m1, mut m2) = (0.0, 0.0);
            for _ in 0..n {
                let w = sample_hg(axis, g, &mut rng);
                assert!((w.length() - 1.0).abs() < 1e-12);
                let mu = w.dot(axis);
                m1 += mu;
                m2 += mu * mu;
            }
            let n = f64::from(n);
            assert!(
                (m1 / n - g).abs() < 5.0 / n.sqrt(),
                "g = {g}: E[μ] = {}",
                m1 / n
            );
            let expected = (1.0 + 2.0 * g * g) / 3.0;
            assert!((m2 / n - expected).abs() < 5.0 / n.sqrt(), "g = {g}");
        }
        let mean_cos: f64 = (0..n)
            .map(|_| sample_cosine(-axis, &mut rng).dot(-axis))
            .sum::<f64>()
            / f64::from(n);
        assert!((mean_cos - 2.0 / 3.0).abs() < 5.0 * 0.24 / f64::from(n).sqrt());
    }

    #[test]
    fn geometry_matches_the_scene_conventions() {
        for deg in [
            Vec3::ZERO,
            Vec3::new(10.0, 20.0, 30.0),
            Vec3::new(-170.0, 95.0, 33.0),
        ] {
            let expected = nimbus_scene::rotation_xyz_deg(deg).as_dmat3();
            assert!(rotation_f64(deg).abs_diff_eq(expected, 1e-6));
        }
        let s = scene(Vec::new(), Vec::new(), Vec::new());
        let (camera, frame) = (CameraRays::new(&s), s.camera.frame_at(0));
        for (px, py) in [(0.0, 0.0), (2.5, 1.25), (6.0, 4.0)] {
            let expected = frame.ray_direction(px as f32, py as f32, 6, 4).as_dvec3();
            assert!(camera.direction(px, py).abs_diff_eq(expected, 1e-6));
        }
    }

    /// A rotated box in front of the camera, lit obliquely, in front of an environment.
    fn lit_box(shapes: Vec<Shape>, gobo: Option<Gobo>) -> Scene {
        let m = medium(
            Vec3::new(0.1, -0.2, 0.0),
            Vec3::new(2.0, 1.5, 1.0),
            Vec3::new(20.0, 35.0, -10.0),
            0.8,
            0.4,
        );
        let light = Light::Directional {
            direction: Vec3::new(0.3, -1.0, 0.4).normalize(),
            irradiance: Vec3::new(2.0, 1.5, 1.0),
            gobo,
        };
        let env = environment(Vec3::new(0.1, 0.2, 0.3));
        scene(vec![m], shapes, vec![light, env])
    }

    #[test]
    fn single_scattering_agrees_with_the_quadrature_reference() {
        let omega = Vec3::new(0.3, -1.0, 0.4).normalize();
        // A sphere up the beam from the box shadows part of it (and is lit itself).
        let sphere = Shape::Sphere {
            center: Vec3::new(0.3, 0.0, 0.0) - 2.5 * omega,
            radius: 0.45,
            albedo: Vec3::new(0.6, 0.4, 0.2),
        };
        // A triangle gobo through the box centre (vertical-ish beam: u ≈ x).
        let gobo = Gobo {
            polygon: vec![
                Vec2::new(-0.7, -0.5),
                Vec2::new(0.6, -0.4),
                Vec2::new(0.0, 0.6),
            ],
            origin: Vec3::new(0.1, -0.2, 0.0) - 5.0 * omega,
        };
        let scenes = [
            ("box", lit_box(Vec::new(), None)),
            ("box + sphere", lit_box(vec![sphere], None)),
            ("box + gobo", lit_box(Vec::new(), Some(gobo))),
        ];
        let origin = DVec3::new(0.0, 0.2, 5.0);
        let targets = [
            DVec3::new(0.1, -0.2, 0.0),
            DVec3::new(0.5, 0.1, 0.2),
            DVec3::new(-0.4, -0.5, -0.3),
            // The sphere's upper front, lit.
            DVec3::new(0.3, 0.36, 0.0) - 2.5 * omega.as_dvec3(),
            DVec3::new(4.0, 3.0, 0.0), // a miss
        ];
        for (i, (name, s)) in scenes.iter().enumerate() {
            for (j, target) in targets.into_iter().enumerate() {
                let opts = McOptions {
                    max_bounces: 1,
                    paths: 200_000,
                    seed: (10 * i + j) as u64,
                };
                let dir = target - origin;
                let expected = quadrature::radiance(s, origin, dir, &QUADRATURE).unwrap();
                let mc = radiance_mc(s, origin, dir, &opts).unwrap();
                assert_within(&mc, expected, 4.0, &format!("{name}, towards {target}"));
            }
        }
    }

    #[test]
    fn without_albedo_higher_orders_add_nothing() {
        // Black medium and black shapes: every path stops at its first scattering, so
        // K = 3 draws the same numbers as K = 1 and gives the same bits.
        let mut s = lit_box(
            vec![Shape::Quad {
                corner: Vec3::new(-3.0, -1.5, 3.0),
                edge_u: Vec3::new(6.0, 0.0, 0.0),
                edge_v: Vec3::new(0.0, 0.0, -6.0),
                albedo: Vec3::ZERO,
            }],
            None,
        );
        let Medium::Box(m) = &mut s.media[0] else {
            unreachable!()
        };
        m.albedo = Vec3::ZERO;
        let (origin, dir) = (DVec3::new(0.0, 0.2, 5.0), DVec3::new(0.02, -0.08, -1.0));
        let one = McOptions {
            max_bounces: 1,
            paths: 20_000,
            seed: 3,
        };
        let three = McOptions {
            max_bounces: 3,
            ..one
        };
        let k1 = radiance_mc(&s, origin, dir, &one).unwrap();
        let k3 = radiance_mc(&s, origin, dir, &three).unwrap();
        assert_eq!(k1, k3);
        // Only the environment through the box remains, and not every path sees it.
        assert!(k1.mean[2] > 0.0 && k1.std_error[2] > 0.0);
    }

    #[test]
    fn radiance_grows_with_the_scattering_order() {
        // A dense, bright box over a bright floor: common random numbers make each
        // path's K = 1 estimate a prefix of its K = 2 and K = 4 ones, so the means are
        // ordered exactly; the increments must also exceed the noise.
        let mut m = medium(
            Vec3::ZERO,
            Vec3::new(2.0, 1.0, 1.5),
            Vec3::new(0.0, 30.0, 10.0),
            2.5,
            0.3,
        );
        m.albedo = Vec3::new(0.95, 0.8, 0.6);
        let floor = Shape::Quad {
            corner: Vec3::new(-4.0, -1.0, 4.0),
            edge_u: Vec3::new(8.0, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, -8.0),
            albedo: Vec3::splat(0.7),
        };
        let s = scene(
            vec![m],
            vec![floor],
            vec![sun(Vec3::new(0.4, -1.0, 0.2), Vec3::splat(3.0))],
        );
        let (origin, dir) = (DVec3::new(0.0, 0.5, 5.0), DVec3::new(0.1, -0.15, -1.0));
        let run = |k: u32| {
            let opts = McOptions {
                max_bounces: k,
                paths: 50_000,
                seed: 5,
            };
            radiance_mc(&s, origin, dir, &opts).unwrap()
        };
        let (k1, k2, k4) = (run(1), run(2), run(4));
        for c in 0..3 {
            assert!(k1.mean[c] <= k2.mean[c] && k2.mean[c] <= k4.mean[c]);
            assert!(
                k2.mean[c] - k1.mean[c] > 4.0 * k2.std_error[c],
                "channel {c}"
            );
            assert!(
                k4.mean[c] - k2.mean[c] > 4.0 * k4.std_error[c],
                "channel {c}"
            );
        }
    }

    /// ∫_a^b f by composite 5-point Gauss–Legendre on `panels` equal pieces.
    fn gauss_legendre(f: impl Fn(f64) -> f64, a: f64, b: f64, panels: u32) -> f64 {
        const NODES: [f64; 5] = [
            0.0,
            -0.538_469_310_105_683_1,
            0.538_469_310_105_683_1,
            -0.906_179_845_938_664,
            0.906_179_845_938_664,
        ];
        const WEIGHTS: [f64; 5] = [
            0.568_888_888_888_888_9,
            0.478_628_670_499_366_5,
            0.478_628_670_499_366_5,
            0.236_926_885_056_189_1,
            0.236_926_885_056_189_1,
        ];
        let h = (b - a) / f64::from(panels);
        (0..panels)
            .map(|i| {
                let mid = a + (f64::from(i) + 0.5) * h;
                (0..5)
                    .map(|j| WEIGHTS[j] * f(mid + 0.5 * h * NODES[j]))
                    .sum::<f64>()
                    * 0.5
                    * h
            })
            .sum()
    }

    #[test]
    fn double_scattering_in_a_slab_matches_a_one_dimensional_integral() {
        // A wide slab z ∈ [0, H] seen along +z from z < 0, lit by a beam travelling +z
        // (so everything is symmetric about the z axis). Order 1: the camera sees
        // backscatter, L1 = σs p(−1) E (1 − e^{−2σH})/(2σ). Order 2: with the second
        // scattering at depth z on the camera ray and the first at distance r in
        // direction u from it, μ = u·z, the first turns ω into −u (cosine −μ), the
        // second −u into −z (cosine μ); integrating r up to the slab face R(μ):
        // L2 = 2π σs² E ∫_0^H e^{−2σz} ∫_{−1}^{1} p(−μ) p(μ) (1 − e^{−σR(1+μ)})/(σ(1+μ)) dμ dz,
        // R = (H − z)/μ for μ > 0 and z/(−μ) for μ < 0.
        let (sigma, h, g) = (1.0f64, 1.0f64, 0.3f64);
        let mut m = medium(
            Vec3::new(0.0, 0.0, 0.5),
            Vec3::new(400.0, 400.0, 1.0),
            Vec3::ZERO,
            sigma as f32,
            g as f32,
        );
        m.albedo = Vec3::new(0.95, 0.6, 0.3);
        let albedo = m.albedo.as_dvec3();
        let s = scene(vec![m], Vec::new(), vec![sun(Vec3::Z, Vec3::ONE)]);

        let p = |mu: f64| phase_hg(mu, g);
        let first = p(-1.0) * (1.0 - (-2.0 * sigma * h).exp()) / (2.0 * sigma);
        // The inner integrand, with (1 − e^{−a})/(1+μ) via expm1 near μ = −1; the
        // substitution μ = ±s² (dμ = 2s ds) resolves the edge near μ = 0 where R → ∞.
        let inner = |z: f64, mu: f64| {
            let r = if mu > 0.0 { (h - z) / mu } else { z / -mu };
            p(-mu) * p(mu) * -(-sigma * r * (1.0 + mu)).exp_m1() / (sigma * (1.0 + mu))
        };
        let second = 2.0
            * PI
            * gauss_legendre(
                |z| {
                    let forward = gauss_legendre(|s| 2.0 * s * inner(z, s * s), 0.0, 1.0, 60);
                    let back = gauss_legendre(|s| 2.0 * s * inner(z, -s * s), 0.0, 1.0, 60);
                    (-2.0 * sigma * z).exp() * (forward + back)
                },
                0.0,
                h,
                60,
            );
        let expected: [f64; 3] = std::array::from_fn(|c| {
            let sigma_s = albedo[c] * sigma;
            sigma_s * first + sigma_s * sigma_s * second
        });

        let opts = McOptions {
            max_bounces: 2,
            paths: 200_000,
            seed: 9,
        };
        let mc = radiance_mc(&s, DVec3::new(0.0, 0.0, -1.0), DVec3::Z, &opts).unwrap();
        assert_within(&mc, expected, 4.0, "slab, K = 2");
        // The second order is a sizeable part of the answer, so the test can see it.
        assert!(second * albedo[0] > 0.3 * first, "{second} vs {first}");
    }

    #[test]
    fn render_agrees_with_the_quadrature_render() {
        // A wide slab fills the whole view, so every pixel is smooth; the quadrature's
        // 6×6 midpoint footprint and the MC's jittered 2×2 strata estimate the same mean.
        let m = medium(
            Vec3::ZERO,
            Vec3::new(20.0, 20.0, 1.5),
            Vec3::new(5.0, -10.0, 0.0),
            1.2,
            0.5,
        );
        let s = scene(
            vec![m],
            Vec::new(),
            vec![sun(Vec3::new(0.2, -0.5, -1.0), Vec3::new(1.0, 2.0, 3.0))],
        );
        let opts = McOptions {
            max_bounces: 1,
            paths: 2_000,
            seed: 21,
        };
        let (mean, std_error) = render_mc(&s, &opts, 2).unwrap();
        assert_eq!((mean.len(), std_error.len()), (24, 24));
        let ref_opts = ReferenceOptions {
            rel_tol: 1e-8,
            footprint_samples: 6,
        };
        let expected = quadrature::render(&s, &ref_opts).unwrap();
        for (i, e) in expected.into_iter().enumerate() {
            let mc = McEstimate {
                mean: mean[i],
                std_error: std_error[i],
            };
            assert_within(&mc, e, 4.5, &format!("pixel {i}"));
        }
        // Same seed, same image; footprint 0 is the pixel centre.
        assert_eq!(render_mc(&s, &opts, 2).unwrap().0, mean);
        let (centre, centre_se) = render_mc(&s, &opts, 0).unwrap();
        let ref_centre = ReferenceOptions {
            rel_tol: 1e-8,
            footprint_samples: 1,
        };
        for (i, e) in quadrature::render(&s, &ref_centre)
            .unwrap()
            .into_iter()
            .enumerate()
        {
            let mc = McEstimate {
                mean: centre[i],
                std_error: centre_se[i],
            };
            assert_within(&mc, e, 4.5, &format!("pixel centre {i}"));
        }
    }

    #[test]
    fn unsupported_scenes_and_options_are_errors() {
        let opts = McOptions {
            max_bounces: 2,
            paths: 16,
            seed: 0,
        };
        let ray = |s: &Scene, opts: &McOptions| {
            radiance_mc(s, DVec3::ZERO, DVec3::X, opts)
                .map(|_| ())
                .map_err(|e| format!("{e:#}"))
        };
        let point = Light::Point {
            position: Vec3::ZERO,
            intensity: Vec3::ONE,
        };
        let sphere = Light::Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
            radiance: Vec3::ONE,
        };
        let env_map = Light::Environment {
            radiance: Vec3::ONE,
            file: Some(PathBuf::from("sky.exr")),
            scale: Vec3::ONE,
        };
        for (light, words) in [
            (point, "point lights"),
            (sphere, "sphere lights"),
            (env_map, "environment maps"),
        ] {
            let message = ray(&scene(Vec::new(), Vec::new(), vec![light]), &opts).unwrap_err();
            assert!(message.contains(words), "{message}");
        }

        let mut s = scene(Vec::new(), Vec::new(), Vec::new());
        s.media.push(Medium::Grid(GridMedium {
            bounds_min: Vec3::splat(-1.0),
            bounds_max: Vec3::ONE,
            density: GridSource::ProceduralCloud {
                dims: [4, 4, 4],
                noise_seed: 1,
            },
            density_scale: 1.0,
            albedo: Vec3::ONE,
            g: 0.0,
            emission: None,
            emission_scale: Vec3::ONE,
            velocity: None,
            frames: Vec::new(),
        }));
        assert!(ray(&s, &opts).unwrap_err().contains("grid media"));

        let s = scene(Vec::new(), Vec::new(), Vec::new());
        assert!(ray(&s, &opts).is_ok());
        let zero_k = McOptions {
            max_bounces: 0,
            ..opts
        };
        assert!(ray(&s, &zero_k).is_err());
        let one_path = McOptions { paths: 1, ..opts };
        assert!(ray(&s, &one_path).is_err());
        assert!(radiance_mc(&s, DVec3::ZERO, DVec3::ZERO, &opts).is_err());
        // 16 paths do not fill 3×3 strata evenly.
        assert!(render_mc(&s, &opts, 3).is_err());
        assert!(render_mc(&s, &opts, 4).is_ok());
    }

    /// Cost of the estimator: `cargo test --release --lib reference_mc -- --ignored
    /// --nocapture`.
    #[test]
    #[ignore]
    fn time_per_million_segments() {
        let mut m = medium(
            Vec3::ZERO,
            Vec3::new(2.0, 1.0, 1.5),
            Vec3::new(0.0, 30.0, 10.0),
            2.5,
            0.3,
        );
        m.albedo = Vec3::splat(0.95);
        let floor = Shape::Quad {
            corner: Vec3::new(-4.0, -1.0, 4.0),
            edge_u: Vec3::new(8.0, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, -8.0),
            albedo: Vec3::splat(0.7),
        };
        let ball = Shape::Sphere {
            center: Vec3::new(1.5, 1.5, 0.0),
            radius: 0.4,
            albedo: Vec3::splat(0.5),
        };
        let s = scene(
            vec![m],
            vec![floor, ball],
            vec![sun(Vec3::new(0.4, -1.0, 0.2), Vec3::splat(3.0))],
        );
        let tracer = Tracer::new(&s).unwrap();
        let opts = McOptions {
            max_bounces: 8,
            paths: 400_000,
            seed: 1,
        };
        let (origin, dir) = (DVec3::new(0.0, 0.5, 5.0), DVec3::new(0.1, -0.15, -1.0));
        let start = std::time::Instant::now();
        let sums = tracer.radiance(origin, dir.normalize(), &opts);
        let seconds = start.elapsed().as_secs_f64();
        let threads = std::thread::available_parallelism().map_or(1, |t| t.get());
        println!(
            "{} paths, {} segments ({:.2} per path) in {seconds:.3} s on {threads} threads: \
             {:.3} s per million segments",
            sums.moments.n,
            sums.segments,
            sums.segments as f64 / sums.moments.n as f64,
            seconds / (sums.segments as f64 * 1e-6)
        );
    }
}
