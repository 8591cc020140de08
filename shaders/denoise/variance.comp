#version 460
// Denoiser stage 2, one invocation per pixel: the luminance variance where prepare.comp
// left none (-1: one frame, no film variance, too short a history), estimated from the
// 7x7 neighbourhood as the mean of the squared luminance residuals residual.comp wrote
// (an image's smooth gradients do not count as noise),
// the neighbours weighted by the geometry guides (depth, normal) so that it stays on the
// pixel's surface, times variance_boost. Elsewhere the variance passes through.

#extension GL_GOOGLE_include_directive : require

#include "common.glsl"

layout(std430, set = 0, binding = BINDING_DENOISE_RESIDUAL) readonly buffer ResidualBlock {
    float residual2[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_VARIANCE_SRC) readonly buffer VarianceSrcBlock {
    float variance_src[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_VARIANCE_DST) writeonly buffer VarianceDstBlock {
    float variance_dst[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_GUIDES) readonly buffer GuidesBlock {
    vec4 guides[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_GRADIENT) readonly buffer GradientBlock {
    vec2 gradient[];
};

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (!inside(p)) {
        return;
    }
    uint i = pixel_index(p);
    float v = variance_src[i];
    if (v >= 0.0) {
        variance_dst[i] = v;
        return;
    }
    bool geometry = has(DENOISE_HAS_DEPTH) || has(DENOISE_HAS_NORMAL);
    vec4 gp = geometry ? guides[i] : vec4(0.0, 0.0, 0.0, -1.0);
    vec2 grad = has(DENOISE_HAS_DEPTH) ? gradient[i] : vec2(0.0);
    float w_sum = 0.0;
    float r2 = 0.0;
    for (int y = -3; y <= 3; ++y) {
        for (int x = -3; x <= 3; ++x) {
            ivec2 q = p + ivec2(x, y);
            if (!inside(q)) {
                continue;
            }
            uint j = pixel_index(q);
            float w = geometry ? geometry_weight(gp, grad, guides[j], vec2(x, y)) : 1.0;
            if (w <= 0.0) {
                continue;
            }
            w_sum += w;
            r2 += w * residual2[j];
        }
    }
    variance_dst[i] = (w_sum > 0.0 ? r2 / w_sum : 0.0) * u_push.variance_boost;
}
