// Volumetric ReSTIR (Lin, Wyman and Yuksel 2021): combining reservoirs with Talbot MIS
// (Algorithm 5, with Algorithm 2's combineReservoir), or pairwise MIS, for temporal and
// spatial reuse.
#ifndef NIMBUS_RESTIR_COMBINE_GLSL
#define NIMBUS_RESTIR_COMBINE_GLSL

#extension GL_GOOGLE_include_directive : require

#include "path.glsl"

// The reservoirs taking part in a combination, as small private arrays (the shader's
// registers; passing structs of rays and headers by value costs far more): where each is
// stored, its pixel and frame (its owner: the representation is relative to that camera
// ray), and its M (the temporal limit may lower it, scaling w_sum by the same factor).
uint cand_at[MAX_CANDIDATES];
uvec2 cand_pixel[MAX_CANDIDATES];
uint cand_set[MAX_CANDIDATES];
float cand_M[MAX_CANDIDATES];
float cand_w_scale[MAX_CANDIDATES];
// Whether candidate i's target function is candidate 0's: the same pixel of a previous
// frame whose camera, lights and density are this frame's (a static scene's temporal
// neighbour). Targets of such candidates are evaluated once, not once per candidate.
bool cand_same_target[MAX_CANDIDATES];
// Candidate i's camera-ray depth anchor (CameraRay.anchor; 0 unless temporal reuse sets it).
float cand_anchor[MAX_CANDIDATES];

// Registers candidate `i` (its header's M unless clamped later).
void candidate_set(uint i, uint at, uvec2 pixel, uint set) {
    cand_at[i] = at;
    cand_pixel[i] = pixel;
    cand_set[i] = set;
    cand_M[i] = res_load_M(at);
    cand_w_scale[i] = 1.0;
    cand_same_target[i] = i == 0u;
    cand_anchor[i] = 0.0;
}

// The camera ray of candidate i's pixel and frame at jitter `code`.
CameraRay candidate_ray(uint i, uint code) {
    CameraRay r = camera_ray(cand_pixel[i], code, cand_set[i]);
    r.anchor = cand_anchor[i];
    return r;
}

// Streams reservoir ri's sample into s with resampling weight w. The sample keeps its
// light vertex; its target becomes p_here, the target at this pixel and frame. True if
// it was taken.
bool combine_stream(inout Reservoir s, Reservoir ri, float p_here, float w, inout uint rng) {
    Reservoir c = ri;
    c.p_hat = p_here;
    c.info = ri.info | INFO_REUSE_TARGET;
    return res_update(s, c, w, rng);
}

// Ends a combination of M = total: a reservoir that took no sample is empty.
void combine_finish(inout Reservoir s, float total, bool taken) {
    s.M = total;
    if (!taken) {
        s.w_sum = 0.0;
        s.p_hat = 0.0;
        s.info = 0u;
    }
}

// Streams candidates 0..n-1 into one reservoir for the pixel of candidate 0. Each
// candidate i's sample lambda_i gets the Talbot weight
//   m_i = M_i p_i(lambda_i) / sum_s M_s p_s(lambda_i)
// with p_s the target function at candidate s's pixel and frame (ray-marched T~), and the
// resampling weight w_i = m_i p_0(lambda_i) W_i, W_i = w_sum_i / (M_i p_hat_i) its
// unbiased contribution weight. Stored as in Algorithm 2: w_sum = sum_i w_i M and M =
// sum_i M_i, so f / p_hat * w_sum / M stays the estimator. Returns the index of the chosen
// candidate (n if none) and the combined header (its p_hat = p_0 of the chosen sample).
uint combine_candidates_talbot(uint n, inout uint rng, out Reservoir s) {
    s = res_empty();
    float k = 0.0;
    for (uint i = 0u; i < n; ++i) {
        k += cand_M[i];
    }
    uint chosen = n;
    for (uint i = 0u; i < n; ++i) {
        Reservoir ri = res_load(cand_at[i]);
        ri.M = cand_M[i];
        ri.w_sum *= cand_w_scale[i];
        if (!res_valid(ri) || !(ri.p_hat > 0.0) || !(ri.w_sum > 0.0) || !(ri.M > 0.0)) {
            continue;
        }
        uint code = res_jitter(ri);
        CameraRay owner = candidate_ray(i, code);
        // The target here (j = 0) first, then at the sample's own pixel (j = i): if either
        // is 0, w_i = 0 whatever the other pixels give, and they are not evaluated.
        float p_sum = 0.0;
        float p_own = 0.0;
        float p_here = 0.0;
        bool dead = false;
        // A combined reservoir already holds the target at its own pixel (computed by the
        // same function for the same ray, frame and path).
        bool has_own = (ri.info & INFO_REUSE_TARGET) != 0u;
        // The target of candidate 0's function for this sample, once known (< 0: not yet),
        // which every candidate with the same target function shares.
        float p_shared = has_own && cand_same_target[i] ? ri.p_hat : -1.0;
        for (uint step = 0u; step < n && !dead; ++step) {
            // Visit order: 0, i, then the others ascending (0, 1, 2, ... when i = 0).
            uint j = i == 0u ? step : (step == 0u ? 0u : (step == 1u ? i : (step <= i ? step - 1u : step)));
            if (!(cand_M[j] > 0.0)) {
                continue;
            }
            float p;
            if (j == i && has_own) {
                p = ri.p_hat;
            } else if (cand_same_target[j] && p_shared >= 0.0) {
                p = p_shared;
            } else {
                p = luminance(path_value(cand_at[i], ri, candidate_ray(j, code), owner, MODE_TARGET, rng));
            }
            if (cand_same_target[j]) {
                p_shared = p;
            }
            p_sum += p * cand_M[j];
            if (j == i) {
                p_own = p;
                dead = !(p > 0.0);
            }
            if (j == 0u) {
                p_here = p;
                dead = dead || !(p > 0.0);
            }
        }
        // Domain: p_sum > 0 (else no pixel could have produced lambda_i: weight 0).
        if (!(p_sum > 0.0) || !(p_here > 0.0)) {
            continue;
        }
        float m = p_own * k / p_sum;
        // Domain: p_hat_i > 0 (checked above).
        float w = p_here / ri.p_hat * ri.w_sum * m;
        if (combine_stream(s, ri, p_here, w, rng)) {
            chosen = i;
        }
    }
    combine_finish(s, k, chosen != n);
    return chosen;
}

// The target function at candidate j's pixel and frame for the sample of reservoir ri
// (stored at candidate i, jitter code `code`, owned by camera ray `owner`); candidate i's
// own value comes from the header when the reservoir already holds it.
float candidate_target(uint i, uint j, Reservoir ri, uint code, CameraRay owner, inout uint rng) {
    bool has_own = (ri.info & INFO_REUSE_TARGET) != 0u;
    if (has_own && (j == i || (cand_same_target[i] && cand_same_target[j]))) {
        return ri.p_hat;
    }
    return luminance(path_value(cand_at[i], ri, candidate_ray(j, code), owner, MODE_TARGET, rng));
}

// As combine_candidates_talbot, with pairwise MIS (Bitterli 2022; Lin et al. 2022,
// "Generalized resampled importance sampling"): candidate 0 (the pixel's own, canonical)
// is weighed against each of the k others alone. With c = M_0 / k,
//   m_i(y) = (1/k) M_i p_i(y) / (M_i p_i(y) + c p_0(y))              for i >= 1,
//   m_0(y) = (1/k) sum_i c p_0(y) / (M_i p_i(y) + c p_0(y)),
// a partition of unity for every y (the pair terms add to 1/k each), so the combined
// estimate stays unbiased; 3k target evaluations instead of (k + 1)^2.
uint combine_candidates_pairwise(uint n, inout uint rng, out Reservoir s) {
    s = res_empty();
    float total = 0.0;
    float k = 0.0;
    for (uint i = 0u; i < n; ++i) {
        total += cand_M[i];
        k += (i > 0u && cand_M[i] > 0.0) ? 1.0 : 0.0;
    }
    // Domain: k >= 1 below (with no other candidate the canonical weight is 1).
    float c = k > 0.0 ? cand_M[0] / k : 0.0;
    uint chosen = n;
    for (uint i = 0u; i < n; ++i) {
        Reservoir ri = res_load(cand_at[i]);
        ri.M = cand_M[i];
        ri.w_sum *= cand_w_scale[i];
        if (!res_valid(ri) || !(ri.p_hat > 0.0) || !(ri.w_sum > 0.0) || !(ri.M > 0.0)) {
            continue;
        }
        uint code = res_jitter(ri);
        CameraRay owner = candidate_ray(i, code);
        float p_here = candidate_target(i, 0u, ri, code, owner, rng);
        if (!(p_here > 0.0)) {
            continue;
        }
        float m;
        if (i == 0u) {
            if (k == 0.0) {
                m = 1.0;
            } else {
                m = 0.0;
                for (uint j = 1u; j < n; ++j) {
                    if (!(cand_M[j] > 0.0)) {
                        continue;
                    }
                    float pj = candidate_target(0u, j, ri, code, owner, rng);
                    // Domain: c p_here > 0, so the denominator is > 0.
                    m += c * p_here / (cand_M[j] * pj + c * p_here);
                }
                m /= k;
            }
        } else {
            float p_own = candidate_target(i, i, ri, code, owner, rng);
            if (!(p_own > 0.0)) {
                continue;
            }
            // Domain: M_i p_own > 0.
            m = cand_M[i] * p_own / (cand_M[i] * p_own + c * p_here) / k;
        }
        // w_i = m_i p_0(y_i) W_i, W_i = w_sum_i / (M_i p_hat_i), stored scaled by the
        // total M (Algorithm 2). Domain: p_hat_i > 0 and M_i > 0 (checked above).
        float w = p_here / ri.p_hat * ri.w_sum * (m * total / ri.M);
        if (combine_stream(s, ri, p_here, w, rng)) {
            chosen = i;
        }
    }
    combine_finish(s, total, chosen != n);
    return chosen;
}

// Streams candidates 0..n-1 into one reservoir for the pixel of candidate 0 with the MIS
// the plan chose; returns the chosen index (n if none).
uint combine_candidates(uint n, inout uint rng, out Reservoir s) {
    if (SC_MIS_PAIRWISE) {
        return combine_candidates_pairwise(n, rng, s);
    }
    return combine_candidates_talbot(n, rng, s);
}

// Writes the combined reservoir to `dst` for the pixel whose camera ray is `here`, copying
// the chosen candidate's path (from `src_at`, owned by camera ray `owner`). Vertex reuse
// re-expresses segment 2 relative to the new x_1 (x_2 stays in world space).
void store_combined(uint dst, Reservoir s, uint src_at, CameraRay owner, CameraRay here) {
    res_store_header(dst, s);
    if (!res_valid(s)) {
        return;
    }
    uint kp = res_vertices(s);
    bool shift_x2 = SC_REUSE_VERTEX && kp >= 2u;
    if (src_at == dst && !shift_x2 && owner.anchor == here.anchor) {
        return;
    }
    float z2 = 0.0;
    uint omega1 = 0u;
    // x_1's depth on this pixel's ray (the owner's past its anchor; see CameraRay.anchor).
    float z1 = res_z(src_at, 1u);
    float z1_here = z1 >= 0.0 ? z1 - owner.anchor + here.anchor : z1;
    if (shift_x2) {
        vec3 x2 = owner.o + z1 * owner.d + res_z(src_at, 2u) * oct_decode(res_omega(src_at, 1u));
        vec3 x1 = here.o + z1_here * here.d;
        z2 = length(x2 - x1);
        omega1 = z2 > 0.0 ? oct_encode((x2 - x1) / z2) : res_omega(src_at, 1u);
    }
    for (uint i = 1u; i <= kp; ++i) {
        float z = res_z(src_at, i);
        uint omega = res_omega(src_at, i);
        if (i == 1u) {
            z = z1_here;
        }
        if (shift_x2 && i == 1u) {
            omega = omega1;
        }
        if (shift_x2 && i == 2u) {
            z = z2;
        }
        res_store_vertex(dst, i, z, omega);
    }
}

#endif
