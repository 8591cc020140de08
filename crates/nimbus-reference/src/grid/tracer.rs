//! The path tracer of the grid oracle.

use std::f64::consts::PI;

use anyhow::ensure;
use glam::DVec3;
use nimbus_scene::{EnvMap, Scene};

use super::lights::{build_lights, load_env_maps, LightF64};
use super::media::{load_grids, LoadedGrid, MediumF64, MediumKind};
use super::GridOptions;
use crate::common::estimate::{radiance_paths, Moments};
use crate::common::geometry::{hit_sphere, spans_by_entry};
use crate::common::rng::Rng;
use crate::common::sampling::{henyey_greenstein, sample_cosine, sample_hg};
use crate::common::surface::{leave_surface, Surface};

/// Paths per work item of [`Tracer::radiance`].
const CHUNK_PATHS: u32 = 1024;

pub(super) struct Tracer {
    pub(super) media: Vec<MediumF64>,
    surfaces: Vec<Surface>,
    lights: Vec<LightF64>,
}

impl Tracer {
    /// Loads every grid and environment map (once) and builds the tracer.
    pub(super) fn new(scene: &Scene) -> anyhow::Result<Self> {
        Self::with_grids(scene, load_grids(scene)?, load_env_maps(scene)?)
    }

    /// Builds the tracer from grids already loaded (`grids[i]` for medium i, `None` for
    /// boxes) and environment maps already loaded (light index, map).
    pub(super) fn with_grids(
        scene: &Scene,
        grids: Vec<Option<LoadedGrid>>,
        maps: Vec<(usize, EnvMap)>,
    ) -> anyhow::Result<Self> {
        let source = scene.source.display();
        ensure!(grids.len() == scene.media.len(), "grid count mismatch");
        let media = scene
            .media
            .iter()
            .zip(grids)
            .enumerate()
            .map(|(i, (medium, loaded))| {
                MediumF64::new(medium, loaded, &format!("{source}: medium {i}"))
            })
            .collect::<anyhow::Result<_>>()?;
        Ok(Self {
            media,
            surfaces: scene.shapes.iter().map(Surface::from_shape).collect(),
            lights: build_lights(scene, maps)?,
        })
    }

    /// The nearest shape hit (t, normal, albedo) or sphere-light hit (t, radiance) of
    /// o + t·d, t > 0.
    fn nearest_hit(&self, o: DVec3, d: DVec3) -> Option<(f64, Hit)> {
        let mut best = None;
        for surface in &self.surfaces {
            if let Some((t, n)) = surface.hit(o, d) {
                if best.as_ref().is_none_or(|(tb, _)| t < *tb) {
                    let emitted = surface.emitted(o + t * d, n, d);
                    best = Some((t, Hit::Surface(n, surface.albedo, emitted)));
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
        // Each medium's first collision, independently; the nearest wins. For disjoint
        // media that is the first medium entered that collides; where media overlap, it
        // picks a medium in proportion to its σt there (extinctions add). Each later
        // medium is sampled only up to the nearest so far (memoryless).
        let mut best: Option<(f64, usize)> = None;
        for (t0, t1, i) in spans_by_entry(&self.media, |m| m.span(o, d, t_max)) {
            let t1 = best.map_or(t1, |(t, _)| t1.min(t));
            if t1 <= t0 {
                continue;
            }
            if let Some(t) = self.media[i].sample_collision(o, d, t0, t1, rng) {
                best = Some((t, i));
            }
        }
        best
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

    /// Σ over lights of one NEE sample: weight · f(l) · V · T, with `f` the phase
    /// function or BRDF·cosine of the direction towards the light.
    fn direct(&self, x: DVec3, f: impl Fn(DVec3) -> f64, rng: &mut Rng) -> DVec3 {
        let mut sum = DVec3::ZERO;
        for i in 0..self.lights.len() {
            let Some(s) = self.lights[i].sample(i, x, rng) else {
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
    pub(super) fn trace_path(&self, o: DVec3, d: DVec3, k_max: u32, rng: &mut Rng) -> DVec3 {
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
                let albedo = match &medium.kind {
                    MediumKind::Grid(grid) => {
                        let albedo = medium.albedo * grid.albedo_factor(p);
                        if grid.emits() {
                            radiance += beta * (DVec3::ONE - albedo) * grid.emission(p);
                        }
                        albedo
                    }
                    MediumKind::Homogeneous { .. } => medium.albedo,
                };
                beta *= albedo;
                scatterings += 1;
                if beta == DVec3::ZERO {
                    break;
                }
                let g = medium.g;
                radiance += beta * self.direct(p, |l| henyey_greenstein(l.dot(d), g), rng);
                if scatterings == k_max {
                    break;
                }
                d = sample_hg(d, g, rng);
                x = p;
            } else {
                match hit {
                    Some((t, Hit::Surface(normal, albedo, emitted))) => {
                        if scatterings == 0 {
                            radiance += beta * emitted;
                        }
                        let (p, n) = leave_surface(x + t * d, normal, d);
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
                                    radiance += beta * env.background(d);
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
    pub(super) fn radiance(&self, o: DVec3, d: DVec3, opts: &GridOptions) -> Moments {
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

/// What a ray hits first.
enum Hit {
    /// A shape: unit normal (either side), albedo, and the radiance it emits back along
    /// the ray.
    Surface(DVec3, DVec3, DVec3),
    /// A sphere light's radiance.
    Emitter(DVec3),
}
