// Heterogeneous grid media, walked by blocks: a DDA over blocks of f^3 voxels, the
// super-voxel walk (f = 8, with min/max/avg of sigma_t per super-voxel), and the
// baseline's unbiased estimators on it (Volumetric ReSTIR sec. 5.1): residual ratio
// tracking [Novák et al. 2014] and decomposition tracking [Kutz et al. 2017].
//
// The includer declares what grid.glsl needs and, before including this file:
//   layout(std430, ...) readonly buffer ... { vec4 super_voxels[]; };  // per density slot:
//       (min, max, avg, 0) of sigma_t over the super-voxel of the slot's brick
#ifndef NIMBUS_GRID_BLOCKS_GLSL
#define NIMBUS_GRID_BLOCKS_GLSL

#include "grid.glsl"
#include "grid_dda.glsl"
#include "grid_dual.glsl"

// Block DDA: block (I, J, K) of edge f voxels covers p-space [I f, (I+1) f] per axis
// (`count` blocks per axis), clipped to the grid's box. Super-voxels (f = 8: block b is the
// super-voxel of brick b) and the coarse piecewise-constant levels of ReSTIR (f = 2^mip)
// use it.

struct GridSuperDda {
    vec3 p0;        // index-space point at s = 0 (t = t_a)
    vec3 dp;        // index-space direction per unit t
    ivec3 cell;     // current block
    ivec3 step_dir; // +-1 per axis
    vec3 s_next;    // s at which each axis leaves the current block
    float s;        // start of the current span
    float len;      // t_b - t_a
    float t_a;      // t at s = 0
    int f;          // block edge in voxels (>= 1)
    ivec3 count;    // blocks per axis
    ivec3 brick;    // super-voxel walks: the brick of the span grid_super_next returned last
    uint slot;      // ... and its slot (NO_BRICK where empty)
};

// Crossing of block `c` along one axis (f voxels each, last one ends at n).
float grid_super_crossing(float p0, float dp, int c, int f, int count, float s_now) {
    return grid_cell_crossing(p0, dp, c, f, 0, count - 1, s_now);
}

// Starts a walk over blocks of edge f (count per axis) along [t0, t1] clipped to the
// bounds; false if that is empty.
bool grid_blocks_begin(vec3 o, vec3 d, float t0, float t1, int f, ivec3 count, out GridSuperDda it) {
    vec2 span = grid_span(o, d);
    it.t_a = max(t0, span.x);
    it.len = min(t1, span.y) - it.t_a;
    it.s = 0.0;
    it.f = max(f, 1);
    it.count = count;
    it.brick = ivec3(0);
    it.slot = NO_BRICK;
    // Empty, reversed or missed interval (also NaN): nothing to walk.
    if (!(it.len > 0.0)) {
        it.len = 0.0;
        return false;
    }
    it.p0 = space_to_index(u_grid.space, o + it.t_a * d);
    it.dp = space_index_dir(u_grid.space, d);
    for (int a = 0; a < 3; ++a) {
        // Domain: f >= 1.
        float fl = floor(it.p0[a] / float(it.f));
        int c = int(fl);
        if (it.dp[a] < -GRID_PARALLEL_EPS && it.p0[a] == fl * float(it.f)) {
            c -= 1;
        }
        it.cell[a] = clamp(c, 0, count[a] - 1);
        it.step_dir[a] = it.dp[a] > 0.0 ? 1 : -1;
        it.s_next[a] = grid_super_crossing(it.p0[a], it.dp[a], it.cell[a], it.f, count[a], 0.0);
    }
    return true;
}

// The current span [s0, s1) and its block's linear index (x fastest); advances to the
// next block. Returns false when the walk is over (nothing returned).
bool grid_blocks_next(inout GridSuperDda it, out float s0, out float s1, out uint index) {
    if (!(it.s < it.len)) {
        return false;
    }
    int a = it.s_next.x <= it.s_next.y ? (it.s_next.x <= it.s_next.z ? 0 : 2)
                                       : (it.s_next.y <= it.s_next.z ? 1 : 2);
    s0 = it.s;
    s1 = min(it.s_next[a], it.len);
    index = uint((it.cell.z * it.count.y + it.cell.y) * it.count.x + it.cell.x);
    // Advance: the walk ends at the span's end or when leaving the grid.
    it.s = s1;
    if (it.s_next[a] >= it.len) {
        it.s = it.len;
    } else {
        it.cell[a] += it.step_dir[a];
        if (it.cell[a] < 0 || it.cell[a] > it.count[a] - 1) {
            it.s = it.len;
        } else {
            it.s_next[a] = grid_super_crossing(it.p0[a], it.dp[a], it.cell[a], it.f, it.count[a], it.s);
        }
    }
    return true;
}

// Moves a block walk past the brick of 8^3 blocks holding its current block (a brick whose
// values are all 0): to where the ray leaves the brick's blocks, recomputing each axis's
// block there.
void grid_blocks_skip_brick(inout GridSuperDda it) {
    grid_dda_skip_brick(it.p0, it.dp, it.f, ivec3(0), it.count - 1, it.step_dir, it.len, it.cell, it.s_next, it.s);
}

// The same past the aligned (2^shift)^3 blocks holding its current block.
void grid_blocks_skip_aligned(inout GridSuperDda it, int shift) {
    grid_dda_skip_block(shift, it.p0, it.dp, it.f, ivec3(0), it.count - 1, it.step_dir, it.len, it.cell, it.s_next,
                        it.s);
}

// Super-voxel walk (blocks of 8, one per brick) over [t0, t1]; false if empty.
bool grid_super_begin(vec3 o, vec3 d, float t0, float t1, out GridSuperDda it) {
    return grid_blocks_begin(o, d, t0, t1, 8, ivec3(u_grid.space.brick_dims), it);
}

// The current span and its super-voxel's (min, max, avg, 0) of sigma_t (0 where the
// brick is empty); advances.
bool grid_super_next(inout GridSuperDda it, out float s0, out float s1, out vec4 bounds) {
    uint index;
    ivec3 brick = it.cell;
    if (!grid_blocks_next(it, s0, s1, index)) {
        return false;
    }
    uint slot = grid_slot(u_grid.space.bricks_offset, u_grid.space.brick_dims, brick);
    bounds = slot == NO_BRICK ? vec4(0.0) : super_voxels[slot];
    it.brick = brick;
    it.slot = slot;
    COUNT_STEP();
    COUNT(CTR_MAJORANT, 1);
    return true;
}

// sigma_t at p-space point p of the non-empty span a super-voxel walk returned last: from
// the density buffer, the span's slot serves every lookup in it (grid_sigma_index_in_brick).
float grid_sigma_index_in_span(vec3 p, GridSuperDda it) {
#ifdef NIMBUS_DENSITY_BUFFER
    if (SC_DENSITY_BUFFER) {
        return grid_sigma_index_in_brick(p, it.brick, it.slot);
    }
#endif
    return grid_sigma_index(p);
}

// A super-voxel span on which null-collision tracking would take more than this many
// tentative collisions on average (residual majorant x length) is tracked exactly
// instead: its closed-form optical depth, or the inversion of it (grid_dual.glsl). One hot
// voxel then costs only the dual cells around it, and no walk runs into GRID_MAX_STEPS.
// Ordinary clouds stay below it everywhere, so the baseline is the paper's there.
// (GRID_EXACT_SPAN_STEPS is in features.glsl.) Where no super-voxel can hold such a span
// (the pass checks every super-voxel's residual majorant against its longest chord), the
// exact branches are compiled out: on lavapipe they cost the lean loops 1.6x even untaken.
layout(constant_id = SC_ID_EXACT_SPANS) const bool SC_EXACT_SPANS = true;

// Unbiased T estimate by residual ratio tracking [Novák et al. 2014] per super-voxel:
// control sigma_c = min, residual majorant sigma_r = max - min,
// T = prod over spans of exp(-sigma_c len) prod_i (1 - (sigma_t(x_i) - sigma_c) / sigma_r);
// spans past GRID_EXACT_SPAN_STEPS contribute their exact exp(-tau). `majorant_scale` >= 1
// multiplies the residual majorant: more, shorter steps with factors nearer 1, so less
// noise for more work (Volumetric ReSTIR sec. 5.1 asks a large majorant of the ratio
// tracking in final shading).
float grid_residual_ratio_tracking_scaled(vec3 o, vec3 d, float t0, float t1,
                                          float majorant_scale, inout uint rng) {
    GridSuperDda it;
    if (!grid_super_begin(o, d, t0, t1, it)) {
        return 1.0;
    }
    float T = 1.0;
    float s0;
    float s1;
    vec4 bounds;
    int steps = 0;
    while (grid_super_next(it, s0, s1, bounds) && T > 0.0) {
        // Empty super-voxel: sigma_t = 0 throughout.
        if (!(bounds.y > 0.0) || !(s1 > s0)) {
            continue;
        }
        float sigma_c = bounds.x;
        float sigma_r = majorant_scale * (bounds.y - bounds.x);
        // A span too hot for null collisions: its exact transmittance.
        if (SC_EXACT_SPANS && sigma_r * (s1 - s0) > float(GRID_EXACT_SPAN_STEPS)) {
            T *= exp(-grid_optical_depth(o, d, it.t_a + s0, it.t_a + s1));
            continue;
        }
        // Control part analytically. Domain: sigma_c (s1 - s0) >= 0.
        T *= exp(-sigma_c * (s1 - s0));
        if (!(sigma_r > 0.0)) {
            continue;
        }
        // Residual part by ratio tracking with majorant sigma_r.
        float s = s0;
        for (;; ++steps) {
            if (steps >= GRID_MAX_STEPS) {
                g_step_cap_hits += 1u;
                return T;
            }
            // Exponential step with rate sigma_r. Domain: sigma_r > 0.
            s += sample_exponential(rng_next(rng), sigma_r);
            if (s >= s1 || T == 0.0) {
                break;
            }
            COUNT(CTR_COLLISIONS, 1);
            // Domain: sigma_r > 0.
            T *= 1.0 - (grid_sigma_index_in_span(it.p0 + it.dp * s, it) - sigma_c) / sigma_r;
        }
    }
    return T;
}

// Residual ratio tracking with the tight per-super-voxel majorant (the baseline's NEE).
float grid_residual_ratio_tracking(vec3 o, vec3 d, float t0, float t1, inout uint rng) {
    return grid_residual_ratio_tracking_scaled(o, d, t0, t1, 1.0, rng);
}

// Decomposition tracking [Kutz et al. 2017] per super-voxel: the collision with the
// homogeneous control sigma_c = min is sampled in closed form, the residual
// sigma_t - sigma_c by delta tracking with majorant max - min; the first of the two is the
// real collision. Spans past GRID_EXACT_SPAN_STEPS sample it by exact inversion of their
// optical depth. Returns its t in [t0, t1), or FAR if the ray passes (probability T).
float grid_sample_collision(vec3 o, vec3 d, float t0, float t1, inout uint rng) {
    GridSuperDda it;
    if (!grid_super_begin(o, d, t0, t1, it)) {
        return FAR;
    }
    float s0;
    float s1;
    vec4 bounds;
    int steps = 0;
    while (grid_super_next(it, s0, s1, bounds)) {
        // Empty super-voxel: no collision possible.
        if (!(bounds.y > 0.0) || !(s1 > s0)) {
            continue;
        }
        float sigma_c = bounds.x;
        float sigma_r = bounds.y - bounds.x;
        // A span too hot for null collisions: regular tracking by exact inversion.
        if (SC_EXACT_SPANS && sigma_r * (s1 - s0) > float(GRID_EXACT_SPAN_STEPS)) {
            float target = sample_exponential(rng_next(rng), 1.0);
            float t = grid_invert_optical_depth(o, d, it.t_a + s0, it.t_a + s1, target);
            if (t < FAR) {
                return t;
            }
            continue;
        }
        // Control collision at rate sigma_c. Domain: sigma_c > 0 where sampled.
        float s_control = sigma_c > 0.0 ? s0 + sample_exponential(rng_next(rng), sigma_c) : FAR;
        float s_limit = min(s_control, s1);
        // Residual collisions before it, by delta tracking.
        if (sigma_r > 0.0) {
            float s = s0;
            for (;; ++steps) {
                if (steps >= GRID_MAX_STEPS) {
                    g_step_cap_hits += 1u;
                    return FAR;
                }
                // Tentative collision at rate sigma_r. Domain: sigma_r > 0.
                s += sample_exponential(rng_next(rng), sigma_r);
                if (s >= s_limit) {
                    break;
                }
                COUNT(CTR_COLLISIONS, 1);
                if (rng_next(rng) * sigma_r < grid_sigma_index_in_span(it.p0 + it.dp * s, it) - sigma_c) {
                    return it.t_a + s;
                }
            }
        }
        if (s_control < s1) {
            return it.t_a + s_control;
        }
    }
    return FAR;
}

// Decomposition tracking's collision and residual ratio tracking's transmittance along one
// ray, in one walk over [t0, t1): both take their residual tentative collisions from one
// Poisson process of rate max - min per super-voxel (each estimator alone is then the one
// above, so both stay unbiased; they are merely correlated), and the walk goes on past the
// collision to t1 for the transmittance. Returns the collision's t in [t0, t1) or FAR
// (the ray passes), and sets T. The baseline's split NEE uses it where the path's next
// direction is also the sky's NEE direction (pathtrace.comp): one walk instead of two.
float grid_collision_and_transmittance(vec3 o, vec3 d, float t0, float t1, inout uint rng, out float T) {
    T = 1.0;
    GridSuperDda it;
    if (!grid_super_begin(o, d, t0, t1, it)) {
        return FAR;
    }
    float t_hit = FAR;
    float s0;
    float s1;
    vec4 bounds;
    int steps = 0;
    while (grid_super_next(it, s0, s1, bounds) && (T > 0.0 || t_hit == FAR)) {
        if (!(bounds.y > 0.0) || !(s1 > s0)) {
            continue;
        }
        float sigma_c = bounds.x;
        float sigma_r = bounds.y - bounds.x;
        if (SC_EXACT_SPANS && sigma_r * (s1 - s0) > float(GRID_EXACT_SPAN_STEPS)) {
            float a = it.t_a + s0;
            float b = it.t_a + s1;
            if (t_hit == FAR) {
                t_hit = grid_invert_optical_depth(o, d, a, b, sample_exponential(rng_next(rng), 1.0));
            }
            T *= exp(-grid_optical_depth(o, d, a, b));
            continue;
        }
        // Domain: sigma_c (s1 - s0) >= 0.
        T *= exp(-sigma_c * (s1 - s0));
        // The control collision, while no collision has been found.
        float s_control = (t_hit == FAR && sigma_c > 0.0) ? s0 + sample_exponential(rng_next(rng), sigma_c) : FAR;
        if (sigma_r > 0.0) {
            float s = s0;
            for (;; ++steps) {
                if (steps >= GRID_MAX_STEPS) {
                    g_step_cap_hits += 1u;
                    return t_hit;
                }
                // Tentative collision at rate sigma_r. Domain: sigma_r > 0.
                s += sample_exponential(rng_next(rng), sigma_r);
                if (s >= s1 || (T == 0.0 && t_hit < FAR)) {
                    break;
                }
                COUNT(CTR_COLLISIONS, 1);
                float r = (grid_sigma_index_in_span(it.p0 + it.dp * s, it) - sigma_c) / sigma_r;
                T *= 1.0 - r;
                // A real residual collision before the control one.
                if (t_hit == FAR && s < s_control && rng_next(rng) < r) {
                    t_hit = it.t_a + s;
                }
            }
        }
        if (t_hit == FAR && s_control < s1) {
            t_hit = it.t_a + s_control;
        }
    }
    return t_hit;
}

#endif
