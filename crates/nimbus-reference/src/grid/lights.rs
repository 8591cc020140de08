//! The lights of the grid oracle and their next-event-estimation samples.

use std::f64::consts::PI;

use anyhow::{bail, Context};
use glam::DVec3;
use nimbus_scene::{EnvMap, Light, Scene};

use super::area::AreaLights;
use crate::common::geometry::hit_sphere;
use crate::common::lights::{Environment, Sun};
use crate::common::rng::Rng;
use crate::common::sampling::{direction_around, sample_sphere};

/// A light of the scene in f64.
pub(super) enum LightF64 {
    Directional(Sun),
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
    /// Every emitting shape at once ([`AreaLights`]).
    Area(AreaLights),
}

/// One NEE sample: unit direction towards the light, distance to it (∞ for distant
/// lights), the light's contribution divided by the sampling pdf, and the index of
/// the sphere light sampled (not an occluder of itself).
pub(super) struct LightSample {
    pub(super) l: DVec3,
    pub(super) distance: f64,
    pub(super) weight: DVec3,
    pub(super) sphere: Option<usize>,
}

impl LightF64 {
    /// One NEE sample of this light, light `i` of the scene, from x (before
    /// visibility), or None when it contributes nothing.
    pub(super) fn sample(&self, i: usize, x: DVec3, rng: &mut Rng) -> Option<LightSample> {
        match self {
            LightF64::Directional(sun) => {
                if sun.gobo.as_ref().is_some_and(|g| !g.lets_through(x)) {
                    return None;
                }
                Some(LightSample {
                    l: -sun.omega,
                    distance: f64::INFINITY,
                    weight: sun.irradiance,
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
                    Environment::Map { .. } => env
                        .sample_map([rng.uniform(), rng.uniform()])
                        .unwrap_or((DVec3::Y, 0.0)),
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
            LightF64::Area(area) => {
                let s = area.sample(x, rng)?;
                // The point lies on a shape: shapes block only short of it.
                Some(LightSample {
                    l: s.l,
                    distance: s.distance * (1.0 - AREA_LIGHT_CLEARANCE),
                    weight: s.weight,
                    sphere: None,
                })
            }
        }
    }
}

/// Relative distance short of a sampled point on an emitting shape within which shapes
/// do not block it (the shape itself, met again within rounding; mesh hits are f32).
const AREA_LIGHT_CLEARANCE: f64 = 1e-5;

/// The scene's lights in f64, with the environment maps already loaded (light index,
/// map), then the emitting shapes as one more light if any shape emits.
pub(super) fn build_lights(
    scene: &Scene,
    mut maps: Vec<(usize, EnvMap)>,
) -> anyhow::Result<Vec<LightF64>> {
    let source = scene.source.display();
    let mut lights = Vec::new();
    for (i, light) in scene.lights.iter().enumerate() {
        lights.push(match light {
            Light::Directional {
                direction,
                irradiance,
                gobo,
            } => LightF64::Directional(Sun::new(*direction, *irradiance, gobo.as_ref())?),
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
                ..
            } => LightF64::Environment(Environment::Constant(
                radiance.as_dvec3() * scale.as_dvec3(),
            )),
            Light::Environment {
                file: Some(f),
                rotation_deg,
                ..
            } => {
                let Some(k) = maps.iter().position(|(j, _)| *j == i) else {
                    bail!("{source}: light {}: {} not loaded", i + 1, f.display());
                };
                let (_, map) = maps.swap_remove(k);
                LightF64::Environment(Environment::map(map, *rotation_deg))
            }
        });
    }
    lights.extend(AreaLights::new(scene).map(LightF64::Area));
    Ok(lights)
}

/// Loads the map of every environment light that has one: (light index, map).
pub(super) fn load_env_maps(scene: &Scene) -> anyhow::Result<Vec<(usize, EnvMap)>> {
    let source = scene.source.display();
    let mut environments = Vec::new();
    for (i, light) in scene.lights.iter().enumerate() {
        if let Light::Environment {
            radiance,
            file: Some(file),
            scale,
            ..
        } = light
        {
            let map = EnvMap::load_exr(file, *radiance * *scale)
                .with_context(|| format!("{source}: light {}", i + 1))?;
            environments.push((i, map));
        }
    }
    Ok(environments)
}
