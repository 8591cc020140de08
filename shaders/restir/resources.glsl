// Volumetric ReSTIR (Lin, Wyman and Yuksel 2021): what the four passes bind. The
// specialization constants, the settings and push-constant records (mirrored by
// RestirUniformsGpu and RestirPush in src/passes/restir.rs), the descriptors of set 0
// (the film's and the grid medium's through film.glsl and grid_resources.glsl, the rest
// here), and where a pixel's reservoir lives. The passes include path.glsl or
// combine.glsl, which include this file.
#ifndef NIMBUS_RESTIR_RESOURCES_GLSL
#define NIMBUS_RESTIR_RESOURCES_GLSL

#extension GL_GOOGLE_include_directive : require

#include "features.glsl"
#include "bindings.glsl"
#include "constants.glsl"
#include "scene.glsl"
#include "grid_types.glsl"

layout(constant_id = SC_ID_HAS_ENV) const bool SC_HAS_ENV = true;
layout(constant_id = SC_ID_MAX_BOUNCES) const uint SC_MAX_BOUNCES = 1u;
layout(constant_id = SC_ID_PIXEL_JITTER) const bool SC_PIXEL_JITTER = true;
layout(constant_id = SC_ID_HAS_EMISSION) const bool SC_HAS_EMISSION = false;
layout(constant_id = SC_ID_HAS_ENV_MAP) const bool SC_HAS_ENV_MAP = false;
// Vertex reuse (x_2 kept in world space) instead of direction reuse.
layout(constant_id = SC_ID_REUSE_VERTEX) const bool SC_REUSE_VERTEX = false;
// Final shading estimates transmittance by ratio tracking instead of the closed form.
layout(constant_id = SC_ID_FINAL_RATIO_TRACKING) const bool SC_FINAL_RATIO_TRACKING = false;
// The medium has a velocity grid (temporal reprojection follows it).
layout(constant_id = SC_ID_HAS_VELOCITY) const bool SC_HAS_VELOCITY = false;

// Settings of the ReSTIR passes (std140). Mirrored by RestirUniformsGpu. 128 bytes.
struct RestirUniforms {
    uvec4 pc_primary;    // xyz dims of the piecewise-constant level for camera rays, w offset
    uvec4 pc_indirect;   // xyz dims of the level for scattered rays, w offset
    uvec4 factors;       // voxels per block edge: x primary level, y indirect, z reuse march, w NEE march
    uvec4 march_dims;    // xyz dims of the reuse march texture (mip_reuse), w unused
    uvec4 nee_dims;      // xyz dims of the NEE march texture (mip_indirect), w unused
    uvec4 settings;      // x candidates M, y temporal limit Q, z spatial neighbours, w reservoir stride (uints)
    vec4 spatial;        // x radius (pixels), y reuse march step (m), z NEE march step (m), w unused
    uvec4 velocity_dims; // xyz dims of the velocity grid, w unused
};

// Push constants of every ReSTIR dispatch. 16 bytes.
struct RestirPush {
    uint frame;  // frame index within the render (0 = first)
    uint src;    // reservoir slot read
    uint dst;    // reservoir slot written
    uint aux;    // temporal: slot of the previous frame; spatial: the round
};

#include "film.glsl"

layout(std140, set = 0, binding = BINDING_PREV_FRAME_UNIFORMS) uniform PrevFrameBlock {
    FrameUniforms u_prev_frame;
};
layout(push_constant) uniform PushBlock {
    RestirPush u_push;
};
layout(std140, set = 0, binding = BINDING_RESTIR_UNIFORMS) uniform RestirBlock {
    RestirUniforms u_restir;
};
// The previous frame's full-resolution density (the current one is grid_resources.glsl's).
layout(set = 0, binding = BINDING_GRID_DENSITY_PREV) uniform sampler3D u_density_prev;
// Mip textures for ray marching (unscaled density, R16F, linear filtering).
layout(set = 0, binding = BINDING_MARCH_REUSE) uniform sampler3D u_march_reuse;
layout(set = 0, binding = BINDING_MARCH_REUSE_PREV) uniform sampler3D u_march_reuse_prev;
layout(set = 0, binding = BINDING_MARCH_NEE) uniform sampler3D u_march_nee;
// Velocity in metres per frame (RGBA16F, linear filtering).
layout(set = 0, binding = BINDING_VELOCITY) uniform sampler3D u_velocity;
// Conservative piecewise-constant sigma_t* (scaled) of the two tracking levels.
layout(std430, set = 0, binding = BINDING_PC_GRID) readonly buffer PcGridBlock {
    float pc_grid[];
};
layout(std430, set = 0, binding = BINDING_RESERVOIRS) buffer ReservoirBlock {
    uint reservoirs[];
};

#include "grid_resources.glsl"
#include "reservoir.glsl"

// Which frame a camera ray, density or light set belongs to.
#define SET_CURRENT 0u
#define SET_PREVIOUS 1u

// The first light record of a set.
uint light_base(uint set) {
    return set == SET_CURRENT ? 0u : u_frame.counts.z;
}

// The reservoir of `pixel` in slot `slot`: slot s of pixel p starts at uint
// (s * pixels + p) * stride, stride = settings.w (see reservoir.glsl).
uint res_at(uint slot, uvec2 pixel) {
    uint pixels = u_frame.image.x * u_frame.image.y;
    return (slot * pixels + pixel.y * u_frame.image.x + pixel.x) * u_restir.settings.w;
}

#endif
