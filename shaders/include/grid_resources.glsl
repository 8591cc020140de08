// The grid medium and the lights that reach it, as the baseline and the ReSTIR passes bind
// them: the medium's settings `u_base` (BaselineUniforms; `u_grid` names its grid), the
// density, emission and super-voxel data, the environment map's tables, and the analytic
// lights; then everything that reads them (grid.glsl, grid_blocks.glsl,
// grid_emission.glsl, lights.glsl). The includer declares `u_frame` (film.glsl) and the
// bool constants SC_HAS_ENV and SC_HAS_ENV_MAP first.
#ifndef NIMBUS_GRID_RESOURCES_GLSL
#define NIMBUS_GRID_RESOURCES_GLSL

#include "bindings.glsl"
#include "grid_types.glsl"
#include "scene.glsl"

layout(std430, set = 0, binding = BINDING_BASELINE_UNIFORMS) readonly buffer BaselineBlock {
    BaselineUniforms u_base_block;
};
// A private copy of the parameters, made by grid_resources_load() at the start of main:
// lavapipe reloads a storage-buffer member at every use inside a loop (it cannot prove the
// film's writes do not alias it), which cost the baseline's tracking loops 25 % (perf-cloud,
// 16 spp); a private copy lives in registers.
BaselineUniforms u_base;

void grid_resources_load() {
    u_base = u_base_block;
}
// Analytic lights (scene.glsl's Light: direction or position or centre by type, E or I or
// L, sphere radius, selection CDF). ReSTIR binds the current frame's set, then the
// previous frame's (u_frame.light_count records each).
layout(std430, set = 0, binding = BINDING_LIGHTS) readonly buffer LightsBlock {
    Light lights[];
};
// The density's atlas: 9^3-texel slots of full-resolution density (unscaled, R32F,
// texelFetch), and the emission grid's (R32F or RGBA32F).
layout(set = 0, binding = BINDING_GRID_DENSITY) uniform sampler3D u_density;
layout(set = 0, binding = BINDING_GRID_EMISSION) uniform sampler3D u_emission;
// The temperature grid's atlas (R32F) and the blackbody table (grid_emission.glsl), read
// only where SC_HAS_BLACKBODY.
layout(set = 0, binding = BINDING_GRID_TEMPERATURE) uniform sampler3D u_temperature;
// The albedo grid's atlas (R32F or RGBA32F), read only where SC_HAS_ALBEDO_GRID.
layout(set = 0, binding = BINDING_GRID_ALBEDO) uniform sampler3D u_albedo;
layout(std430, set = 0, binding = BINDING_BLACKBODY) readonly buffer BlackbodyBlock {
    vec4 blackbody[];
};
// Per density slot: (min, max, avg, 0) of sigma_t over its super-voxel.
layout(std430, set = 0, binding = BINDING_SUPER_VOXELS) readonly buffer SuperVoxelBlock {
    vec4 super_voxels[];
};
// The indirection sections of every sparse grid the pass reads (GridSpace.bricks_offset
// and GridLevel.bricks_offset say where each starts): a brick's slot or NO_BRICK.
layout(std430, set = 0, binding = BINDING_GRID_BRICKS) readonly buffer GridBrickBlock {
    uint grid_bricks[];
};
layout(std430, set = 0, binding = BINDING_ENV_TEXELS) readonly buffer EnvTexelBlock {
    vec4 env_texels[];
};
layout(std430, set = 0, binding = BINDING_ENV_CDF) readonly buffer EnvCdfBlock {
    float env_cdf[];
};

#define u_grid u_base.grid
#define ENV_SIZE u_base.env_size
#include "grid.glsl"
#include "grid_blocks.glsl"
#include "grid_emission.glsl"
#include "lights.glsl"

// The light group (aov.glsl) of light record `index` of lights[], or of the environment
// for LIGHT_ENV.
uint light_group(uint index) {
    if (SC_AOV_GROUPS == 0u) {
        return 0u;
    }
    return index == LIGHT_ENV ? AOV_GROUP_ENV : lights[index].group;
}

#endif
