// Descriptor binding numbers shared by every pass (set 0). Mirrored in
// src/bindings.rs; a test checks that the two agree.
#ifndef NIMBUS_BINDINGS_GLSL
#define NIMBUS_BINDINGS_GLSL

#define BINDING_FRAME_UNIFORMS 0
#define BINDING_ACCUM 1
#define BINDING_ACCUM_SQ 2
#define BINDING_STATS 3
#define BINDING_BOX_MEDIA 4
#define BINDING_SHAPES 5
#define BINDING_LIGHTS 6
#define BINDING_GOBO_PLANES 7
#define BINDING_BASELINE_UNIFORMS 8
#define BINDING_GRID_DENSITY 9
#define BINDING_SUPER_VOXELS 10
#define BINDING_GRID_EMISSION 11
#define BINDING_ENV_TEXELS 12
#define BINDING_ENV_CDF 13
#define BINDING_RESTIR_UNIFORMS 14
#define BINDING_RESERVOIRS 15
#define BINDING_PC_GRID 16
#define BINDING_MARCH_REUSE 17
#define BINDING_MARCH_REUSE_PREV 18
#define BINDING_MARCH_NEE 19
#define BINDING_GRID_DENSITY_PREV 20
#define BINDING_VELOCITY 21
#define BINDING_PREV_FRAME_UNIFORMS 22
#define BINDING_FILM_PARTIAL 23

// Indices into the stats buffer (uint counters).
#define STAT_NON_FINITE 0
#define STAT_STEP_CAP 1
#define STAT_LOOPS_CUT 2
#define STAT_COUNT 4

#endif
