//! The lights of a frame with their selection CDF, and an environment map with its
//! sampling tables.

use super::*;

/// An environment map as `shaders/include/envmap.glsl` reads it.
#[derive(Clone, Debug)]
pub struct GpuEnvMap {
    /// Texels (rgb radiance times `radiance · scale`, w unused), row-major from the top.
    pub texels: Vec<[f32; 4]>,
    /// The sampling tables: the marginal CDF, then the conditional rows.
    pub tables: Vec<f32>,
    /// Width and height in texels.
    pub size: [u32; 2],
    /// Mean luminance of the radiance over the sphere.
    pub mean_luminance: f32,
}

impl GpuEnvMap {
    /// Loads the map of the scene's environment light with a `file`, if there is one
    /// (the plans refuse a map beside another environment light).
    pub fn load(scene: &Scene) -> Result<Option<GpuEnvMap>> {
        let mut found = None;
        for light in &scene.lights {
            if let Light::Environment {
                radiance,
                scale,
                file: Some(file),
                ..
            } = light
            {
                let map = nimbus_scene::EnvMap::load_exr(file, *radiance * *scale)?;
                let sampler = nimbus_scene::EnvSampler::new(&map);
                // Mean radiance luminance over the sphere: integral() is the mean of
                // luminance x sin(theta) over the texel grid, which covers 2 pi^2 in
                // (phi, theta); the sphere is 4 pi.
                let mean_luminance = (sampler.integral() * 2.0 * std::f64::consts::PI.powi(2)
                    / (4.0 * std::f64::consts::PI)) as f32;
                let (marginal, conditional) = sampler.to_gpu_tables();
                found = Some(GpuEnvMap {
                    texels: map.texels.iter().map(|t| [t[0], t[1], t[2], 0.0]).collect(),
                    tables: [marginal, conditional].concat(),
                    size: [map.width, map.height],
                    mean_luminance,
                });
            }
        }
        Ok(found)
    }
}

/// The analytic lights of one frame with their selection CDF (`select_cdf`), the
/// probability that next-event estimation picks the environment, and the constant
/// environment radiance.
pub struct LightSet {
    pub lights: Vec<LightGpu>,
    /// The gobos' half-planes (`LightGpu::gobo_first_plane` indexes them). They depend on
    /// the polygons only, which do not animate, so every frame's set has the same ones.
    pub gobo_planes: Vec<[f32; 4]>,
    pub env_select: f32,
    pub env_radiance: Vec3,
}

impl LightSet {
    /// Lights are selected in proportion to the power they bring to the medium's
    /// bounding sphere (radius R): directional E·πR², point 4π·I, sphere 4π²r²·L,
    /// environment 4π²R²·L (luminance of each; `env_map_luminance` replaces the constant
    /// radiance's when the environment has a map), and the emitting shapes, if
    /// `area_power` (their total π·A·L, [`EmitterTable`](crate::shader_data::EmitterTable)) is positive,
    /// as one `LIGHT_AREA` light after the analytic ones.
    pub fn build(
        scene_lights: &[Light],
        radius: f32,
        env_map_luminance: Option<f32>,
        area_power: f64,
    ) -> LightSet {
        let pi = std::f32::consts::PI;
        let mut lights = Vec::new();
        let mut weights = Vec::new();
        let mut env_radiance = Vec3::ZERO;
        let mut gobo_planes = Vec::new();
        for light in scene_lights {
            // The gobo's origin, (u, v) axes, first half-plane and half-plane count.
            let mut gobo_fields = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, 0, 0);
            let (p0, kind, power_rgb, radius_l, weight) = match light {
                Light::Directional {
                    direction,
                    irradiance,
                    gobo,
                } => {
                    if let Some(gobo) = gobo {
                        let (u, v) = Gobo::basis(*direction);
                        let first = gobo_planes.len() as u32;
                        gobo_planes.extend(gobo_half_planes(&gobo.polygon));
                        gobo_fields = (gobo.origin, u, v, first, gobo.polygon.len() as u32);
                    }
                    (
                        *direction,
                        LIGHT_DIRECTIONAL,
                        *irradiance,
                        0.0,
                        luminance(*irradiance) * pi * radius * radius,
                    )
                }
                Light::Point {
                    position,
                    intensity,
                } => (
                    *position,
                    LIGHT_POINT,
                    *intensity,
                    0.0,
                    luminance(*intensity) * 4.0 * pi,
                ),
                Light::Sphere {
                    center,
                    radius: r,
                    radiance,
                } => (
                    *center,
                    LIGHT_SPHERE,
                    *radiance,
                    *r,
                    luminance(*radiance) * 4.0 * pi * pi * r * r,
                ),
                Light::Environment {
                    radiance,
                    scale,
                    file,
                    ..
                } => {
                    if file.is_none() {
                        env_radiance += *radiance * *scale;
                    }
                    continue;
                }
            };
            lights.push(LightGpu {
                direction_or_position: p0.to_array(),
                r#type: kind,
                irradiance: power_rgb.to_array(),
                radius: radius_l,
                gobo_origin: gobo_fields.0.to_array(),
                gobo_plane_count: gobo_fields.4,
                gobo_u: gobo_fields.1.to_array(),
                gobo_first_plane: gobo_fields.3,
                gobo_v: gobo_fields.2.to_array(),
                select_cdf: 0.0,
                group: 0,
                _pad0: 0,
                _pad1: 0,
                _pad2: 0,
            });
            weights.push(weight.max(0.0));
        }
        if area_power > 0.0 {
            lights.push(LightGpu {
                direction_or_position: [0.0; 3],
                r#type: LIGHT_AREA,
                irradiance: [0.0; 3],
                radius: 0.0,
                gobo_origin: [0.0; 3],
                gobo_plane_count: 0,
                gobo_u: [0.0; 3],
                gobo_first_plane: 0,
                gobo_v: [0.0; 3],
                select_cdf: 0.0,
                group: 0,
                _pad0: 0,
                _pad1: 0,
                _pad2: 0,
            });
            weights.push(area_power as f32);
        }
        let env_luminance = env_map_luminance.unwrap_or_else(|| luminance(env_radiance));
        let env_weight = env_luminance * 4.0 * pi * pi * radius * radius;
        let total: f32 = weights.iter().sum::<f32>() + env_weight;
        let mut env_select = 0.0;
        if total > 0.0 {
            env_select = env_weight / total;
            let mut cdf = 0.0;
            for (light, w) in lights.iter_mut().zip(&weights) {
                cdf += w / total;
                light.select_cdf = cdf;
            }
        }
        LightSet {
            lights,
            gobo_planes,
            env_select,
            env_radiance,
        }
    }
}
