// GPU scene records (std430 storage buffers), the frame's parameters (std430), the push
// constants of a dispatch and the records' type tags (SHAPE_*, LIGHT_*, EMITTER_*): the
// structs BoxMedium, Shape, Emitter, BvhNode, MeshTriangle, Light, FrameUniforms,
// MomentFrame, MomentPush and PassPush. They are declared once, with the Rust structs, in
// src/shader_data/contract/records.rs; build.rs generates gpu_records.glsl from it (every record,
// so grid_types.glsl and restir/resources.glsl include the same header).
#ifndef NIMBUS_SCENE_GLSL
#define NIMBUS_SCENE_GLSL

#include "gpu_records.glsl"

#endif
