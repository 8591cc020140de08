#version 460
// Volumetric ReSTIR pass 2, temporal reuse (sec. 4.4, Algorithm 5): the pixel's initial
// reservoir is combined with the previous frame's final reservoir of one pixel, its
// temporal neighbour, found by a motion vector. The previous reservoir's M is clamped to
// Q M (temporal limit) and scaled by the history's confidence.
//
// Two reprojections (`temporal_reprojection`, SC_TEMPORAL_ALIGNED):
// - "path" (the paper's): the neighbour is the pixel where the first vertex x_1 of the
//   selected path was one frame ago: x_1 moved back through the medium's velocity field and
//   projected by the previous camera. Where x_1 is not in the medium (the path is empty or
//   ends on a light seen directly), velocity resampling (sec. 5.2) draws a point along the
//   camera ray by regular tracking restricted to the medium instead. A reused path keeps
//   its sub-pixel position (its jitter code) and its depth past where the two pixels'
//   centre rays enter the medium.
// - "aligned" (the default): the neighbour is where the pixel's motion point (its centre
//   ray's point at optical depth 1 through the conservative grid: motion_point) was one
//   frame ago. A reused path's jitter code is translated (wrapping around the pixel) so
//   that the previous frame's ray through the motion point becomes this pixel's centre
//   ray, and its depth is kept past the motion point on both rays: a path found near the
//   motion point keeps its world-space vertices. Both depend on the two frames alone,
//   never on the samples.
// An x_1 or motion point on a surface (shapes are static) is projected without the
// velocity, and so is one in a box medium.
//
// Reads and writes slot u_push.src (= dst, in place: each pixel touches only its own
// entry there) and reads the previous frame's slot u_push.aux.

#extension GL_GOOGLE_include_directive : require
#include "combine.glsl"

// The confidence in the previous frame's pixel q_prev as this frame's `pixel`: 0 where the
// camera rays end on different things, else falling linearly with the relative change of
// their T~ (0 at HISTORY_T_TOLERANCE). The rays are this pixel's centre ray and q_prev's
// at jitter `code_prev` (its centre, or under SC_TEMPORAL_ALIGNED the ray through the
// motion point). Sets both candidates' depth anchors to where those rays enter the medium
// (0 unless both do).
float camera_confidence(uvec2 pixel, uvec2 q_prev, uint code_prev) {
    uint end_cur;
    uint end_prev;
    float entry_cur;
    float entry_prev;
    float t_cur = camera_feature(pixel, SET_CURRENT, end_cur, entry_cur);
    float t_prev = camera_feature_at(q_prev, code_prev, SET_PREVIOUS, end_prev, entry_prev);
    if (end_cur != end_prev) {
        return 0.0;
    }
    if (entry_cur < FAR && entry_prev < FAR) {
        cand_anchor[0] = entry_cur;
        cand_anchor[1] = entry_prev;
    }
    return clamp(1.0 - camera_t_change(t_cur, t_prev) / HISTORY_T_TOLERANCE, 0.0, 1.0);
}

// The optical depth through the conservative grid at which a pixel's centre ray has its
// motion point (SC_TEMPORAL_ALIGNED).
#define MOTION_TAU 1.0

// Values of u_restir.history_static (RestirUniforms): the previous frame's camera,
// lights and density are this frame's; only its lights differ (no velocity field).
#define HISTORY_STATIC 1u
#define HISTORY_CAMERA_STILL 2u

// The motion point of `pixel` (SC_TEMPORAL_ALIGNED): a deterministic point of what its
// centre ray sees, whose motion between the frames decides the temporal neighbour, aligns
// the two pixels' sub-pixel positions and anchors the reused paths' depths. Where the ray
// reaches optical depth MOTION_TAU through this frame's conservative grid before its
// opaque end, that point (a typical first collision; half the ray's optical depth where it
// holds less); else the shape or emitting sphere it ends on. False where it sees neither
// (the background; `dir` is the ray's direction). `in_medium`: a point of the medium,
// which moves with the velocity field.
bool motion_point(uvec2 pixel, out vec3 x, out bool in_medium, out vec3 dir) {
    CameraRay r = camera_ray(pixel, JITTER_CODE_CENTRE, SET_CURRENT);
    dir = r.d;
    uint sphere;
    SurfacePoint surface;
    float t_end = opaque_end(0u, r.o, r.d, sphere, surface);
    float sigma_star;
    float tau;
    // The walk stops at MOTION_TAU; where the ray holds less, tau is its whole optical depth.
    float z = pc_track(LEVEL_PRIMARY, r.o, r.d, t_end, MOTION_TAU, sigma_star, tau);
    if (z >= FAR && tau > 0.0) {
        z = pc_track(LEVEL_PRIMARY, r.o, r.d, t_end, 0.5 * tau, sigma_star, tau);
    }
    in_medium = z < FAR;
    if (in_medium) {
        x = r.o + z * r.d;
        return true;
    }
    x = r.o + min(t_end, FAR) * r.d;
    return t_end < FAR;
}

// The paper's motion vector's particle ("path"): x_1 of the selected path (header `cur`
// at `at`), else a point drawn by velocity resampling along the pixel's camera ray, else
// the surface the ray meets first. False where there is none (the background; `dir` is
// the path's camera ray's direction).
bool path_motion_point(uint at, Reservoir cur, inout uint rng, out vec3 x1, out bool in_medium, out vec3 dir) {
    // The selected path's own camera ray (its jitter; the pixel centre region otherwise).
    CameraRay cam = camera_ray(gl_GlobalInvocationID.xy, res_jitter(cur), SET_CURRENT);
    dir = cam.d;
    // x1 exists (anchored); it is a point of the medium, which moves with the velocity
    // field (in_medium), or of a static surface.
    bool anchored = path_x1(at, cur, cam, x1);
    in_medium = anchored && res_z(at, 1u) >= 0.0;
    if (anchored) {
        return true;
    }
    uint sphere;
    SurfacePoint surface;
    float t_end = opaque_end(0u, cam.o, cam.d, sphere, surface);
    float sigma_star;
    float tau_total;
    pc_track(LEVEL_PRIMARY, cam.o, cam.d, t_end, FAR, sigma_star, tau_total);
    if (tau_total > 0.0) {
        // A collision conditioned to happen: tau uniform in probability over
        // [0, tau_total). Domain: 1 - u (1 - e^-tau) in (e^-tau, 1].
        float u = rng_next(rng);
        float tau_target = -log(1.0 - u * (1.0 - exp(-tau_total)));
        float tau;
        float z = pc_track(LEVEL_PRIMARY, cam.o, cam.d, t_end, min(tau_target, tau_total), sigma_star, tau);
        if (z < FAR) {
            x1 = cam.o + z * cam.d;
            in_medium = true;
            return true;
        }
    }
    if (surface.shape != NO_INDEX) {
        // The ray crosses no medium before a shape: follow the surface point.
        x1 = cam.o + surface.t * cam.d;
        return true;
    }
    return false;
}

// The still pipeline (SC_TEMPORAL_STILL; the pass dispatches it on the frames whose
// camera, lights and density are the previous frame's): every pixel's neighbour is itself,
// and the motion code is compiled out of it.
layout(constant_id = SC_ID_TEMPORAL_STILL) const bool SC_TEMPORAL_STILL = false;

// Whether the still pipeline combines each reservoir with its own stored target
// (`still_target = "initial"`): see combine_still.
layout(constant_id = SC_ID_STILL_INITIAL_TARGET) const bool SC_STILL_INITIAL_TARGET = false;

// A static scene's temporal reuse (`still`: the previous frame's reservoir of this very
// pixel, unshifted, with full confidence) takes the arithmetic of
// combine_candidates_talbot for two candidates, written out. The generic combination's
// pairs are not compiled into the still pipeline at all (docs/performance.md, "The
// temporal pass of a still frame").
//
// Both samples' MIS weights are m_i = M_i / (M_0 + M_1): Talbot's weights where the two
// reservoirs share one target function (a still frame's previous target is this
// frame's), and a partition of unity whatever the targets are. With constant weights the
// target cancels sample by sample: w_i = m_i p_i(X_i) W_i and the result's
// W = sum w / p_Y(Y) give E[g(Y) W] = sum_i E[m_i g(X_i) W_i] for any positive p_i, so
// each sample may keep a target of its own, provided the combined reservoir stores the
// chosen sample's (its p_hat) with the sums. The target decides only which sample is
// selected, so how close p_i is to F/W decides the variance, not the mean.
// - SC_STILL_INITIAL_TARGET (`still_target = "initial"`, the default where candidates are
//   delta tracked): each reservoir's stored target, the fresh one's the initial pass's
//   (F with the walked segments' closed-form T and the NEE segment's T~ on mip_indirect)
//   and the history's whatever it kept (that of the fresh sample it once was on a still
//   scene, the reuse target where a moving frame chose it). w_i = w_sum_i; nothing is
//   evaluated (the fresh sample's reuse target was 60 of the pass's 70 ms on lavapipe at
//   320x240).
// - Else the reuse target for both, evaluated for a reservoir that does not hold it
//   already (the pixel's fresh one, and a history that was never combined), in a loop
//   over those: on lavapipe every instruction outside a loop runs for all of a SIMD row's
//   lanes, taken or not.
uint combine_still(inout uint rng, out Reservoir s) {
    s = res_empty();
    combine_here_anchor = cand_anchor[0];
    float k = cand_M[0] + cand_M[1];
    uint chosen = 2u;
    if (SC_STILL_INITIAL_TARGET) {
        for (uint i = 0u; i < 2u; ++i) {
            Reservoir ri = res_load(cand_at[i]);
            // res_update keeps the chosen sample's p_hat and info (whether p_hat is the
            // reuse target: the generic combination's own-target shortcut reads it).
            if (res_valid(ri) && ri.p_hat > 0.0 && cand_M[i] > 0.0 &&
                res_update(s, ri, ri.w_sum * cand_w_scale[i], rng)) {
                chosen = i;
            }
        }
        combine_finish(s, k, chosen != 2u);
        return chosen;
    }
    // Which reservoirs can give a sample, and which of those lack this frame's target.
    float p[2];
    uint usable = 0u;
    uint evaluate = 0u;
    for (uint i = 0u; i < 2u; ++i) {
        Reservoir ri = res_load(cand_at[i]);
        p[i] = ri.p_hat;
        if (res_valid(ri) && ri.p_hat > 0.0 && ri.w_sum * cand_w_scale[i] > 0.0 && cand_M[i] > 0.0) {
            usable |= 1u << i;
            if ((ri.info & INFO_REUSE_TARGET) == 0u) {
                evaluate |= 1u << i;
            }
        }
    }
    while (evaluate != 0u) {
        uint i = uint(findLSB(evaluate));
        evaluate &= evaluate - 1u;
        Reservoir ri = res_load(cand_at[i]);
        uint code = res_jitter(ri);
        float anchor;
        float sigma_here;
        p[i] = shifted_target(cand_at[i], ri, candidate_ray_for(0u, i, code), candidate_ray(i, code), i == 0u, -1.0,
                              1.0, anchor, sigma_here, rng);
    }
    for (uint i = 0u; i < 2u; ++i) {
        if ((usable & (1u << i)) == 0u) {
            continue;
        }
        Reservoir ri = res_load(cand_at[i]);
        ri.M = cand_M[i];
        ri.w_sum *= cand_w_scale[i];
        float pi = p[i];
        float p_sum = 0.0;
        if (cand_M[0] > 0.0) {
            p_sum += pi * cand_M[0];
        }
        if (cand_M[1] > 0.0) {
            p_sum += pi * cand_M[1];
        }
        if (!(p_sum > 0.0) || !(pi > 0.0)) {
            continue;
        }
        float m = pi * k / p_sum;
        // Domain: ri.p_hat > 0 (usable).
        float w = pi / ri.p_hat * ri.w_sum * m;
        if (combine_stream(s, ri, pi, w, rng)) {
            chosen = i;
        }
    }
    combine_finish(s, k, chosen != 2u);
    return chosen;
}

void restir_main();

// The stage, then its counters into the stats buffer.
void main() {
    restir_load();
    restir_main();
    film_flush_counters();
}

void restir_main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (!film_contains(pixel)) {
        return;
    }
    COUNT(CTR_SAMPLES, 1);
    uint at = res_at(u_push.src, pixel);
    uint rng = rng_init(pixel, u_push.frame, 1u, u_frame.seed);

    // The motion vector: where its particle was one frame ago, projected by the previous
    // camera. A static scene's aligned neighbour (history_static: camera, lights and
    // density as in the previous frame) is the pixel itself, unshifted, found without a
    // walk: the still pipeline (SC_TEMPORAL_STILL), which the pass dispatches on every
    // such frame, so that the other pipeline carries none of the still code (on lavapipe,
    // code outside loops costs every lane whether its branch is taken or not).
    bool static_history = SC_TEMPORAL_STILL || u_restir.history_static == HISTORY_STATIC;
    bool still = SC_TEMPORAL_STILL;
    // Only the lights changed (history_static = HISTORY_CAMERA_STILL: the camera and the
    // density as in the previous frame, no velocity field): the aligned neighbour is the
    // pixel itself, unshifted, and the two frames' centre rays are one ray, so the camera's
    // confidence is 1 and their anchors agree; none of it is walked or marched. Decided
    // from the two frames alone, as the motion point is.
    bool camera_still = still || (SC_TEMPORAL_ALIGNED && u_restir.history_static == HISTORY_CAMERA_STILL);
    vec3 x = vec3(0.0);
    vec3 x_prev = vec3(0.0);
    bool in_medium = false;
    vec2 px = vec2(pixel) + 0.5;
    bool on_screen = true;
    if (!camera_still) {
        vec3 dir;
        bool anchored = SC_TEMPORAL_ALIGNED ? motion_point(pixel, x, in_medium, dir)
                                            : path_motion_point(at, res_load(at), rng, x, in_medium, dir);
        if (anchored) {
            // The velocity field moves the grid's points only (box media are static).
            bool moves = SC_HAS_VELOCITY && in_medium && box_medium_at(x) == NO_INDEX;
            x_prev = moves ? x - velocity_at(x) : x;
        } else {
            // Nothing in the medium along the ray: follow the background (a far point).
            x_prev = u_prev_frame.cam_position + dir * 1e6;
        }
        on_screen = camera_project(u_prev_frame, x_prev, px);
    }
    // Written so that a NaN projection (an extreme velocity: f16 texels saturate to inf)
    // fails it too: NaN compares false.
    if (!on_screen || !(px.x >= 0.0 && px.y >= 0.0 && px.x < float(u_frame.width) &&
                        px.y < float(u_frame.height))) {
        // No temporal neighbour: the reservoir stays as it is.
        return;
    }
    uvec2 q_prev = uvec2(px);
    candidate_set(0u, at, pixel, SET_CURRENT);
    candidate_set(1u, res_at(u_push.aux, q_prev), q_prev, SET_PREVIOUS);
    uint code_prev = JITTER_CODE_CENTRE;
    if (SC_TEMPORAL_ALIGNED && !camera_still) {
        // The previous pixel's sub-pixel frame, translated so that its jitter code under
        // the motion point (fract(px)) is this pixel's centre code.
        uvec2 c = min(uvec2(fract(px) * 256.0), uvec2(255u));
        code_prev = c.x | (c.y << 8u);
        uvec2 shift = (c - uvec2(JITTER_CODE_CENTRE & 0xffu, JITTER_CODE_CENTRE >> 8u)) & uvec2(0xffu);
        cand_jitter_shift[1] = shift.x | (shift.y << 8u);
    }
    // A static scene's history is this frame's: full confidence, nothing to compare.
    float confidence = 1.0;
    if (!static_history) {
        confidence = u_restir.history_confidence;
        if (confidence > 0.0 && !camera_still) {
            confidence *= camera_confidence(pixel, q_prev, code_prev);
            if (SC_TEMPORAL_ALIGNED && in_medium) {
                // Depths past the motion point on both rays (each passes through it).
                cand_anchor[0] = length(x - u_frame.cam_position);
                cand_anchor[1] = length(x_prev - u_prev_frame.cam_position);
            }
        }
        if (!(confidence > 0.0)) {
            // Nothing of the previous frame resembles this one: the reservoir stays.
            return;
        }
    }

    // The optical-depth shift where the camera moved over the previous frame's density (a
    // choice from the two frames alone). A still camera's rays are the previous frame's:
    // there the shift is the identity, and the distance shift costs no walk.
    combine_tau_exact = SC_TEMPORAL_TAU_SHIFT && !camera_still && !static_history &&
                        u_restir.history_same_density != 0u;
    // A static scene's previous frame at this very pixel has this frame's target function:
    // the samples' targets are evaluated once (3 path evaluations become 1).
    cand_same_target[1] = static_history && all(equal(q_prev, pixel)) && cand_jitter_shift[1] == 0u;
    // Temporal limit: M_prev <= Q M, scaling w_sum alike so W_prev is unchanged.
    float m_cap = float(u_restir.temporal_limit) * float(u_restir.candidates);
    if (cand_M[1] > m_cap) {
        // Domain: M > m_cap > 0.
        cand_w_scale[1] = m_cap / cand_M[1];
        cand_M[1] = m_cap;
    }
    // The confidence scales M and w_sum alike (W_prev unchanged).
    cand_M[1] *= confidence;
    cand_w_scale[1] *= confidence;
    Reservoir s;
    // (still: q_prev is this pixel, unshifted, so cand_same_target[1].)
    uint chosen;
    if (still) {
        chosen = combine_still(rng, s);
        // The shade cache holds F of the history's path (the previous frame shaded it):
        // where this pixel's path is now another, its flag says so (restir/shade.comp).
        if (chosen != 1u && u_restir.shade_cache_base != 0u) {
            reservoirs[shade_cache_at(pixel) + 3u] = 0u;
        }
    } else {
        chosen = combine_candidates(2u, rng, s);
    }
    uint src_at = chosen < 2u ? cand_at[chosen] : at;
    uint code = res_jitter(s);
    uint owner_i = chosen < 2u ? chosen : 0u;
    CameraRay owner = candidate_ray(owner_i, code);
    if (chosen < 2u) {
        // The path's jitter code in this pixel's sub-pixel frame.
        s.info = (s.info & 0xffffu) | (jitter_code_move(code, owner_i, 0u) << 16u);
    }
    // Under the optical-depth shift, the anchor that puts x_1 where it was evaluated.
    CameraRay here = candidate_ray_for(0u, owner_i, code);
    here.anchor = combine_here_anchor;
    store_combined(at, s, src_at, owner, here);
}
