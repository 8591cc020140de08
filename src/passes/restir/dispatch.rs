//! What the ReSTIR shaders are compiled and dispatched with: their specialization
//! constants for a plan, and how many candidates one initial dispatch may draw within a
//! device's loop budget.

use nimbus_gpu::SpecValue;

use super::schedule::ScheduleSettings;
use crate::plan::RestirPlan;
use crate::shader_data::features::*;

/// The specialization constants of the ReSTIR shaders for a plan; `exact_spans`: some
/// super-voxel of some density frame is hot for final ratio tracking
/// ([`crate::shader_data::scene::needs_exact_spans`]).
/// `two_level`: some brick indirection section is two-level. `pc_buffer`: tracking reads
/// the piecewise-constant levels from their buffer ([`super::resources::pc_in_buffer`]);
/// `density_buffer`: the passes read this frame's density and the ray marches their
/// mips from buffers of quads ([`super::resources::density_in_buffer`]).
pub fn specialization(
    plan: &RestirPlan,
    exact_spans: bool,
    two_level: bool,
    pc_buffer: bool,
    density_buffer: bool,
) -> [(u32, SpecValue); 37] {
    [
        (SC_ID_PC_BUFFER, SpecValue::Bool(pc_buffer)),
        (SC_ID_DENSITY_BUFFER, SpecValue::Bool(density_buffer)),
        (SC_ID_MARCH_BUFFER, SpecValue::Bool(density_buffer)),
        (
            SC_ID_HAS_SPHERE_LIGHTS,
            SpecValue::Bool(plan.has_sphere_lights),
        ),
        (SC_ID_TWO_LEVEL_BRICKS, SpecValue::Bool(two_level)),
        (
            SC_ID_EXACT_SPANS,
            SpecValue::Bool(
                (plan.settings.final_ratio_tracking || plan.candidate_delta) && exact_spans,
            ),
        ),
        (SC_ID_HAS_AREA_LIGHTS, SpecValue::Bool(plan.has_area_lights)),
        (SC_ID_HAS_GOBOS, SpecValue::Bool(plan.has_gobos)),
        (SC_ID_HAS_MEDIA, SpecValue::Bool(plan.has_boxes)),
        (SC_ID_HAS_SHAPES, SpecValue::Bool(plan.has_shapes)),
        (SC_ID_HAS_MESHES, SpecValue::Bool(plan.has_meshes)),
        (SC_ID_HAS_ENV, SpecValue::Bool(plan.has_env)),
        (SC_ID_MAX_BOUNCES, SpecValue::U32(plan.max_bounces)),
        (SC_ID_PIXEL_JITTER, SpecValue::Bool(plan.pixel_jitter)),
        (SC_ID_HAS_EMISSION, SpecValue::Bool(plan.has_emission)),
        (SC_ID_HAS_CONVEX, SpecValue::Bool(plan.has_convex)),
        (SC_ID_HAS_BLACKBODY, SpecValue::Bool(plan.has_blackbody)),
        (SC_ID_HAS_ALBEDO_GRID, SpecValue::Bool(plan.has_albedo_grid)),
        (SC_ID_HAS_ENV_MAP, SpecValue::Bool(plan.has_env_map)),
        (SC_ID_REUSE_VERTEX, SpecValue::Bool(plan.vertex_reuse)),
        (
            SC_ID_FINAL_RATIO_TRACKING,
            SpecValue::Bool(plan.settings.final_ratio_tracking),
        ),
        (SC_ID_HAS_VELOCITY, SpecValue::Bool(plan.has_velocity)),
        (SC_ID_MIS_PAIRWISE, SpecValue::Bool(plan.pairwise_mis)),
        (
            SC_ID_SPATIAL_TAU_SHIFT,
            SpecValue::Bool(plan.spatial_tau_shift),
        ),
        (
            SC_ID_SPATIAL_TAU_EXACT,
            SpecValue::Bool(plan.spatial_tau_exact),
        ),
        (
            SC_ID_SPATIAL_FEATURES,
            SpecValue::Bool(
                plan.settings.spatial_feature_tolerance > 0.0 || plan.settings.spatial_anchor,
            ),
        ),
        (SC_ID_FOLD_EMISSION, SpecValue::Bool(plan.fold_emission)),
        (SC_ID_ENV_REUSE_MAP, SpecValue::Bool(plan.env_reuse_map)),
        (SC_ID_NEE_SPLIT, SpecValue::Bool(plan.nee_split)),
        (
            SC_ID_DIRECT_EACH_WALK,
            SpecValue::Bool(plan.direct_each_walk),
        ),
        (SC_ID_CANDIDATE_DELTA, SpecValue::Bool(plan.candidate_delta)),
        (
            SC_ID_TARGET_SCALAR,
            SpecValue::U32(match plan.settings.target {
                nimbus_scene::TargetScalar::Luminance => SC_TARGET_LUMINANCE,
                nimbus_scene::TargetScalar::Sum => SC_TARGET_SUM,
                nimbus_scene::TargetScalar::Max => SC_TARGET_MAX,
            }),
        ),
        (
            SC_ID_CAMERA_EMISSION,
            SpecValue::Bool(
                plan.has_emission
                    && plan.settings.camera_emission == nimbus_scene::CameraEmission::Stratified,
            ),
        ),
        // The temporal stage's still pipeline sets it (resources::still_specialization).
        (SC_ID_TEMPORAL_STILL, SpecValue::Bool(false)),
        (
            SC_ID_STILL_INITIAL_TARGET,
            SpecValue::Bool(plan.still_initial_target()),
        ),
        (
            SC_ID_TEMPORAL_TAU_SHIFT,
            SpecValue::Bool(plan.temporal && plan.temporal_tau_shift),
        ),
        (
            SC_ID_TEMPORAL_ALIGNED,
            SpecValue::Bool(
                plan.settings.temporal_reprojection == nimbus_scene::TemporalReprojection::Aligned,
            ),
        ),
    ]
}

/// Loop iterations one candidate walk costs, per segment: the blocks of the
/// piecewise-constant level it tracks through (camera segment, then scattered ones), the
/// NEE ray march, and the loops over the lights (nearest emitter, selection, shadow).
pub struct CandidateCost {
    pub pc_blocks: [u32; 2],
    pub march_steps: u32,
    pub lights: u32,
    /// Loop iterations of one ray through the meshes ([`crate::passes::mesh_ray_cost`]).
    pub mesh_rays: u32,
    /// Box media beside the grid (each segment loops over them a few times).
    pub boxes: u32,
    /// Primitives in the emitter table (an area-light sample binary-searches it).
    pub emitters: u32,
    /// Super-voxels a ray may cross (decomposition tracking's walk, `candidate_tracking =
    /// "delta"`).
    pub super_voxels: u32,
    /// Dual cells a ray may cross (the closed-form transmittance of the selected path's
    /// segments, once per dispatch under delta tracking).
    pub dual_cells: u32,
}

pub fn schedule_settings(plan: &RestirPlan, candidates_per_dispatch: u32) -> ScheduleSettings {
    ScheduleSettings {
        temporal: plan.temporal,
        spatial_neighbors: plan.spatial_neighbors,
        spatial_rounds: plan.spatial_rounds,
        candidates: plan.settings.candidates,
        candidates_per_dispatch,
        history_before_spatial: plan.history_before_spatial,
    }
}

/// How many candidates one initial dispatch may draw so that an invocation stays within
/// the device's loop budget (half of it: the other loops of the invocation and a margin),
/// or all M where the device has none. At least 1: one candidate's walk is far below the
/// budget for every grid the loader admits (dims ≤ 4096 per axis).
pub fn candidates_per_dispatch(
    budget: Option<u32>,
    plan: &RestirPlan,
    cost: &CandidateCost,
) -> u32 {
    let Some(budget) = budget else {
        return plan.settings.candidates;
    };
    // A segment's nearest-shape ray and its NEE shadow ray cross the meshes.
    let segment = |blocks: u32| {
        let search = u32::BITS - cost.emitters.leading_zeros();
        u64::from(blocks + cost.march_steps + 3 * cost.lights + 4 * cost.boxes + search + 64)
            + 2 * u64::from(cost.mesh_rays)
    };
    let k = u64::from(plan.max_bounces.max(1));
    // With the direct candidate of every walk the camera segment is walked twice: to its
    // end for T*, then by tracking.
    let direct = if plan.direct_each_walk {
        u64::from(cost.pc_blocks[0])
    } else {
        0
    };
    // Decomposition tracking: the super-voxels and the residual collisions in them (as
    // the baseline counts them), then, once per dispatch, the selected path's segments
    // through the dual cells.
    let (walks, fixed) = if plan.candidate_delta {
        let walk = cost.super_voxels + GRID_EXACT_SPAN_STEPS;
        ([walk, walk], k * u64::from(cost.dual_cells))
    } else {
        (cost.pc_blocks, 0)
    };
    let per_candidate = segment(walks[0]) + direct + (k - 1) * segment(walks[1]) + k;
    let fit = (u64::from(budget / 2).saturating_sub(fixed) / per_candidate.max(1)).max(1);
    u32::try_from(fit)
        .unwrap_or(u32::MAX)
        .min(plan.settings.candidates)
}

#[cfg(test)]
mod tests {
    use super::{candidates_per_dispatch, CandidateCost};
    use crate::plan::RestirPlan;

    /// The shipped cloud's ReSTIR plan at K = 3 with M = 4096 candidates (more than any
    /// budget fits in one dispatch).
    fn plan_k3_m4096() -> RestirPlan {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/assets/scenes/cloud-restir.toml"
        );
        let scene = crate::load_scene(Some(std::path::Path::new(path)), &[]).unwrap();
        let plan = crate::plan::build(&scene, None).unwrap();
        let mut p = plan.restir().unwrap().clone();
        p.settings.candidates = 4096;
        p.max_bounces = 3;
        p
    }

    /// Every walk's direct candidate walks the camera segment a second time, which the
    /// split of M over dispatches must count: lavapipe silently ends the loops of an
    /// invocation past its budget, which would drop candidates and darken the image.
    #[test]
    fn the_direct_candidates_walk_counts_against_the_loop_budget() {
        let mut p = plan_k3_m4096();
        let cost = CandidateCost {
            pc_blocks: [2000, 100],
            march_steps: 300,
            lights: 2,
            mesh_rays: 0,
            boxes: 0,
            emitters: 0,
            super_voxels: 40,
            dual_cells: 2000,
        };
        let budget = 65_535;
        p.candidate_delta = false;
        p.direct_each_walk = false;
        let escape = candidates_per_dispatch(Some(budget), &p, &cost);
        p.direct_each_walk = true;
        let each = candidates_per_dispatch(Some(budget), &p, &cost);
        assert!(each < escape, "{each} vs {escape}");
        // The loops of `each` candidates with the second walk stay within half the budget.
        let segment = |blocks: u64| blocks + 300 + 6 + 64;
        let per = segment(2000) + 2000 + 2 * segment(100) + 3;
        assert!(
            u64::from(each) * per <= u64::from(budget / 2),
            "{each} x {per}"
        );
        assert_eq!(candidates_per_dispatch(None, &p, &cost), 4096);
    }

    /// Delta-tracked candidates count their super-voxels and residual collisions, and
    /// the dispatch's one closed-form walk of the selected path, against the budget.
    #[test]
    fn delta_tracked_candidates_count_their_walks_against_the_loop_budget() {
        let mut p = plan_k3_m4096();
        p.candidate_delta = true;
        p.direct_each_walk = false;
        let cost = CandidateCost {
            pc_blocks: [10, 10],
            march_steps: 300,
            lights: 2,
            mesh_rays: 0,
            boxes: 0,
            emitters: 0,
            super_voxels: 40,
            dual_cells: 3000,
        };
        let budget = 65_535;
        let delta = candidates_per_dispatch(Some(budget), &p, &cost);
        let segment = |blocks: u64| blocks + 300 + 6 + 64;
        let per = 3 * segment(40 + 64) + 3;
        assert!(delta >= 1);
        assert!(
            u64::from(delta) * per + 3 * 3000 <= u64::from(budget / 2),
            "{delta} x {per}"
        );
        // More than the piecewise-constant walks' 10 blocks would allow: the tracking's
        // own walk counts, not the levels'.
        p.candidate_delta = false;
        assert!(candidates_per_dispatch(Some(budget), &p, &cost) > delta);
    }
}
