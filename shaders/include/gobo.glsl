// Gobos of directional lights, shared by the crepuscular pass (box/directional.glsl) and
// the grid passes (lights.glsl): a light travelling along omega has an optional gobo, a
// convex polygon in the plane through gobo_origin spanned by (gobo_u, gobo_v) (scene.glsl's
// Light; the axes are Gobo::basis(omega)). Its gobo_plane_count half-planes start at
// gobo_first_plane in gobo_planes[], and the light passes where all of them hold: a
// prism along omega. Declares SC_HAS_GOBOS and the half-plane buffer: without gobos every
// caller compiles the tests out and the pass binds one zeroed plane.
#ifndef NIMBUS_GOBO_GLSL
#define NIMBUS_GOBO_GLSL

#include "bindings.glsl"
#include "constants.glsl"
#include "features.glsl"
#include "scene.glsl"

// Some directional light has a gobo.
layout(constant_id = SC_ID_HAS_GOBOS) const bool SC_HAS_GOBOS = false;

layout(std430, set = 0, binding = BINDING_GOBO_PLANES) readonly buffer GoboBlock {
    vec4 gobo_planes[]; // (a, b, c, 0): a point (u, v) is inside when a u + b v + c >= 0
};

// Whether x lies inside light l's gobo prism (always true without a gobo).
bool inside_gobo(Light l, vec3 x) {
    if (!SC_HAS_GOBOS) {
        return true;
    }
    uint count = l.gobo_plane_count;
    uint first = l.gobo_first_plane;
    vec3 p = x - l.gobo_origin;
    vec2 uv = vec2(dot(p, l.gobo_u), dot(p, l.gobo_v));
    for (uint i = 0u; i < count; ++i) {
        vec4 plane = gobo_planes[first + i];
        if (plane.x * uv.x + plane.y * uv.y + plane.z < 0.0) {
            return false;
        }
    }
    return true;
}

// The part of [t_a, t_b] where o + t d lies inside light l's gobo prism: each gobo
// half-plane is linear in t, alpha + beta t >= 0. Empty intervals have x > y.
vec2 gobo_interval(Light l, vec3 o, vec3 d, float t_a, float t_b) {
    if (!SC_HAS_GOBOS) {
        return vec2(t_a, t_b);
    }
    uint count = l.gobo_plane_count;
    uint first = l.gobo_first_plane;
    vec3 p = o - l.gobo_origin;
    vec2 uv0 = vec2(dot(p, l.gobo_u), dot(p, l.gobo_v));
    vec2 uv_d = vec2(dot(d, l.gobo_u), dot(d, l.gobo_v));
    for (uint i = 0u; i < count; ++i) {
        vec4 plane = gobo_planes[first + i];
        float alpha = plane.x * uv0.x + plane.y * uv0.y + plane.z;
        float beta = plane.x * uv_d.x + plane.y * uv_d.y;
        if (abs(beta) < 1e-12) {
            // Parallel to this edge: wholly inside or wholly outside.
            if (alpha < 0.0) {
                return vec2(FAR, -FAR);
            }
            continue;
        }
        // Domain: |beta| >= 1e-12.
        float t_edge = -alpha / beta;
        if (beta > 0.0) {
            t_a = max(t_a, t_edge);
        } else {
            t_b = min(t_b, t_edge);
        }
    }
    return vec2(t_a, t_b);
}

#endif
