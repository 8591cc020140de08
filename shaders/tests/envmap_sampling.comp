#version 460
// Test harness for envmap.glsl (tests/suite/kernels/envmap_gpu.rs). One invocation per query; the
// query's mode says what to compute:
//   MODE_SAMPLE:    env_sample(q.a.xy): r0 = (dir, pdf), r1 = (radiance, 0);
//   MODE_PDF:       r0.x = env_pdf(q.a.xyz);
//   MODE_LOOKUP:    r0.xyz = env_lookup(q.a.xyz);
//   MODE_UV:        r0.xy = env_direction_to_uv(q.a.xyz),
//                   r1.xyz = env_uv_to_direction(uintBitsToFloat(q.b.yz));
//   MODE_HISTOGRAM: q.b.x samples from the rng seeded by q.b.y, each binned by the
//                   (u, v) of its direction into HIST_W × HIST_H bins of `histogram`;
//                   samples with pdf <= 0 go to bin HIST_W·HIST_H.

#extension GL_GOOGLE_include_directive : require

#include "constants.glsl"
#include "rng.glsl"

layout(local_size_x = 64) in;

#define BINDING_ENV_TEXELS 0
#define BINDING_ENV_CDF 1

layout(std430, set = 0, binding = BINDING_ENV_TEXELS) readonly buffer EnvTexelBlock {
    vec4 env_texels[];
};
layout(std430, set = 0, binding = BINDING_ENV_CDF) readonly buffer EnvCdfBlock {
    float env_cdf[];
};

// 32 bytes, mirrored in tests/suite/kernels/envmap_gpu.rs.
layout(push_constant) uniform PushBlock {
    uvec4 size;  // (W, H, query count, 0)
} u_push;
#define ENV_SIZE u_push.size.xy

// 32 bytes.
struct Query {
    vec4 a;
    uvec4 b;  // x mode; MODE_HISTOGRAM: y samples, z seed; MODE_UV: yz the uv's bits
};

// 48 bytes.
struct Result {
    vec4 r0;
    vec4 r1;
    uint non_finite;  // how many values computed here are NaN or infinite
    uint pad0;
    uint pad1;
    uint pad2;
};

layout(std430, set = 0, binding = 2) readonly buffer QueryBlock {
    Query queries[];
};
layout(std430, set = 0, binding = 3) writeonly buffer ResultBlock {
    Result results[];
};
layout(std430, set = 0, binding = 4) buffer HistogramBlock {
    uint histogram[];
};

#include "envmap.glsl"
// Included twice on purpose: the include guard must make the second one a no-op.
#include "envmap.glsl"

#define MODE_SAMPLE 0u
#define MODE_PDF 1u
#define MODE_LOOKUP 2u
#define MODE_UV 3u
#define MODE_HISTOGRAM 4u

#define HIST_W 16u
#define HIST_H 8u

uint count_non_finite(vec4 v) {
    uint n = 0u;
    for (int i = 0; i < 4; ++i) {
        n += (isnan(v[i]) || isinf(v[i])) ? 1u : 0u;
    }
    return n;
}

void main() {
    uint index = gl_GlobalInvocationID.x;
    if (index >= u_push.size.z) {
        return;
    }
    Query q = queries[index];
    Result r;
    r.r0 = vec4(0.0);
    r.r1 = vec4(0.0);
    r.non_finite = 0u;
    r.pad0 = 0u;
    r.pad1 = 0u;
    r.pad2 = 0u;
    uint mode = q.b.x;
    if (mode == MODE_SAMPLE) {
        vec3 dir;
        float pdf;
        vec3 radiance = env_sample(q.a.xy, dir, pdf);
        r.r0 = vec4(dir, pdf);
        r.r1 = vec4(radiance, 0.0);
    } else if (mode == MODE_PDF) {
        r.r0.x = env_pdf(q.a.xyz);
    } else if (mode == MODE_LOOKUP) {
        r.r0.xyz = env_lookup(q.a.xyz);
    } else if (mode == MODE_UV) {
        r.r0.xy = env_direction_to_uv(q.a.xyz);
        r.r1.xyz = env_uv_to_direction(uintBitsToFloat(q.b.yz));
    } else if (mode == MODE_HISTOGRAM) {
        uint rng = pcg_hash(q.b.z ^ pcg_hash(index));
        uint bad = 0u;
        for (uint i = 0u; i < q.b.y; ++i) {
            vec2 u;
            u.x = rng_next(rng);
            u.y = rng_next(rng);
            vec3 dir;
            float pdf;
            vec3 radiance = env_sample(u, dir, pdf);
            bad += count_non_finite(vec4(dir, pdf)) + count_non_finite(vec4(radiance, 0.0));
            uint bin = HIST_W * HIST_H;
            if (pdf > 0.0) {
                vec2 uv = env_direction_to_uv(dir);
                uint bx = min(uint(uv.x * float(HIST_W)), HIST_W - 1u);
                uint by = min(uint(uv.y * float(HIST_H)), HIST_H - 1u);
                bin = by * HIST_W + bx;
            }
            atomicAdd(histogram[bin], 1u);
        }
        r.non_finite = bad;
    }
    r.non_finite += count_non_finite(r.r0) + count_non_finite(r.r1);
    results[index] = r;
}
