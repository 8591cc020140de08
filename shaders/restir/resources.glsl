// Volumetric ReSTIR (Lin, Wyman and Yuksel 2021): what the four passes bind. The
// specialization constants, the settings and push-constant records (mirrored by
// RestirUniformsGpu and RestirPush in src/gpu/records.rs), the descriptors of set 0
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
// Spatial reuse weights by pairwise MIS instead of Talbot's.
layout(constant_id = SC_ID_MIS_PAIRWISE) const bool SC_MIS_PAIRWISE = false;

// Settings of the ReSTIR passes (std140). Mirrored by RestirUniformsGpu. 128 bytes.
struct RestirUniforms {
    uvec3 pc_primary_dims;    // dims of the piecewise-constant level for camera rays
    uint pc_primary_offset;   // its first value in pc_grid[]
    uvec3 pc_indirect_dims;   // dims of the level for scattered rays
    uint pc_indirect_offset;  // its first value in pc_grid[]
    uint pc_primary_factor;   // voxels per block edge of the primary level
    uint pc_indirect_factor;  // ... of the indirect level
    uint march_reuse_factor;  // ... of the reuse march texture (mip_reuse)
    uint march_nee_factor;    // ... of the NEE march texture (mip_indirect)
    uvec3 march_reuse_dims;   // dims of the reuse march texture
    uint candidates_per_dispatch; // candidates one initial dispatch draws (its aux: the first)
    uvec3 march_nee_dims;     // dims of the NEE march texture
    uint _pad1;
    uint candidates;          // M: random walks per pixel
    uint temporal_limit;      // Q: cap of the temporal M, in multiples of M
    uint spatial_neighbors;   // neighbours of a spatial round
    uint reservoir_stride;    // uints per reservoir
    float spatial_radius;     // pixels
    float march_reuse_step;   // reuse march step (m)
    float march_nee_step;     // NEE march step (m)
    float _pad2;
    uvec3 velocity_dims;      // dims of the velocity grid (1 x 1 x 1 without one)
    uint _pad3;
};

// Push constants of every ReSTIR dispatch. 16 bytes.
struct RestirPush {
    uint frame;  // frame index within the render (0 = first)
    uint src;    // reservoir slot read
    uint dst;    // reservoir slot written
    uint aux;    // initial: first candidate; temporal: previous slot; spatial: the round
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
    return set == SET_CURRENT ? 0u : u_frame.light_count;
}

// The reservoir of `pixel` in slot `slot`: slot s of pixel p starts at uint
// (s * pixels + p) * stride, stride = reservoir_stride (see reservoir.glsl).
uint res_at(uint slot, uvec2 pixel) {
    uint pixels = u_frame.width * u_frame.height;
    return (slot * pixels + pixel.y * u_frame.width + pixel.x) * u_restir.reservoir_stride;
}

#endif
