#version 460
// Denoiser stage 4, one invocation per pixel: multiplies the filtered colour by the
// albedo factor it was divided by (prepare.comp) into the output image, and keeps this
// frame's guides and moments as the next frame's history (temporal accumulation on).

#extension GL_GOOGLE_include_directive : require

#include "common.glsl"

layout(std430, set = 0, binding = BINDING_DENOISE_COLOR_SRC) readonly buffer ColorSrcBlock {
    vec4 color_src[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_ALBEDO) readonly buffer AlbedoBlock {
    vec4 albedo[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_OUTPUT) writeonly buffer OutputBlock {
    vec4 denoised[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_GUIDES) readonly buffer GuidesBlock {
    vec4 guides[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_GUIDES_PREV) writeonly buffer GuidesPrevBlock {
    vec4 guides_prev[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_MOMENTS) readonly buffer MomentsBlock {
    vec4 moments[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_MOMENTS_PREV) writeonly buffer MomentsPrevBlock {
    vec4 moments_prev[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_HISTORY) writeonly buffer HistoryBlock {
    vec4 history[];
};

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (!inside(p)) {
        return;
    }
    uint i = pixel_index(p);
    vec4 f = color_src[i];
    vec3 a = has(DENOISE_HAS_ALBEDO) ? albedo_factor(finite_or_zero(albedo[i]).rgb) : vec3(1.0);
    denoised[i] = vec4(f.rgb * a, f.a);
    if (has(DENOISE_TEMPORAL)) {
        if (has(DENOISE_HAS_DEPTH) || has(DENOISE_HAS_NORMAL)) {
            guides_prev[i] = guides[i];
        }
        moments_prev[i] = moments[i];
        if (has(DENOISE_WRITE_HISTORY)) {
            history[i] = f;
        }
    }
}
