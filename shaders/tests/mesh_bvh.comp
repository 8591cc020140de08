#version 460
// Test harness for bvh.glsl (tests/suite/kernels/mesh_bvh_gpu.rs). One invocation per query: the
// closest hit of its ray with the mesh whose root is `root` (the traversal the shapes
// use), and whether the any-hit traversal finds something on the same range.

#extension GL_GOOGLE_include_directive : require

#include "bvh.glsl"

layout(local_size_x = 64) in;

// A ray o + t d over (t_min, t_max). 32 bytes, mirrored in the test.
struct MeshQuery {
    vec4 o_t_min;
    vec4 d_t_max;
};

// The answers. 16 bytes.
struct MeshAnswer {
    float t;             // closest hit, FAR if none
    uint slot;           // its index in mesh_triangles[], NO_INDEX if none
    uint triangle;       // its index in its mesh (mesh_triangles[slot].triangle)
    uint occluded;       // 1 if the any-hit traversal found a hit
};

layout(push_constant) uniform PushBlock {
    uint query_count;
    uint root;        // the mesh's root node in bvh_nodes[]
    uint node_count;  // its nodes
    uint pad;
} u_push;

layout(std430, set = 0, binding = 0) readonly buffer QueryBlock {
    MeshQuery queries[];
};
layout(std430, set = 0, binding = 1) writeonly buffer AnswerBlock {
    MeshAnswer answers[];
};

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_push.query_count) {
        return;
    }
    MeshQuery q = queries[i];
    uint slot;
    float t = bvh_trace(u_push.root, u_push.node_count, q.o_t_min.xyz, q.d_t_max.xyz,
                        q.o_t_min.w, q.d_t_max.w, false, slot);
    uint any_slot;
    float t_any = bvh_trace(u_push.root, u_push.node_count, q.o_t_min.xyz, q.d_t_max.xyz,
                            q.o_t_min.w, q.d_t_max.w, true, any_slot);
    MeshAnswer a;
    a.t = t;
    a.slot = slot;
    a.triangle = slot == NO_INDEX ? NO_INDEX : mesh_triangles[slot].triangle;
    a.occluded = t_any < FAR ? 1u : 0u;
    answers[i] = a;
}
