// The grid medium's parameters, shared by grid.glsl and the shaders that include it (the
// includer declares `u_grid` of type GridParams before including grid.glsl): the structs
// GridSpace, GridParams and BaselineUniforms. They are declared once, with the Rust
// structs, in src/shader_data/contract/records.rs; build.rs generates gpu_records.glsl from it.
#ifndef NIMBUS_GRID_TYPES_GLSL
#define NIMBUS_GRID_TYPES_GLSL

#include "gpu_records.glsl"

#endif
