// Path bookkeeping shared by the integrators: Russian roulette on the throughput, and
// the origin of a ray leaving a surface. (ReSTIR's stored paths are restir/path_value.glsl.)
#ifndef NIMBUS_PATH_GLSL
#define NIMBUS_PATH_GLSL

#include "rng.glsl"

// The smallest survival probability of Russian roulette: it bounds the weight 1 / q.
#define RR_MIN_SURVIVAL 0.05

// Russian roulette by the path throughput beta (pbrt's, without the eta scale): the path
// survives with probability q = clamp(max channel of beta, RR_MIN_SURVIVAL, 1) and then
// carries beta / q, so the estimator stays unbiased. Draws one random number; returns
// false when the path ends (beta is then left as it was).
bool russian_roulette(inout vec3 beta, inout uint rng) {
    float q = clamp(max(beta.r, max(beta.g, beta.b)), RR_MIN_SURVIVAL, 1.0);
    if (rng_next(rng) >= q) {
        return false;
    }
    // Domain: q >= RR_MIN_SURVIVAL > 0.
    beta /= q;
    return true;
}

// The origin of a ray leaving the surface point x on the side of the unit normal n: x
// moved off by a distance relative to its magnitude (f32 spacing grows with |x|), so the
// ray does not hit the surface it leaves.
vec3 offset_ray_origin(vec3 x, vec3 n) {
    float eps = 1e-4 * (1.0 + max(max(abs(x.x), abs(x.y)), abs(x.z)));
    return x + eps * n;
}

#endif
