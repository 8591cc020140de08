#version 460
// Test harness for the sampling families of sampling.glsl and phase.glsl
// (tests/suite/kernels/sampling_gpu/). One invocation per input; the push constants' mode says what
// to compute from it:
//   MODE_HG:          sample_hg(axis, g, u), u = input.xy;
//   MODE_COSINE:      sample_cosine_hemisphere(axis, u), u = input.xy;
//   MODE_PHASE:       hg_phase(input.x, g);
//   MODE_SAMPLE:      the family's sample of u = input.xy (xyz; a distance in x) and its
//                     pdf there (w);
//   MODE_ROUND_TRIP:  invert(sample(u)) (xy) and the pdf at the sample (z);
//   MODE_PDF:         the family's pdf (w) at the value input.x: cos theta about the
//                     axis for directions, else the distance.
// A family's parameter is axis_g.w: g (HG), 1 - cos(theta_max) (cone), the rate
// (exponential) or the optical depth x (truncated exponential).

#extension GL_GOOGLE_include_directive : require

#include "sampling.glsl"
#include "phase.glsl"

layout(local_size_x = 64) in;

// 32 bytes, mirrored in tests/suite/kernels/sampling_gpu/.
layout(push_constant) uniform PushBlock {
    vec4 axis_g;  // xyz unit direction d (HG) or normal n (cosine), or cone axis; w the parameter
    uint mode;
    uint count;
    uint family;  // FAMILY_* for MODE_SAMPLE, MODE_ROUND_TRIP and MODE_PDF
    uint pad0;
} u_push;

layout(std430, set = 0, binding = 0) readonly buffer InputBlock {
    vec2 inputs[];
};
layout(std430, set = 0, binding = 1) writeonly buffer OutputBlock {
    vec4 outputs[];
};

#define MODE_HG 0u
#define MODE_COSINE 1u
#define MODE_PHASE 2u
#define MODE_SAMPLE 3u
#define MODE_ROUND_TRIP 4u
#define MODE_PDF 5u

#define FAMILY_HG 0u
#define FAMILY_COSINE 1u
#define FAMILY_SPHERE 2u
#define FAMILY_CONE 3u
#define FAMILY_EXPONENTIAL 4u
#define FAMILY_TRUNCATED_EXPONENTIAL 5u

// The family's sample of u: a direction, or a distance in x.
vec3 family_sample(uint family, vec3 axis, float p, vec2 u) {
    if (family == FAMILY_HG) {
        return sample_hg(axis, p, u);
    }
    if (family == FAMILY_COSINE) {
        return sample_cosine_hemisphere(axis, u);
    }
    if (family == FAMILY_SPHERE) {
        return sample_uniform_sphere(u);
    }
    if (family == FAMILY_CONE) {
        return sample_uniform_cone(axis, p, u);
    }
    if (family == FAMILY_EXPONENTIAL) {
        return vec3(sample_exponential(u.x, p), 0.0, 0.0);
    }
    return vec3(sample_truncated_exponential(p, u.x), 0.0, 0.0);
}

// The family's pdf at x: cos theta about the axis for directions, else the distance.
float family_pdf(uint family, float p, float x) {
    if (family == FAMILY_HG) {
        return hg_pdf(x, p);
    }
    if (family == FAMILY_COSINE) {
        return cosine_hemisphere_pdf(x);
    }
    if (family == FAMILY_SPHERE) {
        return uniform_sphere_pdf();
    }
    if (family == FAMILY_CONE) {
        return uniform_cone_pdf(p);
    }
    if (family == FAMILY_EXPONENTIAL) {
        return exponential_pdf(x, p);
    }
    return truncated_exponential_pdf(p, x);
}

// The family's pdf at its sample s: of cos theta = dot(axis, s) for directions (the
// sphere's is constant), of the distance s.x otherwise.
float family_pdf_at(uint family, vec3 axis, float p, vec3 s) {
    return family_pdf(family, p, family <= FAMILY_CONE ? dot(axis, s) : s.x);
}

// The u the family's sampler takes to s.
vec2 family_invert(uint family, vec3 axis, float p, vec3 s) {
    if (family == FAMILY_HG) {
        return invert_hg(axis, p, s);
    }
    if (family == FAMILY_COSINE) {
        return invert_cosine_hemisphere(axis, s);
    }
    if (family == FAMILY_SPHERE) {
        return invert_uniform_sphere(s);
    }
    if (family == FAMILY_CONE) {
        return invert_uniform_cone(axis, p, s);
    }
    if (family == FAMILY_EXPONENTIAL) {
        return vec2(invert_exponential(s.x, p), 0.0);
    }
    return vec2(invert_truncated_exponential(p, s.x), 0.0);
}

void main() {
    uint index = gl_GlobalInvocationID.x;
    if (index >= u_push.count) {
        return;
    }
    vec2 u = inputs[index];
    vec3 axis = u_push.axis_g.xyz;
    float g = u_push.axis_g.w;
    uint family = u_push.family;
    vec4 result = vec4(0.0);
    if (u_push.mode == MODE_HG) {
        result.xyz = sample_hg(axis, g, u);
    } else if (u_push.mode == MODE_COSINE) {
        result.xyz = sample_cosine_hemisphere(axis, u);
    } else if (u_push.mode == MODE_PHASE) {
        result.w = hg_phase(u.x, g);
    } else if (u_push.mode == MODE_SAMPLE) {
        vec3 s = family_sample(family, axis, g, u);
        result = vec4(s, family_pdf_at(family, axis, g, s));
    } else if (u_push.mode == MODE_ROUND_TRIP) {
        vec3 s = family_sample(family, axis, g, u);
        result.xy = family_invert(family, axis, g, s);
        result.z = family_pdf_at(family, axis, g, s);
    } else {
        result.w = family_pdf(family, g, u.x);
    }
    outputs[index] = result;
}
