//! The render plan: which passes and shader features a scene needs, and why.
//!
//! A scene decides what runs: a pass the scene does not need is not dispatched, and a
//! shader feature it does not use is compiled out through a specialization constant.
//! Features of the scene format that no pass renders yet are errors here, naming the
//! scene file and the table, never silently skipped.

use std::fmt::Write as _;

use anyhow::{bail, Result};
use nimbus_scene::{BoxEstimator, Light, Medium, Scene};

/// Most box media the crepuscular pass takes (`MAX_MEDIA` in crepuscular.comp).
pub const MAX_BOX_MEDIA: usize = 16;
/// Most directional lights the crepuscular pass takes (`MAX_LIGHTS` in crepuscular.comp).
pub const MAX_DIRECTIONAL_LIGHTS: usize = 16;

/// The passes and features for one scene.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderPlan {
    pub crepuscular: Option<CrepuscularPlan>,
    pub baseline: Option<BaselinePlan>,
    /// Every pass the renderer knows, with whether it runs and why.
    pub decisions: Vec<Decision>,
}

/// Settings of the crepuscular-ray (box medium / direct lighting) pass.
#[derive(Clone, Debug, PartialEq)]
pub struct CrepuscularPlan {
    pub estimator: BoxEstimator,
    pub samples_along_ray: u32,
    /// K: scattering orders 1..=K are summed (1 = single scattering).
    pub max_bounces: u32,
    pub features: CrepuscularFeatures,
}

/// Settings of the baseline path tracer for grid media (decomposition tracking and
/// residual ratio tracking on super-voxels).
#[derive(Clone, Debug, PartialEq)]
pub struct BaselinePlan {
    /// K: scattering orders 1..=K.
    pub max_bounces: u32,
    /// Homogeneous box media beside the grid.
    pub has_boxes: bool,
    pub has_emission: bool,
    pub has_shapes: bool,
    pub has_env: bool,
    pub has_env_map: bool,
    pub pixel_jitter: bool,
}

/// Most lights the baseline path tracer takes (`MAX_LIGHTS` in pathtrace.comp).
pub const MAX_BASELINE_LIGHTS: usize = 16;

/// The plan for scenes with grid media.
fn build_volume(scene: &Scene) -> Result<RenderPlan> {
    let file = scene.source.display();
    let integrator = &scene.integrator;
    if integrator.volume == nimbus_scene::VolumeIntegrator::Restir {
        bail!(
            "{file}: [integrator] field `volume` = \"restir\" (the default for grid media): \
             Volumetric ReSTIR is not supported yet; set volume = \"baseline\""
        );
    }
    let grids: Vec<_> = scene
        .media
        .iter()
        .enumerate()
        .filter_map(|(i, m)| match m {
            Medium::Grid(g) => Some((i, g)),
            Medium::Box(_) => None,
        })
        .collect();
    if grids.len() > 1 {
        bail!(
            "{file}: [[medium]] #{}: the baseline path tracer takes one grid medium, this scene has {}",
            grids[1].0 + 1,
            grids.len()
        );
    }
    let boxes = scene.media.len() - 1;
    if boxes > MAX_BOX_MEDIA {
        bail!(
            "{file}: [[medium]]: {boxes} box media next to the grid, the baseline path tracer takes at most {MAX_BOX_MEDIA}"
        );
    }
    let (index, grid) = grids[0];
    let unsupported = if grid.velocity.is_some() || !grid.frames.is_empty() {
        Some("animated density (velocity / [[medium.frame]])")
    } else {
        None
    };
    if let Some(what) = unsupported {
        bail!(
            "{file}: [[medium]] #{} (type = \"grid\"): {what} is not supported yet by the baseline path tracer",
            index + 1
        );
    }
    let envs = scene
        .lights
        .iter()
        .filter(|l| matches!(l, Light::Environment { .. }))
        .count();
    let env_map = scene
        .lights
        .iter()
        .position(|l| matches!(l, Light::Environment { file: Some(_), .. }));
    if let (Some(i), true) = (env_map, envs > 1) {
        bail!(
            "{file}: [[light]] #{}: an environment map cannot be combined with another environment light",
            i + 1
        );
    }
    for (i, light) in scene.lights.iter().enumerate() {
        let kind = match light {
            Light::Directional { gobo: Some(_), .. } => "a directional light with a gobo",
            _ => continue,
        };
        bail!(
            "{file}: [[light]] #{}: {kind} is not supported yet by the baseline path tracer",
            i + 1
        );
    }
    let lights = scene
        .lights
        .iter()
        .filter(|l| !matches!(l, Light::Environment { .. }))
        .count();
    if lights > MAX_BASELINE_LIGHTS {
        bail!(
            "{file}: [[light]]: {lights} lights, the baseline path tracer takes at most {MAX_BASELINE_LIGHTS}"
        );
    }
    let has_env = scene
        .lights
        .iter()
        .any(|l| matches!(l, Light::Environment { .. }));
    let baseline = BaselinePlan {
        max_bounces: integrator.max_bounces,
        has_boxes: boxes > 0,
        has_emission: grid.emission.is_some(),
        has_shapes: !scene.shapes.is_empty(),
        has_env,
        has_env_map: env_map.is_some(),
        pixel_jitter: scene.render.pixel_jitter,
    };
    let decisions = vec![
        Decision {
            name: "pass baseline path tracer",
            enabled: true,
            reason: format!(
                "grid medium #{}: decomposition tracking + residual ratio tracking on {}x super-voxels, \
                 K = {}, {lights} analytic light(s)",
                index + 1,
                nimbus_scene::SUPER_VOXEL_FACTOR,
                integrator.max_bounces
            ),
        },
        Decision {
            name: "  SC_HAS_SHAPES",
            enabled: baseline.has_shapes,
            reason: format!("{} shape(s)", scene.shapes.len()),
        },
        Decision {
            name: "  SC_HAS_MEDIA (boxes)",
            enabled: boxes > 0,
            reason: format!("{boxes} homogeneous box medium(s) beside the grid"),
        },
        Decision {
            name: "  SC_HAS_EMISSION",
            enabled: baseline.has_emission,
            reason: if baseline.has_emission {
                "the grid emits: absorbed emission added at every real collision".into()
            } else {
                "nothing emits: emission lookups compiled out".into()
            },
        },
        Decision {
            name: "  SC_HAS_ENV",
            enabled: has_env,
            reason: if env_map.is_some() {
                "environment map: seen by camera rays, importance-sampled in next-event estimation \
                 (SC_HAS_ENV_MAP)"
                    .into()
            } else if has_env {
                "constant environment: seen by camera rays, light by next-event estimation".into()
            } else {
                "no environment".into()
            },
        },
        Decision {
            name: "pass crepuscular",
            enabled: false,
            reason: "no box media".into(),
        },
        Decision {
            name: "pass restir (initial, temporal, spatial, shade)",
            enabled: false,
            reason: "[integrator] volume = \"baseline\"".into(),
        },
    ];
    Ok(RenderPlan {
        crepuscular: None,
        baseline: Some(baseline),
        decisions,
    })
}

/// The pass's specialization constants.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CrepuscularFeatures {
    pub has_media: bool,
    pub has_shapes: bool,
    pub has_gobos: bool,
    pub has_env: bool,
    pub pixel_jitter: bool,
}

/// One line of `--explain`: a pass or feature, in or out, and the reason.
#[derive(Clone, Debug, PartialEq)]
pub struct Decision {
    pub name: &'static str,
    pub enabled: bool,
    pub reason: String,
}

/// The estimator ids of `SC_ESTIMATOR` in `shaders/box/crepuscular.comp`.
pub fn estimator_id(estimator: BoxEstimator) -> u32 {
    match estimator {
        BoxEstimator::Mcwvds => 0,
        BoxEstimator::Reds => 1,
        BoxEstimator::Rees => 2,
        BoxEstimator::Rm => 3,
        BoxEstimator::Mcds => 4,
    }
}

/// Build the plan for `scene`, or say which part of it cannot be rendered yet.
/// `samples_along_ray` overrides the scene's `[integrator] box_samples`.
pub fn build(scene: &Scene, samples_along_ray: Option<u32>) -> Result<RenderPlan> {
    let file = scene.source.display();

    // Grid media go to the volume integrators.
    if scene.media.iter().any(|m| matches!(m, Medium::Grid(_))) {
        return build_volume(scene);
    }

    // Reject what the crepuscular pass does not render, naming where it is.
    for (i, light) in scene.lights.iter().enumerate() {
        let kind = match light {
            Light::Directional { .. } => continue,
            Light::Environment { file: None, .. } => continue,
            Light::Environment { file: Some(_), .. } => "type = \"environment\" with a `file`",
            Light::Point { .. } => "type = \"point\"",
            Light::Sphere { .. } => "type = \"sphere\"",
        };
        bail!(
            "{file}: [[light]] #{} ({kind}): not supported yet by the crepuscular pass \
             (directional lights and constant environments are)",
            i + 1
        );
    }
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

    let features = CrepuscularFeatures {
        has_media: media > 0,
        has_shapes: shapes > 0,
        has_gobos: gobos > 0,
        has_env: env,
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
        name: "  SC_HAS_SHAPES",
        enabled: features.has_shapes,
        reason: if features.has_shapes {
            format!("{shapes} shape(s) occlude light and reflect it (Lambertian)")
        } else {
            "no shapes: shadow rays compiled out".into()
        },
    });
    decisions.push(Decision {
        name: "  SC_HAS_GOBOS",
        enabled: features.has_gobos,
        reason: if features.has_gobos {
            format!("{gobos} light(s) masked by a gobo")
        } else {
            "no light has a gobo".into()
        },
    });
    decisions.push(Decision {
        name: "  SC_HAS_ENV",
        enabled: features.has_env,
        reason: if features.has_env {
            "constant environment seen by escaping rays (it does not light the medium or surfaces \
             in the single-scattering box pass)"
                .into()
        } else {
            "no environment: escaping rays see black".into()
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
    decisions.push(Decision {
        name: "pass restir (initial, temporal, spatial, shade)",
        enabled: false,
        reason: "no grid media".into(),
    });
    decisions.push(Decision {
        name: "pass baseline path tracer",
        enabled: false,
        reason: "no grid media".into(),
    });

    Ok(RenderPlan {
        baseline: None,
        crepuscular: Some(CrepuscularPlan {
            estimator,
            samples_along_ray,
            max_bounces,
            features,
        }),
        decisions,
    })
}

impl RenderPlan {
    /// The text of `nimbus render --explain`.
    pub fn explain(&self, scene: &Scene) -> String {
        let r = &scene.render;
        let mut out = String::new();
        let _ = writeln!(
            out,
            "render plan for {}: {}x{} pixels, {} frame(s) x {} spp, seed {}",
            scene.source.display(),
            r.width,
            r.height,
            r.frames,
            r.spp,
            r.seed
        );
        for d in &self.decisions {
            let mark = if d.enabled { "[on ]" } else { "[off]" };
            let _ = writeln!(out, "  {mark} {:<48} {}", d.name, d.reason);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn scene(extra: &str) -> Scene {
        let text = format!(
            "[camera]\nposition = [0, 0, 30]\nlook_at = [0, 0, 0]\n{extra}\n[integrator]\nbox_estimator = \"rees\"\n"
        );
        nimbus_scene::parse_str(&text, Path::new("plan.toml")).expect("parses")
    }

    #[test]
    fn too_many_lights_or_media_are_errors_naming_the_table() {
        let lights = "[[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1\n"
            .repeat(17);
        let err = build(&scene(&lights), None).unwrap_err().to_string();
        assert!(
            err.contains("plan.toml") && err.contains("[[light]]") && err.contains("at most 16"),
            "{err}"
        );

        let media: String = (0..17)
            .map(|i| format!("[[medium]]\ntype = \"box\"\ncenter = [{}, 0, 0]\nsize = [1, 1, 1]\nsigma_t = 1\n", 2 * i))
            .collect();
        let err = build(&scene(&media), None).unwrap_err().to_string();
        assert!(
            err.contains("plan.toml") && err.contains("[[medium]]") && err.contains("at most 16"),
            "{err}"
        );
    }

    #[test]
    fn features_follow_the_scene() {
        let plain = build(&scene(""), None).unwrap();
        let f = plain.crepuscular.as_ref().unwrap().features;
        assert!(!f.has_media && !f.has_shapes && !f.has_gobos && !f.has_env && f.pixel_jitter);

        let gobo = scene(
            "[[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1\ngobo = [[0, 0], [1, 0], [0, 1]]\n\
             [[medium]]\ntype = \"box\"\ncenter = [0, 0, 0]\nsize = [1, 1, 1]\nsigma_t = 1\n",
        );
        let plan = build(&gobo, Some(7)).unwrap();
        let p = plan.crepuscular.as_ref().unwrap();
        assert!(p.features.has_gobos && p.features.has_media);
        assert_eq!(p.samples_along_ray, 7);
        assert_eq!(p.estimator, BoxEstimator::Rees);
        assert!(plan.explain(&gobo).contains("[on ]   SC_HAS_GOBOS"));
    }

    #[test]
    fn grid_scenes_name_what_the_baseline_does_not_take() {
        let grid = |i: u32| {
            format!(
                "[[medium]]\ntype = \"grid\"\nbounds_min = [{x}, 0, 0]\nbounds_max = [{y}, 1, 1]\n\
                 density = {{ procedural = \"cloud\", dims = [4, 4, 4] }}\n",
                x = 2 * i,
                y = 2 * i + 1
            )
        };
        let text = |body: &str, volume: &str| {
            format!(
                "[camera]\nposition = [0, 0, 30]\nlook_at = [0, 0, 0]\n{body}\n[integrator]\nvolume = \"{volume}\"\n"
            )
        };
        let err = |body: &str, volume: &str| {
            let scene = nimbus_scene::parse_str(&text(body, volume), Path::new("grid.toml"))
                .expect("parses");
            build(&scene, None).unwrap_err().to_string()
        };
        let e = err(&grid(0), "restir");
        assert!(
            e.contains("grid.toml") && e.contains("[integrator]") && e.contains("`volume`"),
            "{e}"
        );
        let e = err(&format!("{}{}", grid(0), grid(1)), "baseline");
        assert!(
            e.contains("[[medium]] #2") && e.contains("one grid medium"),
            "{e}"
        );
        let gobo = "[[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1\ngobo = [[0, 0], [1, 0], [0, 1]]\n";
        let e = err(&format!("{}{gobo}", grid(0)), "baseline");
        assert!(e.contains("[[light]] #1") && e.contains("gobo"), "{e}");

        let ok =
            nimbus_scene::parse_str(&text(&grid(0), "baseline"), Path::new("grid.toml")).unwrap();
        let plan = build(&ok, None).unwrap();
        assert!(plan.crepuscular.is_none());
        let b = plan.baseline.as_ref().unwrap();
        assert!(!b.has_emission && !b.has_env && !b.has_env_map && !b.has_boxes);
        assert!(plan
            .explain(&ok)
            .contains("[on ] pass baseline path tracer"));
    }
}
