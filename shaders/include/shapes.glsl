// Opaque shapes: their buffer, nearest hit with normal, occlusion queries, and the
// radiance an emitting shape sends (shape_emitted). Needs `u_frame` (shape_count =
// number of shapes) and the bool constant SC_HAS_SHAPES to be declared by the including
// pass; declares SC_HAS_MESHES itself (meshes traverse their BVH, bvh.glsl; without
// meshes the traversal is compiled out), and SC_HAS_AREA_LIGHTS through emitters.glsl.
#ifndef NIMBUS_SHAPES_GLSL
#define NIMBUS_SHAPES_GLSL

#include "bindings.glsl"
#include "features.glsl"
#include "geometry.glsl"
#include "scene.glsl"
#include "bvh.glsl"
#include "emitters.glsl"

// Some shapes are triangle meshes.
layout(constant_id = SC_ID_HAS_MESHES) const bool SC_HAS_MESHES = false;

layout(std430, set = 0, binding = BINDING_SHAPES) readonly buffer ShapesBlock {
    Shape shapes[];
};

// The mesh triangle (index into mesh_triangles[]) of the last hit nearest_shape
// returned, if that was a mesh: shape_normal reads its normal.
uint g_nearest_triangle = NO_INDEX;

// Hit distance of one shape along o + t d within (t_min, t_max); FAR if none. For a
// mesh, `triangle` is the hit triangle; with any_hit, any hit ends its traversal.
float intersect_shape(Shape s, vec3 o, vec3 d, float t_min, float t_max, bool any_hit, out uint triangle) {
    uint type = s.type;
    triangle = NO_INDEX;
    if (SC_HAS_MESHES && type == SHAPE_MESH) {
        uint root = floatBitsToUint(s.p[0].x);
        uint node_count = floatBitsToUint(s.p[0].w);
        float t = bvh_trace(root, node_count, o, d, t_min, t_max, any_hit, triangle);
        return t;
    }
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

// Geometric normal of shape `s` at the surface point x, not normalized, on its own side:
// a quad's cross(edge_u, edge_v), a mesh triangle's counter-clockwise normal (of the
// triangle the last nearest_shape hit; 0 if none), a box's or a sphere's outward normal.
vec3 shape_outward_normal(Shape s, vec3 x) {
    uint type = s.type;
    vec3 n;
    if (SC_HAS_MESHES && type == SHAPE_MESH) {
        n = g_nearest_triangle == NO_INDEX ? vec3(0.0) : mesh_triangle_normal(g_nearest_triangle);
    } else if (type == SHAPE_QUAD) {
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
    return n;
}

// Geometric normal of shape `s` at the surface point x, facing against d. For a mesh:
// of the triangle the last nearest_shape hit, so call it for that hit.
vec3 shape_normal(Shape s, vec3 x, vec3 d) {
    vec3 n = shape_outward_normal(s, x);
    // A mesh hit without a triangle normal faces the ray.
    if (SC_HAS_MESHES && s.type == SHAPE_MESH && n == vec3(0.0)) {
        n = -d;
    }
    n = normalize(n);
    return dot(n, d) > 0.0 ? -n : n;
}

// The radiance shape `shape_index` emits from its surface point x back along a ray of
// direction d (towards -d): its emission on the side it emits to (a quad's or mesh
// triangle's normal side, a box's or sphere's outside), 0 from behind, for a shape that
// does not emit, or without area lights. Call it right after the nearest_shape that hit
// it (a mesh's triangle is that hit's).
vec3 shape_emitted(uint shape_index, vec3 x, vec3 d) {
    if (!SC_HAS_AREA_LIGHTS || shape_index == NO_INDEX) {
        return vec3(0.0);
    }
    Shape s = shapes[shape_index];
    if (!any(greaterThan(s.emission, vec3(0.0)))) {
        return vec3(0.0);
    }
    return dot(shape_outward_normal(s, x), d) < 0.0 ? s.emission : vec3(0.0);
}

// Nearest shape hit along o + t d in (t_min, t_max): distance (FAR if none) and index.
float nearest_shape(vec3 o, vec3 d, float t_min, float t_max, out uint index) {
    float t_hit = t_max;
    index = NO_INDEX;
    if (SC_HAS_SHAPES) {
        uint count = u_frame.shape_count;
        for (uint s = 0u; s < count; ++s) {
            uint triangle;
            float t = intersect_shape(shapes[s], o, d, t_min, t_hit, false, triangle);
            if (t < t_hit) {
                t_hit = t;
                index = s;
                g_nearest_triangle = triangle;
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
        uint triangle;
        if (intersect_shape(shapes[s], o, d, t_min, t_max, true, triangle) < FAR) {
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
