// Henyey–Greenstein phase function.
#ifndef NIMBUS_PHASE_GLSL
#define NIMBUS_PHASE_GLSL

#include "constants.glsl"

// p(cos_theta) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos_theta)^1.5), theta between the
// travel directions before and after scattering.
// Domain: |g| < 1 (validated), so denom >= (1 - |g|)^2 > 0.
float hg_phase(float cos_theta, float g) {
    float denom = 1.0 + g * g - 2.0 * g * clamp(cos_theta, -1.0, 1.0);
    return INV_4PI * (1.0 - g * g) / (denom * sqrt(denom));
}

#endif
