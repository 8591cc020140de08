//! Directional lights and environments in f64, and the lights of the box oracles'
//! scenes.

use anyhow::{bail, Context};
use glam::{DVec3, Vec3};
use nimbus_scene::{EnvMap, EnvRotation, EnvSampler, Gobo, Light, Scene};

use super::geometry::{normalized, GoboF64};

/// A directional light.
pub(crate) struct Sun {
    /// Unit travel direction ω.
    pub(crate) omega: DVec3,
    pub(crate) irradiance: DVec3,
    pub(crate) gobo: Option<GoboF64>,
}

impl Sun {
    /// The light travelling along `direction` (not zero), with its optional gobo.
    pub(crate) fn new(
        direction: Vec3,
        irradiance: Vec3,
        gobo: Option<&Gobo>,
    ) -> anyhow::Result<Self> {
        Ok(Self {
            omega: normalized(direction.as_dvec3(), "light direction")?,
            irradiance: irradiance.as_dvec3(),
            gobo: gobo.map(|g| GoboF64::new(direction, g)),
        })
    }
}

/// An environment light: constant radiance, or an EXR map (times `radiance · scale`)
/// with its sampler, turned about +Y by `rotation` (the light's `rotation_deg`).
pub(crate) enum Environment {
    Constant(DVec3),
    Map {
        map: EnvMap,
        sampler: EnvSampler,
        rotation: EnvRotation,
    },
}

impl Environment {
    /// The map light `map` turned by `rotation_deg`, with its sampler.
    pub(crate) fn map(map: EnvMap, rotation_deg: f32) -> Self {
        let sampler = EnvSampler::new(&map);
        Self::Map {
            map,
            sampler,
            rotation: EnvRotation::from_degrees(f64::from(rotation_deg)),
        }
    }

    /// The radiance arriving from direction `d` (towards the environment): the map's
    /// nearest texel (`EnvMap::lookup`, the scene format's mapping) of d turned back
    /// into the map.
    pub(crate) fn radiance(&self, d: DVec3) -> DVec3 {
        match self {
            Self::Constant(l) => *l,
            Self::Map { map, rotation, .. } => {
                let [r, g, b] = map.lookup(rotation.world_to_map(d));
                DVec3::new(f64::from(r), f64::from(g), f64::from(b))
            }
        }
    }

    /// What a camera ray escaping along `d` sees: the map interpolated between texel
    /// centres (`EnvMap::lookup_bilinear`), as the renderer's background; the light
    /// reaching the scene is [`Environment::radiance`].
    pub(crate) fn background(&self, d: DVec3) -> DVec3 {
        match self {
            Self::Constant(l) => *l,
            Self::Map { map, rotation, .. } => {
                let [r, g, b] = map.lookup_bilinear(rotation.world_to_map(d));
                DVec3::new(f64::from(r), f64::from(g), f64::from(b))
            }
        }
    }

    /// A direction drawn from the map's importance sampler, turned into the world, and
    /// its solid-angle pdf (a turn keeps solid angle); `None` for a constant
    /// environment.
    pub(crate) fn sample_map(&self, u: [f64; 2]) -> Option<(DVec3, f64)> {
        match self {
            Self::Constant(_) => None,
            Self::Map {
                sampler, rotation, ..
            } => {
                let (d, pdf) = sampler.sample(u);
                Some((rotation.map_to_world(d), pdf))
            }
        }
    }

    /// Whether the environment is black everywhere (then it lights nothing).
    pub(crate) fn is_black(&self) -> bool {
        match self {
            Self::Constant(l) => *l == DVec3::ZERO,
            Self::Map { map, .. } => map.texels.iter().flatten().all(|&c| c == 0.0),
        }
    }
}

/// The lights of a scene that may only have directional and environment lights: the
/// suns, and the environment (the sum of the constant ones, or the one map, loaded).
/// Any other light, or a map beside another environment light, is an error that names
/// `what`, the oracle.
pub(crate) fn suns_and_environment(
    scene: &Scene,
    what: &str,
) -> anyhow::Result<(Vec<Sun>, Environment)> {
    let source = scene.source.display();
    let mut suns = Vec::new();
    let mut constant = DVec3::ZERO;
    let mut map = None;
    let mut rotation = 0.0;
    let mut environments = 0;
    for (i, light) in scene.lights.iter().enumerate() {
        match light {
            Light::Directional {
                direction,
                irradiance,
                gobo,
            } => suns.push(Sun::new(*direction, *irradiance, gobo.as_ref())?),
            Light::Environment {
                radiance,
                file,
                scale,
                rotation_deg,
            } => {
                environments += 1;
                match file {
                    None => constant += radiance.as_dvec3() * scale.as_dvec3(),
                    Some(f) => {
                        let loaded = EnvMap::load_exr(f, *radiance * *scale)
                            .with_context(|| format!("{source}: light {}", i + 1))?;
                        map = Some(loaded);
                        rotation = *rotation_deg;
                    }
                }
            }
            Light::Point { .. } => {
                bail!("{source}: light {i}: point lights are not supported by the {what}")
            }
            Light::Sphere { .. } => {
                bail!("{source}: light {i}: sphere lights are not supported by the {what}")
            }
        }
    }
    let environment = match map {
        Some(_) if environments > 1 => bail!(
            "{source}: an environment map cannot be combined with another environment light \
             in the {what}"
        ),
        Some(map) => Environment::map(map, rotation),
        None => Environment::Constant(constant),
    };
    Ok((suns, environment))
}

/// The lights of a scene that may only have directional lights and constant
/// environment lights: the suns, and the summed environment radiance (`radiance ·
/// scale`). Any other light is an error that names `what`, the oracle.
pub(crate) fn suns_and_sky(scene: &Scene, what: &str) -> anyhow::Result<(Vec<Sun>, DVec3)> {
    let source = scene.source.display();
    let mut suns = Vec::new();
    let mut environment = DVec3::ZERO;
    for (i, light) in scene.lights.iter().enumerate() {
        match light {
            Light::Directional {
                direction,
                irradiance,
                gobo,
            } => suns.push(Sun::new(*direction, *irradiance, gobo.as_ref())?),
            Light::Environment {
                radiance,
                file: None,
                scale,
                ..
            } => environment += radiance.as_dvec3() * scale.as_dvec3(),
            Light::Environment { file: Some(f), .. } => bail!(
                "{source}: light {i}: environment maps ({}) are not supported by the {what} \
                 (constant radiance only)",
                f.display()
            ),
            Light::Point { .. } => {
                bail!("{source}: light {i}: point lights are not supported by the {what}")
            }
            Light::Sphere { .. } => {
                bail!("{source}: light {i}: sphere lights are not supported by the {what}")
            }
        }
    }
    Ok((suns, environment))
}
