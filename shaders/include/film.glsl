// The film: per-pixel running sums over frames, the count of non-finite samples, and
// the pixel loop of the path-tracing integrators. Every per-pixel pass includes this
// file after its specialization constants (SC_PIXEL_JITTER at least): it sets the
// workgroup (one invocation per pixel, GROUP_SIZE_X x GROUP_SIZE_Y) and declares the
// frame's uniforms `u_frame` (FrameUniforms: image = width, height, spp, seed) and the
// three film buffers.
//
// accum[p]    rgb: sum over frames of the frame's pixel estimate, a: frames
// accum_sq[p] rgb: sum of squares of the frame estimates (the renderer's standard error)
// A non-finite sample is never written: it is counted in stats[STAT_NON_FINITE] and the
// pass decides what stands for it (left out of the mean, or 0). Walks cut short at
// GRID_MAX_STEPS are counted in stats[STAT_STEP_CAP].
#ifndef NIMBUS_FILM_GLSL
#define NIMBUS_FILM_GLSL

#include "features.glsl"
#include "bindings.glsl"
#include "scene.glsl"

layout(local_size_x = GROUP_SIZE_X, local_size_y = GROUP_SIZE_Y) in;

layout(std140, set = 0, binding = BINDING_FRAME_UNIFORMS) uniform FrameBlock {
    FrameUniforms u_frame;
};
layout(std430, set = 0, binding = BINDING_ACCUM) buffer AccumBlock {
    vec4 accum[];
};
layout(std430, set = 0, binding = BINDING_ACCUM_SQ) buffer AccumSqBlock {
    vec4 accum_sq[];
};
layout(std430, set = 0, binding = BINDING_STATS) buffer StatsBlock {
    uint stats[];
};

#include "camera.glsl"
#include "counters.glsl"
#include "rng.glsl"

// Whether `pixel` lies inside the image (dispatches round up to whole workgroups).
bool film_contains(uvec2 pixel) {
    return pixel.x < u_frame.width && pixel.y < u_frame.height;
}

// True for a finite sample; counts a NaN or infinite one instead.
bool film_sample_finite(vec3 L) {
    if (any(isnan(L)) || any(isinf(L))) {
        atomicAdd(stats[STAT_NON_FINITE], 1u);
        return false;
    }
    return true;
}

// Adds this invocation's counters (counters.glsl) to the stats buffer. Every pass calls
// it once per invocation, after its work.
void film_flush_counters() {
    if (g_step_cap_hits > 0u) {
        atomicAdd(stats[STAT_STEP_CAP], g_step_cap_hits);
        g_step_cap_hits = 0u;
    }
}

// Add one frame's estimate of `pixel` to the running sums.
void film_accumulate(uvec2 pixel, vec3 estimate) {
    uint index = pixel.y * u_frame.width + pixel.x;
    accum[index] += vec4(estimate, 1.0);
    accum_sq[index] += vec4(estimate * estimate, 0.0);
}

// ---------------------------------------------------------------------------------------
// The pixel loop of the path tracers (crepuscular, baseline): u_frame.spp camera
// samples per pixel per frame, each with its own random stream, jittered over the
// pixel's footprint (box filter).

// Radiance arriving at o from direction -d, estimated by the including pass; only a pass
// that calls film_pixel_estimate defines it.
vec3 radiance(vec3 o, vec3 d, inout uint rng);

// The frame's estimate of `pixel`: the mean of its finite camera samples (0 if none).
// Sample s of the frame draws from the stream (pixel, frame, sample_base + s, seed).
vec3 film_pixel_estimate(uvec2 pixel, uint frame, uint sample_base) {
    vec3 sum = vec3(0.0);
    uint kept = 0u;
    for (uint s = 0u; s < u_frame.spp; ++s) {
        uint rng = rng_init(pixel, frame, sample_base + s, u_frame.seed);
        vec2 px = vec2(pixel) + pixel_jitter(rng);
        vec3 L = radiance(u_frame.cam_position, camera_direction(u_frame, px), rng);
        if (film_sample_finite(L)) {
            sum += L;
            kept += 1u;
        }
    }
    film_flush_counters();
    return kept > 0u ? sum / float(kept) : vec3(0.0);
}

#endif
