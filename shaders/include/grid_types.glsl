// The grid medium's parameters, shared by grid.glsl and the shaders that include it (the
// includer declares `u_grid` of this type before including grid.glsl). Mirrored in Rust
// as a #[repr(C)] 64-byte struct; std140 and std430 lay it out identically.
#ifndef NIMBUS_GRID_TYPES_GLSL
#define NIMBUS_GRID_TYPES_GLSL

struct GridParams {
    vec4 bounds_min;   // xyz world, w = density_scale
    vec4 bounds_max;   // xyz world, w = global max of sigma_t (majorant for ratio/delta tracking)
    uvec4 dims;        // voxel dims xyz, w = super-voxel factor (8)
    uvec4 super_dims;  // super-voxel grid dims xyz (ceil(dims / factor)), w unused
};

// The grid medium and what lights it, read by the baseline path tracer and the ReSTIR
// passes (std140 uniform at BINDING_BASELINE_UNIFORMS, named `u_base` by includers).
// Mirrored by BaselineUniformsGpu in src/gpu_scene.rs. 144 bytes.
struct BaselineUniforms {
    GridParams grid;
    vec4 albedo_g;         // rgb albedo, w HG g
    vec4 env_select;       // x: probability that NEE picks the environment
    vec4 emission_scale;   // rgb
    uvec4 emission_dims;   // xyz: the emission grid's own resolution
    uvec4 env_size;        // xy: environment map width and height
};

#endif
