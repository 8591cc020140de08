// Homogeneous box media (scene.glsl's BoxMedium): their buffer `media`, the span of a ray
// inside one, and the closed-form optical depth of all of them along a ray. The includer
// declares `u_frame` (box_media_count = number of box media) and the bool constant SC_HAS_MEDIA
// (without it there are no box media).
#ifndef NIMBUS_BOX_MEDIA_GLSL
#define NIMBUS_BOX_MEDIA_GLSL

#include "bindings.glsl"
#include "constants.glsl"
#include "geometry.glsl"
#include "scene.glsl"

layout(std430, set = 0, binding = BINDING_BOX_MEDIA) readonly buffer MediaBlock {
    BoxMedium media[];
};

// Span of o + t d inside box medium m: (t_in, t_out), t_in > t_out for a miss.
vec2 box_medium_span(uint m, vec3 o, vec3 d) {
    BoxMedium bm = media[m];
    vec3 o_local;
    vec3 d_local;
    to_box_frame(bm.world_to_local, bm.center, o, d, o_local, d_local);
    return intersect_slabs(o_local, d_local, bm.half_size);
}

// Optical depth of the box media other than `skip` along o + t d, t in [t_min, t_max].
float box_optical_depth_except(vec3 o, vec3 d, float t_min, float t_max, uint skip) {
    float tau = 0.0;
    uint count = SC_HAS_MEDIA ? u_frame.box_media_count : 0u;
    for (uint m = 0u; m < count; ++m) {
        if (m == skip) {
            continue;
        }
        tau += media[m].sigma_t * overlap_length(box_medium_span(m, o, d), t_min, t_max);
    }
    return tau;
}

// Optical depth of all box media along o + t d, t in [t_min, t_max].
float box_optical_depth(vec3 o, vec3 d, float t_min, float t_max) {
    return box_optical_depth_except(o, d, t_min, t_max, NO_INDEX);
}

#endif
