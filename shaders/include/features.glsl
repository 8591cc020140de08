// The numbers the shaders and the Rust side must agree on: specialization-constant IDs
// (`layout(constant_id = SC_ID_X) const ... SC_X`; one ID means one feature in every
// pass that declares it), the box estimator IDs (ESTIMATOR_*) and the limits the shaders
// hard-code. They are declared once, with the Rust constants and their meaning, in
// src/shader_data/contract/features.rs; build.rs generates gpu_features.glsl from it.
#ifndef NIMBUS_FEATURES_GLSL
#define NIMBUS_FEATURES_GLSL

#include "gpu_features.glsl"

#endif
