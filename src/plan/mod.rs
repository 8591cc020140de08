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
    pub restir: Option<RestirPlan>,
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

/// Settings of the Volumetric ReSTIR passes (initial, temporal, spatial, shade).
#[derive(Clone, Debug, PartialEq)]
pub struct RestirPlan {
    /// K: scattering events per path, 1..=MAX_RESTIR_BOUNCES.
    pub max_bounces: u32,
    pub has_emission: bool,
    pub has_env: bool,
    pub has_env_map: bool,
    pub pixel_jitter: bool,
    /// The medium has a velocity grid for temporal reprojection.
    pub has_velocity: bool,
    /// The density changes over the frames ([[medium.frame]]).
    pub animated_density: bool,
    /// M: random walks per pixel per frame.
    pub candidates: u32,
    /// Temporal reuse runs (from the second frame on).
    pub temporal: bool,
    /// Q: the previous frame's M is clamped to Q·M.
    pub temporal_limit: u32,
    pub spatial_neighbors: u32,
    pub spatial_radius_px: f32,
    pub spatial_rounds: u32,
    /// Vertex reuse instead of direction reuse.
    pub vertex_reuse: bool,
    /// Final shading by ratio tracking instead of the closed-form transmittance.
    pub final_ratio_tracking: bool,
    pub mip_candidates: u32,
    pub mip_indirect: u32,
    pub mip_reuse: u32,
}

/// Most scattering events per path ReSTIR stores (reservoirs hold K vertices).
pub const MAX_RESTIR_BOUNCES: u32 = 16;
/// Most spatial neighbours (Talbot MIS costs (N + 1)² target evaluations per pixel).
pub const MAX_SPATIAL_NEIGHBORS: u32 = 16;

/// Most lights the baseline path tracer takes (`MAX_LIGHTS` in pathtrace.comp).
pub const MAX_BASELINE_LIGHTS: usize = 16;

/// The plan for scenes with grid media.
fn build_volume(scene: &Scene) -> Result<RenderPlan> {
    let file = scene.source.display();
    let integrator = &scene.integrator;
    let restir = integrator.volume == nimbus_scene::VolumeIntegrator::Restir;
    let integrator_name = if restir {
        "Volumetric ReSTIR"
    } else {
        "the baseline path tracer"
    };
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
            "{file}: [[medium]] #{}: {integrator_name} takes one grid medium, this scene has {}",
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
    let animated = grid.velocity.is_some() || !grid.frames.is_empty();
    if animated && !restir {
        bail!(
            "{file}: [[medium]] #{} (type = \"grid\"): animated density (velocity / [[medium.frame]]) is not supported yet by the baseline path tracer; use volume = \"restir\"",
            index + 1
        );
    }
    if restir {
        if let Some(i) = scene.media.iter().position(|m| matches!(m, Medium::Box(_))) {
            bail!(
                "{file}: [[medium]] #{} (type = \"box\"): Volumetric ReSTIR renders one grid medium alone; box media beside it need volume = \"baseline\"",
                i + 1
            );
        }
        if !scene.shapes.is_empty() {
            bail!(
                "{file}: [[shape]] #1: Volumetric ReSTIR does not render surfaces yet; use [integrator] volume = \"baseline\""
            );
        }
        if integrator.max_bounces > MAX_RESTIR_BOUNCES {
            bail!(
                "{file}: [integrator] field `max_bounces` = {}: Volumetric ReSTIR stores paths of at most {MAX_RESTIR_BOUNCES} scattering events",
                integrator.max_bounces
            );
        }
        if integrator.restir.spatial_neighbors > MAX_SPATIAL_NEIGHBORS {
            bail!(
                "{file}: [integrator.restir] field `spatial_neighbors` = {}: at most {MAX_SPATIAL_NEIGHBORS} (Talbot MIS costs (N + 1)^2 path evaluations per pixel)",
                integrator.restir.spatial_neighbors
            );
        }
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
            "{file}: [[light]] #{}: {kind} is not supported yet by {integrator_name}",
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
            "{file}: [[light]]: {lights} lights, {integrator_name} takes at most {MAX_BASELINE_LIGHTS}"
        );
    }
    let has_env = scene
        .lights
        .iter()
        .any(|l| matches!(l, Light::Environment { .. }));
    if restir {
        return Ok(restir_plan(
            scene,
            index,
            grid,
            has_env,
            env_map.is_some(),
            lights,
        ));
    }
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
        restir: None,
        decisions,
    })
}

/// The ReSTIR plan for a validated grid scene.
fn restir_plan(
    scene: &Scene,
    index: usize,
    grid: &nimbus_scene::GridMedium,
    has_env: bool,
    has_env_map: bool,
    lights: usize,
) -> RenderPlan {
    let s = &scene.integrator.restir;
    let k = scene.integrator.max_bounces;
    let plan = RestirPlan {
        max_bounces: k,
        has_emission: grid.emission.is_some(),
        has_env,
        has_env_map,
        pixel_jitter: scene.render.pixel_jitter,
        has_velocity: grid.velocity.is_some(),
        animated_density: !grid.frames.is_empty(),
        candidates: s.candidates,
        temporal: s.temporal,
        temporal_limit: s.temporal_limit,
        spatial_neighbors: s.spatial_neighbors,
        spatial_radius_px: s.spatial_radius_px,
        spatial_rounds: s.spatial_rounds,
        vertex_reuse: s.reuse == nimbus_scene::ReuseMode::Vertex,
        final_ratio_tracking: s.final_ratio_tracking,
        mip_candidates: s.mip_candidates,
        mip_indirect: s.mip_indirect,
        mip_reuse: s.mip_reuse,
    };
    let frames = scene.render.frames;
    let spatial = plan.spatial_neighbors > 0 && plan.spatial_rounds > 0;
    let on = |name: &'static str, enabled: bool, reason: String| Decision {
        name,
        enabled,
        reason,
    };
    let decisions = vec![
        on(
            "pass restir initial",
            true,
            format!(
                "grid medium #{}: M = {} random walks per pixel, regular tracking on mip {} (camera) / {} (scattered), \
                 K = {k}, {lights} analytic light(s); {} bytes of reservoir per pixel and slot, 3 slots",
                index + 1,
                plan.candidates,
                plan.mip_candidates,
                plan.mip_indirect,
                crate::passes::restir::reservoir_bytes(k)
            ),
        ),
        on(
            "pass restir temporal",
            plan.temporal && frames > 1,
            if !plan.temporal {
                "[integrator.restir] temporal = false".into()
            } else if frames > 1 {
                format!(
                    "from the second frame: reprojection of x1{}, Q = {}",
                    if plan.has_velocity {
                        " through the velocity field"
                    } else {
                        ""
                    },
                    plan.temporal_limit
                )
            } else {
                "a single frame has no previous one".into()
            },
        ),
        on(
            "pass restir spatial",
            spatial,
            if spatial {
                format!(
                    "{} round(s) of {} neighbours within {} px, Talbot MIS, T~ marched on mip {}, {} reuse",
                    plan.spatial_rounds,
                    plan.spatial_neighbors,
                    plan.spatial_radius_px,
                    plan.mip_reuse,
                    if plan.vertex_reuse {
                        "vertex"
                    } else {
                        "direction"
                    }
                )
            } else {
                "spatial_neighbors or spatial_rounds is 0".into()
            },
        ),
        on(
            "pass restir shade",
            true,
            if plan.final_ratio_tracking {
                "F with ratio-tracking transmittance (global majorant)".into()
            } else {
                "F with closed-form transmittance through the trilinear grid".into()
            },
        ),
        on(
            "  SC_HAS_EMISSION",
            plan.has_emission,
            if plan.has_emission {
                "the grid emits: emission candidates at every vertex".into()
            } else {
                "nothing emits: emission candidates compiled out".into()
            },
        ),
        on(
            "  SC_HAS_ENV",
            has_env,
            if has_env_map {
                "environment map, importance-sampled in NEE (SC_HAS_ENV_MAP)".into()
            } else if has_env {
                "constant environment".into()
            } else {
                "no environment".into()
            },
        ),
        on(
            "  SC_REUSE_VERTEX",
            plan.vertex_reuse,
            if plan.vertex_reuse {
                "vertex reuse: x2 kept in world space (volume-measure geometry term)".into()
            } else {
                "direction reuse (z_i, omega_i)".into()
            },
        ),
        on(
            "  SC_HAS_VELOCITY",
            plan.has_velocity,
            if plan.has_velocity {
                "temporal reprojection follows the velocity grid".into()
            } else {
                "no velocity grid: reprojection by the camera only".into()
            },
        ),
        on(
            "  SC_PIXEL_JITTER",
            plan.pixel_jitter,
            "sub-pixel jitter hashed from (pixel, frame)".into(),
        ),
        on(
            "pass baseline path tracer",
            false,
            "[integrator] volume = \"restir\"".into(),
        ),
        on("pass crepuscular", false, "no box media".into()),
    ];
    RenderPlan {
        crepuscular: None,
        baseline: None,
        restir: Some(plan),
        decisions,
    }
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
        restir: None,
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
        let restir = nimbus_scene::parse_str(&text(&grid(0), "restir"), Path::new("grid.toml"))
            .expect("parses");
        let plan = build(&restir, None).unwrap();
        let r = plan.restir.as_ref().expect("restir plan");
        assert!(plan.baseline.is_none() && !r.has_emission && !r.vertex_reuse);
        assert_eq!(
            (r.candidates, r.temporal_limit, r.spatial_neighbors),
            (4, 4, 3)
        );
        let e = err(&format!("{}{}", grid(0), grid(1)), "restir");
        assert!(
            e.contains("[[medium]] #2") && e.contains("Volumetric ReSTIR"),
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
