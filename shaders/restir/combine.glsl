// Volumetric ReSTIR (Lin, Wyman and Yuksel 2021): combining reservoirs with Talbot MIS
// (Algorithm 5, with Algorithm 2's combineReservoir), or pairwise MIS, for temporal and
// spatial reuse.
#ifndef NIMBUS_RESTIR_COMBINE_GLSL
#define NIMBUS_RESTIR_COMBINE_GLSL

#extension GL_GOOGLE_include_directive : require

#include "path_value.glsl"

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
// Candidate i's sub-pixel frame (jitter code units, x in bits 0-7 and y in 8-15, each mod
// 256): a path owned by candidate i with jitter code c is evaluated at candidate j with
// code c - shift_i + shift_j per axis (jitter_code_move), a translation of the pixel's
// 256 x 256 grid that wraps around (a bijection: Jacobian 1). 0 unless temporal reuse
// aligns the two frames' pixels (see temporal.comp).
uint cand_jitter_shift[MAX_CANDIDATES];

// Jitter code `code` of candidate `from`'s sub-pixel frame in candidate `to`'s.
uint jitter_code_move(uint code, uint from, uint to) {
    uint a = cand_jitter_shift[from];
    uint b = cand_jitter_shift[to];
    uint x = ((code & 0xffu) - (a & 0xffu) + (b & 0xffu)) & 0xffu;
    uint y = (((code >> 8u) & 0xffu) - ((a >> 8u) & 0xffu) + ((b >> 8u) & 0xffu)) & 0xffu;
    return x | (y << 8u);
}

// ---------------------------------------------------------------------------------------
// The optical-depth shift of spatial reuse (SC_SPATIAL_TAU_SHIFT; spatial.comp defines
// COMBINE_SPATIAL). Direction reuse keeps a neighbour's first distance z_1, which puts x_1
// outside the medium or deep inside it on this pixel's ray. This shift keeps x_1's optical
// depth tau_1 through the conservative grid (level LEVEL_PRIMARY, the one regular tracking
// drew it on: tau_1 is its Exp(1) draw) and finds x_1 where this ray reaches tau_1. In the
// tau_1 coordinate the shift is the identity (Jacobian 1), so every target of a
// combination is taken per unit of tau_1: p / sigma*(x_1), sigma* on the evaluating ray
// (the ratio of the two rays' sigma* is the shift's Jacobian in z_1). Headers keep the
// z_1 measure: a reservoir's p_hat is divided by sigma* at its own x_1 on loading and
// the combined one multiplied by sigma* at the pixel's x_1 on storing (w_sum, an
// estimate of the integral, is the same in both). Paths without a medium x_1 (the camera
// ray ends on a light or a surface) keep the distance shift, a translation.
#ifndef COMBINE_SPATIAL
#define COMBINE_SPATIAL 0
#endif

// The exact optical-depth shift: set by temporal.comp per frame (SC_TEMPORAL_TAU_SHIFT, a
// moving camera over the density of the previous frame) and by spatial.comp
// (SC_SPATIAL_TAU_EXACT, every frame). The same structure as the shift through the
// conservative grid above, with tau_1 the exact optical depth through the grid's own
// trilinear density (grid_optical_depth, grid_invert_optical_depth) instead of tau* through
// the conservative grid, and sigma_t at x_1 as the measure's density. A target then
// per unit of tau_1 is sigma_s T~ L / sigma_t: the camera segment's T~ and the density at
// x_1 nearly cancel between the two rays (both reach x_1 at one optical depth), so a
// reused path's target changes by the light at its vertices (along its stored
// directions) alone. The distance shift (with anchors) also carries the change of the
// camera segment's optical depth into the target ratio, frame after frame.
bool combine_tau_exact = false;

// Whether this combination shifts x_1 by optical depth.
bool tau_shift() {
    return (COMBINE_SPATIAL != 0 && SC_SPATIAL_TAU_SHIFT) || combine_tau_exact;
}

// The anchor of the pixel's camera ray that puts the chosen sample's x_1 where the
// combination evaluated it (CameraRay.anchor: store_combined translates z_1 by it).
float combine_here_anchor = 0.0;

// tau_1 of the path stored at `at` on its owner's ray (< 0: no medium x_1 to shift; the
// path keeps its distance) and sigma* at its x_1 (1 without the shift; sigma_t under the
// exact shift, combine_tau_exact). sigma* = 0 (no majorant at x_1, so no density: the
// path's target is 0 everywhere) gives tau_1 = -2.
float path_tau(uint at, Reservoir r, CameraRay owner, out float sigma_star) {
    sigma_star = 1.0;
    if (!tau_shift() || res_vertices(r) < 1u) {
        return -1.0;
    }
    float z1 = res_z(at, 1u);
    if (!(z1 >= 0.0)) {
        return -1.0;
    }
    // x_1 on the owner's own ray (path_value's translation by the owner's anchor is 0).
    vec3 x1 = owner.o + z1 * owner.d;
    if (combine_tau_exact) {
        // sigma_t = 0 at x_1: nothing scatters or emits there (the grid is the only
        // medium), so the path's target is 0 on every ray.
        sigma_star = grid_sigma_t(x1);
        if (!(sigma_star > 0.0)) {
            return -2.0;
        }
        return grid_optical_depth(owner.o, owner.d, 0.0, z1);
    }
    sigma_star = pc_sigma_star_at(LEVEL_PRIMARY, x1);
    if (!(sigma_star > 0.0)) {
        return -2.0;
    }
    float s_unused;
    float tau;
    pc_track(LEVEL_PRIMARY, owner.o, owner.d, z1, FAR, s_unused, tau);
    return tau;
}

// The target of the path stored at `at` (header r, owner ray `owner`, tau_1 `tau1` and
// sigma* `sigma_own` from path_tau) on camera ray `ray` (same = ray is the owner's own):
// target_scalar of path_value, per unit of tau_1 under the optical-depth shift. `anchor` is
// the ray's anchor that places x_1 there (for store_combined); `sigma_here` the sigma*
// that converts the result back to the z_1 measure (1 without the shift).
float shifted_target(uint at, Reservoir r, CameraRay ray, CameraRay owner, bool same, float tau1, float sigma_own,
                     out float anchor, out float sigma_here, inout uint rng) {
    anchor = ray.anchor;
    sigma_here = 1.0;
    if (tau1 >= 0.0) {
        if (same) {
            sigma_here = sigma_own;
        } else {
            float z;
            if (combine_tau_exact) {
                z = grid_invert_optical_depth(ray.o, ray.d, 0.0, FAR, tau1);
                sigma_here = z < FAR ? grid_sigma_t(ray.o + z * ray.d) : 0.0;
            } else {
                float tau;
                z = pc_track(LEVEL_PRIMARY, ray.o, ray.d, FAR, tau1, sigma_here, tau);
            }
            // This ray's optical depth stays below tau_1: the shifted path does not exist.
            if (z >= FAR || !(sigma_here > 0.0)) {
                return 0.0;
            }
            // path_value puts x_1 at z_1 - owner.anchor + ray.anchor.
            anchor = z - res_z(at, 1u) + owner.anchor;
            ray.anchor = anchor;
        }
    }
    float p = target_scalar(path_value(at, r, ray, owner, MODE_TARGET, rng));
    // Domain: sigma_here > 0 (checked above, or 1).
    return p / sigma_here;
}

// The sub-pixel centre's jitter code (offset 127.5 / 256 per axis).
#define JITTER_CODE_CENTRE 0x7f7fu
// Floor of the transmittance a relative change is measured against: below it a camera ray
// is opaque enough that changes of T~ are not changes of what the pixel shows.
#define HISTORY_T_FLOOR 0.001
// The relative change of the camera ray's T~ at which the history's confidence is 0
// (linear from 1 at no change).
#define HISTORY_T_TOLERANCE 0.1

// The optical depth through the conservative grid at which a camera ray counts as having
// entered the medium (its depth anchor).
#define ANCHOR_TAU 1e-3

// T~ of the camera ray through `pixel` at jitter `code` in a frame's set up to its first
// opaque end, what ends it (a shape: its index; an emitting sphere: 0x10000 + its index
// in the set; nothing: NO_INDEX) and where it enters the medium (FAR if it does not): the
// first point past optical depth ANCHOR_TAU through this frame's conservative grid.
float camera_feature_at(uvec2 pixel, uint code, uint set, out uint end, out float entry) {
    CameraRay r = camera_ray(pixel, code, set);
    uint sphere;
    SurfacePoint s;
    float t_end = opaque_end(light_base(set), r.o, r.d, sphere, s);
    end = s.shape != NO_INDEX ? s.shape : (sphere != NO_INDEX ? 0x10000u + sphere : NO_INDEX);
    float sigma_star;
    float tau;
    entry = pc_track(LEVEL_PRIMARY, r.o, r.d, t_end, ANCHOR_TAU, sigma_star, tau);
    return reuse_transmittance(set, r.o, r.d, t_end);
}

// camera_feature_at on the ray through the pixel's centre.
float camera_feature(uvec2 pixel, uint set, out uint end, out float entry) {
    return camera_feature_at(pixel, JITTER_CODE_CENTRE, set, end, entry);
}

// The relative change between two camera rays' T~ (relative to the larger, floored at
// HISTORY_T_FLOOR): what the history's confidence and spatial reuse's neighbour test
// compare.
float camera_t_change(float t_a, float t_b) {
    // Domain: the denominator >= HISTORY_T_FLOOR > 0.
    return abs(t_a - t_b) / max(max(t_a, t_b), HISTORY_T_FLOOR);
}

// Registers candidate `i` (its header's M unless clamped later).
void candidate_set(uint i, uint at, uvec2 pixel, uint set) {
    cand_at[i] = at;
    cand_pixel[i] = pixel;
    cand_set[i] = set;
    cand_M[i] = res_load_M(at);
    cand_w_scale[i] = 1.0;
    cand_same_target[i] = i == 0u;
    cand_anchor[i] = 0.0;
    cand_jitter_shift[i] = 0u;
}

// The camera ray of candidate j's pixel and frame for a path owned by candidate i with
// jitter code `code` (in i's sub-pixel frame).
CameraRay candidate_ray_for(uint j, uint i, uint code) {
    CameraRay r = camera_ray(cand_pixel[j], jitter_code_move(code, i, j), cand_set[j]);
    r.anchor = cand_anchor[j];
    return r;
}

// The camera ray of candidate i's pixel and frame at its own jitter `code`.
CameraRay candidate_ray(uint i, uint code) {
    return candidate_ray_for(i, i, code);
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
    combine_here_anchor = cand_anchor[0];
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
        // Under the optical-depth shift, tau_1 and the own-measure target p_hat / sigma*.
        float sigma_own;
        float tau1 = path_tau(cand_at[i], ri, owner, sigma_own);
        if (tau1 == -2.0) {
            continue;
        }
        // Domain: sigma_own > 0 (path_tau).
        float p_hat_i = ri.p_hat / sigma_own;
        // The target here (j = 0) first, then at the sample's own pixel (j = i): if either
        // is 0, w_i = 0 whatever the other pixels give, and they are not evaluated.
        float p_sum = 0.0;
        float p_own = 0.0;
        float p_here = 0.0;
        float anchor_here = cand_anchor[0];
        float sigma_here = 1.0;
        bool dead = false;
        // A combined reservoir already holds the target at its own pixel (computed by the
        // same function for the same ray, frame and path).
        bool has_own = (ri.info & INFO_REUSE_TARGET) != 0u;
        // The target of candidate 0's function for this sample, once known (< 0: not yet),
        // which every candidate with the same target function shares.
        float p_shared = has_own && cand_same_target[i] ? p_hat_i : -1.0;
        for (uint step = 0u; step < n && !dead; ++step) {
            // Visit order: 0, i, then the others ascending (0, 1, 2, ... when i = 0).
            uint j = i == 0u ? step : (step == 0u ? 0u : (step == 1u ? i : (step <= i ? step - 1u : step)));
            if (!(cand_M[j] > 0.0)) {
                continue;
            }
            float p;
            float anchor_j = j == i ? owner.anchor : cand_anchor[j];
            float sigma_j = j == i ? sigma_own : 1.0;
            if (j == i && has_own) {
                p = p_hat_i;
            } else if (cand_same_target[j] && p_shared >= 0.0) {
                // (Temporal reuse only, where x_1 keeps its distance.)
                p = p_shared;
            } else {
                p = shifted_target(cand_at[i], ri, candidate_ray_for(j, i, code), owner, j == i, tau1, sigma_own,
                                   anchor_j, sigma_j, rng);
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
                anchor_here = anchor_j;
                sigma_here = sigma_j;
                dead = dead || !(p > 0.0);
            }
        }
        // Domain: p_sum > 0 (else no pixel could have produced lambda_i: weight 0).
        if (!(p_sum > 0.0) || !(p_here > 0.0)) {
            continue;
        }
        float m = p_own * k / p_sum;
        // Domain: p_hat_i > 0 (checked above).
        float w = p_here / p_hat_i * ri.w_sum * m;
        // The header keeps the z_1 measure of this pixel's ray.
        if (combine_stream(s, ri, p_here * sigma_here, w, rng)) {
            chosen = i;
            combine_here_anchor = anchor_here;
        }
    }
    combine_finish(s, k, chosen != n);
    return chosen;
}

// The target function at candidate j's pixel and frame for the sample of reservoir ri
// (stored at candidate i, jitter code `code`, owned by camera ray `owner`, tau_1 and
// sigma* from path_tau); candidate i's own value comes from the header when the reservoir
// already holds it. Per unit of tau_1 under the optical-depth shift (see shifted_target,
// which also gives `anchor` and `sigma_here`).
float candidate_target(uint i, uint j, Reservoir ri, uint code, CameraRay owner, float tau1, float sigma_own,
                       out float anchor, out float sigma_here, inout uint rng) {
    bool has_own = (ri.info & INFO_REUSE_TARGET) != 0u;
    anchor = j == i ? owner.anchor : cand_anchor[j];
    sigma_here = j == i ? sigma_own : 1.0;
    if (has_own && (j == i || (cand_same_target[i] && cand_same_target[j]))) {
        // Domain: sigma_own > 0 (path_tau).
        return ri.p_hat / sigma_own;
    }
    return shifted_target(cand_at[i], ri, candidate_ray_for(j, i, code), owner, j == i, tau1, sigma_own, anchor,
                          sigma_here, rng);
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
    combine_here_anchor = cand_anchor[0];
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
        float sigma_own;
        float tau1 = path_tau(cand_at[i], ri, owner, sigma_own);
        if (tau1 == -2.0) {
            continue;
        }
        // Domain: sigma_own > 0 (path_tau).
        float p_hat_i = ri.p_hat / sigma_own;
        float anchor_here;
        float sigma_here;
        float anchor_unused;
        float sigma_unused;
        float p_here = candidate_target(i, 0u, ri, code, owner, tau1, sigma_own, anchor_here, sigma_here, rng);
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
                    float pj = candidate_target(0u, j, ri, code, owner, tau1, sigma_own, anchor_unused,
                                                sigma_unused, rng);
                    // Domain: c p_here > 0, so the denominator is > 0.
                    m += c * p_here / (cand_M[j] * pj + c * p_here);
                }
                m /= k;
            }
        } else {
            float p_own = candidate_target(i, i, ri, code, owner, tau1, sigma_own, anchor_unused, sigma_unused, rng);
            if (!(p_own > 0.0)) {
                continue;
            }
            // Domain: M_i p_own > 0.
            m = cand_M[i] * p_own / (cand_M[i] * p_own + c * p_here) / k;
        }
        // w_i = m_i p_0(y_i) W_i, W_i = w_sum_i / (M_i p_hat_i), stored scaled by the
        // total M (Algorithm 2). Domain: p_hat_i > 0 and M_i > 0 (checked above).
        float w = p_here / p_hat_i * ri.w_sum * (m * total / ri.M);
        // The header keeps the z_1 measure of this pixel's ray.
        if (combine_stream(s, ri, p_here * sigma_here, w, rng)) {
            chosen = i;
            combine_here_anchor = anchor_here;
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
