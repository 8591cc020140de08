// Ray–primitive intersection for box media and opaque shapes.
#ifndef NIMBUS_GEOMETRY_GLSL
#define NIMBUS_GEOMETRY_GLSL

#include "constants.glsl"

// Intersect o + t d with the box |x_a| <= h_a (box-local coordinates): (t_in, t_out),
// with t_in > t_out for a miss. An axis the ray is parallel to (|d_a| < 1e-30)
// constrains nothing when o lies within the slab and misses otherwise; a ray lying in
// a face plane counts as inside (the slab is closed).
vec2 intersect_slabs(vec3 o, vec3 d, vec3 h) {
    float t_in = -FAR;
    float t_out = FAR;
    for (int a = 0; a < 3; ++a) {
        if (abs(d[a]) < 1e-30) {
            if (abs(o[a]) > h[a]) {
                return vec2(FAR, -FAR);
            }
            continue;
        }
        // Domain: |d[a]| >= 1e-30.
        float inv_d = 1.0 / d[a];
        float t_a = (-h[a] - o[a]) * inv_d;
        float t_b = (h[a] - o[a]) * inv_d;
        t_in = max(t_in, min(t_a, t_b));
        t_out = min(t_out, max(t_a, t_b));
    }
    return vec2(t_in, t_out);
}

// Transform a world ray into the frame of a box given by rows of R^T and its centre.
void to_box_frame(vec4 rows[3], vec3 center, vec3 o, vec3 d, out vec3 o_local, out vec3 d_local) {
    vec3 p = o - center;
    o_local = vec3(dot(rows[0].xyz, p), dot(rows[1].xyz, p), dot(rows[2].xyz, p));
    d_local = vec3(dot(rows[0].xyz, d), dot(rows[1].xyz, d), dot(rows[2].xyz, d));
}

// Length of [t_in, t_out] ∩ [t_min, t_max], zero when empty.
float overlap_length(vec2 span, float t_min, float t_max) {
    return max(0.0, min(span.y, t_max) - max(span.x, t_min));
}

// Nearest hit of o + t d with a two-sided parallelogram, t in (t_min, t_max); FAR if none.
// Domain: dot(n, d) == 0 (ray parallel to the plane) is a miss.
float intersect_quad(vec3 corner, vec3 edge_u, vec3 edge_v, vec3 w, vec3 o, vec3 d, float t_min, float t_max) {
    vec3 n = cross(edge_u, edge_v);
    float denom = dot(n, d);
    if (abs(denom) < 1e-30) {
        return FAR;
    }
    float t = dot(corner - o, n) / denom;
    if (t <= t_min || t >= t_max) {
        return FAR;
    }
    vec3 p = o + t * d - corner;
    float alpha = dot(w, cross(p, edge_v));
    float beta = dot(w, cross(edge_u, p));
    return (alpha >= 0.0 && alpha <= 1.0 && beta >= 0.0 && beta <= 1.0) ? t : FAR;
}

// Nearest hit of o + t d (d unit) with a sphere, t in (t_min, t_max); FAR if none.
// Uses the distance of the centre from the ray (pbrt's robust discriminant form).
float intersect_sphere(vec3 center, float radius, vec3 o, vec3 d, float t_min, float t_max) {
    vec3 oc = o - center;
    float b = dot(oc, d);
    vec3 perp = oc - b * d;
    float disc = radius * radius - dot(perp, perp);
    if (disc < 0.0) {
        return FAR;
    }
    float root = sqrt(disc);
    float q = (b > 0.0) ? -b - root : -b + root;
    // Domain: the two roots are q and c / q with c = |oc|^2 - r^2; q == 0 only when
    // b == 0 and disc == 0, a tangent ray, whose single root is -b = 0.
    float c = dot(oc, oc) - radius * radius;
    float t0 = q;
    float t1 = (abs(q) > 0.0) ? c / q : q;
    float t_near = min(t0, t1);
    float t_far = max(t0, t1);
    if (t_near > t_min && t_near < t_max) {
        return t_near;
    }
    if (t_far > t_min && t_far < t_max) {
        return t_far;
    }
    return FAR;
}

#endif
