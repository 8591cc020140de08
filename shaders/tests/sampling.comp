#version 460
// Test harness for sampling.glsl and phase.glsl (tests/sampling_gpu.rs). One invocation per
// input; the push constants' mode says what to compute from it:
//   MODE_HG:      sample_hg(axis, g, u), u = input.xy;
//   MODE_COSINE:  sample_cosine_hemisphere(axis, u), u = input.xy;
//   MODE_PHASE:   hg_phase(input.x, g).

#extension GL_GOOGLE_include_directive : require

#include "sampling.glsl"
#include "phase.glsl"

layout(local_size_x = 64) in;

// 32 bytes, mirrored in tests/sampling_gpu.rs.
layout(push_constant) uniform PushBlock {
    vec4 axis_g;  // xyz unit direction d (HG) or normal n (cosine), w the HG asymmetry g
    uint mode;
    uint count;
    uint pad0;
    uint pad1;
} u_push;

layout(std430, set = 0, binding = 0) readonly buffer InputBlock {
    vec2 inputs[];
};
// xyz the sampled direction (MODE_HG, MODE_COSINE), w the phase value (MODE_PHASE).
layout(std430, set = 0, binding = 1) writeonly buffer OutputBlock {
    vec4 outputs[];
};

#define MODE_HG 0u
#define MODE_COSINE 1u
#define MODE_PHASE 2u

void main() {
    uint index = gl_GlobalInvocationID.x;
    if (index >= u_push.count) {
        return;
    }
    vec2 u = inputs[index];
    vec3 axis = u_push.axis_g.xyz;
    float g = u_push.axis_g.w;
    vec4 result = vec4(0.0);
    if (u_push.mode == MODE_HG) {
        result.xyz = sample_hg(axis, g, u);
    } else if (u_push.mode == MODE_COSINE) {
        result.xyz = sample_cosine_hemisphere(axis, u);
    } else {
        result.w = hg_phase(u.x, g);
    }
    outputs[index] = result;
}
