// Per-invocation counters of events a pass reports through the stats buffer: code deep in
// an estimator bumps them, and film_flush_counters (film.glsl) adds them to `stats` once
// per invocation.
//
// g_step_cap_hits is always counted: a walk cut at GRID_MAX_STEPS makes the image wrong,
// and the renderer refuses to stay silent about it.
//
// The work counters (COUNT / COUNT_STEP) measure cost deterministically: the same scene,
// seed and device give the same counts, whatever else the machine is doing, so a test can
// pin them where a timing could not. They exist only where the renderer asks for them
// (`nimbus profile --counters`, `nimbus bench`): with SC_COUNTERS false (the default)
// every COUNT is dead code and compiles out.
#ifndef NIMBUS_COUNTERS_GLSL
#define NIMBUS_COUNTERS_GLSL

#include "features.glsl"

// Walks that reached GRID_MAX_STEPS (their estimate is cut short: biased).
uint g_step_cap_hits = 0u;

layout(constant_id = SC_ID_COUNTERS) const bool SC_COUNTERS = false;
layout(constant_id = SC_ID_COUNTER_SLOT) const uint SC_COUNTER_SLOT = 0u;

// The counters (src/shader_data/counters.rs names them for reports; keep both in step).
// Camera samples: paths started at the camera (ReSTIR: pixels the pass worked on).
#define CTR_SAMPLES 0
// Tracking steps outside shadow rays: dual cells, super-voxels, piecewise-constant blocks
// or ray-march samples a walk visits (an empty brick crossed at once is one step).
#define CTR_STEPS 1
// Density fetches: trilinear lookups of the density (8 texels each) and filtered
// ray-march samples.
#define CTR_DENSITY 2
// Majorant fetches: super-voxel bounds and piecewise-constant (sigma*) voxels read.
#define CTR_MAJORANT 3
// Tentative collisions of delta, decomposition and ratio tracking (null or real).
#define CTR_COLLISIONS 4
// Shadow rays (transmittance estimates towards a light or along a reused segment).
#define CTR_SHADOW_RAYS 5
// Tracking steps inside shadow rays.
#define CTR_SHADOW_STEPS 6
// Mesh BVH nodes visited.
#define CTR_BVH_NODES 7

uint g_counters[COUNTER_COUNT] = uint[COUNTER_COUNT](0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u);
// True while a shadow ray is traced: its steps count as CTR_SHADOW_STEPS.
bool g_counting_shadow = false;

// Adds n to counter c (compiled out without SC_COUNTERS).
#define COUNT(c, n)                       \
    if (SC_COUNTERS) {                    \
        g_counters[c] += uint(n);         \
    }

// One tracking step, on a shadow ray or not.
#define COUNT_STEP()                                                            \
    if (SC_COUNTERS) {                                                          \
        g_counters[g_counting_shadow ? CTR_SHADOW_STEPS : CTR_STEPS] += 1u;     \
    }

// Marks the start and end of a shadow ray's transmittance estimate.
#define COUNT_SHADOW_BEGIN()                  \
    if (SC_COUNTERS) {                        \
        g_counters[CTR_SHADOW_RAYS] += 1u;    \
        g_counting_shadow = true;             \
    }
#define COUNT_SHADOW_END()            \
    if (SC_COUNTERS) {                \
        g_counting_shadow = false;    \
    }

#endif
