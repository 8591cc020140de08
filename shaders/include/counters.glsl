// Per-invocation counters of events a pass reports through the stats buffer: code deep in
// an estimator bumps them, and film_flush_counters (film.glsl) adds them to `stats` once
// per invocation. A counter that is not 0 after a render is reported by the renderer.
#ifndef NIMBUS_COUNTERS_GLSL
#define NIMBUS_COUNTERS_GLSL

// Walks that reached GRID_MAX_STEPS (their estimate is cut short: biased).
uint g_step_cap_hits = 0u;

#endif
