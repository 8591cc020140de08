// Directional lights of the crepuscular pass, with their gobos: where along a ray a
// light can reach (the gobo prism), and how much of it arrives at a point (shapes and
// the box media's closed-form transmittance on the way). The includer declares
// `Light lights[]`, `vec4 gobo_planes[]`, the bool constant SC_HAS_GOBOS, and includes
// shapes.glsl and box_media.glsl first.
//
// A light travels along omega = direction_or_position, so it reaches x from direction
// -omega. Its gobo is a convex polygon in the plane through gobo_origin spanned by
// (gobo_u, gobo_v): gobo_plane_count half-planes from index gobo_first_plane on, and the
// light passes where all of them hold (a prism along omega).
#ifndef NIMBUS_BOX_DIRECTIONAL_GLSL
#define NIMBUS_BOX_DIRECTIONAL_GLSL

#include "constants.glsl"
#include "scene.glsl"

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

// The part of [t_enter, t_b] light l can reach (its gobo interval), empty as a
// zero-length interval at t_enter.
vec2 light_interval(Light l, vec3 o, vec3 d, float t_enter, float t_b) {
    vec2 iv = gobo_interval(l, o, d, t_enter, t_b);
    return iv.y > iv.x ? iv : vec2(t_enter, t_enter);
}

// Shadow-ray factor at x towards light direction -omega: 0 behind a shape, else the
// transmittance of the box media other than `skip` (medium `skip` is analytic).
float light_visibility(vec3 x, vec3 omega, uint skip) {
    if (occluded(x, -omega, 0.0)) {
        return 0.0;
    }
    return exp(-box_optical_depth_except(x, -omega, 0.0, FAR, skip));
}

// Irradiance from light l arriving unscattered at x: E · gobo · visibility · T to the
// light. `t_min` offsets the shadow ray's start (0 inside media, > 0 on surfaces).
vec3 light_arriving(Light l, vec3 x, float t_min) {
    vec3 omega = l.direction_or_position;
    if (!inside_gobo(l, x)) {
        return vec3(0.0);
    }
    if (occluded(x, -omega, t_min)) {
        return vec3(0.0);
    }
    float tau = box_optical_depth(x, -omega, 0.0, FAR);
    return l.irradiance * exp(-tau);
}

#endif
