//! Directional lights in f64, and the lights of the box oracles' scenes.

use anyhow::bail;
use glam::{DVec3, Vec3};
use nimbus_scene::{Gobo, Light, Scene};

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
