// The film: per-pixel running sums over frames, and the count of non-finite samples.
// Every pass that writes the image includes this file; it declares the three buffers.
// The includer declares `u_frame` (FrameUniforms: image.x is the width).
//
// accum[p]    rgb: sum over frames of the frame's pixel estimate, a: frames
// accum_sq[p] rgb: sum of squares of the frame estimates (the renderer's standard error)
// A non-finite sample is never written: it is counted in stats[STAT_NON_FINITE] and the
// pass decides what stands for it (left out of the mean, or 0).
#ifndef NIMBUS_FILM_GLSL
#define NIMBUS_FILM_GLSL

#include "bindings.glsl"

layout(std430, set = 0, binding = BINDING_ACCUM) buffer AccumBlock {
    vec4 accum[];
};
layout(std430, set = 0, binding = BINDING_ACCUM_SQ) buffer AccumSqBlock {
    vec4 accum_sq[];
};
layout(std430, set = 0, binding = BINDING_STATS) buffer StatsBlock {
    uint stats[];
};

// Whether `pixel` lies inside the image (dispatches round up to whole workgroups).
bool film_contains(uvec2 pixel) {
    return pixel.x < u_frame.image.x && pixel.y < u_frame.image.y;
}

// True for a finite sample; counts a NaN or infinite one instead.
bool film_sample_finite(vec3 L) {
    if (any(isnan(L)) || any(isinf(L))) {
        atomicAdd(stats[STAT_NON_FINITE], 1u);
        return false;
    }
    return true;
}

// Add one frame's estimate of `pixel` to the running sums.
void film_accumulate(uvec2 pixel, vec3 estimate) {
    uint index = pixel.y * u_frame.image.x + pixel.x;
    accum[index] += vec4(estimate, 1.0);
    accum_sq[index] += vec4(estimate * estimate, 0.0);
}

#endif
