#version 460
// Denoiser stage 2, one invocation per pixel: the luminance variance where prepare.comp
// left none (-1: one frame, no film variance, too short a history), estimated from the
// 7x7 neighbourhood as the mean square of the luminance's residuals from their 4
// neighbours' mean (residual() below: an image's smooth gradients do not count as noise),
// the neighbours weighted by the geometry guides (depth, normal) so that it stays on the
// pixel's surface, times variance_boost. Elsewhere the variance passes through.

#extension GL_GOOGLE_include_directive : require

#include "common.glsl"

layout(std430, set = 0, binding = BINDING_DENOISE_COLOR_SRC) readonly buffer ColorSrcBlock {
    vec4 color_src[];
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

// The luminance at q minus the mean of its neighbours in the image (left, right, up,
// down), scaled so that its square estimates the noise's variance where the noise is
// independent between pixels (Var = sigma^2 (1 + 1/k) for k neighbours): a smooth
// gradient of the image (whose Laplacian is 0) adds nothing.
float residual(ivec2 q) {
    float l = luminance(color_src[pixel_index(q)].rgb);
    float sum = 0.0;
    float k = 0.0;
    for (int n = 0; n < 4; ++n) {
        ivec2 o = n < 2 ? ivec2(2 * n - 1, 0) : ivec2(0, 2 * n - 5);
        if (inside(q + o)) {
            sum += luminance(color_src[pixel_index(q + o)].rgb);
            k += 1.0;
        }
    }
    return (l - sum / k) * inversesqrt(1.0 + 1.0 / k);
}

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
            float r = residual(q);
            w_sum += w;
            r2 += w * r * r;
        }
    }
    variance_dst[i] = (w_sum > 0.0 ? r2 / w_sum : 0.0) * u_push.variance_boost;
}
