#version 460
// Denoiser stage 3, one iteration of the edge-avoiding a-trous wavelet filter, one
// invocation per pixel: the 5x5 B3-spline kernel (1/16, 1/4, 3/8) with holes of `step`
// pixels, each tap weighted by the geometry guides (common.glsl) and by the luminance
// difference in units of the pixel's standard deviation (its variance prefiltered by a
// 3x3 Gaussian): exp(-|l_p - l_q| / (sigma_luminance sqrt(var_p) + 1e-10)). The variance
// goes through the same weights squared (the variance of the weighted mean, as SVGF
// does), so each iteration stops at the noise that is left. The first iteration also
// writes the temporal history.

#extension GL_GOOGLE_include_directive : require

#include "common.glsl"

layout(std430, set = 0, binding = BINDING_DENOISE_COLOR_SRC) readonly buffer ColorSrcBlock {
    vec4 color_src[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_VARIANCE_SRC) readonly buffer VarianceSrcBlock {
    float variance_src[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_COLOR_DST) writeonly buffer ColorDstBlock {
    vec4 color_dst[];
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
layout(std430, set = 0, binding = BINDING_DENOISE_HISTORY) writeonly buffer HistoryBlock {
    vec4 history[];
};

const float KERNEL[3] = float[3](3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0);

// The 3x3 Gaussian (1/4, 1/8, 1/16) of the variance around p, renormalised at the border.
float blurred_variance(ivec2 p) {
    float sum = 0.0;
    float w_sum = 0.0;
    for (int y = -1; y <= 1; ++y) {
        for (int x = -1; x <= 1; ++x) {
            ivec2 q = p + ivec2(x, y);
            if (!inside(q)) {
                continue;
            }
            float w = (x == 0 ? 0.5 : 0.25) * (y == 0 ? 0.5 : 0.25);
            sum += w * variance_src[pixel_index(q)];
            w_sum += w;
        }
    }
    return sum / w_sum;
}

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (!inside(p)) {
        return;
    }
    uint i = pixel_index(p);
    vec4 cp = color_src[i];
    float lp = luminance(cp.rgb);
    bool geometry = has(DENOISE_HAS_DEPTH) || has(DENOISE_HAS_NORMAL);
    vec4 gp = geometry ? guides[i] : vec4(0.0, 0.0, 0.0, -1.0);
    vec2 grad = has(DENOISE_HAS_DEPTH) ? gradient[i] : vec2(0.0);
    float phi = u_push.sigma_luminance * sqrt(max(blurred_variance(p), 0.0)) + 1e-10;
    int hole = int(u_push.step);

    float w_center = KERNEL[0] * KERNEL[0];
    vec4 sum = w_center * cp;
    float w_sum = w_center;
    float var_sum = w_center * w_center * variance_src[i];
    for (int y = -2; y <= 2; ++y) {
        for (int x = -2; x <= 2; ++x) {
            if (x == 0 && y == 0) {
                continue;
            }
            ivec2 offset = ivec2(x, y) * hole;
            ivec2 q = p + offset;
            if (!inside(q)) {
                continue;
            }
            uint j = pixel_index(q);
            vec4 cq = color_src[j];
            float w = KERNEL[abs(x)] * KERNEL[abs(y)]
                * exp(-abs(lp - luminance(cq.rgb)) / phi);
            if (geometry) {
                w *= geometry_weight(gp, grad, guides[j], vec2(offset));
            }
            sum += w * cq;
            w_sum += w;
            var_sum += w * w * variance_src[j];
        }
    }
    vec4 out_color = sum / w_sum;
    color_dst[i] = out_color;
    variance_dst[i] = var_sum / (w_sum * w_sum);
    if (has(DENOISE_WRITE_HISTORY)) {
        history[i] = out_color;
    }
}
