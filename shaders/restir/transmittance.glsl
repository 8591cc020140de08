// Volumetric ReSTIR: transmittance along a path's segments in a frame's set. Targets use
// a ray-marched trilinear T~ on a mip texture (sec. 5.1): mip_reuse for the targets of
// reuse, mip_indirect for the NEE segments of initial candidates; final shading uses an
// unbiased T (the closed form or residual ratio tracking, grid.glsl and grid_blocks.glsl).
#ifndef NIMBUS_RESTIR_TRANSMITTANCE_GLSL
#define NIMBUS_RESTIR_TRANSMITTANCE_GLSL

#include "resources.glsl"
#include "counters.glsl"

// Media lookups for a frame's set.

float sigma_t_of(uint set, vec3 x) {
    return set == SET_CURRENT ? grid_sigma_t(x)
                              : grid_sigma_t_at(u_density_prev, u_restir.density_prev_offset, x);
}

// The largest optical depth a ray-marched T~ reports (T~ >= e^-64, a normal float).
#define MARCH_MAX_TAU 64.0

// T~ along o + t d, t in [t0, t1]: midpoint ray marching of the mip level L (its atlas
// `tex`, indirection section at `offset`) with steps of at most `step` metres, the texture
// filtered linearly inside a slot (the apron holds the upper neighbours); where
// SC_MARCH_BUFFER the same trilinear filter from its quads from slot `quad_base` on of
// march_quads (two loads; the hardware filter's weights may round otherwise, so T~ may
// differ in the last bits, consistently for every evaluation of a frame). Samples in an
// empty brick read 0, so the march jumps over such bricks to the first sample past them
// (the same sum). Deterministic, so a target function is a function of the path (needed by
// the MIS weights).
float march_transmittance(sampler3D tex, GridLevel L, uint offset, uint quad_base, float step, vec3 o,
                          vec3 d, float t0, float t1) {
    vec2 span = grid_span(o, d);
    float a = max(t0, span.x);
    float b = min(t1, span.y);
    if (!(a < b)) {
        return 1.0;
    }
    // Domain: step > 0 (a voxel diagonal).
    int n = int(clamp(ceil((b - a) / step), 1.0, float(MARCH_MAX_STEPS)));
    float dt = (b - a) / float(n);
    // The level's lattice coordinate u = p / factor - 0.5 along the ray. Domain: factor >= 1.
    float inv_f = 1.0 / float(L.factor);
    vec3 u0 = space_to_index(u_grid.space, o + a * d) * inv_f - 0.5;
    vec3 du = space_index_dir(u_grid.space, d) * inv_f;
    vec3 lo = vec3(L.lattice_min);
    vec3 hi = vec3(L.lattice_max);
    // Domain: the atlas has at least one slot.
    vec3 inv_size = 1.0 / vec3(textureSize(tex, 0));
    // The sum at which the optical depth reaches MARCH_MAX_TAU: past it T~ is e^-64
    // whatever the rest of the segment holds, so the march stops there (deep in a dense
    // cloud, most of a light segment). Domain: density_scale * dt > 0, else no cap.
    float scale_dt = u_grid.density_scale * dt;
    float sum_cap = scale_dt > 0.0 ? MARCH_MAX_TAU / scale_dt : FAR;
    float sum = 0.0;
    // The brick of the previous sample and its slot's first texel: consecutive samples
    // mostly share a brick, whose indirection lookup and slot arithmetic (three integer
    // divisions) are then not repeated.
    ivec3 brick_at = ivec3(-1);
    uint slot = NO_BRICK;
    vec3 origin = vec3(0.0);
    for (int j = 0; j < n; ++j) {
        float t = (float(j) + 0.5) * dt;
        vec3 u = clamp(u0 + du * t, lo, hi);
        ivec3 brick = ivec3(floor(u)) >> 3;
        if (brick != brick_at) {
            brick_at = brick;
            slot = grid_slot(offset, L.brick_dims, brick);
            origin = vec3(grid_slot_origin(slot, L.slots_x, L.slots_y) - brick * 8);
        }
        if (slot == NO_BRICK) {
            // Jump to the last sample before the ray leaves the brick (clamped samples
            // stay in it: no exit on that side).
            float t_exit = FAR;
            for (int k = 0; k < 3; ++k) {
                float edge = du[k] > 0.0 ? float(brick[k] * 8 + 8) : float(brick[k] * 8);
                bool exits = du[k] > 0.0 ? edge <= hi[k] : edge > lo[k];
                if (abs(du[k]) > GRID_PARALLEL_EPS && exits) {
                    // Domain: |du| > 0.
                    t_exit = min(t_exit, (edge - u0[k]) / du[k]);
                }
            }
            // Domain: dt > 0. floor keeps the jump from passing a sample in the next brick.
            float next = floor(min(t_exit / dt - 0.5, float(n)));
            j = max(j, int(next) - 1);
            continue;
        }
        COUNT_STEP();
        COUNT(CTR_DENSITY, 1);
        if (SC_MARCH_BUFFER) {
            // The filter's lower texel floor(u) and weights fract(u): in the slot, texels
            // floor(u) - 8 brick (0..7) and one further (its apron at 8).
            vec3 fl = floor(u);
            vec3 w = u - fl;
            ivec3 l = ivec3(fl) - brick * 8;
            int q = int(quad_base + slot) * 729 + (l.z * 9 + l.y) * 9 + l.x;
            vec4 q0 = march_quads[q];
            vec4 q1 = march_quads[q + 81];
            float a0 = mix(mix(q0.x, q0.y, w.x), mix(q0.z, q0.w, w.x), w.y);
            float a1 = mix(mix(q1.x, q1.y, w.x), mix(q1.z, q1.w, w.x), w.y);
            sum += mix(a0, a1, w.z);
        } else {
            vec3 texel = origin + u + 0.5;
            sum += textureLod(tex, texel * inv_size, 0.0).r;
        }
        if (sum >= sum_cap) {
            return exp(-MARCH_MAX_TAU);
        }
    }
    // Domain: density_scale * sum * dt >= 0. Capped at MARCH_MAX_TAU so T~ (and with it
    // every target function) stays > 0 wherever the path contributes: RIS is unbiased
    // only if p^ > 0 wherever f > 0, and an approximate T~ may exceed the true depth.
    return exp(-min(u_grid.density_scale * sum * dt, MARCH_MAX_TAU));
}

// T~ for target functions of reuse (mip_reuse) in a frame's set.
float reuse_transmittance(uint set, vec3 o, vec3 d, float t1) {
    float step = u_restir.march_reuse_step;
    COUNT_SHADOW_BEGIN();
    float T;
    if (set == SET_CURRENT) {
        T = march_transmittance(u_march_reuse, u_restir.march_reuse, u_restir.march_reuse.bricks_offset,
                                u_restir.march_reuse.quad_base, step, o, d, 0.0, t1);
    } else {
        T = march_transmittance(u_march_reuse_prev, u_restir.march_reuse, u_restir.march_reuse_prev_offset,
                                u_restir.march_reuse_prev_quad_base, step, o, d, 0.0, t1);
    }
    COUNT_SHADOW_END();
    return T;
}

// T~ of NEE segments of initial candidates (mip_indirect).
float nee_transmittance(vec3 o, vec3 d, float t1) {
    COUNT_SHADOW_BEGIN();
    float T = march_transmittance(u_march_nee, u_restir.march_nee, u_restir.march_nee.bricks_offset,
                                  u_restir.march_nee.quad_base, u_restir.march_nee_step, o, d, 0.0, t1);
    COUNT_SHADOW_END();
    return T;
}

// The residual majorant's multiple in final ratio tracking: the paper's advice is a large
// majorant ("forcing a smaller average step"); the tight global one it replaced gave
// 7-27x the per-frame RMSE of the closed form.
#define FINAL_RATIO_MAJORANT_SCALE 4.0

// Unbiased T for final shading: the closed form through the trilinear grid, or residual
// ratio tracking per super-voxel with a 4x majorant.
float final_transmittance(vec3 o, vec3 d, float t1, inout uint rng) {
    COUNT_SHADOW_BEGIN();
    float T = SC_FINAL_RATIO_TRACKING
                  ? grid_residual_ratio_tracking_scaled(o, d, 0.0, t1, FINAL_RATIO_MAJORANT_SCALE, rng)
                  : grid_transmittance(o, d, 0.0, t1);
    COUNT_SHADOW_END();
    return T;
}

#endif
