// Analytic lights and the environment for grid-medium passes (baseline and ReSTIR):
// light selection for next-event estimation, re-evaluation of a stored light vertex
// from another shading point, and what a ray sees when it ends on a light.
//
// The includer declares, before including this file:
//   Light lights[]            (std430; scene.glsl: type, radius of a sphere, select_cdf =
//                              selection CDF over the analytic lights of a set)
//   BaselineUniforms u_base   (env_select = probability that NEE picks the environment,
//                              emitter_count = primitives in the emitter table)
//   FrameUniforms u_frame     (light_count = analytic lights per set, env_radiance)
//   bool constants SC_HAS_ENV, SC_HAS_ENV_MAP, and envmap.glsl's buffers (included here).
//
// A light set is `light_count` records starting at `base`: ReSTIR keeps the current frame's
// set at 0 and the previous frame's right after it, for animated lights. The environment
// map's turn of the set's frame, `env_rot` = (cos, sin) (FrameUniforms::env_rotation of
// that frame: u_frame's for the current one), goes with `base` wherever the environment
// is looked up or sampled.
//
// Measures: a directional light and a point light are deltas (their "radiance" is E and
// I / d^2, their pdf a selection probability); the environment is sampled in solid angle;
// a sphere light in AREA measure, so a stored point on it can be re-evaluated from any
// shading point: L_area = L cos_l / d^2 and pdf_area = pdf_solid_angle cos_l / d^2.
//
// Emitting shapes (area lights, SC_HAS_AREA_LIGHTS) are one LIGHT_AREA record of the set,
// selected in proportion to their total power like the others; a sample then picks a
// primitive of the emitter table by its power CDF and a point on it (emitters.glsl), in
// AREA measure: L_area = Le cos_l / d^2, pdf_area = p_select p_prim pdf_point. The sample
// names the primitive (`prim`), and light_eval re-evaluates a stored (prim, point) from
// another shading point.
//
// A directional light with a gobo (SC_HAS_GOBOS, gobo.glsl) reaches only the points inside
// its gobo prism: elsewhere light_sample returns no sample and light_eval zero.
#ifndef NIMBUS_LIGHTS_GLSL
#define NIMBUS_LIGHTS_GLSL

#include "constants.glsl"
#include "geometry.glsl"
#include "sampling.glsl"
#include "scene.glsl"
#include "envmap.glsl"
#include "emitters.glsl"
#include "gobo.glsl"

// The light index of the environment in a stored path.
#define LIGHT_ENV 0xffu

// One next-event sample.
struct LightSample {
    vec3 L;           // arriving radiance in the light's measure (see above)
    vec3 L_over_pdf;  // L / pdf, formed without the cancelling factors
    vec3 wi;          // unit direction towards the light
    vec3 point;       // the sampled point (sphere and area lights), else x + dist wi
    float dist;       // distance to the light vertex, FAR for directional / environment
    float pdf;        // selection x measure pdf; 0 for an unusable sample
    uint index;       // light index in its set, LIGHT_ENV, or NO_INDEX for none
    uint prim;        // LIGHT_AREA: the emitter primitive (index into emitters[]); else 0
};

LightSample light_sample_none() {
    LightSample s;
    s.L = vec3(0.0);
    s.L_over_pdf = vec3(0.0);
    s.wi = vec3(0.0, 1.0, 0.0);
    s.point = vec3(0.0);
    s.dist = FAR;
    s.pdf = 0.0;
    s.index = NO_INDEX;
    s.prim = 0u;
    return s;
}

// Whether light `index` of the set at `base` is the area light (the emitting shapes).
bool light_is_area(uint base, uint index) {
    return SC_HAS_AREA_LIGHTS && index < u_frame.light_count && lights[base + index].type == LIGHT_AREA;
}

// Constant environment radiance or the texel along d of the map turned by env_rot.
vec3 env_radiance_along(vec3 d, vec2 env_rot) {
    if (!SC_HAS_ENV) {
        return vec3(0.0);
    }
    return SC_HAS_ENV_MAP ? env_lookup_rotated(d, env_rot) : u_frame.env_radiance;
}

// What a camera ray escaping along d sees: the constant environment, or the map turned
// by env_rot interpolated between texel centres (env_lookup_bilinear; light reaching the
// scene keeps env_radiance_along's nearest texel).
vec3 env_background_along(vec3 d, vec2 env_rot) {
    if (!SC_HAS_ENV) {
        return vec3(0.0);
    }
    return SC_HAS_ENV_MAP ? env_background_rotated(d, env_rot) : u_frame.env_radiance;
}

// Some light of the scene is a sphere light (else nearest_sphere_light has none to find:
// on lavapipe its loop read every light's record on every segment and shadow ray).
layout(constant_id = SC_ID_HAS_SPHERE_LIGHTS) const bool SC_HAS_SPHERE_LIGHTS = true;

// Nearest emitting sphere of the set at `base` along o + t d in (t_min, t_max): its
// distance (FAR if none) and index.
float nearest_sphere_light(uint base, vec3 o, vec3 d, float t_min, float t_max, out uint index) {
    index = NO_INDEX;
    if (!SC_HAS_SPHERE_LIGHTS) {
        return FAR;
    }
    float t_hit = t_max;
    uint count = u_frame.light_count;
    for (uint l = 0u; l < count; ++l) {
        Light light = lights[base + l];
        if (light.type != LIGHT_SPHERE) {
            continue;
        }
        float t = intersect_sphere(light.direction_or_position, light.radius, o, d, t_min, t_hit);
        if (t < t_hit) {
            t_hit = t;
            index = l;
        }
    }
    return index == NO_INDEX ? FAR : t_hit;
}

// Whether light `index` of the set at `base` is a delta light (directional or point):
// its next-event term needs no sampling, so split NEE adds it at every vertex.
bool light_is_delta(uint base, uint index) {
    uint type = lights[base + index].type;
    return type == LIGHT_DIRECTIONAL || type == LIGHT_POINT;
}

// A sample of the environment, selected with probability p_select > 0 (u2 in [0, 1)^2,
// the map turned by env_rot): importance-sampled by luminance x sin(theta) for a map,
// uniform over the sphere for a constant radiance.
LightSample light_sample_env(vec2 env_rot, vec3 x, float p_select, vec2 u2) {
    LightSample s = light_sample_none();
    s.index = LIGHT_ENV;
    if (SC_HAS_ENV_MAP) {
        float pdf_sa;
        s.L = env_sample_rotated(u2, env_rot, s.wi, pdf_sa);
        s.pdf = p_select * pdf_sa;
    } else {
        s.wi = sample_uniform_sphere(u2);
        s.L = u_frame.env_radiance;
        s.pdf = p_select * uniform_sphere_pdf();
    }
    // Domain: pdf > 0 for a usable sample (0 at the map's poles or black texels).
    s.L_over_pdf = s.pdf > 0.0 ? s.L / s.pdf : vec3(0.0);
    s.point = x + s.wi;
    return s;
}

// A sample of analytic light `chosen` of the set at `base`, selected with probability
// p_select; u_prim in [0, 1) picks the area light's primitive, u2 in [0, 1)^2 the point.
LightSample light_sample_chosen(uint base, vec3 x, uint chosen, float p_select, float u_prim, vec2 u2) {
    LightSample s = light_sample_none();
    if (!(p_select > 0.0)) {
        return s;
    }
    Light light = lights[base + chosen];
    uint type = light.type;
    s.index = chosen;
    if (type == LIGHT_DIRECTIONAL) {
        // Outside the gobo prism the light carries nothing.
        if (SC_HAS_GOBOS && !inside_gobo(light, x)) {
            return light_sample_none();
        }
        s.wi = -light.direction_or_position;
        s.L = light.irradiance;
        s.pdf = p_select;
        // Domain: p_select > 0.
        s.L_over_pdf = s.L / p_select;
        s.point = x + s.wi;
        return s;
    }
    if (SC_HAS_AREA_LIGHTS && type == LIGHT_AREA) {
        uint count = u_base.emitter_count;
        if (count == 0u) {
            return light_sample_none();
        }
        uint prim = sample_emitter(count, u_prim);
        float p_prim = emitter_pmf(prim);
        if (!(p_prim > 0.0)) {
            return light_sample_none();
        }
        EmitterPoint ep = emitter_sample_point(emitters[prim], x, u2);
        if (!ep.valid) {
            return light_sample_none();
        }
        s.prim = prim;
        s.wi = ep.wi;
        s.dist = ep.dist;
        s.point = ep.point;
        s.L = ep.L;
        s.pdf = p_select * p_prim * ep.pdf_area;
        // Domain: p_select > 0, p_prim > 0.
        s.L_over_pdf = ep.L_over_pdf / (p_select * p_prim);
        return s;
    }
    vec3 to_light = light.direction_or_position - x;
    float d2 = dot(to_light, to_light);
    if (type == LIGHT_POINT) {
        // Domain: a point light off the shading point (d2 > 0).
        if (!(d2 > 0.0)) {
            return light_sample_none();
        }
        s.dist = sqrt(d2);
        s.wi = to_light / s.dist;
        s.point = light.direction_or_position;
        s.L = light.irradiance / d2;
        s.pdf = p_select;
        s.L_over_pdf = s.L / p_select;
        return s;
    }
    // Emitting sphere: uniform in the cone it subtends, pdf_sa = 1 / (2 pi (1 - cos_max)).
    float t_hit;
    float cos_l;
    float one_minus_cos_max;
    if (!sample_sphere_cone(light.direction_or_position, light.radius, x, u2, s.wi, t_hit, cos_l,
                            one_minus_cos_max)) {
        return light_sample_none();
    }
    s.dist = t_hit;
    s.point = x + t_hit * s.wi;
    // Domain: t_hit > 0 (x outside the sphere).
    float g = cos_l / (t_hit * t_hit);
    s.L = light.irradiance * g;
    // Domain: one_minus_cos_max > 0 since radius > 0.
    s.pdf = p_select * g / (2.0 * PI * one_minus_cos_max);
    // L / pdf with the geometry factor cancelled (finite even at grazing cos_l = 0).
    s.L_over_pdf = light.irradiance * (2.0 * PI * one_minus_cos_max / p_select);
    return s;
}


// Pick a light for next-event estimation at x: the environment with probability
// env_select, else an analytic light (or the area light) by the power CDF; for the area
// light, u's place within its CDF interval picks the primitive. u in [0, 1), u2 in
// [0, 1)^2. The map is turned by env_rot.
LightSample light_sample(uint base, vec2 env_rot, vec3 x, float u, vec2 u2) {
    float p_env = u_base.env_select;
    if (SC_HAS_ENV && u >= 1.0 - p_env) {
        return light_sample_env(env_rot, x, p_env, u2);
    }
    uint count = u_frame.light_count;
    uint chosen = NO_INDEX;
    float cdf_before = 0.0;
    for (uint l = 0u; l < count; ++l) {
        float cdf = lights[base + l].select_cdf;
        if (u < cdf) {
            chosen = l;
            break;
        }
        cdf_before = cdf;
    }
    if (chosen == NO_INDEX) {
        return light_sample_none();
    }
    float p_select = lights[base + chosen].select_cdf - cdf_before;
    // u's place within the chosen light's interval [cdf_before, select_cdf): in [0, 1).
    float u_prim = p_select > 0.0 ? min((u - cdf_before) / p_select, EMITTER_ONE_MINUS_EPSILON) : 0.0;
    return light_sample_chosen(base, x, chosen, p_select, u_prim, u2);
}

// Pick one of the lights that are not delta lights (the environment, sphere lights, the
// area light) for split next-event estimation, in proportion to their share of the power
// CDF, and sample it; p_select is the probability it was picked. No sample where there is
// none. u in [0, 1), u2 in [0, 1)^2, the map turned by env_rot.
LightSample light_sample_rest(uint base, vec2 env_rot, vec3 x, float u, vec2 u2, out float p_select) {
    p_select = 0.0;
    float p_env = SC_HAS_ENV ? u_base.env_select : 0.0;
    float total = p_env;
    uint count = u_frame.light_count;
    float cdf_before = 0.0;
    uint last = NO_INDEX;
    for (uint l = 0u; l < count; ++l) {
        float cdf = lights[base + l].select_cdf;
        if (!light_is_delta(base, l) && cdf > cdf_before) {
            total += cdf - cdf_before;
            last = l;
        }
        cdf_before = cdf;
    }
    if (!(total > 0.0)) {
        return light_sample_none();
    }
    float v = u * total;
    if (SC_HAS_ENV && p_env > 0.0 && (v < p_env || last == NO_INDEX)) {
        p_select = p_env / total;
        return light_sample_env(env_rot, x, p_select, u2);
    }
    v -= p_env;
    cdf_before = 0.0;
    for (uint l = 0u; l < count; ++l) {
        float cdf = lights[base + l].select_cdf;
        float p = cdf - cdf_before;
        cdf_before = cdf;
        if (light_is_delta(base, l) || !(p > 0.0)) {
            continue;
        }
        // The last one takes what rounding leaves over.
        if (v < p || l == last) {
            p_select = p / total;
            float u_prim = min(max(v, 0.0) / p, EMITTER_ONE_MINUS_EPSILON);
            return light_sample_chosen(base, x, l, p_select, u_prim, u2);
        }
        v -= p;
    }
    return light_sample_none();
}

// Re-evaluate a stored light vertex from shading point x: the light `index` of the set at
// `base` (or LIGHT_ENV), with `dir` the stored direction (directional lights ignore it,
// the environment uses it, turned by env_rot), `prim` the emitter primitive (the area
// light) and `point` the stored point (sphere and area lights). Returns the arriving
// radiance in the light's measure and sets wi / dist; zero when the vertex cannot be
// reached from x (the back of a sphere or of an emitting triangle, a point light at x, x
// outside a gobo prism).
vec3 light_eval(uint base, vec2 env_rot, uint index, vec3 dir, uint prim, vec3 point, vec3 x, out vec3 wi,
                out float dist) {
    wi = dir;
    dist = FAR;
    if (index == LIGHT_ENV) {
        return env_radiance_along(dir, env_rot);
    }
    if (index >= u_frame.light_count) {
        return vec3(0.0);
    }
    Light light = lights[base + index];
    uint type = light.type;
    if (type == LIGHT_DIRECTIONAL) {
        wi = -light.direction_or_position;
        return (SC_HAS_GOBOS && !inside_gobo(light, x)) ? vec3(0.0) : light.irradiance;
    }
    vec3 target = type == LIGHT_POINT ? light.direction_or_position : point;
    vec3 to_light = target - x;
    float d2 = dot(to_light, to_light);
    // Domain: a vertex off the shading point.
    if (!(d2 > 0.0)) {
        return vec3(0.0);
    }
    dist = sqrt(d2);
    wi = to_light / dist;
    if (type == LIGHT_POINT) {
        return light.irradiance / d2;
    }
    if (SC_HAS_AREA_LIGHTS && type == LIGHT_AREA) {
        // Le max(0, cos_l) / d^2, one-sided for triangles, outwards for spheres.
        return prim < u_base.emitter_count ? emitter_eval(prim, point, wi, d2) : vec3(0.0);
    }
    // A point on a sphere is seen from x only from its outer side.
    float cos_l = dot(normalize(point - light.direction_or_position), -wi);
    if (!(cos_l > 0.0)) {
        return vec3(0.0);
    }
    return light.irradiance * (cos_l / d2);
}

// True if an emitting sphere blocks the segment from x along wi before `dist` (the light
// vertex itself lies at dist; a sphere hit within the last 1e-4 of it is the vertex).
bool light_blocked(uint base, vec3 x, vec3 wi, float dist) {
    uint blocker;
    float t_max = dist >= FAR ? FAR : dist * (1.0 - 1e-4);
    return nearest_sphere_light(base, x, wi, 1e-6, t_max, blocker) < FAR;
}

// What a camera ray from o along d sees at its end beyond the media: the nearest emitting
// sphere (its radiance) or the environment (weighted by u_frame.background: 0 for a
// transparent film; the map turned by env_rot). `t_end` is where the ray ends (FAR when
// it escapes).
vec3 light_seen(uint base, vec2 env_rot, vec3 o, vec3 d, out float t_end) {
    uint index;
    t_end = nearest_sphere_light(base, o, d, 0.0, FAR, index);
    if (index != NO_INDEX) {
        return lights[base + index].irradiance;
    }
    // The background is weighted for a transparent film (u_frame.background = 0).
    return env_background_along(d, env_rot) * u_frame.background;
}

#endif
