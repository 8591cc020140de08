// The Henyey–Greenstein phase function and its sampling family (pbrt's HGPhaseFunction):
// hg_phase is p, sample_hg draws a direction with pdf exactly p, hg_pdf is that pdf and
// invert_hg maps a direction back to its u.
#ifndef NIMBUS_PHASE_GLSL
#define NIMBUS_PHASE_GLSL

#include "constants.glsl"
#include "sampling.glsl"

// Below this |g| the phase function is sampled as uniform (the inversion's 1 / g).
#define HG_ISOTROPIC_G 1e-3

// The denominator 1 + g^2 - 2 g cos_theta of HG formed as a sum of non-negative terms,
// (1 - g)^2 + 2 g (1 - cos) for g >= 0 and (1 + g)^2 - 2 g (1 + cos) for g < 0, from
// 1 - cos and 1 + cos, so it does not cancel at the peak when |g| -> 1.
float hg_denominator(float one_minus_cos, float one_plus_cos, float g) {
    return g >= 0.0 ? (1.0 - g) * (1.0 - g) + 2.0 * g * one_minus_cos
                    : (1.0 + g) * (1.0 + g) - 2.0 * g * one_plus_cos;
}

// p(cos_theta) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos_theta)^1.5), theta between the
// travel directions before and after scattering (1 -+ cos is exact in f32 for |cos| >= 0.5).
// Domain: |g| < 1 (validated), so denom >= (1 - |g|)^2 > 0.
float hg_phase(float cos_theta, float g) {
    float c = clamp(cos_theta, -1.0, 1.0);
    float denom = hg_denominator(1.0 - c, 1.0 + c, g);
    return INV_4PI * (1.0 - g * g) / (denom * sqrt(denom));
}

// Sample a travel direction after scattering from travel direction `d` with HG
// asymmetry g (pbrt's SampleHenyeyGreenstein); the phase/pdf ratio is 1.
vec3 sample_hg(vec3 d, float g, vec2 u) {
    float cos_theta;
    if (abs(g) < HG_ISOTROPIC_G) {
        cos_theta = 1.0 - 2.0 * u.x;
    } else {
        // Domain: 1 + g - 2 g u.x lies in [1 - |g|, 1 + |g|] > 0 for |g| < 1.
        float sq = (1.0 - g * g) / (1.0 + g - 2.0 * g * u.x);
        cos_theta = (1.0 + g * g - sq * sq) / (2.0 * g);
    }
    return spherical_direction(d, clamp(cos_theta, -1.0, 1.0), 2.0 * PI * u.y);
}

// The solid-angle pdf of sample_hg at cos_theta = dot(d, w): the phase function itself,
// since sample_hg samples it exactly.
float hg_pdf(float cos_theta, float g) {
    return hg_phase(cos_theta, g);
}

// The u that sample_hg(d, g, u) takes to unit w. u.x = 1 - F(mu) with F the CDF of
// mu = cos(theta) (sample_hg's cos_theta falls as u.x grows):
//   1 - F(mu) = (1 + g)(1 - mu) / (s (1 - g + s)),  s = sqrt(1 + g^2 - 2 g mu),
// with 1 -+ mu = |w -+ d|^2 / 2 (no cancellation near the poles).
vec2 invert_hg(vec3 d, float g, vec3 w) {
    vec3 dm = w - d;
    vec3 dp = w + d;
    float one_minus_mu = 0.5 * dot(dm, dm);
    float one_plus_mu = 0.5 * dot(dp, dp);
    float ux;
    if (abs(g) < HG_ISOTROPIC_G) {
        ux = 0.5 * one_minus_mu;
    } else {
        float s = sqrt(hg_denominator(one_minus_mu, one_plus_mu, g));
        // Domain: s >= 1 - |g| > 0 and 1 - g + s > 0.
        ux = (1.0 + g) * one_minus_mu / (s * (1.0 - g + s));
    }
    return vec2(clamp(ux, 0.0, 1.0), invert_azimuth(d, w));
}

#endif
