// Directional lights of the crepuscular pass, with their gobos: where along a ray a
// light can reach (the gobo prism), and how much of it arrives at a point (shapes and
// the box media's closed-form transmittance on the way). The includer declares
// `Light lights[]` and includes shapes.glsl and box_media.glsl first; the gobo geometry
// (SC_HAS_GOBOS, gobo_planes[], inside_gobo, gobo_interval) is gobo.glsl's.
//
// A light travels along omega = direction_or_position, so it reaches x from direction
// -omega.
#ifndef NIMBUS_BOX_DIRECTIONAL_GLSL
#define NIMBUS_BOX_DIRECTIONAL_GLSL

#include "constants.glsl"
#include "scene.glsl"
#include "gobo.glsl"

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
