// GPU scene records (std430). Mirrored by #[repr(C)] structs in src/gpu_scene.rs; a
// test checks the sizes.
#ifndef NIMBUS_SCENE_GLSL
#define NIMBUS_SCENE_GLSL

// A homogeneous box medium. 96 bytes.
struct BoxMedium {
    vec4 world_to_local[3]; // rows of R^T; local = R^T (x - center)
    vec4 center_sigma_t;    // xyz centre, w sigma_t (1/m)
    vec4 half_size_g;       // xyz half extents, w HG g
    vec4 sigma_s;           // rgb sigma_s = albedo * sigma_t
};

#define SHAPE_QUAD 0u
#define SHAPE_BOX 1u
#define SHAPE_SPHERE 2u

// An opaque Lambertian shape. 96 bytes.
//   quad:   p[0] corner, p[1] edge_u, p[2] edge_v, p[3].xyz w = n / dot(n, n), n = cross(edge_u, edge_v)
//   box:    p[0..2] rows of R^T, p[3].xyz centre, p[4].xyz half extents
//   sphere: p[0].xyz centre, p[0].w radius
struct Shape {
    vec4 p[5];
    vec4 albedo_type; // rgb albedo, w = shape type as float (exact small integer)
};

#define LIGHT_DIRECTIONAL 0u

// An analytic light. 80 bytes.
struct Light {
    vec4 direction_type;   // xyz unit travel direction, w type
    vec4 irradiance;       // rgb W/m^2
    vec4 gobo_origin;      // xyz point on the gobo plane, w = number of gobo half-planes (0: none)
    vec4 gobo_u;           // xyz gobo u axis, w = first half-plane index
    vec4 gobo_v;           // xyz gobo v axis
};

// Parameters fixed for a frame (std140 uniform). 128 bytes.
struct FrameUniforms {
    vec4 cam_position;   // w tan(hfov / 2)
    vec4 cam_forward;    // w tan(vfov / 2)
    vec4 cam_right;
    vec4 cam_up;
    vec4 env_radiance;   // rgb radiance of escaping rays
    uvec4 image;         // width, height, spp, seed
    uvec4 counts;        // box media, shapes, lights, samples along a camera ray
    vec4 reserved;
};

// Push constants of a dispatch. 16 bytes.
struct PassPush {
    uint frame;        // frame index within the render
    uint sample_base;  // index of this dispatch's first sample per pixel
    uint pad0;
    uint pad1;
};

#endif
