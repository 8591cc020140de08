//! The plan of scenes without grid media: the crepuscular pass renders box media,
//! shapes and the background under directional and environment lights.

use anyhow::{bail, Result};
use nimbus_scene::{BoxEstimator, Light, Medium, Scene};

use super::{
    CrepuscularFeatures, CrepuscularPlan, Decision, Integrator, MAX_BOX_MEDIA,
    MAX_DIRECTIONAL_LIGHTS,
};

/// The crepuscular plan of a scene without grid media and its decision rows.
/// `samples_along_ray` overrides the scene's `[integrator] box_samples`.
pub(super) fn build(
    scene: &Scene,
    samples_along_ray: Option<u32>,
) -> Result<(Integrator, Vec<Decision>)> {
    let file = scene.source.display();

    // Reject what the crepuscular pass does not render, naming where it is.
    if let Some(&(a, b)) = scene.overlaps.first() {
        bail!(
            "{file}: [[medium]] #{} and [[medium]] #{} overlap: the crepuscular pass takes \
             disjoint box media only (its analytic single scattering is per box); the \
             baseline path tracer renders overlapping media beside a grid medium \
             ([integrator] volume = \"baseline\")",
            a + 1,
            b + 1
        );
    }
    for (i, light) in scene.lights.iter().enumerate() {
        let kind = match light {
            Light::Directional { .. } | Light::Environment { .. } => continue,
            Light::Point { .. } => "type = \"point\"",
            Light::Sphere { .. } => "type = \"sphere\"",
        };
        bail!(
            "{file}: [[light]] #{} ({kind}): not supported yet by the crepuscular pass \
             (directional and environment lights are)",
            i + 1
        );
    }
    if let Some(i) = scene.shapes.iter().position(|s| s.emits()) {
        bail!(
            "{file}: [[shape]] #{} (type = \"{}\"): field `emission`: emitting shapes (area \
             lights) are not supported yet by the crepuscular pass; the baseline path tracer \
             renders them beside a grid medium ([integrator] volume = \"baseline\")",
            i + 1,
            scene.shapes[i].type_name()
        );
    }
    let env_map = super::environment_map(scene)?;
    let integrator = &scene.integrator;
    let box_media = scene.media.len();
    if box_media > MAX_BOX_MEDIA {
        bail!(
            "{file}: [[medium]]: {box_media} box media, the crepuscular pass takes at most {MAX_BOX_MEDIA}"
        );
    }
    let directional_lights = scene
        .lights
        .iter()
        .filter(|l| matches!(l, Light::Directional { .. }))
        .count();
    if directional_lights > MAX_DIRECTIONAL_LIGHTS {
        bail!(
            "{file}: [[light]]: {directional_lights} directional lights, the crepuscular pass takes at most {MAX_DIRECTIONAL_LIGHTS}"
        );
    }
    let samples_along_ray = samples_along_ray.unwrap_or(integrator.box_samples);
    if samples_along_ray == 0 || samples_along_ray > 65_536 {
        bail!("samples along a camera ray must be in 1..=65536, got {samples_along_ray}");
    }

    let media = scene.media.len();
    let shapes = scene.shapes.len();
    let directional = directional_lights;
    let gobos = scene
        .lights
        .iter()
        .filter(|l| matches!(l, Light::Directional { gobo: Some(_), .. }))
        .count();
    let env = scene
        .lights
        .iter()
        .any(|l| matches!(l, Light::Environment { .. }));

    let convex = scene
        .media
        .iter()
        .filter(|m| matches!(m, Medium::Convex(_)))
        .count();
    let max_pieces = max_pieces(scene);
    let features = CrepuscularFeatures {
        has_media: media > 0,
        has_convex: convex > 0,
        max_pieces,
        has_shapes: shapes > 0,
        has_meshes: scene
            .shapes
            .iter()
            .any(|s| matches!(s, nimbus_scene::Shape::Mesh { .. })),
        has_gobos: gobos > 0,
        has_env: env,
        has_env_map: env_map.is_some(),
        pixel_jitter: scene.render.pixel_jitter,
    };
    let max_bounces = integrator.max_bounces;
    let estimator = integrator.box_estimator;
    let mut decisions = vec![Decision {
        name: "pass crepuscular",
        enabled: true,
        reason: if media > 0 {
            format!(
                "{media} box medium(s), {directional} directional light(s): {} by {} \
                 with {samples_along_ray} samples along each path segment",
                if max_bounces == 1 {
                    "single scattering".to_string()
                } else {
                    format!("scattering orders 1..={max_bounces} (path tracing)")
                },
                estimator.name()
            )
        } else {
            format!("no media: direct lighting of {shapes} shape(s) and the background only")
        },
    }];
    decisions.push(Decision {
        name: "  SC_HAS_MEDIA",
        enabled: features.has_media,
        reason: if features.has_media {
            format!("{media} box medium(s) scatter and attenuate")
        } else {
            "no media: in-scattering and transmittance compiled out".into()
        },
    });
    decisions.push(Decision {
        name: "  SC_HAS_CONVEX",
        enabled: features.has_convex,
        reason: if features.has_convex {
            format!(
                "{convex} convex medium(s): spans clipped by their planes, up to {max_pieces} \
                 trapezoid pieces per segment (SC_MAX_PIECES)"
            )
        } else {
            "only boxes: plane clipping compiled out, 3 trapezoid pieces per segment".into()
        },
    });
    decisions.push(Decision {
        name: "  SC_HAS_SHAPES",
        enabled: features.has_shapes,
        reason: if features.has_shapes {
            format!("{shapes} shape(s) occlude light and reflect it (Lambertian)")
        } else {
            "no shapes: shadow rays compiled out".into()
        },
    });
    decisions.push(super::meshes_decision(scene));
    decisions.push(Decision {
        name: "  SC_HAS_GOBOS",
        enabled: features.has_gobos,
        reason: if features.has_gobos {
            format!("{gobos} light(s) masked by a gobo")
        } else {
            "no light has a gobo".into()
        },
    });
    let lit = match (media > 0, shapes > 0) {
        (true, true) => "the media and the surfaces",
        (true, false) => "the media",
        (false, true) => "the surfaces",
        (false, false) => "nothing",
    };
    decisions.push(Decision {
        name: "  SC_HAS_ENV",
        enabled: features.has_env,
        reason: if features.has_env {
            format!(
                "{} environment: seen by camera rays, lights {lit} by next-event estimation \
                 ({samples_along_ray} samples along each in-medium stretch and at each surface hit)",
                if features.has_env_map { "map" } else { "constant" }
            )
        } else {
            "no environment: escaping rays see black, environment lighting compiled out".into()
        },
    });
    decisions.push(Decision {
        name: "  SC_HAS_ENV_MAP",
        enabled: features.has_env_map,
        reason: if features.has_env_map {
            "environment map: directions by a one-sample mixture of the map's importance \
             sampling and the phase function or cosine lobe (balance heuristic)"
                .into()
        } else if features.has_env {
            "constant environment: directions by the phase function or cosine lobe alone".into()
        } else {
            "no environment map".into()
        },
    });
    decisions.push(Decision {
        name: "  SC_MAX_BOUNCES",
        enabled: max_bounces > 1,
        reason: if max_bounces > 1 {
            format!("K = {max_bounces}: paths continue by free-flight collisions and Lambertian reflections")
        } else {
            "K = 1: single-scattering variant, path continuation compiled out".into()
        },
    });
    decisions.push(Decision {
        name: "  SC_PIXEL_JITTER",
        enabled: features.pixel_jitter,
        reason: if features.pixel_jitter {
            "rays jittered over the pixel footprint (box filter)".into()
        } else {
            "[render] pixel_jitter = false: every ray through the pixel centre".into()
        },
    });
    if estimator == BoxEstimator::Me {
        let size = integrator.moment_map_size;
        decisions.push(Decision {
            name: "  pass moments",
            enabled: features.has_shapes && features.has_media,
            reason: if features.has_shapes && features.has_media {
                format!(
                    "ME: a {size}x{size} moment shadow map (4 moments, mip chain) per directional \
                     light over the media's footprint, traced through {shapes} shape(s) once \
                     (lights and shapes are static); {samples_along_ray} lookups along each segment"
                )
            } else {
                "ME without shapes: every visibility ratio is 1, no moment map is made".into()
            },
        });
    }
    let plan = CrepuscularPlan {
        estimator,
        samples_along_ray,
        moment_map_size: integrator.moment_map_size,
        max_bounces,
        features,
    };
    Ok((Integrator::Crepuscular(plan), decisions))
}

/// The most pieces a camera segment can have in any medium under any directional light:
/// the light-facing planes of a convex medium (a plane within 1e-4 of parallel to the
/// light counts, so that rounding never makes the shader see more), 3 for a box.
pub fn max_pieces(scene: &Scene) -> u32 {
    let mut most = 3u32;
    for medium in &scene.media {
        let Medium::Convex(c) = medium else {
            continue;
        };
        for light in &scene.lights {
            let Light::Directional { direction, .. } = light else {
                continue;
            };
            let omega = direction.as_dvec3();
            let facing = c
                .planes
                .iter()
                .filter(|p| {
                    let n = glam::DVec3::new(p[0].into(), p[1].into(), p[2].into());
                    -n.dot(omega) > -1e-4
                })
                .count();
            most = most.max(facing as u32);
        }
    }
    most
}
