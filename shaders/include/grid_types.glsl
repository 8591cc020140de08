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

#endif
