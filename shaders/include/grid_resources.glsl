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

layout(std140, set = 0, binding = BINDING_BASELINE_UNIFORMS) uniform BaselineBlock {
    BaselineUniforms u_base;
};
// Analytic lights (scene.glsl's Light: direction or position or centre by type, E or I or
// L, sphere radius, selection CDF). ReSTIR binds the current frame's set, then the
// previous frame's (u_frame.light_count records each).
layout(std430, set = 0, binding = BINDING_LIGHTS) readonly buffer LightsBlock {
    Light lights[];
};
// Full-resolution density (unscaled, R32, texelFetch).
layout(set = 0, binding = BINDING_GRID_DENSITY) uniform sampler3D u_density;
layout(set = 0, binding = BINDING_GRID_EMISSION) uniform sampler3D u_emission;
layout(std430, set = 0, binding = BINDING_SUPER_VOXELS) readonly buffer SuperVoxelBlock {
    vec4 super_voxels[];
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

#endif
