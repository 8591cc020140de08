// The grid medium's parameters, shared by grid.glsl and the shaders that include it (the
// includer declares `u_grid` of type GridParams before including grid.glsl). Mirrored member
// by member by the #[repr(C)] structs in src/gpu/records.rs; tests/suite/layout.rs checks them.
#ifndef NIMBUS_GRID_TYPES_GLSL
#define NIMBUS_GRID_TYPES_GLSL

// A sparse grid on the GPU: where its index space sits in the world, and where its 8^3
// bricks are (an indirection section of grid_bricks[] and an atlas of 9^3-texel slots,
// each a brick plus one apron layer on its high side). See grid.glsl for the index
// spaces. 160 bytes; std140 and std430 lay it out identically.
struct GridSpace {
    vec4 world_to_index_x;   // general affine path: p = (dot(row, vec4(x, 1)) per row)
    vec4 world_to_index_y;
    vec4 world_to_index_z;
    vec3 box_min;            // axis-aligned path: world box the p-space box maps to
    uint axis_aligned;       // 1: p = (x - box_min) * scale + index_min, scale = index / box size
    vec3 box_max;
    uint bricks_offset;      // first indirection entry of the grid in grid_bricks[]
    vec3 index_min;          // p-space box the grid fills (0 outside)
    uint slots_x;            // atlas slots per axis (x, y; z follows from the slot count)
    vec3 index_max;
    uint slots_y;
    ivec3 lattice_min;       // lattice clamp range (inclusive)
    uint channels;           // values per lattice point (1, or 3 for rgb emission)
    ivec3 lattice_max;
    uint _pad0;
    uvec3 brick_dims;        // bricks per axis of the indirection section
    uint _pad1;
};

// 192 bytes.
struct GridParams {
    vec3 bounds_min;          // world bounding box of the medium's extent
    float density_scale;      // sigma_t = density_scale * density
    vec3 bounds_max;
    float sigma_t_max;        // global max of sigma_t (majorant for ratio / delta tracking)
    GridSpace space;          // the density (unscaled) and its super-voxel records
};

// The grid medium and what lights it, read by the baseline path tracer and the ReSTIR
// passes (std430 storage buffer at BINDING_BASELINE_UNIFORMS, named `u_base` by
// includers).
// Mirrored by BaselineUniformsGpu. 736 bytes.
struct BaselineUniforms {
    GridParams grid;
    vec3 albedo;            // rgb single-scattering albedo (times albedo_grid with one)
    float g;                // HG asymmetry
    float env_select;       // probability that next-event estimation picks the environment
    uint emitter_count;     // primitives in emitters[] (0 without area lights)
    float temperature_offset; // kelvin = temperature_offset + temperature_scale * grid
    float temperature_scale;
    vec3 emission_scale;    // rgb: Le = emission_scale * trilinear emission grid
    float blackbody_scale;  // plus blackbody_scale * RGB(kelvin) (SC_HAS_BLACKBODY)
    GridSpace emission;     // the emission grid (its own index space and bricks)
    GridSpace temperature;  // the temperature grid (SC_HAS_BLACKBODY)
    GridSpace albedo_grid;  // the albedo grid (SC_HAS_ALBEDO_GRID)
    uvec2 env_size;         // environment map width and height (1 x 1 without a map)
    uvec2 _pad5;
};

#endif
