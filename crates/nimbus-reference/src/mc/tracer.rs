//! The analog path tracer of the box Monte Carlo oracle.

use std::f64::consts::PI;

use anyhow::bail;
use glam::DVec3;
use nimbus_scene::Scene;

use super::{McOptions, WHAT};
use crate::common::estimate::{radiance_paths, McEstimate, Moments, PathSums};
use crate::common::geometry::{homogeneous, spans_by_entry, Region};
use crate::common::lights::{suns_and_environment, Environment, Sun};
use crate::common::rng::Rng;
use crate::common::sampling::{henyey_greenstein, sample_cosine, sample_hg};
use crate::common::surface::{leave_surface, nearest_surface, Surface};

/// Paths per work item of [`Tracer::radiance`] (the unit shared among threads).
const CHUNK_PATHS: u32 = 4096;

struct BoxMediumF64 {
    bounds: Region,
    sigma_t: f64,
    albedo: DVec3,
    g: f64,
}

/// The scene in f64, checked against what the estimator models.
pub(super) struct Tracer {
    media: Vec<BoxMediumF64>,
    surfaces: Vec<Surface>,
    suns: Vec<Sun>,
    environment: Environment,
    /// The environment is not black: paths go on after their K-th scattering to see
    /// whether they escape.
    sky: bool,
}

/// Running moments over paths, with the number of free-flight rays traced (camera ray
/// plus one per continued scattering).
#[derive(Clone, Copy, Default)]
pub(super) struct Sums {
    pub(super) moments: Moments,
    pub(super) segments: u64,
}

impl Sums {
    pub(super) fn add(&mut self, l: DVec3, segments: u32) {
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
    pub(super) fn new(scene: &Scene) -> anyhow::Result<Self> {
        let source = scene.source.display();
        let mut media = Vec::new();
        for (i, medium) in scene.media.iter().enumerate() {
            let (Some(bounds), Some((sigma_t, albedo, g))) =
                (Region::of(medium), homogeneous(medium))
            else {
                bail!(
                    "{source}: medium {i}: grid media are not supported by the Monte Carlo \
                     reference (homogeneous boxes and convex media only)"
                );
            };
            media.push(BoxMediumF64 {
                bounds,
                sigma_t,
                albedo,
                g,
            });
        }

        let surfaces = scene.shapes.iter().map(Surface::from_shape).collect();

        let (suns, environment) = suns_and_environment(scene, WHAT)?;
        let sky = !environment.is_black();
        Ok(Self {
            media,
            surfaces,
            suns,
            environment,
            sky,
        })
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
        for (t0, t1, i) in spans_by_entry(&self.media, |m| m.bounds.clip(o, d, 0.0, t_max)) {
            let sigma_t = self.media[i].sigma_t;
            if sigma_t <= 0.0 {
                continue;
            }
            let t = t0 + rng.exponential(sigma_t);
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
                let (a, b) = m.bounds.clip(x, towards, 0.0, f64::INFINITY)?;
                Some(m.sigma_t * (b - a))
            })
            .sum();
        sun.irradiance * (-optical_depth).exp()
    }

    /// One path from o along unit d with at most `k_max` scatterings: its radiance
    /// estimate and the number of free-flight rays it traced. After the K-th scattering
    /// a path under a non-black environment traces one more ray, which counts only if it
    /// escapes (the environment's light scattered K times).
    pub(super) fn trace_path(&self, o: DVec3, d: DVec3, k_max: u32, rng: &mut Rng) -> (DVec3, u32) {
        let (mut x, mut d) = (o, d);
        let mut beta = DVec3::ONE;
        let mut radiance = DVec3::ZERO;
        let mut scatterings = 0;
        let mut segments = 0;
        loop {
            segments += 1;
            let surface = nearest_surface(&self.surfaces, x, d);
            let t_surface = surface.map_or(f64::INFINITY, |(t, _, _)| t);
            if let Some((t, i)) = self.sample_collision(x, d, t_surface, rng) {
                // A (K+1)-th scattering carries nothing more.
                if scatterings == k_max {
                    break;
                }
                // Medium collision: weight σs/σt, NEE with the phase of ω → −d.
                let medium = &self.media[i];
                let p = x + t * d;
                beta *= medium.albedo;
                for sun in &self.suns {
                    let phase = henyey_greenstein(sun.omega.dot(-d), medium.g);
                    radiance += beta * phase * self.sunlight_at(p, sun);
                }
                scatterings += 1;
                if beta == DVec3::ZERO || (scatterings == k_max && !self.sky) {
                    break;
                }
                d = sample_hg(d, medium.g, rng);
                x = p;
            } else if let Some((t, normal, albedo)) = surface {
                if scatterings == k_max {
                    break;
                }
                // Lambertian reflection: weight albedo, NEE with the cosine at the normal
                // facing the incoming ray.
                let (p, n) = leave_surface(x + t * d, normal, d);
                beta *= albedo;
                for sun in &self.suns {
                    let cosine = n.dot(-sun.omega).max(0.0);
                    if cosine > 0.0 {
                        radiance += beta / PI * cosine * self.sunlight_at(p, sun);
                    }
                }
                scatterings += 1;
                if beta == DVec3::ZERO || (scatterings == k_max && !self.sky) {
                    break;
                }
                d = sample_cosine(n, rng);
                x = p;
            } else {
                // Escape: the environment, seen by the camera ray (its background, the
                // map interpolated) or arriving after 1..=K scatterings.
                radiance += beta
                    * if scatterings == 0 {
                        self.environment.background(d)
                    } else {
                        self.environment.radiance(d)
                    };
                break;
            }
        }
        (radiance, segments)
    }

    /// `opts.paths` paths along one camera ray, in chunks shared among threads; path i
    /// uses stream i of the seed, and chunks are merged in order.
    pub(super) fn radiance(&self, o: DVec3, d: DVec3, opts: &McOptions) -> Sums {
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
