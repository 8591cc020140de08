// The environment in the crepuscular pass: what camera rays see of it, and its light on
// the box media and the Lambertian shapes by next-event estimation.
//
// The environment is a constant radiance (u_frame.env_radiance) or, with SC_HAS_ENV_MAP,
// an equirectangular map (envmap.glsl; its texels are already times `radiance · scale`),
// turned about +Y by the frame's u_frame.env_rotation (looked up, sampled and its pdf
// evaluated turned).
// Its light reaches the camera after a scattering only through next-event estimation
// here: a path that continues after a scattering and escapes adds nothing (only the
// camera ray sees the environment), so every scattering order is counted once and no
// weight is shared with the path's own continuation.
//
// Per path segment, N = u_frame.ray_samples samples:
//   media     N stratified distances along each in-medium stretch [t_enter, t_b] by the
//             camera transmittance, truncated to the stretch: pdf(t) = sigma_t T(t_enter
//             -> t) / (1 - T_span), so sigma_s T / pdf = albedo (1 - T_span) exactly;
//             at each one direction w with the phase function p(d . w) (light arriving
//             from w travels along -w and leaves along -d: cos theta = d . w).
//   surfaces  N directions at the hit, for the Lambertian BRDF albedo / pi times cos.
// Directions: under a constant sky the phase function or the cosine lobe alone, whose
// f / pdf is then the sky radiance times V T. Under a map, a one-sample mixture: the map's
// importance sampling or the lobe with probability 1/2 each, weighted by the balance
// heuristic, f / ((p_map + p_lobe) / 2). p_lobe > 0 wherever f > 0, so the mixture pdf is
// never 0 where it divides, and the weight p_lobe / pdf is at most 2. V T is the shapes'
// visibility and every box medium's closed-form transmittance towards the environment.
//
// The includer declares `u_frame`, the bool constants SC_HAS_ENV and SC_HAS_ENV_MAP, and
// includes phase.glsl, sampling.glsl, path.glsl, shapes.glsl and box_media.glsl first.
#ifndef NIMBUS_BOX_ENVIRONMENT_GLSL
#define NIMBUS_BOX_ENVIRONMENT_GLSL

#include "bindings.glsl"

layout(std430, set = 0, binding = BINDING_ENV_TEXELS) readonly buffer EnvTexelBlock {
    vec4 env_texels[];
};
layout(std430, set = 0, binding = BINDING_ENV_CDF) readonly buffer EnvCdfBlock {
    float env_cdf[];
};
#define ENV_SIZE u_frame.env_size
#include "envmap.glsl"

// The environment's radiance arriving from direction w (pointing away from the scene).
vec3 sky_radiance(vec3 w) {
    if (!SC_HAS_ENV) {
        return vec3(0.0);
    }
    return SC_HAS_ENV_MAP ? env_lookup_rotated(w, u_frame.env_rotation) : u_frame.env_radiance;
}

// What a camera ray escaping along w sees: the map interpolated between texel centres
// (env_lookup_bilinear); the light the scene receives keeps sky_radiance's nearest texel.
vec3 sky_background(vec3 w) {
    if (!SC_HAS_ENV) {
        return vec3(0.0);
    }
    return SC_HAS_ENV_MAP ? env_background_rotated(w, u_frame.env_rotation) : u_frame.env_radiance;
}

// Visibility times transmittance from x towards the environment along unit w: 0 behind
// a shape, else exp(-optical depth of every box medium).
float sky_visibility(vec3 x, vec3 w) {
    if (occluded(x, w, 0.0)) {
        return 0.0;
    }
    return exp(-box_optical_depth(x, w, 0.0, FAR));
}

// One sample of the environment's radiance in-scattered at x towards -d, per unit sigma_s,
// in a medium of HG asymmetry g: an estimate of the integral over w of p(d . w) L(w) V T.
vec3 sample_sky_inscatter(vec3 x, vec3 d, float g, inout uint rng) {
    vec2 u = vec2(rng_next(rng), rng_next(rng));
    vec3 w;
    // p / pdf of the sampled direction.
    float weight = 1.0;
    if (SC_HAS_ENV_MAP) {
        // Sample the map or the phase function, each with probability 1/2.
        if (rng_next(rng) < 0.5) {
            float pdf_map;
            env_sample_rotated(u, u_frame.env_rotation, w, pdf_map);
        } else {
            w = sample_hg(d, g, u);
        }
        float phase = hg_phase(dot(d, w), g);
        // Domain: phase > 0 for |g| < 1, so the mixture pdf is > 0; weight <= 2.
        weight = phase / (0.5 * (env_pdf_rotated(w, u_frame.env_rotation) + phase));
    } else {
        // Sample the phase function: p / pdf = 1.
        w = sample_hg(d, g, u);
    }
    vec3 L = sky_radiance(w);
    if (!any(greaterThan(L, vec3(0.0)))) {
        return vec3(0.0);
    }
    return L * (weight * sky_visibility(x, w));
}

// One sample of the environment's radiance reflected at x_off (already off the surface)
// with unit normal n, per unit albedo: an estimate of the integral over w of
// L(w) max(n . w, 0) / pi V T.
vec3 sample_sky_reflect(vec3 x_off, vec3 n, inout uint rng) {
    vec2 u = vec2(rng_next(rng), rng_next(rng));
    vec3 w;
    // (cos / pi) / pdf of the sampled direction.
    float weight = 1.0;
    if (SC_HAS_ENV_MAP) {
        // Sample the map or the cosine lobe, each with probability 1/2.
        if (rng_next(rng) < 0.5) {
            float pdf_map;
            env_sample_rotated(u, u_frame.env_rotation, w, pdf_map);
        } else {
            w = sample_cosine_hemisphere(n, u);
        }
        float lobe = cosine_hemisphere_pdf(dot(n, w));
        // Handle a direction below the surface (a map sample): it reflects nothing.
        if (!(lobe > 0.0)) {
            return vec3(0.0);
        }
        // Domain: lobe > 0, so the mixture pdf is > 0; weight <= 2.
        weight = lobe / (0.5 * (env_pdf_rotated(w, u_frame.env_rotation) + lobe));
    } else {
        // Sample the cosine lobe: (cos / pi) / pdf = 1.
        w = sample_cosine_hemisphere(n, u);
    }
    vec3 L = sky_radiance(w);
    if (!any(greaterThan(L, vec3(0.0)))) {
        return vec3(0.0);
    }
    return L * (weight * sky_visibility(x_off, w));
}

// The environment's light single-scattered towards o by box medium m along o + t d, t in
// [t_enter, t_b], from N stratified distances. The caller checked t_b > t_enter and
// sigma_t > 0. Excludes the transmittance of other media between o and t_enter.
vec3 sky_scatter_box(uint m, vec3 o, vec3 d, float t_enter, float t_b, inout uint rng) {
    BoxMedium bm = media[m];
    float span = t_b - t_enter;
    // The stretch's optical depth.
    float x = bm.sigma_t * span;
    uint n = max(u_frame.ray_samples, 1u);
    vec3 sum = vec3(0.0);
    for (uint k = 0u; k < n; ++k) {
        // Stratified random number k of n, then t by the truncated camera transmittance.
        float r = (float(k) + rng_next(rng)) / float(n);
        float t = t_enter + sample_truncated_exponential(x, r) * span;
        sum += sample_sky_inscatter(o + t * d, d, bm.g, rng);
    }
    // sigma_s T / pdf = albedo (1 - exp(-x)), with 1 - exp(-x) = x (1 - exp(-x)) / x
    // exact for small x. Domain: sigma_t > 0 (the caller's check) and n >= 1.
    vec3 albedo = bm.sigma_s / bm.sigma_t;
    return albedo * (x * one_minus_exp_over_x(x)) * (sum / float(n));
}

// The environment's light reflected towards the camera by the Lambertian shape s at x
// (unit normal n facing the incoming ray), from N directions.
vec3 sky_reflect(Shape s, vec3 x, vec3 n, inout uint rng) {
    // Shadow rays leave from just off the surface.
    vec3 x_off = offset_ray_origin(x, n);
    uint count = max(u_frame.ray_samples, 1u);
    vec3 sum = vec3(0.0);
    for (uint k = 0u; k < count; ++k) {
        sum += sample_sky_reflect(x_off, n, rng);
    }
    // Domain: count >= 1.
    return s.albedo * (sum / float(count));
}

#endif
