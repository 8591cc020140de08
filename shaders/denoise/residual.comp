#version 460
// Denoiser stage 2a, one invocation per pixel, only where the film gives no variance:
// the squared residual of the pixel's luminance from the mean of its neighbours in the
// image (left, right, up, down), scaled so that it estimates the noise's variance where
// the noise is independent between pixels (Var = sigma^2 (1 + 1/k) for k neighbours): a
// smooth gradient of the image (whose Laplacian is 0) adds nothing. variance.comp
// averages it over 7x7 pixels.

#extension GL_GOOGLE_include_directive : require

#include "common.glsl"

layout(std430, set = 0, binding = BINDING_DENOISE_COLOR_SRC) readonly buffer ColorSrcBlock {
    vec4 color_src[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_RESIDUAL) writeonly buffer ResidualBlock {
    float residual2[];
};

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (!inside(p) || has(DENOISE_FILM_VARIANCE)) {
        return;
    }
    float l = luminance(color_src[pixel_index(p)].rgb);
    float sum = 0.0;
    float k = 0.0;
    for (int n = 0; n < 4; ++n) {
        ivec2 o = n < 2 ? ivec2(2 * n - 1, 0) : ivec2(0, 2 * n - 5);
        if (inside(p + o)) {
            sum += luminance(color_src[pixel_index(p + o)].rgb);
            k += 1.0;
        }
    }
    float r = l - sum / k;
    residual2[pixel_index(p)] = r * r / (1.0 + 1.0 / k);
}
