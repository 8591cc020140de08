#version 460
// Test harness for grid.glsl and grid_blocks.glsl (tests/suite/kernels/grid_volume/). One
// invocation per query; the query's mode says what to compute along its ray o + t d over
// [t0, t1]:
//   MODE_CLOSED_FORM: optical depth, transmittance, the box span and sigma_t at o;
//   MODE_ESTIMATORS: `samples` ratio-tracking and residual-ratio-tracking estimates of T,
//                    returned as sums and sums of squares;
//   MODE_COLLISION:  one decomposition-tracking collision distance.

#extension GL_GOOGLE_include_directive : require

#include "grid_types.glsl"

layout(local_size_x = 64) in;

// The density's atlas of 9^3-texel slots and, per slot, its super-voxel's (min, max,
// avg, 0) of sigma_t; the indirection (brick -> slot) at binding 4.
layout(set = 0, binding = 0) uniform sampler3D u_density;
layout(std430, set = 0, binding = 1) readonly buffer SuperVoxelBlock {
    vec4 super_voxels[];
};
layout(std430, set = 0, binding = 4) readonly buffer GridBrickBlock {
    uint grid_bricks[];
};

// A query. 48 bytes, mirrored in tests/suite/kernels/grid_volume/.
struct Query {
    vec4 o_t0;     // xyz origin, w t0
    vec4 d_t1;     // xyz unit direction, w t1
    uint mode;
    uint samples;  // MODE_ESTIMATORS: estimates to sum
    uint seed;
    uint pad;
};

// The answers. 48 bytes.
struct Result {
    vec4 r0;
    vec4 r1;
    uint non_finite;  // how many values computed here are NaN or infinite
    uint pad0;
    uint pad1;
    uint pad2;
};

layout(push_constant) uniform PushBlock {
    uint query_count;
    uint pad0;
    uint pad1;
    uint pad2;
} u_push;
// The medium (192 bytes: more than the 128 bytes of push constants Vulkan guarantees).
layout(std430, set = 0, binding = 5) readonly buffer GridBlock {
    GridParams u_grid_params;
};
#define u_grid u_grid_params

layout(std430, set = 0, binding = 2) readonly buffer QueryBlock {
    Query queries[];
};
layout(std430, set = 0, binding = 3) writeonly buffer ResultBlock {
    Result results[];
};

#include "grid.glsl"
#include "grid_blocks.glsl"
// Included twice on purpose: the include guards must make the second one a no-op.
#include "grid.glsl"
#include "grid_blocks.glsl"

#define MODE_CLOSED_FORM 0u
#define MODE_ESTIMATORS 1u
#define MODE_COLLISION 2u

uint count_non_finite(vec4 v) {
    uint n = 0u;
    for (int i = 0; i < 4; ++i) {
        n += (isnan(v[i]) || isinf(v[i])) ? 1u : 0u;
    }
    return n;
}

void main() {
    uint index = gl_GlobalInvocationID.x;
    if (index >= u_push.query_count) {
        return;
    }
    Query q = queries[index];
    vec3 o = q.o_t0.xyz;
    vec3 d = q.d_t1.xyz;
    float t0 = q.o_t0.w;
    float t1 = q.d_t1.w;
    Result r;
    r.r0 = vec4(0.0);
    r.r1 = vec4(0.0);
    r.non_finite = 0u;
    r.pad0 = 0u;
    r.pad1 = 0u;
    r.pad2 = 0u;
    uint rng = pcg_hash(q.seed ^ pcg_hash(index));
    if (q.mode == MODE_CLOSED_FORM) {
        vec2 span = grid_span(o, d);
        r.r0 = vec4(grid_optical_depth(o, d, t0, t1), grid_transmittance(o, d, t0, t1),
                    grid_sigma_t(o), 0.0);
        // The span itself is infinite-free only on a hit; report it clamped.
        r.r1 = vec4(clamp(span, -FAR, FAR), 0.0, 0.0);
    } else if (q.mode == MODE_ESTIMATORS) {
        float sum_ratio = 0.0;
        float sum_sq_ratio = 0.0;
        float sum_residual = 0.0;
        float sum_sq_residual = 0.0;
        uint bad = 0u;
        for (uint i = 0u; i < q.samples; ++i) {
            float a = grid_ratio_tracking(o, d, t0, t1, rng);
            float b = grid_residual_ratio_tracking(o, d, t0, t1, rng);
            bad += count_non_finite(vec4(a, b, 0.0, 0.0));
            sum_ratio += a;
            sum_sq_ratio += a * a;
            sum_residual += b;
            sum_sq_residual += b * b;
        }
        r.r0 = vec4(sum_ratio, sum_sq_ratio, sum_residual, sum_sq_residual);
        r.non_finite = bad;
    } else {
        r.r0.x = grid_sample_collision(o, d, t0, t1, rng);
    }
    r.non_finite += count_non_finite(r.r0) + count_non_finite(r.r1);
    results[index] = r;
}
