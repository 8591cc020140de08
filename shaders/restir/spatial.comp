#version 460
// Volumetric ReSTIR pass 3, spatial reuse (sec. 4.3, Algorithm 5): the pixel's reservoir
// is combined with `spatial_neighbors` reservoirs within `spatial_radius_px`, picked by a
// low-discrepancy sequence (golden-ratio radii and plastic-number angles, randomly rotated
// per pixel, frame and round), with Talbot MIS over every pair of (sample, pixel): the
// target functions are re-evaluated with T~ ray marched on mip_reuse (Algorithm 4), and
// paths move between pixels by direction reuse (or vertex reuse, SC_REUSE_VERTEX).
// One round: reads slot u_push.src, writes slot u_push.dst (u_push.aux = round).

#extension GL_GOOGLE_include_directive : require
// The spatial optical-depth shift of x_1 (SC_SPATIAL_TAU_SHIFT, through the conservative
// grid or, SC_SPATIAL_TAU_EXACT, the density itself) applies here; temporal reuse has its
// own (SC_TEMPORAL_TAU_SHIFT).
#define COMBINE_SPATIAL 1
#include "combine.glsl"

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
    uint rng = rng_init(pixel, u_push.frame, 2u + u_push.aux, u_frame.seed);
    // Every candidate is of this frame: the exact optical depth is one density's.
    combine_tau_exact = SC_SPATIAL_TAU_SHIFT && SC_SPATIAL_TAU_EXACT;

    candidate_set(0u, res_at(u_push.src, pixel), pixel, SET_CURRENT);
    uint n = 1u;
    uint neighbors = min(u_restir.spatial_neighbors, MAX_SPATIAL_NEIGHBORS);
    // Only where the history is short (spatial_max_history): elsewhere the pixel's
    // reservoir passes through (combined with itself alone).
    if (u_restir.spatial_max_m > 0.0 && cand_M[0] >= u_restir.spatial_max_m) {
        neighbors = 0u;
    }
    // The camera feature of this pixel's centre ray (neighbour test and depth anchors).
    bool features = SC_SPATIAL_FEATURES && neighbors > 0u;
    uint end_here = NO_INDEX;
    float entry_here = FAR;
    float t_here = 0.0;
    if (features) {
        t_here = camera_feature(pixel, SET_CURRENT, end_here, entry_here);
        if (u_restir.spatial_anchor != 0u && entry_here < FAR) {
            cand_anchor[0] = entry_here;
        }
    }
    float radius = u_restir.spatial_radius;
    // Random rotation of the sequence for this pixel, frame and round.
    float r0 = rng_next(rng);
    float a0 = rng_next(rng);
    for (uint j = 0u; j < neighbors; ++j) {
        // Radius by sqrt for uniform area density; angle by the plastic-number sequence.
        float rho = radius * sqrt(fract(r0 + float(j) * 0.6180339887));
        float phi = 2.0 * PI * fract(a0 + float(j) * 0.7548776662);
        ivec2 q = ivec2(pixel) + ivec2(round(rho * vec2(cos(phi), sin(phi))));
        if (q == ivec2(pixel) || q.x < 0 || q.y < 0 || q.x >= int(u_frame.width) ||
            q.y >= int(u_frame.height)) {
            continue;
        }
        float anchor_q = cand_anchor[0];
        if (features) {
            // A deterministic test of the two pixels' centre rays (never of the samples),
            // so the combination stays unbiased: the neighbour is left out where its ray
            // ends on something else or sees a different T~.
            uint end_q;
            float entry_q;
            float t_q = camera_feature(uvec2(q), SET_CURRENT, end_q, entry_q);
            float tol = u_restir.spatial_feature_tolerance;
            if (tol > 0.0 && (end_q != end_here || camera_t_change(t_here, t_q) >= tol)) {
                continue;
            }
            if (u_restir.spatial_anchor != 0u && entry_here < FAR && entry_q < FAR) {
                anchor_q = entry_q;
            }
        }
        candidate_set(n, res_at(u_push.src, uvec2(q)), uvec2(q), SET_CURRENT);
        cand_anchor[n] = anchor_q;
        ++n;
    }
    Reservoir s;
    uint chosen = combine_candidates(n, rng, s);
    uint dst = res_at(u_push.dst, pixel);
    uint src_at = chosen < n ? cand_at[chosen] : cand_at[0];
    uint code = res_jitter(s);
    CameraRay owner = candidate_ray(chosen < n ? chosen : 0u, code);
    // Under the optical-depth shift, the anchor that puts x_1 where it was evaluated.
    CameraRay here = camera_ray(pixel, code, SET_CURRENT);
    here.anchor = combine_here_anchor;
    store_combined(dst, s, src_at, owner, here);
}
