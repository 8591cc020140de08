// Henyey–Greenstein phase function.
#ifndef NIMBUS_PHASE_GLSL
#define NIMBUS_PHASE_GLSL

#include "constants.glsl"

// p(cos_theta) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos_theta)^1.5), theta between the
// travel directions before and after scattering.
// The denominator 1 + g^2 - 2 g cos is formed as a sum of non-negative terms,
// (1 - g)^2 + 2 g (1 - cos) for g >= 0 and (1 + g)^2 - 2 g (1 + cos) for g < 0, so it
// does not cancel at the peak when |g| -> 1 (1 -+ cos is exact in f32 for |cos| >= 0.5).
// Domain: |g| < 1 (validated), so denom >= (1 - |g|)^2 > 0.
float hg_phase(float cos_theta, float g) {
    float c = clamp(cos_theta, -1.0, 1.0);
    float denom = g >= 0.0 ? (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - c)
                           : (1.0 + g) * (1.0 + g) - 2.0 * g * (1.0 + c);
    return INV_4PI * (1.0 - g * g) / (denom * sqrt(denom));
}

#endif
