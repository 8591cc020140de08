// Volumetric ReSTIR (Lin, Wyman and Yuksel 2021): what the four passes bind. The
// specialization constants, the settings and push-constant records (RestirUniforms and
// RestirPush, declared in src/shader_data/contract/records.rs), the descriptors of set 0
// (the film's and the grid medium's through film.glsl and grid_resources.glsl, the rest
// here), and where a pixel's reservoir lives. The passes include path_value.glsl or
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
// A temperature grid glows as a blackbody (grid_emission.glsl).
layout(constant_id = SC_ID_HAS_BLACKBODY) const bool SC_HAS_BLACKBODY = false;
// The grid's albedo is a grid (grid_albedo in grid_emission.glsl).
layout(constant_id = SC_ID_HAS_ALBEDO_GRID) const bool SC_HAS_ALBEDO_GRID = false;
layout(constant_id = SC_ID_HAS_ENV_MAP) const bool SC_HAS_ENV_MAP = false;
// Vertex reuse (x_2 kept in world space) instead of direction reuse.
layout(constant_id = SC_ID_REUSE_VERTEX) const bool SC_REUSE_VERTEX = false;
// Final shading estimates transmittance by ratio tracking instead of the closed form.
layout(constant_id = SC_ID_FINAL_RATIO_TRACKING) const bool SC_FINAL_RATIO_TRACKING = false;
// The medium has a velocity grid (temporal reprojection follows it).
layout(constant_id = SC_ID_HAS_VELOCITY) const bool SC_HAS_VELOCITY = false;
// Spatial reuse weights by pairwise MIS instead of Talbot's.
layout(constant_id = SC_ID_MIS_PAIRWISE) const bool SC_MIS_PAIRWISE = false;
// Spatial reuse shifts x_1 by its optical depth tau_1 (restir/combine.glsl).
layout(constant_id = SC_ID_SPATIAL_TAU_SHIFT) const bool SC_SPATIAL_TAU_SHIFT = false;
// ... by its exact optical depth through the grid's own density (`"optical_depth_exact"`).
layout(constant_id = SC_ID_SPATIAL_TAU_EXACT) const bool SC_SPATIAL_TAU_EXACT = false;
// Spatial reuse reads its pixels' camera features (the neighbour test, depth anchors).
layout(constant_id = SC_ID_SPATIAL_FEATURES) const bool SC_SPATIAL_FEATURES = false;
// A medium vertex's emission is part of its split-NEE candidate (restir/path_lights.glsl).
layout(constant_id = SC_ID_FOLD_EMISSION) const bool SC_FOLD_EMISSION = false;
// Reservoirs keep an environment sample's direction in the map's frame (env_reuse = "map").
layout(constant_id = SC_ID_ENV_REUSE_MAP) const bool SC_ENV_REUSE_MAP = false;
layout(constant_id = SC_ID_NEE_SPLIT) const bool SC_NEE_SPLIT = false;
layout(constant_id = SC_ID_DIRECT_EACH_WALK) const bool SC_DIRECT_EACH_WALK = false;
// Candidates by decomposition tracking on the exact density (restir/initial.comp).
layout(constant_id = SC_ID_CANDIDATE_DELTA) const bool SC_CANDIDATE_DELTA = false;
// How the target function makes a scalar of a path's RGB contribution (SC_TARGET_*).
layout(constant_id = SC_ID_TARGET_SCALAR) const uint SC_TARGET_SCALAR = SC_TARGET_LUMINANCE;
// The camera segment's emission is estimated in final shading by samples stratified in
// sigma_t T, outside the reservoirs (`camera_emission = "stratified"`).
layout(constant_id = SC_ID_CAMERA_EMISSION) const bool SC_CAMERA_EMISSION = false;
// Temporal reuse finds the previous pixel by the pixel's motion point and aligns the two
// pixels' sub-pixel positions there (`temporal_reprojection = "aligned"`), else by the
// selected path's x_1 (the paper's).
layout(constant_id = SC_ID_TEMPORAL_ALIGNED) const bool SC_TEMPORAL_ALIGNED = false;
// Temporal reuse moves a medium x_1 by its optical depth through the grid's own density
// (`temporal_shift = "optical_depth"`; restir/combine.glsl) where the density did not change.
layout(constant_id = SC_ID_TEMPORAL_TAU_SHIFT) const bool SC_TEMPORAL_TAU_SHIFT = false;
// Opaque shapes beside the grid: paths may have surface vertices (restir/path_surfaces.glsl).
layout(constant_id = SC_ID_HAS_SHAPES) const bool SC_HAS_SHAPES = false;
// Homogeneous box media beside the grid (restir/vertex_media.glsl).
layout(constant_id = SC_ID_HAS_MEDIA) const bool SC_HAS_MEDIA = false;

// GridLevel, RestirUniforms and RestirPush come with the records (scene.glsl).

#include "film.glsl"

layout(std430, set = 0, binding = BINDING_PREV_FRAME_UNIFORMS) readonly buffer PrevFrameBlock {
    FrameUniforms u_prev_frame_block;
};
FrameUniforms u_prev_frame;
layout(push_constant) uniform PushBlock {
    RestirPush u_push;
};
layout(std430, set = 0, binding = BINDING_RESTIR_UNIFORMS) readonly buffer RestirBlock {
    RestirUniforms u_restir_block;
};
// Private copies of the parameter blocks (grid_resources_load says why), made by
// restir_load() at the start of every stage's main.
RestirUniforms u_restir;
// The previous frame's full-resolution density atlas (the current one is
// grid_resources.glsl's; the same image when the density does not change).
layout(set = 0, binding = BINDING_GRID_DENSITY_PREV) uniform sampler3D u_density_prev;
// Atlases of the mips for ray marching (unscaled density, R16F or R32F, linear filtering
// inside a slot: the apron holds the neighbours).
layout(set = 0, binding = BINDING_MARCH_REUSE) uniform sampler3D u_march_reuse;
layout(set = 0, binding = BINDING_MARCH_REUSE_PREV) uniform sampler3D u_march_reuse_prev;
layout(set = 0, binding = BINDING_MARCH_NEE) uniform sampler3D u_march_nee;
// Velocity in metres per frame over the medium's world box (dense RGBA16F, linear filtering).
layout(set = 0, binding = BINDING_VELOCITY) uniform sampler3D u_velocity;
// Atlas of the conservative piecewise-constant sigma_t* (scaled, R32F, texelFetch) of both
// tracking levels.
layout(set = 0, binding = BINDING_PC_GRID) uniform sampler3D u_pc;
// The same texels slot after slot, each slot's 9^3 x fastest (src/shader_data/sparse.rs,
// upload_slot_major), read instead of u_pc where SC_PC_BUFFER: on lavapipe a texelFetch is
// a call into the sampler's code, a buffer load one loop over the lanes (regular tracking
// fetches a sigma_t* at every block it crosses). One float where the atlas is read.
layout(constant_id = SC_ID_PC_BUFFER) const bool SC_PC_BUFFER = false;
layout(std430, set = 0, binding = BINDING_PC_TEXELS) readonly buffer PcTexelBlock {
    float pc_texels[];
};
// The ray-march mips (this frame's reuse mip, the previous frame's, the NEE mip) as one
// buffer of quads, each level's slots from its quad_base, each slot's 9^3 texels x fastest,
// a texel and its +x, +y and +x+y neighbours (src/shader_data/sparse.rs,
// upload_march_quads), read instead of the linearly filtered atlases where
// SC_MARCH_BUFFER: on lavapipe a filtered textureLod is a call into the sampler's code,
// two 16-byte loads two loops over the lanes. One quad where the atlases are read.
layout(constant_id = SC_ID_MARCH_BUFFER) const bool SC_MARCH_BUFFER = false;
layout(std430, set = 0, binding = BINDING_MARCH_QUADS) readonly buffer MarchQuadBlock {
    vec4 march_quads[];
};
layout(std430, set = 0, binding = BINDING_RESERVOIRS) buffer ReservoirBlock {
    uint reservoirs[];
};
// The shade cache's entry of `pixel` in reservoirs[] (u_restir.shade_cache_base != 0):
// the RGB F (float bits) that final shading last evaluated for the pixel's path, and a
// flag, 1 while that path is still the pixel's.
uint shade_cache_at(uvec2 pixel) {
    return u_restir.shade_cache_base + 4u * (pixel.y * u_frame.width + pixel.x);
}

// This frame's density is read from a storage buffer where SC_DENSITY_BUFFER (grid.glsl;
// `[integrator.restir] density_fetch`); the previous frame's from its atlas.
#define NIMBUS_DENSITY_BUFFER 1
#include "grid_resources.glsl"
#include "shapes.glsl"
#include "box_media.glsl"
#include "reservoir.glsl"

// Copies every parameter block into its private copy; the first statement of every main.
void restir_load() {
    film_load();
    grid_resources_load();
    u_prev_frame = u_prev_frame_block;
    u_restir = u_restir_block;
}

// Which frame a camera ray, density or light set belongs to.
#define SET_CURRENT 0u
#define SET_PREVIOUS 1u

// The first light record of a set.
uint light_base(uint set) {
    return set == SET_CURRENT ? 0u : u_frame.light_count;
}

// The environment map's turn (cos, sin) in a set's frame: a path reused from the
// previous frame is evaluated in this frame with this frame's turn.
vec2 env_rotation_of(uint set) {
    return set == SET_CURRENT ? u_frame.env_rotation : u_prev_frame.env_rotation;
}

// Velocity (m per frame) at world x, linearly filtered (temporal reprojection and the
// motion AOV).
vec3 velocity_at(vec3 x) {
    vec4 h = vec4(x, 1.0);
    vec3 uvw = vec3(dot(u_restir.velocity_uvw_x, h), dot(u_restir.velocity_uvw_y, h),
                    dot(u_restir.velocity_uvw_z, h));
    return textureLod(u_velocity, uvw, 0.0).xyz;
}

// The reservoir of `pixel` in slot `slot`: slot s of pixel p starts at uint
// (s * pixels + p) * stride, stride = reservoir_stride (see reservoir.glsl).
uint res_at(uint slot, uvec2 pixel) {
    uint pixels = u_frame.width * u_frame.height;
    return (slot * pixels + pixel.y * u_frame.width + pixel.x) * u_restir.reservoir_stride;
}

#endif
