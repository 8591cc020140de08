// The film: per-pixel running sums over frames, the count of non-finite samples, and
// the pixel loop of the path-tracing integrators. Every per-pixel pass includes this
// file after its specialization constants (SC_PIXEL_JITTER at least): it sets the
// workgroup (one invocation per pixel, GROUP_SIZE_X x GROUP_SIZE_Y) and declares the
// frame's uniforms `u_frame` (FrameUniforms: image = width, height, spp, seed) and the
// four film buffers.
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

// The frame's parameters, and every other pass's parameter block, are read-only storage
// buffers, not uniform buffers: lavapipe (Mesa 22.3, our CI device) "inlines" uniform-buffer
// values that reach a branch or a loop bound into a specialised copy of the shader and,
// for a shader such as ours, compiles that copy again with LLVM at every dispatch and
// never frees it. That cost 8-80 ms of every dispatch (a 1x1 frame of the window scene:
// 77 ms; of the ReSTIR and baseline grid passes: 24 ms) inside the GPU timestamps, and
// 3-11 MB of host memory per frame, without end. Storage-buffer loads are not inlined.
layout(std430, set = 0, binding = BINDING_FRAME_UNIFORMS) readonly buffer FrameBlock {
    FrameUniforms u_frame_block;
};
// A private copy, made by film_load() at the start of every pass's main: see
// grid_resources_load (grid_resources.glsl) for why.
FrameUniforms u_frame;

void film_load() {
    u_frame = u_frame_block;
}
layout(std430, set = 0, binding = BINDING_ACCUM) buffer AccumBlock {
    vec4 accum[];
};
layout(std430, set = 0, binding = BINDING_ACCUM_SQ) buffer AccumSqBlock {
    vec4 accum_sq[];
};
layout(std430, set = 0, binding = BINDING_STATS) buffer StatsBlock {
    uint stats[];
};
// Per pixel, two vec4: a frame's radiance and coverage sums so far and its count of
// finite samples, while the frame's samples are shared among dispatches (see
// film_take_samples; one element where the device takes a frame in one dispatch).
layout(std430, set = 0, binding = BINDING_FILM_PARTIAL) buffer FilmPartialBlock {
    vec4 film_partial[];
};

#include "camera.glsl"
#include "counters.glsl"
#include "rng.glsl"
#include "aov.glsl"

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
    // The work counters, 64 bits each (a carry into the high word where the low one
    // wraps): a 1080p frame's steps overflow 32 bits; then each counter's largest value
    // in one invocation (32 bits).
    if (SC_COUNTERS) {
        for (uint c = 0u; c < uint(COUNTER_COUNT); ++c) {
            uint n = g_counters[c];
            if (n > 0u) {
                uint at = STAT_COUNT + 2u * (SC_COUNTER_SLOT * uint(COUNTER_COUNT) + c);
                uint before = atomicAdd(stats[at], n);
                if (before + n < before) {
                    atomicAdd(stats[at + 1u], 1u);
                }
                // The longest invocation: on a GPU a dispatch lasts as long as its slowest
                // lane, which the sums above average away.
                atomicMax(stats[STAT_COUNT + 2u * uint(COUNTER_COUNT * COUNTER_SLOTS) +
                                SC_COUNTER_SLOT * uint(COUNTER_COUNT) + c], n);
            }
            g_counters[c] = 0u;
        }
    }
    // lavapipe (llvmpipe) silently ends every loop of an invocation once 65535 loop
    // iterations (all loops together) have run in it, so a long invocation returns a cut
    // estimate. A loop of two trips that the compiler cannot count ahead then runs once:
    // count it, and the renderer refuses the image.
    uint trips = 2u + (u_frame.width >> 31u);
    uint runs = 0u;
    for (uint i = 0u; i < trips; ++i) {
        runs += 1u;
    }
    if (runs < trips) {
        atomicAdd(stats[STAT_LOOPS_CUT], 1u);
    }
}

// Add one frame's estimate of `pixel` (radiance, coverage alpha) to the running sums.
void film_accumulate(uvec2 pixel, vec3 estimate, float alpha) {
    uint index = pixel.y * u_frame.width + pixel.x;
    vec4 x = vec4(estimate, alpha);
    accum[index] += x;
    accum_sq[index] += x * x;
}

// Whether the film's alpha is wanted at all: off where nothing reads it (nimbus profile,
// study and bench), and then every pixel reads as opaque.
layout(constant_id = SC_ID_ALPHA) const bool SC_ALPHA = true;

// The transmittance of the camera ray through every medium up to the first opaque surface
// or emitter it meets (0 when it meets one), set by the integrator for the camera sample
// it traces when g_alpha_wanted: the film's alpha is 1 - its mean. A pass that never sets
// it leaves the pixel opaque.
float g_camera_transmittance = 0.0;
// Whether the integrator computes g_camera_transmittance for the sample it traces now.
bool g_alpha_wanted = SC_ALPHA;

// A diagnostic (`nimbus profile --coherent-lanes`): every invocation of a workgroup takes
// the camera samples (random stream and sub-pixel position) of the workgroup's first
// pixel, so the lanes of a SIMD row or warp all trace the same paths and no loop waits for
// its slowest lane. The frame then costs the same work per lane as the scene's without the
// divergence; its image is not the scene's.
layout(constant_id = SC_ID_COHERENT_LANES) const bool SC_COHERENT_LANES = false;

// ---------------------------------------------------------------------------------------
// The pixel loop of the path tracers (crepuscular, baseline): the frame's u_frame.spp
// camera samples per pixel, taken by one dispatch or shared among several (each adds
// its own estimate to the sums), each with its own random stream, jittered over the
// pixel's footprint (box filter).

// Radiance arriving at o from direction -d, estimated by the including pass; only a pass
// that calls film_pixel_estimate defines it.
vec3 radiance(vec3 o, vec3 d, inout uint rng);

// The path tracers' pixel loop: a frame's u_frame.spp camera samples of `pixel`
// are drawn by one dispatch (sample_base = 0, sample_count = spp) or by several in turn
// where the device limits loop iterations. Sample s draws from the stream (pixel, frame,
// s, seed). A share that does not end the frame leaves its sums (radiance, coverage,
// finite samples) in film_partial; the one that ends it adds the frame's estimate (rgb
// the mean radiance of its finite samples, a the coverage 1 - T; 0 if none is finite) to
// the film: one estimate per pixel and frame, however the frame was shared. The path
// AOVs (aov.glsl) follow the beauty's sums exactly (per sample, per frame, partial sums
// between dispatches), and the frame's first dispatch writes the geometric AOVs.
//
// In the grid passes the coverage is that of the frame's first camera sample alone: the
// camera ray's transmittance is a closed form (the grid's costs a dual-cell walk of the
// whole ray, 38 % of a 16-spp baseline frame when every sample paid it), the sample's
// sub-pixel position is uniform over the footprint, so the frame's alpha is an unbiased
// estimate of the pixel's coverage all the same, and over frames it converges as before.
// A pass whose camera-ray transmittance is cheap (the crepuscular pass: box media in
// closed form) defines FILM_ALPHA_EVERY_SAMPLE before including this file and averages
// every sample's coverage, so that its beauty minus its transparent render is exactly
// (1 - alpha) x background per pixel.
void film_take_samples(uvec2 pixel, uint frame, uint sample_base, uint sample_count) {
    uint index = pixel.y * u_frame.width + pixel.x;
    vec3 sum = vec3(0.0);
    float coverage = 1.0;
    float kept = 0.0;
    if (sample_base > 0u) {
        vec4 a = film_partial[2u * index];
        sum = a.rgb;
        coverage = a.a;
        kept = film_partial[2u * index + 1u].x;
    }
    if (sample_base == 0u) {
        aov_geometry_pixel(pixel);
    }
    aov_frame_begin(index, sample_base);
    uvec2 source = SC_COHERENT_LANES ? gl_WorkGroupID.xy * uvec2(GROUP_SIZE_X, GROUP_SIZE_Y) : pixel;
    for (uint s = 0u; s < sample_count; ++s) {
        uint rng = rng_init(source, frame, sample_base + s, u_frame.seed);
        aov_sample_begin();
        vec2 px = vec2(source) + pixel_jitter(rng);
        g_camera_transmittance = 0.0;
#ifdef FILM_ALPHA_EVERY_SAMPLE
        g_alpha_wanted = SC_ALPHA;
#else
        g_alpha_wanted = SC_ALPHA && sample_base + s == 0u;
#endif
        COUNT(CTR_SAMPLES, 1);
        vec3 L = radiance(u_frame.cam_position, camera_direction(u_frame, px), rng);
        bool finite = film_sample_finite(L);
#ifdef FILM_ALPHA_EVERY_SAMPLE
        // The mean coverage of the finite samples (the first one's until there is one).
        if (finite) {
            float c = 1.0 - clamp(g_camera_transmittance, 0.0, 1.0);
            coverage = kept > 0.0 ? coverage + c : c;
        }
#else
        if (g_alpha_wanted) {
            coverage = 1.0 - clamp(g_camera_transmittance, 0.0, 1.0);
        }
#endif
        if (finite) {
            sum += L;
            kept += 1.0;
            aov_sample_keep();
        }
    }
    film_flush_counters();
    if (sample_base + sample_count < u_frame.spp) {
        film_partial[2u * index] = vec4(sum, coverage);
        film_partial[2u * index + 1u] = vec4(kept, 0.0, 0.0, 0.0);
        aov_frame_store(index);
        return;
    }
    aov_frame_end(index, kept);
    // Domain: kept >= 1 where divided.
    vec3 estimate = kept > 0.0 ? sum / kept : vec3(0.0);
#ifdef FILM_ALPHA_EVERY_SAMPLE
    coverage = kept > 0.0 ? coverage / kept : 1.0;
#endif
    film_accumulate(pixel, estimate, coverage);
}

#endif
