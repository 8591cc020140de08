// The emitter table: every primitive of the scene's emitting shapes (area lights) with
// its power CDF (scene.glsl's Emitter, built by src/shader_data/emitters.rs), and how next-event
// estimation samples it: a primitive by binary search in the CDF (O(log n)), then a
// point on it (a triangle: uniform in area; a sphere: uniform in the cone it subtends,
// converted to area measure). Declares SC_HAS_AREA_LIGHTS: without area lights every
// caller compiles this out and the pass binds a one-record table.
//
// Measure: AREA, like a sphere light's stored point (lights.glsl): the sample carries
// L = Le cos_l / d^2 and pdf_area, so a stored point can be re-evaluated from any
// shading point.
#ifndef NIMBUS_EMITTERS_GLSL
#define NIMBUS_EMITTERS_GLSL

#include "bindings.glsl"
#include "constants.glsl"
#include "features.glsl"
#include "geometry.glsl"
#include "sampling.glsl"
#include "scene.glsl"

// Some shapes emit: the emitter table is sampled and camera rays see emission.
layout(constant_id = SC_ID_HAS_AREA_LIGHTS) const bool SC_HAS_AREA_LIGHTS = false;

layout(std430, set = 0, binding = BINDING_EMITTERS) readonly buffer EmittersBlock {
    Emitter emitters[];
};

// The largest float below 1.
#define EMITTER_ONE_MINUS_EPSILON 0.99999994

// Pick the primitive whose CDF interval holds u in [0, 1): the first i with u < cdf[i]
// among `count` >= 1 entries (a zero-power entry has an empty interval, never picked).
uint sample_emitter(uint count, float u) {
    uint lo = 0u;
    uint hi = count - 1u;
    while (lo < hi) {
        uint mid = (lo + hi) / 2u;
        if (u < emitters[mid].cdf) {
            hi = mid;
        } else {
            lo = mid + 1u;
        }
    }
    return lo;
}

// Probability that sample_emitter picks primitive i.
float emitter_pmf(uint i) {
    return emitters[i].cdf - (i == 0u ? 0.0 : emitters[i - 1u].cdf);
}

// Unit normal of the side primitive e emits to, at its point p: a triangle's
// counter-clockwise normal, a sphere's outward one; 0 for a degenerate triangle.
vec3 emitter_normal(Emitter e, vec3 p) {
    vec3 n = e.type == EMITTER_SPHERE ? p - e.p0 : cross(e.p1 - e.p0, e.p2 - e.p0);
    float len = length(n);
    // Domain: len > 0 where divided.
    return len > 0.0 ? n / len : vec3(0.0);
}

// One point on an emitter primitive, seen from a shading point.
struct EmitterPoint {
    vec3 point;       // on the primitive
    vec3 wi;          // unit direction from the shading point towards it
    float dist;       // distance to it
    vec3 L;           // Le cos_l / d^2 (area measure)
    float pdf_area;   // density of `point` in area, given the primitive
    vec3 L_over_pdf;  // L / pdf_area with the geometry factor cancelled where it can be
    bool valid;       // false from behind, from inside a sphere, or on the shading point
};

// A direction from x uniform in the cone the sphere (center, radius) subtends, pdf_sa =
// 1 / (2 pi (1 - cos_max)), and where it meets the sphere (t_hit): false from inside the
// sphere or when rounding makes the ray miss it. one_minus_cos_max (> 0 since radius > 0)
// is formed without cancellation, sin2 / (1 + cos); cos_l is the outward normal's cosine
// against -wi. Sphere lights and emitting spheres both sample this way.
bool sample_sphere_cone(vec3 center, float radius, vec3 x, vec2 u, out vec3 wi, out float t_hit, out float cos_l,
                        out float one_minus_cos_max) {
    wi = vec3(0.0, 1.0, 0.0);
    t_hit = FAR;
    cos_l = 0.0;
    one_minus_cos_max = 0.0;
    vec3 to_center = center - x;
    float d2 = dot(to_center, to_center);
    if (!(d2 > radius * radius)) {
        return false;
    }
    float d_center = sqrt(d2);
    vec3 axis = to_center / d_center;
    float sin2_max = radius * radius / d2;
    float cos_max = sqrt(max(0.0, 1.0 - sin2_max));
    one_minus_cos_max = sin2_max / (1.0 + cos_max);
    wi = sample_uniform_cone(axis, one_minus_cos_max, u);
    t_hit = intersect_sphere(center, radius, x, wi, 0.0, FAR);
    if (t_hit >= FAR) {
        return false;
    }
    vec3 point = x + t_hit * wi;
    cos_l = max(0.0, dot(normalize(point - center), -wi));
    return true;
}

// Sample a point on primitive e as seen from x, u in [0, 1)^2.
EmitterPoint emitter_sample_point(Emitter e, vec3 x, vec2 u) {
    EmitterPoint s;
    s.valid = false;
    s.point = x;
    s.wi = vec3(0.0, 1.0, 0.0);
    s.dist = FAR;
    s.L = vec3(0.0);
    s.pdf_area = 0.0;
    s.L_over_pdf = vec3(0.0);
    if (e.type == EMITTER_SPHERE) {
        // Uniform in the cone the sphere subtends: pdf_sa = 1 / (2 pi (1 - cos_max)),
        // pdf_area = pdf_sa cos_l / d^2.
        float t_hit;
        float cos_l;
        float one_minus_cos_max;
        if (!sample_sphere_cone(e.p0, e.p1.x, x, u, s.wi, t_hit, cos_l, one_minus_cos_max)) {
            return s;
        }
        s.dist = t_hit;
        s.point = x + t_hit * s.wi;
        // Domain: t_hit > 0 (x outside the sphere).
        float g = cos_l / (t_hit * t_hit);
        s.L = e.radiance * g;
        s.pdf_area = g * uniform_cone_pdf(one_minus_cos_max);
        s.L_over_pdf = e.radiance * (2.0 * PI * one_minus_cos_max);
        s.valid = true;
        return s;
    }
    // Triangle: uniform barycentrics (b0, b1) = (1 - sqrt(u0), u1 sqrt(u0)), pdf 1 / area.
    float su = sqrt(u.x);
    float b0 = 1.0 - su;
    float b1 = u.y * su;
    s.point = b0 * e.p0 + b1 * e.p1 + (1.0 - b0 - b1) * e.p2;
    vec3 n = emitter_normal(e, s.point);
    vec3 to_point = s.point - x;
    float d2 = dot(to_point, to_point);
    // Domain: a point off the shading point, on a triangle of positive area.
    if (!(d2 > 0.0) || !(e.area > 0.0)) {
        return s;
    }
    s.dist = sqrt(d2);
    s.wi = to_point / s.dist;
    float cos_l = dot(n, -s.wi);
    // One-sided: nothing from behind.
    if (!(cos_l > 0.0)) {
        return s;
    }
    float g = cos_l / d2;
    s.L = e.radiance * g;
    s.pdf_area = 1.0 / e.area;
    s.L_over_pdf = e.radiance * (g * e.area);
    s.valid = true;
    return s;
}

// The radiance primitive `prim` sends from its point `point` towards a shading point in
// direction -wi (wi from the shading point towards it), in area measure over d^2:
// Le max(0, cos_l) / d2; 0 from behind.
vec3 emitter_eval(uint prim, vec3 point, vec3 wi, float d2) {
    Emitter e = emitters[prim];
    float cos_l = dot(emitter_normal(e, point), -wi);
    // Domain: d2 > 0 (checked by the caller).
    return cos_l > 0.0 ? e.radiance * (cos_l / d2) : vec3(0.0);
}

#endif
