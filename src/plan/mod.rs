//! The render plan: which integrator and shader features a scene needs, and why.
//!
//! A scene decides what runs: a pass the scene does not need is not created, and a
//! shader feature it does not use is compiled out through a specialization constant.
//! Features of the scene format that no pass renders yet are errors here, naming the
//! scene file and the table, never silently skipped.
//!
//! [`build`] picks one [`Integrator`] (box scenes: `boxes.rs`; grid scenes: `volume.rs`)
//! and one decision table, [`RenderPlan::decisions`]: a row for every pass the renderer
//! has (from [`PASSES`]) and every feature of the chosen one, on or off with the
//! reason. `nimbus render --explain` prints that table.
//!
//! The plan decides everything a pass reads, so that `--explain` shows the real
//! decisions and the data flows one way (scene → plan → passes → renderer → output):
//! ReSTIR's mip levels ([`levels`]: chosen from the grids' content when the plan is
//! built), its reservoir slots ([`RestirPlan::reservoir_slots`]), the error batches
//! ([`error_batch`]), and the render's memory footprint ([`footprint`]:
//! `crate::budget::Footprint::of`, from the plan and the files' headers alone), which the
//! renderer checks before it allocates anything.

pub mod aovs;
mod boxes;
pub mod footprint;
pub mod levels;
mod volume;

use std::fmt::Write as _;

use anyhow::Result;
use nimbus_scene::{BoxEstimator, GridMedium, Light, Medium, RestirSettings, Scene};

use crate::shader_data::features;

pub use aovs::AovPlan;
pub use levels::{
    load_frames, AskedLevels, LevelChoice, Levels, MAX_AUTO_LEVEL, MAX_LEVEL_EXCESS_TAU,
    MAX_MARCH_ERROR, MIN_AUTO_INDIRECT,
};
pub use volume::{MAX_BASELINE_LIGHTS, MAX_RESTIR_BOUNCES, MAX_SPATIAL_NEIGHBORS};

/// Most box media the crepuscular pass takes (`MAX_MEDIA` in features.glsl).
pub const MAX_BOX_MEDIA: usize = features::MAX_MEDIA as usize;
/// Most directional lights the crepuscular pass takes (`MAX_LIGHTS` in features.glsl).
pub const MAX_DIRECTIONAL_LIGHTS: usize = features::MAX_LIGHTS as usize;

/// The passes and features for one scene.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderPlan {
    pub integrator: Integrator,
    /// Every pass the renderer knows and every feature of the chosen one, with whether
    /// it is on and why: the table `--explain` prints.
    pub decisions: Vec<Decision>,
    /// The output layers beside the beauty (`[render] aovs`).
    pub aov: AovPlan,
}

/// The integrator that renders a scene, with its settings.
#[derive(Clone, Debug, PartialEq)]
pub enum Integrator {
    /// Box media and surfaces under collimated light: `passes::crepuscular`.
    Crepuscular(CrepuscularPlan),
    /// One grid medium by decomposition + residual ratio tracking: `passes::baseline`.
    Baseline(BaselinePlan),
    /// One grid medium by Volumetric ReSTIR: `passes::restir`.
    Restir(RestirPlan),
}

/// Which integrator, without its settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IntegratorKind {
    Crepuscular,
    Baseline,
    Restir,
}

/// Every pass the renderer has, in `--explain` order, with the integrator that runs it.
pub const PASSES: [(IntegratorKind, &str); 3] = [
    (IntegratorKind::Crepuscular, "pass crepuscular"),
    (IntegratorKind::Baseline, "pass baseline path tracer"),
    (
        IntegratorKind::Restir,
        "pass restir (initial, temporal, spatial, shade)",
    ),
];

impl Integrator {
    pub fn kind(&self) -> IntegratorKind {
        match self {
            Integrator::Crepuscular(_) => IntegratorKind::Crepuscular,
            Integrator::Baseline(_) => IntegratorKind::Baseline,
            Integrator::Restir(_) => IntegratorKind::Restir,
        }
    }
}

/// Settings of the crepuscular-ray (box medium / direct lighting) pass.
#[derive(Clone, Debug, PartialEq)]
pub struct CrepuscularPlan {
    pub estimator: BoxEstimator,
    pub samples_along_ray: u32,
    /// Texels per side of the ME estimator's moment maps.
    pub moment_map_size: u32,
    /// K: scattering orders 1..=K are summed (1 = single scattering).
    pub max_bounces: u32,
    pub features: CrepuscularFeatures,
}

/// The crepuscular pass's specialization constants.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CrepuscularFeatures {
    pub has_media: bool,
    /// Some media are convex polyhedra.
    pub has_convex: bool,
    /// Entries of the shaders' piece tables: the most light-facing planes of any medium
    /// and light (3 for boxes).
    pub max_pieces: u32,
    pub has_shapes: bool,
    /// Some shapes are triangle meshes (BVH traversal compiled in).
    pub has_meshes: bool,
    pub has_gobos: bool,
    /// An environment light: seen by camera rays, and lighting media and surfaces.
    pub has_env: bool,
    /// The environment is an importance-sampled map (else a constant radiance).
    pub has_env_map: bool,
    pub pixel_jitter: bool,
}

/// Settings of the baseline path tracer for grid media (decomposition tracking and
/// residual ratio tracking on super-voxels).
#[derive(Clone, Debug, PartialEq)]
pub struct BaselinePlan {
    /// K: scattering orders 1..=K.
    pub max_bounces: u32,
    /// Homogeneous box media beside the grid.
    pub has_boxes: bool,
    /// Some of them are convex polyhedra (`type = "convex"`).
    pub has_convex: bool,
    /// The grid emits (an emission grid, a temperature grid or both).
    pub has_emission: bool,
    /// The grid has a temperature grid (blackbody emission).
    pub has_blackbody: bool,
    /// The grid's albedo is a grid.
    pub has_albedo_grid: bool,
    pub has_shapes: bool,
    /// Some shapes are triangle meshes.
    pub has_meshes: bool,
    /// Some shapes emit (area lights: the emitter table is sampled).
    pub has_area_lights: bool,
    /// Some light is a sphere light (SC_HAS_SPHERE_LIGHTS).
    pub has_sphere_lights: bool,
    /// Some directional light has a gobo (SC_HAS_GOBOS).
    pub has_gobos: bool,
    pub has_env: bool,
    pub has_env_map: bool,
    pub pixel_jitter: bool,
    /// Split next-event estimation (SC_NEE_SPLIT): every delta light at every vertex,
    /// plus one sample of the other lights.
    pub nee_split: bool,
    /// With `nee_split`, where the other lights are a constant environment alone: its
    /// NEE rides on the path's next segment (SC_SKY_ALONG_PATH).
    pub sky_along_path: bool,
    /// Where the density is read from (SC_DENSITY_BUFFER): `Auto` is settled by the
    /// device when the pass is created.
    pub density_fetch: nimbus_scene::DensityFetch,
}

/// Settings of the Volumetric ReSTIR passes (initial, temporal, spatial, shade).
#[derive(Clone, Debug, PartialEq)]
pub struct RestirPlan {
    /// The scene's `[integrator.restir]` settings as far as the passes read them (without
    /// spatial reuse its spatial settings are the defaults: one plan whatever they say).
    /// A setting the passes take as it is (M = `candidates`, `final_ratio_tracking`,
    /// `sigma_star_floor`, the mip levels asked for) is read from here, so a new one is
    /// added to the scene format alone; the fields below are what the plan derives from
    /// the settings and the scene (`temporal`, `temporal_limit`, `spatial_rounds` and
    /// `spatial_max_history` are the settings' own values, kept as fields for the study
    /// harness, which reads and resets them).
    pub settings: RestirSettings,
    /// K: scattering events per path, 1..=MAX_RESTIR_BOUNCES.
    pub max_bounces: u32,
    /// The grid emits (an emission grid, a temperature grid or both).
    pub has_emission: bool,
    /// The grid has a temperature grid (blackbody emission).
    pub has_blackbody: bool,
    /// The grid's albedo is a grid.
    pub has_albedo_grid: bool,
    pub has_env: bool,
    pub has_env_map: bool,
    pub pixel_jitter: bool,
    /// The medium has a velocity grid for temporal reprojection.
    pub has_velocity: bool,
    /// The density changes over the frames ([[medium.frame]]).
    pub animated_density: bool,
    /// Temporal reuse runs (from the second frame on).
    pub temporal: bool,
    /// Q: the previous frame's M is clamped to Q·M.
    pub temporal_limit: u32,
    /// Q on the frames whose camera moved, whose density frame changed or (under
    /// `env_reuse = "map"`) whose environment map turned: the smaller of `temporal_limit`
    /// and `temporal_limit_moving` (`temporal_limit` where no frame does
    /// ([`has_moving_frames`])).
    pub temporal_limit_moving: u32,
    pub spatial_neighbors: u32,
    pub spatial_radius_px: f32,
    /// On which frames spatial reuse runs: every frame, or only those whose camera (and
    /// with `"camera_or_density"` also whose density frame) differs from the previous
    /// frame's.
    pub spatial_when: nimbus_scene::SpatialWhen,
    pub spatial_rounds: u32,
    /// Vertex reuse instead of direction reuse.
    pub vertex_reuse: bool,
    /// The mip levels the passes use, chosen from the grids' content when the plan is
    /// built ([`LevelChoice::of`]).
    pub levels: LevelChoice,
    /// Pairwise MIS in spatial reuse instead of Talbot's.
    pub pairwise_mis: bool,
    /// Spatial reuse moves x_1 by its optical depth through the conservative grid
    /// (`spatial_shift = "optical_depth"`; the grid alone carries the majorant: with box
    /// or convex media the distance shift is kept).
    pub spatial_tau_shift: bool,
    /// ... by the exact optical depth through the grid's own density
    /// (`spatial_shift = "optical_depth_exact"`; SC_SPATIAL_TAU_EXACT).
    pub spatial_tau_exact: bool,
    /// Temporal reuse moves a medium x_1 by its optical depth through the grid's own
    /// density on the frames whose density did not change (`temporal_shift =
    /// "optical_depth"`, with the grid as the only medium; SC_TEMPORAL_TAU_SHIFT).
    pub temporal_tau_shift: bool,
    /// Emission folded into the split-NEE candidates (`emission = "folded"`, with split
    /// NEE and an emitting grid only).
    pub fold_emission: bool,
    /// Reservoirs keep an environment map sample's direction in the map's frame
    /// (`env_reuse = "map"`, with an environment map).
    pub env_reuse_map: bool,
    /// Spatial reuse only where the reservoir's M after temporal reuse is below this
    /// many times M (0: everywhere).
    pub spatial_max_history: f32,
    /// The temporal stage's output (not the spatial one) is the next frame's history.
    pub history_before_spatial: bool,
    /// Split next-event estimation (SC_NEE_SPLIT): every delta light plus one
    /// environment sample at each vertex.
    pub nee_split: bool,
    /// Every walk adds the camera ray's end as a candidate (`direct = "each_walk"`), not
    /// only walks that escape (the paper's). Regular tracking only.
    pub direct_each_walk: bool,
    /// Candidates by decomposition tracking on the exact density (`candidate_tracking =
    /// "delta"`, SC_CANDIDATE_DELTA), else by regular tracking through the
    /// piecewise-constant grid.
    pub candidate_delta: bool,
    /// Opaque shapes beside the grid: paths get surface vertices (SC_HAS_SHAPES).
    pub has_shapes: bool,
    /// Some shapes are triangle meshes (SC_HAS_MESHES).
    pub has_meshes: bool,
    /// Homogeneous box media beside the grid (SC_HAS_MEDIA).
    pub has_boxes: bool,
    /// Some of them are convex polyhedra (SC_HAS_CONVEX).
    pub has_convex: bool,
    /// Some shapes emit: area lights in NEE, emission seen by camera rays
    /// (SC_HAS_AREA_LIGHTS).
    pub has_area_lights: bool,
    /// Some light is a sphere light (SC_HAS_SPHERE_LIGHTS).
    pub has_sphere_lights: bool,
    /// Some directional light has a gobo (SC_HAS_GOBOS).
    pub has_gobos: bool,
}

impl CrepuscularPlan {
    /// Whether the plan runs the moment-map stage: ME in a scene whose shapes can shadow
    /// the media (without shapes every visibility ratio is 1 and no map is needed).
    pub fn needs_moment_maps(&self) -> bool {
        self.estimator == BoxEstimator::Me && self.features.has_shapes && self.features.has_media
    }
}

/// Mip levels of a moment map of `size` texels per side (a power of two).
pub fn moment_levels(size: u32) -> u32 {
    size.max(1).ilog2() + 1
}

/// Texels of one light's moment map and its mip chain.
pub fn moment_texels_per_light(size: u64) -> u64 {
    (0..moment_levels(size as u32))
        .map(|k| (size >> k) * (size >> k))
        .sum()
}

impl RestirPlan {
    /// M on the frames whose temporal history is full (`candidates_settled`), where it
    /// is fewer than `candidates`; `None` where every frame draws `candidates` (no
    /// temporal reuse, or a settled M of at least M).
    pub fn candidates_settled(&self) -> Option<u32> {
        let s = &self.settings;
        (self.temporal && s.candidates_settled < s.candidates).then_some(s.candidates_settled)
    }

    /// Whether spatial reuse runs.
    pub fn spatial(&self) -> bool {
        self.spatial_neighbors > 0 && self.spatial_rounds > 0
    }

    /// What the plan decided from the grid's content that the user should know (the
    /// levels chosen or refined), one sentence each.
    pub fn notes(&self) -> Vec<String> {
        self.levels.reasons(self.asked_levels())
    }

    /// The mip levels the scene asks for (`auto` ones: `None`); the footprint bounds what
    /// they can become.
    pub fn asked_levels(&self) -> AskedLevels {
        AskedLevels::of(&self.settings)
    }

    /// The plan as a pass that reads this frame's density from its buffer of quads
    /// (`density_fetch`, which the pass decides with the device) renders it, if that
    /// changes anything: there `candidate_tracking = "auto"` takes delta tracking wherever
    /// the plan took regular tracking. An exact trilinear lookup from the buffer costs
    /// about what regular tracking's conservative-grid lookups do (lavapipe, 160x120,
    /// K = 3: 1.00-1.03x the frame), so the tracking ratio's variance is left out for
    /// free (per-frame MSE 0.89-0.93x; docs/restir.md, "Which tracking").
    pub fn with_density_buffer(&self) -> Option<RestirPlan> {
        let auto = self.settings.candidate_tracking == nimbus_scene::CandidateTracking::Auto;
        (auto && !self.candidate_delta).then(|| RestirPlan {
            candidate_delta: true,
            direct_each_walk: false,
            ..self.clone()
        })
    }

    /// The reservoir slots the plan's schedule uses ([`reservoir_slots`]).
    pub fn reservoir_slots(&self) -> u32 {
        reservoir_slots(
            self.spatial_neighbors,
            self.spatial_rounds,
            self.history_before_spatial,
        )
    }

    /// Whether the pass builds the temporal stage's still pipeline: temporal reuse with the
    /// aligned reprojection (the paper's reprojection keeps its own walk on still frames).
    pub fn builds_still_temporal(&self) -> bool {
        self.temporal
            && self.settings.temporal_reprojection == nimbus_scene::TemporalReprojection::Aligned
    }

    /// Whether the pass keeps the shade cache (`shade_cache`, on by default): the RGB F
    /// that final shading evaluated for each pixel's path, reused on a still frame whose
    /// temporal stage (the still pipeline, [`Self::builds_still_temporal`]) kept that path
    /// (restir/shade.comp). F must then be a function of the path alone: the closed-form
    /// transmittance (ratio tracking draws random numbers), direction reuse (vertex reuse
    /// re-expresses x_2 when it stores a kept path, which may round), and no path AOVs
    /// (they split F into slots the cache does not hold).
    pub fn keeps_shade_cache(&self, aov: &AovPlan) -> bool {
        self.builds_still_temporal()
            && !self.settings.final_ratio_tracking
            && self.settings.reuse == nimbus_scene::ReuseMode::Direction
            && aov.path_slots() == 0
            && self.settings.shade_cache
    }

    /// Whether the still temporal pipeline resamples each reservoir by its own stored
    /// target, the fresh one's the initial pass's (SC_STILL_INITIAL_TARGET;
    /// restir/temporal.comp, combine_still), so that it evaluates no target:
    /// `still_target = "initial"`, or `"auto"` where the candidates are delta tracked
    /// (their target has the walked segments' exact T; regular tracking's has T*, far
    /// below T in dense voxels, and final shading divides by it).
    pub fn still_initial_target(&self) -> bool {
        self.builds_still_temporal()
            && match self.settings.still_target {
                nimbus_scene::StillTarget::Auto => self.candidate_delta,
                nimbus_scene::StillTarget::Initial => true,
                nimbus_scene::StillTarget::Reuse => false,
            }
    }
}

/// Bytes per pixel of ReSTIR's shade cache ([`RestirPlan::keeps_shade_cache`]): RGB F and
/// a flag, four u32s.
pub const SHADE_CACHE_BYTES_PER_PIXEL: u64 = 16;

/// The reservoir slots ReSTIR's schedule needs: 2 (initial and temporal in one, the
/// previous frame's history in the other, spatial rounds alternating between them), or 3
/// when the history is taken before spatial reuse and that slot must survive two or more
/// spatial rounds (`passes::restir::schedule`).
pub fn reservoir_slots(
    spatial_neighbors: u32,
    spatial_rounds: u32,
    history_before_spatial: bool,
) -> u32 {
    let spatial = spatial_neighbors > 0 && spatial_rounds > 0;
    if spatial && history_before_spatial && spatial_rounds >= 2 {
        3
    } else {
        2
    }
}

/// The frame's M and Q: `candidates` and `temporal_limit`, or on a frame whose history
/// is full the settled M with the Q that keeps the history's cap of `temporal_limit` ·
/// `candidates` candidates (the temporal pass caps the previous M at Q·M of the frame's
/// own; rounded, at least 1).
pub fn settled_candidates(
    candidates: u32,
    temporal_limit: u32,
    settled: Option<u32>,
) -> (u32, u32) {
    match settled {
        Some(m) if m > 0 && m < candidates => {
            let cap = u64::from(temporal_limit) * u64::from(candidates);
            let m64 = u64::from(m);
            let q = ((cap + m64 / 2) / m64).clamp(1, u64::from(u32::MAX));
            (m, q as u32)
        }
        _ => (candidates, temporal_limit),
    }
}

/// Frames per batch of the error estimate for `plan`: ReSTIR's temporal reuse carries
/// each reservoir's history into the next frames, with weight capped at Q times the
/// frame's own (Q = `temporal_limit`), so a frame's influence decays roughly like
/// (Q/(Q+1))^k after k frames; batches of 4·(Q + 1) frames hold most of it (about 2%
/// leaks into the next batch at Q = 4). Every other integrator draws fresh random
/// numbers each frame: 1.
pub fn error_batch(plan: &RenderPlan) -> u32 {
    match plan.restir() {
        Some(p) if p.temporal => {
            // Settled frames (`candidates_settled`) keep the history's Q·M candidates with
            // fewer of their own, so their Q is the larger one.
            let (_, q) = settled_candidates(
                p.settings.candidates,
                p.temporal_limit,
                p.candidates_settled(),
            );
            4u32.saturating_mul(q.saturating_add(1))
        }
        _ => 1,
    }
}

/// The grid medium of `scene` with density frames and its index among the media.
pub fn animated_grid(scene: &Scene) -> Option<(usize, &GridMedium)> {
    scene.media.iter().enumerate().find_map(|(i, m)| match m {
        Medium::Grid(g) if !g.frames.is_empty() => Some((i, g)),
        _ => None,
    })
}

/// Whether `scene`'s grid medium has density frames.
pub fn has_density_frames(scene: &Scene) -> bool {
    animated_grid(scene).is_some()
}

/// The static scene of density grid `index` (0: the base `density`, i: the i-th
/// `[[medium.frame]]`'s): the grid's density and the temperature, albedo and emission
/// grids in effect with it replaced, its frames dropped.
pub fn scene_of_grid(scene: &Scene, index: usize) -> Scene {
    let mut s = scene.clone();
    if let Some((m, grid)) = animated_grid(scene) {
        let density = grid
            .density_sources()
            .nth(index)
            .cloned()
            .unwrap_or_else(|| grid.density.clone());
        let temperature = grid.temperature_source_at_index(index).cloned();
        let albedo = grid.albedo_source_at_index(index).cloned();
        let emission = grid.emission_source_at_index(index).cloned();
        if let Medium::Grid(g) = &mut s.media[m] {
            g.density = density;
            if let (Some(t), Some(source)) = (g.temperature.as_mut(), temperature) {
                t.source = source;
            }
            g.albedo_grid = albedo;
            g.emission = emission;
            g.frames.clear();
        }
    }
    s
}

/// One line of `--explain`: a pass or feature, in or out, and the reason.
#[derive(Clone, Debug, PartialEq)]
pub struct Decision {
    pub name: &'static str,
    pub enabled: bool,
    pub reason: String,
}

impl Decision {
    pub fn new(name: &'static str, enabled: bool, reason: impl Into<String>) -> Decision {
        Decision {
            name,
            enabled,
            reason: reason.into(),
        }
    }
}

/// The `SC_HAS_MESHES` row of a plan: on with the scene's meshes, their triangles and
/// BVH nodes, else why the traversal is compiled out.
pub fn meshes_decision(scene: &Scene) -> Decision {
    let meshes: Vec<&nimbus_scene::MeshShape> = scene
        .shapes
        .iter()
        .filter_map(|s| match s {
            nimbus_scene::Shape::Mesh { mesh, .. } => Some(mesh.as_ref()),
            _ => None,
        })
        .collect();
    if meshes.is_empty() {
        return Decision::new(
            "  SC_HAS_MESHES",
            false,
            "no mesh shapes: BVH traversal compiled out",
        );
    }
    let (nodes, triangles) = crate::shader_data::meshes::mesh_counts(scene);
    let depth = meshes.iter().map(|m| m.bvh.depth()).max().unwrap_or(0);
    let dropped: u64 = meshes.iter().map(|m| m.dropped_degenerate).sum();
    let build_ms: f64 = meshes.iter().map(|m| m.bvh_build_seconds).sum::<f64>() * 1e3;
    let mut reason = format!(
        "{} mesh(es), {triangles} triangles, {nodes} BVH nodes (deepest leaf at depth {depth}, \
         built in {build_ms:.0} ms on load): stack traversal, watertight ray-triangle test",
        meshes.len()
    );
    if dropped > 0 {
        reason += &format!("; {dropped} degenerate triangle(s) dropped on load");
    }
    Decision::new("  SC_HAS_MESHES", true, reason)
}

/// The index of the scene's environment-map light, if it has one; a map beside another
/// environment light is refused (each pass samples one environment), naming the light.
pub fn environment_map(scene: &Scene) -> Result<Option<usize>> {
    use nimbus_scene::Light;
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
        anyhow::bail!(
            "{}: [[light]] #{}: an environment map cannot be combined with another environment light",
            scene.source.display(),
            i + 1
        );
    }
    Ok(env_map)
}

/// The estimator ids of `SC_ESTIMATOR` in `shaders/box/crepuscular.comp`.
pub fn estimator_id(estimator: BoxEstimator) -> u32 {
    match estimator {
        BoxEstimator::Mcwvds => features::ESTIMATOR_MCWVDS,
        BoxEstimator::Reds => features::ESTIMATOR_REDS,
        BoxEstimator::Rees => features::ESTIMATOR_REES,
        BoxEstimator::Rm => features::ESTIMATOR_RM,
        BoxEstimator::Mcds => features::ESTIMATOR_MCDS,
        BoxEstimator::Me => features::ESTIMATOR_ME,
    }
}

/// What a render makes of its frames. It decides ReSTIR's `temporal = "auto"`: temporal
/// reuse makes each frame better and the frames correlated, which pays where each frame
/// is looked at and not where only their mean is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Product {
    /// Each frame is an image (an animation, real-time frames, a profile, a per-frame
    /// study): temporal reuse on.
    Frames,
    /// The mean of the frames of a static scene is the image (`nimbus render` of a scene
    /// without keyframes or density frames): ReSTIR's frames independent (fresh
    /// candidates each frame, no temporal pass), 6x as efficient for that mean as
    /// temporal reuse's correlated frames on the benchmark cloud (docs/performance.md,
    /// "What a ReSTIR still can be"). An animated scene's frames are images whatever is
    /// asked.
    Still,
}

/// Build the plan for `scene` when each of its frames is an image ([`Product::Frames`]),
/// or say which part of it cannot be rendered yet. `samples_along_ray` overrides the
/// scene's `[integrator] box_samples`.
pub fn build(scene: &Scene, samples_along_ray: Option<u32>) -> Result<RenderPlan> {
    build_for(scene, samples_along_ray, Product::Frames)
}

/// [`build`] for what the render makes of its frames.
pub fn build_for(
    scene: &Scene,
    samples_along_ray: Option<u32>,
    product: Product,
) -> Result<RenderPlan> {
    let (integrator, rows) = if scene.media.iter().any(|m| matches!(m, Medium::Grid(_))) {
        volume::build(scene, product)?
    } else {
        boxes::build(scene, samples_along_ray)?
    };
    let plan = RenderPlan::new(scene, integrator, rows);
    // The baseline pass does not read a velocity field, so its motion AOV would show a
    // moving medium as still: refused rather than written wrong.
    if plan.baseline().is_some() && plan.aov.wants(nimbus_scene::Aov::Motion) {
        if let Some(i) = scene
            .media
            .iter()
            .position(|m| matches!(m, Medium::Grid(g) if g.velocity.is_some()))
        {
            anyhow::bail!(
                "{}: [render] aovs asks for motion and [[medium]] #{} has a velocity field, \
                 which the baseline integrator's motion AOV does not follow (it moves with \
                 the camera only): render it with [integrator] volume = \"restir\", whose \
                 motion follows the velocity, or leave motion out",
                scene.source.display(),
                i + 1
            );
        }
    }
    Ok(plan)
}

impl RenderPlan {
    /// The plan of `integrator`: its own rows (its pass first, then its features),
    /// followed by one "off" row for every other pass of [`PASSES`].
    fn new(scene: &Scene, integrator: Integrator, rows: Vec<Decision>) -> RenderPlan {
        let kind = integrator.kind();
        let mut decisions = rows;
        for (other, name) in PASSES {
            if other != kind {
                decisions.push(Decision::new(name, false, off_reason(scene, kind, other)));
            }
        }
        let aov = AovPlan::of(scene);
        if aov.any() {
            decisions.push(aov.decision());
        }
        RenderPlan {
            integrator,
            decisions,
            aov,
        }
    }

    pub fn crepuscular(&self) -> Option<&CrepuscularPlan> {
        match &self.integrator {
            Integrator::Crepuscular(p) => Some(p),
            _ => None,
        }
    }

    pub fn baseline(&self) -> Option<&BaselinePlan> {
        match &self.integrator {
            Integrator::Baseline(p) => Some(p),
            _ => None,
        }
    }

    pub fn restir(&self) -> Option<&RestirPlan> {
        match &self.integrator {
            Integrator::Restir(p) => Some(p),
            _ => None,
        }
    }

    /// What the plan decided from the scene's content that a render reports, one
    /// sentence each (ReSTIR's mip levels).
    pub fn notes(&self) -> Vec<String> {
        self.restir().map_or_else(Vec::new, RestirPlan::notes)
    }

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
        for note in self.notes() {
            let _ = writeln!(out, "  note: {note}");
        }
        if let Some(note) = self.stills_note(scene) {
            let _ = writeln!(out, "  note: {note}");
        }
        out
    }

    /// What to use for a still: the baseline, whose samples are independent and cheaper
    /// than ReSTIR's frames. A note for a static scene rendered by ReSTIR (whose output
    /// is the mean of its frames).
    pub fn stills_note(&self, scene: &Scene) -> Option<String> {
        let restir = self.restir()?;
        if scene.is_animated() {
            return None;
        }
        let (why, rest) = if restir.temporal {
            (
                "temporal reuse (temporal = true) makes ReSTIR's frames correlated real-time \
                 frames, and for a still the baseline is 8x as efficient",
                "; temporal = \"auto\" (the default) makes a still's frames independent (6x \
                 temporal reuse's efficiency, 0.7x the baseline's)",
            )
        } else {
            (
                "ReSTIR's frames are independent here (temporal reuse off: 6x its efficiency \
                 for a still, 2.8x Mitsuba 3's), and the baseline is still 1.4x as efficient",
                "",
            )
        };
        Some(format!(
            "this static scene renders a still, the mean of its frames; {why} (perf-cloud, \
             K = 3, lavapipe: error^2 x time, docs/performance.md): set [integrator] volume = \
             \"baseline\" (or --set integrator.volume=baseline) for stills, keep ReSTIR for \
             animations and real-time frames{rest}"
        ))
    }
}

/// Why pass `other` does not run when `chosen` renders `scene`.
fn off_reason(scene: &Scene, chosen: IntegratorKind, other: IntegratorKind) -> &'static str {
    use IntegratorKind::*;
    match (chosen, other) {
        (Crepuscular, _) => "no grid media",
        (_, Crepuscular) => {
            if scene.media.iter().any(|m| matches!(m, Medium::Box(_))) {
                "box media beside a grid are rendered by the volume integrator"
            } else {
                "no box media"
            }
        }
        (Baseline, _) => "[integrator] volume = \"baseline\"",
        (Restir, _) => "[integrator] volume = \"restir\"",
    }
}

#[cfg(test)]
mod tests;

/// The scene as far as its integrator reads it (what a study compares to render
/// configurations that only differ in unread settings once): the settings of the other integrators
/// are reset to their defaults (the box-medium pass reads neither `volume` nor
/// `[integrator.restir]`; the grid integrators read neither the box estimator nor
/// `box_samples`; the baseline reads no ReSTIR knob).
pub fn effective_scene(scene: &Scene, plan: &RenderPlan) -> Scene {
    let defaults = nimbus_scene::Integrator::default();
    let mut s = scene.clone();
    let i = &mut s.integrator;
    match &plan.integrator {
        Integrator::Crepuscular(_) => {
            i.volume = defaults.volume;
            i.restir = defaults.restir;
        }
        Integrator::Baseline(_) => {
            i.restir = defaults.restir;
            i.box_estimator = defaults.box_estimator;
            i.box_samples = defaults.box_samples;
        }
        Integrator::Restir(p) => {
            i.box_estimator = defaults.box_estimator;
            i.box_samples = defaults.box_samples;
            // "auto" and the Q it resolves to render the same, and so does every settled M
            // that takes no effect.
            i.restir.temporal_limit = Some(p.temporal_limit);
            i.restir.candidates_settled = p.candidates_settled().unwrap_or(i.restir.candidates);
            if !spatial_on(p) {
                // Without spatial reuse its settings are read by nothing.
                i.restir = volume::without_spatial(&i.restir);
            }
            if !has_moving_frames(scene, p.animated_density, p.env_reuse_map) {
                // No frame moves (camera, density, a map under map reuse): no moving
                // frame's limit.
                i.restir.temporal_limit_moving = defaults.restir.temporal_limit_moving;
            }
        }
    }
    s
}

/// Whether some frame of `scene` moves its camera, changes its density frame (with
/// `animated_density`) or turns its environment map (with `map_reuse`: reused
/// environment samples turn with the map, `env_reuse = "map"`): where ReSTIR's
/// `temporal_limit_moving` applies (the pass decides frame by frame, by
/// [`env_map_rotation`] for the map; without such a frame the setting is read by
/// nothing).
pub(crate) fn has_moving_frames(scene: &Scene, animated_density: bool, map_reuse: bool) -> bool {
    let map_turns = scene.lights.iter().enumerate().any(|(i, l)| {
        matches!(l, Light::Environment { file: Some(_), .. })
            && scene.light_keyframes.get(i).is_some_and(|k| !k.is_empty())
    });
    !scene.camera.keyframes.is_empty() || animated_density || (map_reuse && map_turns)
}

/// The turn (degrees) of the environment map among `lights` (one scene frame's), if
/// there is a map: a frame whose turn differs from the previous frame's moved the
/// samples that `env_reuse = "map"` keeps.
pub(crate) fn env_map_rotation(lights: &[Light]) -> Option<f32> {
    lights.iter().find_map(|l| match l {
        Light::Environment {
            file: Some(_),
            rotation_deg,
            ..
        } => Some(*rotation_deg),
        _ => None,
    })
}

/// Whether a ReSTIR plan runs spatial reuse.
pub fn spatial_on(p: &RestirPlan) -> bool {
    p.spatial_neighbors > 0 && p.spatial_rounds > 0
}

/// The plan as far as its passes read it: without spatial reuse, ReSTIR's spatial
/// settings are read by nothing (`mis` is: temporal reuse combines with it too).
pub fn effective_plan(plan: &RenderPlan) -> RenderPlan {
    let mut p = plan.clone();
    if let Integrator::Restir(r) = &mut p.integrator {
        if !spatial_on(r) {
            r.spatial_neighbors = 0;
            r.spatial_rounds = 0;
            r.spatial_radius_px = 0.0;
            r.spatial_when = nimbus_scene::SpatialWhen::Always;
            r.spatial_tau_shift = false;
            r.spatial_max_history = 0.0;
        }
    }
    p
}
