// The grid medium's parameters, shared by grid.glsl and the shaders that include it (the
// includer declares `u_grid` of this type before including grid.glsl). Mirrored member by
// member by the #[repr(C)] structs in src/gpu/records.rs; tests/layout.rs checks them.
#ifndef NIMBUS_GRID_TYPES_GLSL
#define NIMBUS_GRID_TYPES_GLSL

// 64 bytes; std140 and std430 lay it out identically.
struct GridParams {
    vec3 bounds_min;          // world
    float density_scale;      // sigma_t = density_scale * density
    vec3 bounds_max;          // world
    float sigma_t_max;        // global max of sigma_t (majorant for ratio / delta tracking)
    uvec3 dims;               // voxel dims
    uint super_voxel_factor;  // voxels per super-voxel edge (8)
    uvec3 super_dims;         // super-voxel grid dims (ceil(dims / factor))
    uint _pad0;
};

// The grid medium and what lights it, read by the baseline path tracer and the ReSTIR
// passes (std140 uniform at BINDING_BASELINE_UNIFORMS, named `u_base` by includers).
// Mirrored by BaselineUniformsGpu. 144 bytes.
struct BaselineUniforms {
    GridParams grid;
    vec3 albedo;            // rgb single-scattering albedo
    float g;                // HG asymmetry
    float env_select;       // probability that next-event estimation picks the environment
    float _pad0;
    float _pad1;
    float _pad2;
    vec3 emission_scale;    // rgb: Le = emission_scale * trilinear emission grid
    float _pad3;
    uvec3 emission_dims;    // the emission grid's own resolution (1 x 1 x 1 without one)
    uint _pad4;
    uvec2 env_size;         // environment map width and height (1 x 1 without a map)
    uvec2 _pad5;
};

#endif
