//! The plan of scenes with a grid medium: the baseline path tracer or Volumetric
//! ReSTIR, with what each takes beside the grid.

use anyhow::{bail, Result};
use nimbus_scene::{Light, Medium, Scene};

use super::levels::CANDIDATE_DELTA_MARCH_ERROR;
use super::{
    AskedLevels, BaselinePlan, Decision, Integrator, LevelChoice, RestirPlan, MAX_BOX_MEDIA,
};

/// Most scattering events per path ReSTIR stores (reservoirs hold K vertices).
pub const MAX_RESTIR_BOUNCES: u32 = crate::shader_data::features::MAX_RESTIR_BOUNCES;
/// Most spatial neighbours (validated by the scene loader).
pub use nimbus_scene::MAX_SPATIAL_NEIGHBORS;

/// Most analytic lights of a grid scene. ReSTIR names a light by an 8-bit index
/// (`MAX_RESTIR_LIGHTS`, 255); 16 keeps the per-frame light records and their power CDF
/// small for both grid integrators.
pub const MAX_BASELINE_LIGHTS: usize = 16;
/// Emitting shapes add one `LIGHT_AREA` record to the set, so a set holds at most
/// `MAX_BASELINE_LIGHTS + 1` records, which must stay below ReSTIR's environment index.
const _: () =
    assert!(MAX_BASELINE_LIGHTS < crate::shader_data::features::MAX_RESTIR_LIGHTS as usize);

/// The plan of a scene with a grid medium and its decision rows.
pub(super) fn build(scene: &Scene, product: super::Product) -> Result<(Integrator, Vec<Decision>)> {
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
            _ => None,
        })
        .collect();
    let has_convex = scene.media.iter().any(|m| matches!(m, Medium::Convex(_)));
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
    if restir {
        if let Some(shape) = scene.shapes.first() {
            if integrator.restir.reuse == nimbus_scene::ReuseMode::Vertex {
                bail!(
                    "{file}: [integrator.restir] field `reuse` = \"vertex\": vertex reuse keeps x2 in \
                     world space with a volume-measure geometry term, which a surface vertex \
                     ([[shape]] #1, type = \"{}\") does not have; use reuse = \"direction\" (the default) \
                     with shapes",
                    shape.type_name()
                );
            }
        }
        if scene.render.spp > 1 {
            bail!(
                "{file}: [render] field `spp` = {}: Volumetric ReSTIR renders one path per pixel \
                 per frame, so spp would be ignored; its work per frame is set by \
                 [integrator.restir] `candidates` (random walks per pixel) and its total by \
                 [render] `frames`. Set spp = 1 (the default) or use volume = \"baseline\"",
                scene.render.spp
            );
        }
        if integrator.restir.nee == nimbus_scene::NeeMode::Split && !nee_split_applies(scene) {
            bail!(
                "{file}: [integrator.restir] field `nee` = \"split\": split next-event estimation \
                 adds every directional and point light to one sample of the environment, so it \
                 needs at least one of those lights and an environment, and no sphere lights or \
                 emitting shapes; use nee = \"one\" or \"auto\" (the default) for this scene"
            );
        }
        if integrator.max_bounces > MAX_RESTIR_BOUNCES {
            bail!(
                "{file}: [integrator] field `max_bounces` = {}: Volumetric ReSTIR stores paths of at most {MAX_RESTIR_BOUNCES} scattering events",
                integrator.max_bounces
            );
        }
    }
    let env_map = super::environment_map(scene)?;
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
        return restir_plan(
            scene,
            index,
            grid,
            has_env,
            env_map.is_some(),
            lights,
            boxes,
            product,
        );
    }
    let (nee_split, sky_along_path, nee_decisions) =
        baseline_nee(scene, integrator.max_bounces, has_env && env_map.is_none());
    let density_fetch = integrator.baseline.density_fetch;
    let baseline = BaselinePlan {
        nee_split,
        sky_along_path,
        density_fetch,
        max_bounces: integrator.max_bounces,
        has_boxes: boxes > 0,
        has_convex,
        has_emission: grid.emission.is_some() || grid.temperature.is_some(),
        has_blackbody: grid.temperature.is_some(),
        has_albedo_grid: grid.albedo_grid.is_some(),
        has_shapes: !scene.shapes.is_empty(),
        has_meshes: scene
            .shapes
            .iter()
            .any(|s| matches!(s, nimbus_scene::Shape::Mesh { .. })),
        has_area_lights: scene.shapes.iter().any(|s| s.emits()),
        has_sphere_lights: has_sphere_lights(scene),
        has_gobos: gobo_count(scene) > 0,
        has_env,
        has_env_map: env_map.is_some(),
        pixel_jitter: scene.render.pixel_jitter,
    };
    let mut decisions = vec![
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
        super::meshes_decision(scene),
        area_lights_decision(scene),
        sphere_lights_decision(scene),
        gobos_decision(scene),
    ];
    decisions.extend(nee_decisions);
    decisions.extend([
        Decision::new(
            "  SC_DENSITY_BUFFER",
            density_fetch == nimbus_scene::DensityFetch::Buffer,
            match density_fetch {
                nimbus_scene::DensityFetch::Auto => {
                    "[integrator.baseline] density_fetch = \"auto\": the density is read from a \
                     storage buffer of its slots on a CPU device where it takes at most 128 MiB \
                     (lavapipe: a texelFetch is a call into the sampler's code, a trilinear \
                     lookup from the buffer two 16-byte loads; 0.64x a frame), from the atlas \
                     image on a GPU"
                }
                nimbus_scene::DensityFetch::Image => {
                    "[integrator.baseline] density_fetch = \"image\": the atlas image, by texelFetch"
                }
                nimbus_scene::DensityFetch::Buffer => {
                    "[integrator.baseline] density_fetch = \"buffer\": a storage buffer of the \
                     density's slots (10^3 texels of 16 bytes each)"
                }
            },
        ),
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
                "the grid does not emit: its emission lookups compiled out".into()
            },
        },
        blackbody_decision(grid),
        albedo_grid_decision(grid),
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
    ]);
    Ok((Integrator::Baseline(baseline), decisions))
}

/// The `SC_HAS_SPHERE_LIGHTS` row of both grid integrators.
fn sphere_lights_decision(scene: &Scene) -> Decision {
    let spheres = sphere_light_count(scene);
    if spheres == 0 {
        return Decision::new(
            "  SC_HAS_SPHERE_LIGHTS",
            false,
            "no sphere light: segments and shadow rays look for none (compiled out)",
        );
    }
    Decision::new(
        "  SC_HAS_SPHERE_LIGHTS",
        true,
        format!("{spheres} sphere light(s): seen by camera rays, blocking shadow rays"),
    )
}

/// Directional lights with a gobo.
fn gobo_count(scene: &Scene) -> usize {
    scene
        .lights
        .iter()
        .filter(|l| matches!(l, Light::Directional { gobo: Some(_), .. }))
        .count()
}

/// The `SC_HAS_GOBOS` row of both grid integrators: on with the gobo'd directional
/// lights, else why the gobo test is compiled out.
fn gobos_decision(scene: &Scene) -> Decision {
    let gobos = gobo_count(scene);
    if gobos == 0 {
        return Decision::new(
            "  SC_HAS_GOBOS",
            false,
            "no light has a gobo: the gobo test compiled out",
        );
    }
    Decision::new(
        "  SC_HAS_GOBOS",
        true,
        format!(
            "{gobos} directional light(s) masked by a gobo: next-event estimation and the \
             re-evaluation of a stored light vertex test the gobo prism at the shading point"
        ),
    )
}

/// The `SC_HAS_AREA_LIGHTS` row of the baseline: on with the emitting shapes and their
/// primitives in the emitter table, else why emitter sampling is compiled out.
fn area_lights_decision(scene: &Scene) -> Decision {
    let emitting = scene.shapes.iter().filter(|s| s.emits()).count();
    if emitting == 0 {
        return Decision::new(
            "  SC_HAS_AREA_LIGHTS",
            false,
            "no shape emits: emitter sampling and seen emission compiled out",
        );
    }
    let primitives: u64 = scene
        .shapes
        .iter()
        .map(|s| u64::from(crate::shader_data::emitters::emitter_primitives(s)))
        .sum();
    Decision::new(
        "  SC_HAS_AREA_LIGHTS",
        true,
        format!(
            "{emitting} emitting shape(s), {primitives} emitter primitive(s): seen by camera rays, \
             one light of next-event estimation by power (binary search in the power CDF, \
             then a point on the primitive)"
        ),
    )
}

/// The baseline's next-event estimation: split (every delta light at every vertex, plus
/// one sample of the other lights) or one light per vertex by power; whether the split's
/// sky rides on the path's next segment (SC_SKY_ALONG_PATH: the other lights are a
/// constant environment alone); and the `--explain` rows. `"auto"` splits where one delta
/// light shares the scene with other lights and either K = 1 or the sky rides along.
/// Measured on the benchmark cloud (sun + constant sky, lavapipe, per-sample variance and
/// time, efficiency against one light per vertex): at K = 1 split 1.29x (g = 0) and 1.91x
/// (g = 0.8); at K = 3 split with its own sky shadow ray 1.00x and 1.06x, with the sky
/// along the path 1.22x and 1.07x (docs/performance.md). Several delta lights (a shadow
/// ray each at every vertex) were not measured.
fn baseline_nee(
    scene: &Scene,
    max_bounces: u32,
    constant_sky: bool,
) -> (bool, bool, Vec<Decision>) {
    let delta = scene
        .lights
        .iter()
        .filter(|l| matches!(l, Light::Directional { .. } | Light::Point { .. }))
        .count();
    let other = scene
        .lights
        .iter()
        .filter(|l| !matches!(l, Light::Directional { .. } | Light::Point { .. }))
        .count()
        + usize::from(scene.shapes.iter().any(|s| s.emits()));
    // The split's other-light sample is a constant sky drawn from the vertex's own lobe,
    // the path's next direction's distribution.
    let sky_alone = constant_sky && other_lights_are_the_sky(scene);
    let mode = scene.integrator.baseline.nee;
    let split = match mode {
        nimbus_scene::NeeMode::One => false,
        nimbus_scene::NeeMode::Split => delta > 0 && delta + other > 1,
        nimbus_scene::NeeMode::Auto => delta == 1 && other > 0 && (max_bounces == 1 || sky_alone),
    };
    let sky_along_path = split && sky_alone && max_bounces > 1;
    let reason = if split {
        format!(
            "every vertex adds its {delta} delta (directional, point) light(s), one shadow ray \
             each, to one sample of the {other} other light(s): no sample is spent choosing \
             between them{}",
            if mode == nimbus_scene::NeeMode::Auto {
                " ([integrator.baseline] nee = \"auto\": one delta light, and K = 1 or a \
                 constant sky as the other light, where split measured 1.1-1.9x the efficiency)"
            } else {
                ""
            }
        )
    } else {
        match mode {
            nimbus_scene::NeeMode::One => {
                "[integrator.baseline] nee = \"one\": one light per vertex, chosen by power".into()
            }
            _ if delta == 0 || delta + other <= 1 => format!(
                "one light per vertex, chosen by power ({delta} delta light(s), {other} other \
                 light(s): nothing to split)"
            ),
            _ => format!(
                "one light per vertex, chosen by power ([integrator.baseline] nee = \"auto\" \
                 splits only with one delta light, and at K = 1 or with a constant sky as the \
                 other light, where it measured faster at equal error; here K = {max_bounces} \
                 with {delta} delta light(s) and {other} other(s); nee = \"split\" asks for it)"
            ),
        }
    };
    let sky_reason = if sky_along_path {
        "the constant sky's NEE direction is the path's next one (both drawn from the vertex's \
         phase or cosine lobe): the next segment's walk samples its collision and estimates the \
         sky's transmittance in one (1.22x the efficiency of a separate sky shadow ray at K = 3, \
         g = 0)"
            .to_string()
    } else if split && sky_alone {
        "K = 1: no next segment for the sky to ride on".to_string()
    } else {
        "only with split NEE whose other light is a constant sky".to_string()
    };
    (
        split,
        sky_along_path,
        vec![
            Decision::new("  SC_NEE_SPLIT", split, reason),
            Decision::new("  SC_SKY_ALONG_PATH", sky_along_path, sky_reason),
        ],
    )
}

/// Whether some light is a sphere light (camera rays and shadow rays look for one).
fn has_sphere_lights(scene: &Scene) -> bool {
    sphere_light_count(scene) > 0
}

/// The scene's sphere lights.
fn sphere_light_count(scene: &Scene) -> usize {
    scene
        .lights
        .iter()
        .filter(|l| matches!(l, Light::Sphere { .. }))
        .count()
}

/// Whether the lights other than directional and point lights are environments alone
/// (no sphere lights, no emitting shapes).
fn other_lights_are_the_sky(scene: &Scene) -> bool {
    !scene
        .lights
        .iter()
        .any(|l| matches!(l, Light::Sphere { .. }))
        && !scene.shapes.iter().any(|s| s.emits())
}

/// ReSTIR's temporal reuse for `scene` rendered as `product`: as asked, or for `"auto"`
/// off in a still of a static scene ([`super::Product::Still`]) and on otherwise.
fn temporal_choice(scene: &Scene, product: super::Product) -> bool {
    scene
        .integrator
        .restir
        .temporal
        .unwrap_or(product == super::Product::Frames || scene.is_animated())
}

/// Whether the candidates' walks use delta tracking (`candidate_tracking`; `"auto"`:
/// where each frame leans on its candidates, temporal reuse off or a density that changes
/// from frame to frame, or where the candidates' level misses the field, its march error
/// above [`CANDIDATE_DELTA_MARCH_ERROR`]).
fn candidate_delta(
    s: &nimbus_scene::RestirSettings,
    temporal: bool,
    animated_density: bool,
    levels: &LevelChoice,
) -> bool {
    match s.candidate_tracking {
        nimbus_scene::CandidateTracking::Delta => true,
        nimbus_scene::CandidateTracking::Regular => false,
        nimbus_scene::CandidateTracking::Auto => {
            !temporal
                || animated_density
                || candidates_march_error(levels).is_some_and(|e| e > CANDIDATE_DELTA_MARCH_ERROR)
        }
    }
}

/// What `--explain` says of the candidates' tracking.
/// Whether `spatial_when` leaves every frame of `scene` without spatial reuse: its trigger
/// (the camera's motion, or with `"camera_or_density"` also a change of density frame)
/// never fires.
fn spatial_never(when: nimbus_scene::SpatialWhen, scene: &Scene, animated_density: bool) -> bool {
    let camera_still = scene.camera.keyframes.is_empty();
    match when {
        nimbus_scene::SpatialWhen::Always => false,
        nimbus_scene::SpatialWhen::CameraMoves => camera_still,
        nimbus_scene::SpatialWhen::CameraOrDensity => camera_still && !animated_density,
    }
}

fn tracking_reason(s: &nimbus_scene::RestirSettings, plan: &RestirPlan) -> String {
    let what = if plan.candidate_delta {
        "the candidates' walks find their vertices by the baseline's decomposition tracking on \
         the exact density (density sigma_t T, the target's own: no tracking ratio in a \
         candidate's weight); the selected path's walked T is computed once, in closed form"
    } else {
        "regular tracking through the conservative piecewise-constant grid (the paper's)"
    };
    let why = match s.candidate_tracking {
        nimbus_scene::CandidateTracking::Delta => "candidate_tracking = \"delta\"".to_string(),
        nimbus_scene::CandidateTracking::Regular => "candidate_tracking = \"regular\"".to_string(),
        nimbus_scene::CandidateTracking::Auto => {
            let error = candidates_march_error(&plan.levels)
                .map(|e| format!("{e:.3}"))
                .unwrap_or_else(|| "unmeasured".into());
            let cause = if !plan.temporal {
                "temporal reuse is off, so every frame stands on its candidates".to_string()
            } else if plan.animated_density {
                "the density changes from frame to frame, so the history is weak".to_string()
            } else if plan.candidate_delta {
                format!(
                    "mip {} of the candidates misses the field (march error {error} > \
                     {CANDIDATE_DELTA_MARCH_ERROR})",
                    plan.levels.levels.candidates
                )
            } else {
                format!(
                    "a static density under temporal reuse, and mip {} of the candidates fits \
                     the field (march error {error} <= {CANDIDATE_DELTA_MARCH_ERROR}); where the \
                     density is read from its buffer of quads (density_fetch, \"auto\" on a CPU \
                     device) delta tracking instead, whose exact lookups cost as little \
                     there",
                    plan.levels.levels.candidates
                )
            };
            format!("candidate_tracking = \"auto\": {cause}")
        }
    };
    format!("[integrator.restir] {why}: {what}")
}

/// The march error of the candidates' level (the camera segments' regular tracking),
/// where the plan measured the errors.
fn candidates_march_error(levels: &LevelChoice) -> Option<f64> {
    let errors = levels.march_errors.as_ref()?;
    let at = (levels.levels.candidates as usize).min(errors.len().checked_sub(1)?);
    Some(errors[at])
}

/// Whether split next-event estimation applies: delta (directional, point) lights and an
/// environment, and no other lights (sphere lights, emitting shapes).
fn nee_split_applies(scene: &Scene) -> bool {
    let delta = scene
        .lights
        .iter()
        .any(|l| matches!(l, Light::Directional { .. } | Light::Point { .. }));
    let env = scene
        .lights
        .iter()
        .any(|l| matches!(l, Light::Environment { .. }));
    let other = scene
        .lights
        .iter()
        .any(|l| matches!(l, Light::Sphere { .. }))
        || scene.shapes.iter().any(|s| s.emits());
    delta && env && !other
}

/// The ReSTIR plan for a validated grid scene.
// The facts `build` has already worked out, passed rather than worked out twice.
#[allow(clippy::too_many_arguments)]
fn restir_plan(
    scene: &Scene,
    index: usize,
    grid: &nimbus_scene::GridMedium,
    has_env: bool,
    has_env_map: bool,
    lights: usize,
    boxes: usize,
    product: super::Product,
) -> Result<(Integrator, Vec<Decision>)> {
    let s = &scene.integrator.restir;
    let temporal = temporal_choice(scene, product);
    // `"auto"` took temporal reuse off (the decision row says why).
    let temporal_auto_off = s.temporal.is_none() && !temporal;
    // ReSTIR keeps one temperature, albedo and emission grid resident for the whole
    // animation; rather than render frames with the wrong fire or colour, it refuses
    // frames that swap them (the baseline renders each frame's).
    let shading = |f: &nimbus_scene::GridFrame| {
        [
            ("temperature", f.temperature.is_some()),
            ("albedo", f.albedo.is_some()),
            ("emission", f.emission.is_some()),
        ]
        .into_iter()
        .find(|(_, given)| *given)
        .map(|(key, _)| key)
    };
    if let Some((j, key)) = grid
        .frames
        .iter()
        .enumerate()
        .find_map(|(j, f)| shading(f).map(|key| (j, key)))
    {
        anyhow::bail!(
            "{}: [[medium]] #{} > [[medium.frame]] #{} gives `{key}`, and Volumetric ReSTIR \
             keeps one {key} grid for the whole animation: render it with [integrator] \
             volume = \"baseline\" (which follows each frame's grids), or leave the frames' \
             {key} out",
            scene.source.display(),
            index + 1,
            j + 1
        );
    }
    let asked_levels = AskedLevels::of(s);
    let k = scene.integrator.max_bounces;
    let env_reuse_map = s.env_reuse == nimbus_scene::EnvReuse::Map && has_env_map;
    let temporal_limit = scene.restir_temporal_limit();
    let mut plan = RestirPlan {
        max_bounces: k,
        has_emission: grid.emission.is_some() || grid.temperature.is_some(),
        has_blackbody: grid.temperature.is_some(),
        has_albedo_grid: grid.albedo_grid.is_some(),
        has_env,
        has_env_map,
        pixel_jitter: scene.render.pixel_jitter,
        has_velocity: grid.velocity.is_some(),
        animated_density: !grid.frames.is_empty(),
        // Set below, once spatial reuse is known.
        settings: nimbus_scene::RestirSettings {
            temporal: Some(temporal),
            temporal_limit: Some(temporal_limit),
            ..s.clone()
        },
        temporal,
        temporal_limit,
        temporal_limit_moving: if super::has_moving_frames(
            scene,
            !grid.frames.is_empty(),
            env_reuse_map,
        ) {
            temporal_limit.min(s.temporal_limit_moving)
        } else {
            temporal_limit
        },
        // spatial_when = "camera_moves" under a camera that never moves, or
        // "camera_or_density" where neither the camera nor the density moves: no spatial
        // pass.
        spatial_neighbors: if spatial_never(s.spatial_when, scene, !grid.frames.is_empty()) {
            0
        } else {
            s.spatial_neighbors
        },
        spatial_radius_px: s
            .spatial_radius_px
            .unwrap_or_else(|| nimbus_scene::auto_spatial_radius_px(scene.render.width)),
        spatial_when: s.spatial_when,
        spatial_rounds: s.spatial_rounds,
        vertex_reuse: s.reuse == nimbus_scene::ReuseMode::Vertex,
        levels: LevelChoice::of(scene, index, grid, asked_levels)?,
        pairwise_mis: s.mis == nimbus_scene::MisMode::Pairwise,
        spatial_max_history: s.spatial_max_history,
        // `boxes`: the media beside the grid (box and convex).
        spatial_tau_shift: matches!(
            s.spatial_shift,
            nimbus_scene::SpatialShift::OpticalDepth
                | nimbus_scene::SpatialShift::ExactOpticalDepth
        ) && boxes == 0,
        spatial_tau_exact: s.spatial_shift == nimbus_scene::SpatialShift::ExactOpticalDepth
            && boxes == 0,
        temporal_tau_shift: s.temporal_shift == nimbus_scene::TemporalShift::OpticalDepth
            && boxes == 0,
        // Set below, once split NEE is known.
        fold_emission: false,
        env_reuse_map,
        history_before_spatial: s.temporal_history == nimbus_scene::HistoryMode::Temporal,
        // Set below, once the levels are known.
        direct_each_walk: false,
        candidate_delta: false,
        nee_split: match s.nee {
            nimbus_scene::NeeMode::One => false,
            nimbus_scene::NeeMode::Split => true,
            nimbus_scene::NeeMode::Auto => nee_split_applies(scene),
        },
        has_shapes: !scene.shapes.is_empty(),
        has_meshes: scene
            .shapes
            .iter()
            .any(|s| matches!(s, nimbus_scene::Shape::Mesh { .. })),
        has_boxes: boxes > 0,
        has_convex: scene.media.iter().any(|m| matches!(m, Medium::Convex(_))),
        has_area_lights: scene.shapes.iter().any(|s| s.emits()),
        has_sphere_lights: has_sphere_lights(scene),
        has_gobos: gobo_count(scene) > 0,
    };
    plan.candidate_delta = candidate_delta(s, temporal, plan.animated_density, &plan.levels);
    plan.direct_each_walk = s.direct == nimbus_scene::DirectMode::EachWalk && !plan.candidate_delta;
    // Folded emission needs the environment's sampler at every vertex (q > 0 wherever it
    // draws): split NEE, or the environment as the only light; and emission.
    let env_only = matches!(scene.lights.as_slice(), [Light::Environment { .. }])
        && !scene.shapes.iter().any(|s| s.emits());
    plan.fold_emission = s.fold_emission && (plan.nee_split || env_only) && plan.has_emission;
    let frames = scene.render.frames;
    let spatial = plan.spatial();
    if !spatial {
        plan.settings = without_spatial(&plan.settings);
    }
    if !super::has_moving_frames(scene, plan.animated_density, plan.env_reuse_map) {
        // Read by nothing where no frame moves (camera, density, a map under map reuse):
        // one plan whatever it says.
        plan.settings.temporal_limit_moving =
            nimbus_scene::RestirSettings::default().temporal_limit_moving;
    }
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
                "grid medium #{}: M = {} random walks per pixel{}, {}, \
                 K = {k}, {lights} analytic light(s), target = {} of the path's RGB; {} bytes of \
                 reservoir per pixel and slot, {} slots",
                index + 1,
                s.candidates,
                match plan.candidates_settled() {
                    Some(m) => format!(
                        " ({m} once the history is full, after {} frames in a row on which \
                         nothing changed: candidates_settled; the history keeps its cap of {} \
                         candidates)",
                        plan.temporal_limit,
                        u64::from(plan.temporal_limit) * u64::from(s.candidates)
                    ),
                    None => String::new(),
                },
                if plan.candidate_delta {
                    format!(
                        "delta tracking on the exact density, NEE marched on mip {}",
                        mip_text(asked_levels.indirect, plan.levels.levels.indirect)
                    )
                } else {
                    format!(
                        "regular tracking on mip {} for camera rays and {} for scattered ones",
                        mip_text(Some(asked_levels.candidates), plan.levels.levels.candidates),
                        mip_text(asked_levels.indirect, plan.levels.levels.indirect)
                    )
                },
                match s.target {
                    nimbus_scene::TargetScalar::Luminance => "luminance",
                    nimbus_scene::TargetScalar::Sum => "sum",
                    nimbus_scene::TargetScalar::Max => "max",
                },
                crate::shader_data::reservoir_bytes(k),
                plan.reservoir_slots()
            ),
        ),
        on(
            "pass restir temporal",
            plan.temporal && frames > 1,
            if temporal_auto_off {
                "temporal = \"auto\": this static scene renders a still, the mean of its \
                 frames, and independent frames (fresh candidates each frame) make that mean \
                 about 6x as efficient as temporal reuse's correlated ones (perf-cloud, K = 3: \
                 docs/performance.md); temporal = true keeps it"
                    .into()
            } else if !plan.temporal {
                "[integrator.restir] temporal = false".into()
            } else if frames > 1 {
                format!(
                    "from the second frame: reprojection of {}{}, x1 moved by its {}, Q = {}{}{}, history = the {} output",
                    match s.temporal_reprojection {
                        nimbus_scene::TemporalReprojection::Path =>
                            "the selected path's x1 (temporal_reprojection = \"path\", the paper's)",
                        nimbus_scene::TemporalReprojection::Aligned =>
                            "the pixel's motion point (optical depth 1 along its centre ray), the reused path's \
                             sub-pixel position aligned there (temporal_reprojection = \"aligned\", SC_TEMPORAL_ALIGNED)",
                    },
                    if plan.has_velocity {
                        " through the velocity field"
                    } else {
                        ""
                    },
                    if plan.temporal_tau_shift {
                        "optical depth through the density where the camera moved over an unchanged \
                         density (temporal_shift = \"optical_depth\", SC_TEMPORAL_TAU_SHIFT), else its depth past the anchors"
                    } else if s.temporal_shift == nimbus_scene::TemporalShift::OpticalDepth {
                        "depth past the anchors (temporal_shift = \"optical_depth\" needs the grid to be the only medium)"
                    } else {
                        "depth past the anchors"
                    },
                    plan.temporal_limit,
                    match s.temporal_limit {
                        Some(_) => String::new(),
                        None if scene.is_animated() => format!(
                            " (temporal_limit = \"auto\": {} where something moves)",
                            nimbus_scene::ANIMATED_TEMPORAL_LIMIT
                        ),
                        None => format!(
                            " (temporal_limit = \"auto\": {} where nothing moves)",
                            nimbus_scene::STILL_TEMPORAL_LIMIT
                        ),
                    },
                    if plan.temporal_limit_moving != plan.temporal_limit {
                        format!(
                            " (Q = {} on frames whose camera or density moved{}: temporal_limit_moving)",
                            plan.temporal_limit_moving,
                            if plan.env_reuse_map {
                                " or whose environment map turned (env_reuse = \"map\")"
                            } else {
                                ""
                            }
                        )
                    } else {
                        String::new()
                    },
                    if plan.history_before_spatial {
                        "temporal"
                    } else {
                        "spatial"
                    }
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
                    "{}{} round(s) of {} neighbours within {} px{}{}, {} MIS, x_1 shifted by its {}{}, T~ marched on mip {}, {} reuse",
                    match plan.spatial_when {
                        nimbus_scene::SpatialWhen::Always => "",
                        nimbus_scene::SpatialWhen::CameraMoves => "on frames whose camera moved: ",
                        nimbus_scene::SpatialWhen::CameraOrDensity =>
                            "on frames whose camera or density frame changed: ",
                    },
                    plan.spatial_rounds,
                    plan.spatial_neighbors,
                    plan.spatial_radius_px,
                    if plan.spatial_max_history > 0.0 {
                        format!(
                            " where the history holds M < {} x {}",
                            plan.spatial_max_history, s.candidates
                        )
                    } else {
                        String::new()
                    },
                    if s.spatial_feature_tolerance > 0.0 {
                        format!(
                            ", leaving out neighbours whose centre ray ends elsewhere or whose T~ differs by {} or more",
                            s.spatial_feature_tolerance
                        )
                    } else {
                        String::new()
                    },
                    if plan.pairwise_mis { "pairwise" } else { "Talbot" },
                    if plan.spatial_tau_exact {
                        "exact optical depth through the density"
                    } else if plan.spatial_tau_shift {
                        "optical depth through the conservative grid"
                    } else if s.spatial_shift != nimbus_scene::SpatialShift::Distance {
                        "distance (the optical-depth shifts need the grid to be the only medium)"
                    } else {
                        "distance"
                    },
                    // (The optical-depth shift places a medium x_1 itself; anchors move
                    // only the other paths.)
                    if s.spatial_anchor && !plan.spatial_tau_shift {
                        " past where each pixel's centre ray enters the medium"
                    } else {
                        ""
                    },
                    mip_text(asked_levels.reuse, plan.levels.levels.reuse),
                    if plan.vertex_reuse {
                        "vertex"
                    } else {
                        "direction"
                    }
                )
            } else if s.spatial_neighbors > 0
                && s.spatial_rounds > 0
                && plan.spatial_when == nimbus_scene::SpatialWhen::CameraMoves
            {
                "spatial_when = \"camera_moves\" and the camera does not move (it pays where the \
                 temporal history is weak, docs/restir.md)"
                    .into()
            } else if s.spatial_neighbors > 0
                && s.spatial_rounds > 0
                && plan.spatial_when == nimbus_scene::SpatialWhen::CameraOrDensity
            {
                "spatial_when = \"camera_or_density\" and neither the camera nor the density \
                 moves (it pays where the temporal history is weak, docs/restir.md)"
                    .into()
            } else {
                "spatial_neighbors or spatial_rounds is 0".into()
            },
        ),
        on(
            "pass restir shade",
            true,
            format!(
                "{}{}",
                if s.final_ratio_tracking {
                    "F with ratio-tracking transmittance (global majorant)"
                } else {
                    "F with closed-form transmittance through the trilinear grid"
                },
                if plan.has_emission
                    && s.camera_emission == nimbus_scene::CameraEmission::Stratified
                {
                    ", plus the camera ray's emission by 8 samples stratified in sigma_t T \
                     (exact inversion of the optical depth) (camera_emission = \"stratified\", SC_CAMERA_EMISSION)"
                } else {
                    ""
                }
            ),
        ),
        on(
            "  SC_HAS_SHAPES",
            plan.has_shapes,
            if plan.has_shapes {
                format!(
                    "{} shape(s): surface vertices in the walks and the stored paths, visibility in \
                     every target and in final shading",
                    scene.shapes.len()
                )
            } else {
                "no shapes: surface code compiled out".into()
            },
        ),
        super::meshes_decision(scene),
        area_lights_decision(scene),
        sphere_lights_decision(scene),
        gobos_decision(scene),
        on(
            "  SC_NEE_SPLIT",
            plan.nee_split,
            if plan.nee_split {
                "every directional and point light plus one environment sample at each vertex: \
                 a path carries the mix of sun and sky its vertex receives"
                    .into()
            } else if s.nee == nimbus_scene::NeeMode::One {
                "[integrator.restir] nee = \"one\": one light per vertex, chosen by power".into()
            } else {
                "one light per vertex, chosen by power (split needs directional or point lights \
                 and an environment alone besides)"
                    .into()
            },
        ),
        on(
            "  SC_FOLD_EMISSION",
            plan.fold_emission,
            if plan.fold_emission {
                "each medium vertex's emission joins its split-NEE candidate (weighted by the \
                 environment sample's density)"
                    .into()
            } else if s.fold_emission {
                "emission = \"folded\" needs an emitting grid, and split NEE or an \
                 environment as the only light: emission paths are candidates of their own"
                    .into()
            } else {
                "emission paths are candidates of their own (emission = \"separate\")".into()
            },
        ),
        on(
            "  SC_ENV_REUSE_MAP",
            plan.env_reuse_map,
            if plan.env_reuse_map {
                "reused environment samples keep their direction in the map's frame: they turn \
                 with a turning map (a small sun keeps its samples)"
                    .into()
            } else if has_env_map {
                "reused environment samples keep their world direction (env_reuse = \"world\")"
                    .into()
            } else {
                "no environment map".into()
            },
        ),
        on(
            "  SC_CANDIDATE_DELTA",
            plan.candidate_delta,
            tracking_reason(s, &plan),
        ),
        on(
            "  SC_DIRECT_EACH_WALK",
            plan.direct_each_walk,
            if plan.candidate_delta {
                "delta-tracked walks add what the camera ray sees where they escape, with \
                 weight L exactly ([integrator.restir] direct applies to regular tracking)"
                    .into()
            } else if plan.direct_each_walk {
                "every walk adds what its camera ray sees behind the medium as a candidate \
                 (target L T* of the whole camera segment)"
                    .into()
            } else {
                "[integrator.restir] direct = \"escape\": only walks that escape the camera \
                 segment add what it sees (the paper's)"
                    .into()
            },
        ),
        on(
            "  SC_PC_BUFFER",
            s.pc_fetch == nimbus_scene::DensityFetch::Buffer,
            match s.pc_fetch {
                nimbus_scene::DensityFetch::Auto => {
                    "[integrator.restir] pc_fetch = \"auto\": regular tracking reads sigma_t* \
                     from a slot-major storage buffer of the piecewise-constant levels on a CPU \
                     device where it takes at most 128 MiB (lavapipe: a texelFetch is a call \
                     into the sampler's code, a buffer load one loop over the lanes), from \
                     their atlas image on a GPU"
                        .into()
                }
                nimbus_scene::DensityFetch::Image => {
                    "[integrator.restir] pc_fetch = \"image\": the levels' atlas image, by \
                     texelFetch"
                        .into()
                }
                nimbus_scene::DensityFetch::Buffer => {
                    "[integrator.restir] pc_fetch = \"buffer\": a slot-major storage buffer of \
                     the piecewise-constant levels (9^3 floats per slot)"
                        .into()
                }
            },
        ),
        on(
            "  SC_DENSITY_BUFFER",
            s.density_fetch == nimbus_scene::DensityFetch::Buffer,
            match s.density_fetch {
                nimbus_scene::DensityFetch::Auto => {
                    "[integrator.restir] density_fetch = \"auto\": this frame's density \
                     (vertices, delta tracking, final shading's closed-form transmittance) and \
                     the ray marches' mips are read from storage buffers of quads on a CPU \
                     device where each takes at most 128 MiB (lavapipe: a trilinear lookup \
                     from one is two 16-byte loads, from an atlas eight texelFetch calls or a \
                     filtered textureLod), from the atlas images on a GPU"
                        .into()
                }
                nimbus_scene::DensityFetch::Image => {
                    "[integrator.restir] density_fetch = \"image\": the density's atlas image \
                     by texelFetch, the march mips' by linear filtering"
                        .into()
                }
                nimbus_scene::DensityFetch::Buffer => {
                    "[integrator.restir] density_fetch = \"buffer\": storage buffers of the \
                     density's slots (10^3 quads per slot, the baseline's layout) and of the \
                     march mips' (9^3 quads per slot)"
                        .into()
                }
            },
        ),
        on(
            "  SC_HAS_MEDIA (boxes)",
            plan.has_boxes,
            format!(
                "{boxes} homogeneous box medium(s) beside the grid: tracked exactly, closed-form \
                 transmittance"
            ),
        ),
        on(
            "  SC_HAS_EMISSION",
            plan.has_emission,
            if plan.has_emission {
                "the grid emits: emission candidates at every vertex".into()
            } else {
                "the grid does not emit: its emission candidates compiled out".into()
            },
        ),
        blackbody_decision(grid),
        albedo_grid_decision(grid),
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
        {
            let cache = plan.keeps_shade_cache(&super::AovPlan::of(scene));
            on(
                "  shade cache",
                cache,
                if cache {
                    "[integrator.restir] shade_cache = true: on a still frame (camera, lights \
                     and density as before) whose temporal reuse keeps a pixel's path, final \
                     shading reuses the F it evaluated for that path on the previous frame (16 \
                     bytes a pixel; the same images)"
                        .into()
                } else if !plan.settings.shade_cache {
                    "[integrator.restir] shade_cache = false: every frame evaluates F".into()
                } else {
                    "F is evaluated every frame: the cache needs temporal reuse with the aligned \
                     reprojection, the closed-form final transmittance, direction reuse and no \
                     path AOVs"
                        .into()
                },
            )
        },
        {
            let initial = plan.still_initial_target();
            on(
                "  SC_STILL_INITIAL_TARGET",
                initial,
                if initial {
                    "a still frame's temporal reuse resamples each reservoir by its own stored \
                     target (the fresh sample's initial target): no target evaluated"
                        .into()
                } else if !plan.builds_still_temporal() {
                    "no still temporal pipeline (temporal reuse off, or the paper's reprojection)"
                        .into()
                } else if plan.settings.still_target == nimbus_scene::StillTarget::Reuse {
                    "[integrator.restir] still_target = \"reuse\": a still frame's temporal \
                     reuse evaluates the fresh sample's reuse target"
                        .into()
                } else {
                    "still_target = \"auto\" with regularly tracked candidates (T* is in their \
                     target): a still frame's temporal reuse evaluates the fresh sample's reuse \
                     target"
                        .into()
                },
            )
        },
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
    ];
    Ok((Integrator::Restir(plan), decisions))
}

/// `settings` as far as the passes read them without spatial reuse: its spatial
/// settings are the defaults.
pub(super) fn without_spatial(
    settings: &nimbus_scene::RestirSettings,
) -> nimbus_scene::RestirSettings {
    let d = nimbus_scene::RestirSettings::default();
    nimbus_scene::RestirSettings {
        spatial_neighbors: 0,
        spatial_rounds: 0,
        spatial_radius_px: d.spatial_radius_px,
        spatial_when: d.spatial_when,
        spatial_shift: d.spatial_shift,
        spatial_max_history: d.spatial_max_history,
        spatial_feature_tolerance: d.spatial_feature_tolerance,
        spatial_anchor: d.spatial_anchor,
        ..settings.clone()
    }
}

/// A mip level of the plan for --explain: the level `used`, and whether it was chosen
/// from the content (`asked` is `None`: `auto`) or refined below the level `asked` (the
/// plan's notes say why).
fn mip_text(asked: Option<u32>, used: u32) -> String {
    match asked {
        None => format!("{used} (auto)"),
        Some(l) if l == used => used.to_string(),
        Some(l) => format!("{used} (refined from {l})"),
    }
}

/// SC_HAS_ALBEDO_GRID: whether the grid's albedo is read from a grid at every vertex.
fn albedo_grid_decision(grid: &nimbus_scene::GridMedium) -> Decision {
    Decision {
        name: "  SC_HAS_ALBEDO_GRID",
        enabled: grid.albedo_grid.is_some(),
        reason: if grid.albedo_grid.is_some() {
            "albedo grid: read trilinearly at every collision".into()
        } else {
            format!(
                "constant albedo {}: its grid lookups compiled out",
                grid.albedo
            )
        },
    }
}

/// SC_HAS_BLACKBODY: whether the grid's emission adds a temperature grid's blackbody
/// radiance.
fn blackbody_decision(grid: &nimbus_scene::GridMedium) -> Decision {
    Decision {
        name: "  SC_HAS_BLACKBODY",
        enabled: grid.temperature.is_some(),
        reason: match &grid.temperature {
            Some(t) => format!(
                "temperature grid: Le += {} x RGB({} K + {} K x temperature), table lookup",
                t.blackbody_scale, t.offset, t.scale
            ),
            None => "no temperature grid: blackbody lookups compiled out".into(),
        },
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    /// A grid scene rendered by `volume` with `[render] spp`.
    fn grid_scene(volume: &str, spp: u32) -> Scene {
        let text = format!(
            "[render]\nspp = {spp}\n[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n\
             [[medium]]\ntype = \"grid\"\nbounds_min = [-1, -1, -1]\nbounds_max = [1, 1, 1]\n\
             density = {{ procedural = \"cloud\", dims = [4, 4, 4] }}\n\
             [integrator]\nvolume = \"{volume}\"\n"
        );
        nimbus_scene::parse_str(&text, Path::new("spp.toml")).unwrap()
    }

    /// `candidate_tracking = "auto"`: delta tracking where the candidates' level misses
    /// the field (the test cloud's voxel-scale noise at mip 1), where temporal reuse is
    /// off, and where the density is animated; regular tracking on the smooth benchmark
    /// cumulus under temporal reuse; "delta" and "regular" as asked. `--explain` says why.
    #[test]
    fn auto_candidate_tracking_follows_the_content_and_the_history() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        use nimbus_scene::FieldOverride;
        let plan = |file: &str, overrides: &[FieldOverride]| {
            let scene = crate::load_scene(Some(&root.join(file)), overrides).unwrap();
            match build(&scene, crate::plan::Product::Frames).unwrap().0 {
                Integrator::Restir(p) => (p.candidate_delta, p.direct_each_walk, scene),
                _ => panic!("{file}: not ReSTIR"),
            }
        };
        let noisy = "assets/scenes/cloud-restir.toml";
        let smooth = "assets/scenes/bench/cloud-g0.toml";
        assert!(plan(noisy, &[]).0);
        let (delta, each_walk, scene) = plan(smooth, &[]);
        assert!(!delta && each_walk);
        let restir = match build(&scene, crate::plan::Product::Frames).unwrap().0 {
            Integrator::Restir(p) => p,
            _ => unreachable!(),
        };
        let why = tracking_reason(&restir.settings, &restir);
        assert!(why.contains("fits the field (march error 0.030"), "{why}");
        assert!(
            plan(
                smooth,
                &[FieldOverride::new("integrator.restir.temporal", false)]
            )
            .0
        );
        assert!(plan("assets/scenes/plume-anim.toml", &[]).0);
        let (delta, each_walk, _) = plan(
            smooth,
            &[FieldOverride::new(
                "integrator.restir.candidate_tracking",
                "delta",
            )],
        );
        assert!(delta && !each_walk);
        assert!(
            !plan(
                noisy,
                &[FieldOverride::new(
                    "integrator.restir.candidate_tracking",
                    "regular"
                )]
            )
            .0
        );
    }

    /// ReSTIR draws one path per pixel per frame: spp > 1 would be ignored, so it is
    /// refused with what sets its work instead; the baseline takes any spp.
    #[test]
    fn restir_refuses_more_than_one_sample_per_pixel() {
        let message = format!(
            "{:#}",
            build(&grid_scene("restir", 4), crate::plan::Product::Frames).unwrap_err()
        );
        for needle in [
            "spp.toml",
            "[render]",
            "`spp` = 4",
            "Volumetric ReSTIR",
            "[integrator.restir] `candidates`",
            "`frames`",
        ] {
            assert!(message.contains(needle), "{needle:?} missing: {message}");
        }
        assert!(build(&grid_scene("restir", 1), crate::plan::Product::Frames).is_ok());
        let (integrator, _) =
            build(&grid_scene("baseline", 4), crate::plan::Product::Frames).unwrap();
        assert!(matches!(integrator, Integrator::Baseline(_)));
    }

    /// The baseline's `nee`: "auto" splits with one delta light among others at K = 1, and
    /// at any K where the other light is a constant sky (which then rides on the path's
    /// next segment), not with a sphere light at K = 3, the sun alone or two delta lights;
    /// "split" splits wherever a delta light has company; "one" never. `--explain` names
    /// the choices.
    #[test]
    fn the_baseline_splits_next_event_estimation_where_it_measured_faster() {
        let plan = |lights: &str, bounces: u32, nee: &str| {
            let text = format!(
                "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n{lights}\
                 [[medium]]\ntype = \"grid\"\nbounds_min = [-1, -1, -1]\nbounds_max = [1, 1, 1]\n\
                 density = {{ procedural = \"cloud\", dims = [4, 4, 4] }}\n\
                 [integrator]\nvolume = \"baseline\"\nmax_bounces = {bounces}\n\
                 [integrator.baseline]\nnee = \"{nee}\"\n"
            );
            let scene = nimbus_scene::parse_str(&text, Path::new("nee.toml")).unwrap();
            let (integrator, decisions) = build(&scene, crate::plan::Product::Frames).unwrap();
            let Integrator::Baseline(plan) = integrator else {
                panic!("not the baseline")
            };
            let row = |name: &str| {
                decisions
                    .iter()
                    .find(|d| d.name.trim() == name)
                    .unwrap_or_else(|| panic!("no {name} row"))
                    .clone()
            };
            assert_eq!(row("SC_NEE_SPLIT").enabled, plan.nee_split);
            assert_eq!(row("SC_SKY_ALONG_PATH").enabled, plan.sky_along_path);
            (
                plan.nee_split,
                plan.sky_along_path,
                row("SC_NEE_SPLIT").reason,
            )
        };
        let sun = "[[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 3\n";
        let sky = "[[light]]\ntype = \"environment\"\nradiance = 0.3\n";
        let point = "[[light]]\ntype = \"point\"\nposition = [0, 2, 0]\nintensity = 3\n";
        let bulb = "[[light]]\ntype = \"sphere\"\ncenter = [0, 3, 0]\nradius = 0.2\nradiance = 5\n";
        let sun_sky = format!("{sun}{sky}");
        let sun_bulb = format!("{sun}{bulb}");
        let two_deltas_sky = format!("{sun}{point}{sky}");
        assert!(plan(&sun_sky, 1, "auto").0);
        assert!(!plan(&sun_sky, 1, "auto").1);
        assert!(plan(&sun_sky, 3, "auto").0);
        assert!(plan(&sun_sky, 3, "auto").1);
        assert!(plan(&sun_bulb, 1, "auto").0);
        assert!(!plan(&sun_bulb, 3, "auto").0);
        assert!(!plan(sun, 1, "auto").0);
        assert!(!plan(sky, 1, "auto").0);
        assert!(!plan(&two_deltas_sky, 1, "auto").0);
        assert!(plan(&two_deltas_sky, 3, "split").1);
        assert!(plan(&sun_bulb, 3, "split").0);
        assert!(!plan(&sun_bulb, 3, "split").1);
        assert!(!plan(sky, 3, "split").0);
        assert!(!plan(&sun_sky, 3, "one").0);
        let (_, _, why) = plan(&sun_bulb, 3, "auto");
        assert!(
            why.contains("K = 3") && why.contains("nee = \"split\""),
            "{why}"
        );
        let (_, _, why) = plan(&sun_sky, 1, "auto");
        assert!(why.contains("1 delta") && why.contains("1 other"), "{why}");
    }
}
