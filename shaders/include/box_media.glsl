// Homogeneous box and convex media (scene.glsl's BoxMedium): their buffers `media` and
// `medium_planes`, the span of a ray inside one, the distance to its boundary towards a
// light, and the closed-form optical depth of all of them along a ray. The includer
// declares `u_frame` (box_media_count = number of media) and the bool constant
// SC_HAS_MEDIA (without it there are no media); SC_HAS_CONVEX (declared here, false by
// default) compiles the convex media's planes in.
//
// A convex medium is a BoxMedium with plane_count > 0: the planes (n, d), n . x <= d in
// its local frame, lie in medium_planes[plane_first ..], and half_size bounds it, so a
// ray first meets its bounding box (the slab test) and is then clipped by each plane.
#ifndef NIMBUS_BOX_MEDIA_GLSL
#define NIMBUS_BOX_MEDIA_GLSL

#include "bindings.glsl"
#include "box_analytic.glsl"
#include "constants.glsl"
#include "features.glsl"
#include "geometry.glsl"
#include "scene.glsl"

layout(constant_id = SC_ID_HAS_CONVEX) const bool SC_HAS_CONVEX = false;

layout(std430, set = 0, binding = BINDING_BOX_MEDIA) readonly buffer MediaBlock {
    BoxMedium media[];
};
layout(std430, set = 0, binding = BINDING_MEDIUM_PLANES) readonly buffer MediumPlanesBlock {
    vec4 medium_planes[]; // (n, d) of the convex media: n . x <= d inside (local frame)
};

// Whether medium bm is a convex polyhedron (else a box).
bool medium_is_convex(BoxMedium bm) {
    return SC_HAS_CONVEX && bm.plane_count > 0u;
}

// Whether the local point x_local (inside bm's bounding box) lies in bm: always for a
// box, on the inner side of every plane (to within rounding: 1e-5 of the plane's
// offset plus 1e-6 m) for a convex medium.
bool medium_contains_local(BoxMedium bm, vec3 x_local) {
    if (!medium_is_convex(bm)) {
        return true;
    }
    uint count = min(bm.plane_count, MAX_CONVEX_PLANES);
    for (uint i = 0u; i < count; ++i) {
        vec4 plane = medium_planes[bm.plane_first + i];
        if (dot(plane.xyz, x_local) > plane.w + 1e-5 * abs(plane.w) + 1e-6) {
            return false;
        }
    }
    return true;
}

// Clip the span (t_in, t_out) of o + t d (local frame) by convex medium bm's planes:
// each plane keeps the side n . x <= d. A ray parallel to a plane (|n . d| < 1e-30)
// keeps the span when it starts inside it and misses otherwise.
vec2 convex_clip(BoxMedium bm, vec3 o_local, vec3 d_local, vec2 span) {
    uint count = min(bm.plane_count, MAX_CONVEX_PLANES);
    for (uint i = 0u; i < count; ++i) {
        vec4 plane = medium_planes[bm.plane_first + i];
        float denom = dot(plane.xyz, d_local);
        float num = plane.w - dot(plane.xyz, o_local);
        if (abs(denom) < 1e-30) {
            if (num < 0.0) {
                return vec2(FAR, -FAR);
            }
            continue;
        }
        // Domain: |denom| >= 1e-30.
        float t = num / denom;
        if (denom > 0.0) {
            span.y = min(span.y, t);
        } else {
            span.x = max(span.x, t);
        }
    }
    return span;
}

// Span of o + t d inside medium m: (t_in, t_out), t_in > t_out for a miss.
vec2 box_medium_span(uint m, vec3 o, vec3 d) {
    BoxMedium bm = media[m];
    vec3 o_local;
    vec3 d_local;
    to_box_frame(bm.world_to_local, bm.center, o, d, o_local, d_local);
    vec2 span = intersect_slabs(o_local, d_local, bm.half_size);
    if (medium_is_convex(bm) && span.y > span.x) {
        span = convex_clip(bm, o_local, d_local, span);
    }
    return span;
}

// Distance from local point x inside medium bm to its boundary towards the light (along
// -omega, unit, local frame): 0 when nothing stops the ray.
float medium_light_distance(BoxMedium bm, vec3 x_local, vec3 omega_local) {
    if (!medium_is_convex(bm)) {
        return box_light_distance(x_local, omega_local, bm.half_size);
    }
    float d_m = FAR;
    uint count = min(bm.plane_count, MAX_CONVEX_PLANES);
    for (uint i = 0u; i < count; ++i) {
        d_m = min(d_m, plane_light_distance(medium_planes[bm.plane_first + i], x_local, omega_local));
    }
    return d_m < FAR ? max(d_m, 0.0) : 0.0;
}

// Build the piece table of T_box of medium bm over [t_a, t_b] of the local ray o + t d
// (camera transmittance from t_enter) for light travelling along omega (local frame).
BoxPieces medium_pieces(BoxMedium bm, vec3 o_local, vec3 d_local, vec3 omega_local, float t_enter, float t_a, float t_b) {
    if (!medium_is_convex(bm)) {
        return box_pieces(o_local, d_local, omega_local, bm.half_size, bm.sigma_t, t_enter, t_a, t_b);
    }
    // Re-base the lines at t_a (see box_pieces).
    vec3 x_a = fma(vec3(t_a), d_local, o_local);
    exit_lines_clear();
    uint count = min(bm.plane_count, MAX_CONVEX_PLANES);
    for (uint i = 0u; i < count; ++i) {
        exit_lines_add_plane(medium_planes[bm.plane_first + i], x_a, d_local, omega_local);
    }
    return pieces_from_lines(bm.sigma_t, t_enter, t_a, t_b);
}

// Optical depth of the media other than `skip` along o + t d, t in [t_min, t_max].
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

// Optical depth of all media along o + t d, t in [t_min, t_max].
float box_optical_depth(vec3 o, vec3 d, float t_min, float t_max) {
    return box_optical_depth_except(o, d, t_min, t_max, NO_INDEX);
}

#endif
