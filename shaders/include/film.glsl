// The film: per-pixel running sums over frames, the count of non-finite samples, and
// the pixel loop of the path-tracing integrators. Every per-pixel pass includes this
// file after its specialization constants (SC_PIXEL_JITTER at least): it sets the
// workgroup (one invocation per pixel, GROUP_SIZE_X x GROUP_SIZE_Y) and declares the
// frame's uniforms `u_frame` (FrameUniforms: image = width, height, spp, seed) and the
// three film buffers.
//
// accum[p]    rgb: sum over frames of the frame's pixel estimate; a: sum of its coverage
//             (alpha = 1 - the camera ray's transmittance, see g_camera_transmittance)
// accum_sq[p] sum of squares of the same (the renderer's standard errors). The renderer
//             counts the frames itself.
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

// Add one frame's estimate of `pixel` (radiance, coverage alpha) to the running sums.
void film_accumulate(uvec2 pixel, vec3 estimate, float alpha) {
    uint index = pixel.y * u_frame.width + pixel.x;
    vec4 x = vec4(estimate, alpha);
    accum[index] += x;
    accum_sq[index] += x * x;
}

// The transmittance of the camera ray through every medium up to the first opaque surface
// or emitter it meets (0 when it meets one), set by the integrator for the camera sample
// it traces: the film's alpha is 1 - its mean. A pass that never sets it leaves the
// pixel opaque.
float g_camera_transmittance = 0.0;

// ---------------------------------------------------------------------------------------
// The pixel loop of the path tracers (crepuscular, baseline): u_frame.spp camera
// samples per pixel per frame, each with its own random stream, jittered over the
// pixel's footprint (box filter).

// Radiance arriving at o from direction -d, estimated by the including pass; only a pass
// that calls film_pixel_estimate defines it.
vec3 radiance(vec3 o, vec3 d, inout uint rng);

// The frame's estimate of `pixel`: rgb the mean radiance of its finite camera samples, a
// the mean coverage 1 - T of the same samples (0 and 1 if none is finite). Sample s of
// the frame draws from the stream (pixel, frame, sample_base + s, seed).
vec4 film_pixel_estimate(uvec2 pixel, uint frame, uint sample_base) {
    vec3 sum = vec3(0.0);
    float coverage = 0.0;
    uint kept = 0u;
    for (uint s = 0u; s < u_frame.spp; ++s) {
        uint rng = rng_init(pixel, frame, sample_base + s, u_frame.seed);
        vec2 px = vec2(pixel) + pixel_jitter(rng);
        g_camera_transmittance = 0.0;
        vec3 L = radiance(u_frame.cam_position, camera_direction(u_frame, px), rng);
        if (film_sample_finite(L)) {
            sum += L;
            coverage += 1.0 - clamp(g_camera_transmittance, 0.0, 1.0);
            kept += 1u;
        }
    }
    film_flush_counters();
    // Domain: kept >= 1 where divided.
    return kept > 0u ? vec4(sum, coverage) / float(kept) : vec4(0.0, 0.0, 0.0, 1.0);
}

#endif
