// Descriptor binding numbers shared by every pass (set 0), BINDING_*, and the indices
// into the stats buffer, STAT_*. They are declared once, with the Rust constants, in
// src/shader_data/contract/bindings.rs; build.rs generates gpu_bindings.glsl from it.
#ifndef NIMBUS_BINDINGS_GLSL
#define NIMBUS_BINDINGS_GLSL

#include "gpu_bindings.glsl"

#endif
