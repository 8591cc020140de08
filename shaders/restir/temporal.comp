#version 460
// Volumetric ReSTIR pass 2, temporal reuse (sec. 4.4, Algorithm 5): the pixel's initial
// reservoir is combined with the previous frame's final reservoir of the pixel where the
// first vertex x_1 of its selected path was one frame ago: x_1 moved back through the
// medium's velocity field and projected by the previous camera. Where x_1 is not in the
// medium (the path is empty or ends on a light seen directly), velocity resampling
// (sec. 5.2) draws a point along the camera ray by regular tracking restricted to the
// medium instead. An x_1 on a surface (shapes are static) is projected without the
// velocity, and so is the surface a ray meets before any medium, or an x_1 in a box
// medium. The previous reservoir's
// M is clamped to Q M (temporal limit).
//
// Reads and writes slot u_push.src (= dst, in place: each pixel touches only its own
// entry there) and reads the previous frame's slot u_push.aux.

#extension GL_GOOGLE_include_directive : require
#include "combine.glsl"

// The confidence in the previous frame's pixel q_prev as this frame's `pixel`: 0 where the
// camera rays end on different things, else falling linearly with the relative change of
// their T~ (0 at HISTORY_T_TOLERANCE). Sets both candidates' depth anchors to where their
// centre rays enter the medium (0 unless both do).
float camera_confidence(uvec2 pixel, uvec2 q_prev) {
    uint end_cur;
    uint end_prev;
    float entry_cur;
    float entry_prev;
    float t_cur = camera_feature(pixel, SET_CURRENT, end_cur, entry_cur);
    float t_prev = camera_feature(q_prev, SET_PREVIOUS, end_prev, entry_prev);
    if (end_cur != end_prev) {
        return 0.0;
    }
    if (entry_cur < FAR && entry_prev < FAR) {
        cand_anchor[0] = entry_cur;
        cand_anchor[1] = entry_prev;
    }
    return clamp(1.0 - camera_t_change(t_cur, t_prev) / HISTORY_T_TOLERANCE, 0.0, 1.0);
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
    Reservoir cur = res_load(at);
    // The selected path's own camera ray (its jitter; the pixel centre region otherwise).
    CameraRay cam = camera_ray(pixel, res_jitter(cur), SET_CURRENT);

    // The motion vector's particle: x_1 of the selected path, else velocity resampling.
    vec3 x1 = vec3(0.0);
    // x1 exists (anchored); it is a point of the medium, which moves with the velocity
    // field (in_medium), or of a static surface.
    bool anchored = path_x1(at, cur, cam, x1);
    bool in_medium = anchored && res_z(at, 1u) >= 0.0;
    if (!anchored) {
        uint sphere;
        float t_end = nearest_sphere_light(0u, cam.o, cam.d, 1e-6, FAR, sphere);
        SurfacePoint surface = surface_along(cam.o, cam.d, t_end);
        t_end = min(t_end, surface.t);
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
                anchored = true;
                in_medium = true;
            }
        }
        if (!anchored && surface.shape != NO_INDEX) {
            // The ray crosses no medium before a shape: follow the surface point.
            x1 = cam.o + surface.t * cam.d;
            anchored = true;
        }
    }
    vec3 x_prev;
    vec2 px;
    bool on_screen;
    if (anchored) {
        // The velocity field moves the grid's points only (box media are static).
        bool moves = SC_HAS_VELOCITY && in_medium && box_medium_at(x1) == NO_INDEX;
        x_prev = moves ? x1 - velocity_at(x1) : x1;
        on_screen = camera_project(u_prev_frame, x_prev, px);
    } else {
        // Nothing in the medium along the ray: follow the background (a far point).
        on_screen = camera_project(u_prev_frame, u_prev_frame.cam_position + cam.d * 1e6, px);
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
    // A static scene's history is this frame's: full confidence, nothing to compare.
    float confidence = 1.0;
    if (u_restir.history_static == 0u) {
        confidence = u_restir.history_confidence;
        if (confidence > 0.0) {
            confidence *= camera_confidence(pixel, q_prev);
        }
        if (!(confidence > 0.0)) {
            // Nothing of the previous frame resembles this one: the reservoir stays.
            return;
        }
    }

    // A static scene's previous frame at this very pixel has this frame's target function:
    // the samples' targets are evaluated once (3 path evaluations become 1).
    cand_same_target[1] = u_restir.history_static != 0u && all(equal(q_prev, pixel));
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
    uint chosen = combine_candidates(2u, rng, s);
    uint src_at = chosen < 2u ? cand_at[chosen] : at;
    uint code = res_jitter(s);
    CameraRay owner = candidate_ray(chosen < 2u ? chosen : 0u, code);
    store_combined(at, s, src_at, owner, candidate_ray(0u, code));
}
