// Opaque shapes: their buffer, nearest hit with normal, and occlusion queries. Needs
// `u_frame` (shape_count = number of shapes) and the bool constant SC_HAS_SHAPES to be
// declared by the including pass.
#ifndef NIMBUS_SHAPES_GLSL
#define NIMBUS_SHAPES_GLSL

#include "bindings.glsl"
#include "geometry.glsl"
#include "scene.glsl"

layout(std430, set = 0, binding = BINDING_SHAPES) readonly buffer ShapesBlock {
    Shape shapes[];
};

// Hit distance of one shape along o + t d within (t_min, t_max); FAR if none.
float intersect_shape(Shape s, vec3 o, vec3 d, float t_min, float t_max) {
    uint type = s.type;
    if (type == SHAPE_QUAD) {
        return intersect_quad(s.p[0].xyz, s.p[1].xyz, s.p[2].xyz, s.p[3].xyz, o, d, t_min, t_max);
    }
    if (type == SHAPE_SPHERE) {
        return intersect_sphere(s.p[0].xyz, s.p[0].w, o, d, t_min, t_max);
    }
    vec4 rows[3] = vec4[3](s.p[0], s.p[1], s.p[2]);
    vec3 o_local;
    vec3 d_local;
    to_box_frame(rows, s.p[3].xyz, o, d, o_local, d_local);
    vec2 span = intersect_slabs(o_local, d_local, s.p[4].xyz);
    if (span.x > span.y) {
        return FAR;
    }
    if (span.x > t_min && span.x < t_max) {
        return span.x;
    }
    if (span.y > t_min && span.y < t_max) {
        return span.y;
    }
    return FAR;
}

// Geometric normal of shape `s` at the surface point x, facing against d.
vec3 shape_normal(Shape s, vec3 x, vec3 d) {
    uint type = s.type;
    vec3 n;
    if (type == SHAPE_QUAD) {
        n = cross(s.p[1].xyz, s.p[2].xyz);
    } else if (type == SHAPE_SPHERE) {
        n = x - s.p[0].xyz;
    } else {
        // Box: the local axis along which the point is farthest out relative to the
        // half extent is the face it lies on.
        vec4 rows[3] = vec4[3](s.p[0], s.p[1], s.p[2]);
        vec3 p = x - s.p[3].xyz;
        vec3 local = vec3(dot(rows[0].xyz, p), dot(rows[1].xyz, p), dot(rows[2].xyz, p));
        vec3 rel = abs(local) / s.p[4].xyz;
        int axis = (rel.x >= rel.y && rel.x >= rel.z) ? 0 : ((rel.y >= rel.z) ? 1 : 2);
        n = rows[axis].xyz * sign(local[axis] == 0.0 ? 1.0 : local[axis]);
    }
    n = normalize(n);
    return dot(n, d) > 0.0 ? -n : n;
}

// Nearest shape hit along o + t d in (t_min, t_max): distance (FAR if none) and index.
float nearest_shape(vec3 o, vec3 d, float t_min, float t_max, out uint index) {
    float t_hit = t_max;
    index = NO_INDEX;
    if (SC_HAS_SHAPES) {
        uint count = u_frame.shape_count;
        for (uint s = 0u; s < count; ++s) {
            float t = intersect_shape(shapes[s], o, d, t_min, t_hit);
            if (t < t_hit) {
                t_hit = t;
                index = s;
            }
        }
    }
    return index == NO_INDEX ? FAR : t_hit;
}

// Whether any shape blocks o + t d for t in (t_min, t_max).
bool occluded_before(vec3 o, vec3 d, float t_min, float t_max) {
    if (!SC_HAS_SHAPES) {
        return false;
    }
    uint count = u_frame.shape_count;
    for (uint s = 0u; s < count; ++s) {
        if (intersect_shape(shapes[s], o, d, t_min, t_max) < FAR) {
            return true;
        }
    }
    return false;
}

// Whether any shape blocks o + t d for t in (t_min, FAR).
bool occluded(vec3 o, vec3 d, float t_min) {
    return occluded_before(o, d, t_min, FAR);
}

#endif
