// Direction sampling: Henyey–Greenstein and cosine-weighted hemispheres.
#ifndef NIMBUS_SAMPLING_GLSL
#define NIMBUS_SAMPLING_GLSL

#include "constants.glsl"

// An orthonormal basis (t, b) around unit n (Duff et al. 2017).
void orthonormal_basis(vec3 n, out vec3 t, out vec3 b) {
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    // Domain: s + n.z has magnitude >= 1, since s has the sign of n.z.
    float a = -1.0 / (s + n.z);
    float c = n.x * n.y * a;
    t = vec3(1.0 + s * n.x * n.x * a, s * c, -s * n.x);
    b = vec3(c, s + n.y * n.y * a, -n.y);
}

// Sample a travel direction after scattering from travel direction `d` with HG
// asymmetry g (pbrt's SampleHenyeyGreenstein); the phase/pdf ratio is 1.
vec3 sample_hg(vec3 d, float g, vec2 u) {
    float cos_theta;
    if (abs(g) < 1e-3) {
        cos_theta = 1.0 - 2.0 * u.x;
    } else {
        // Domain: 1 + g - 2 g u.x lies in [1 - |g|, 1 + |g|] > 0 for |g| < 1.
        float sq = (1.0 - g * g) / (1.0 + g - 2.0 * g * u.x);
        cos_theta = (1.0 + g * g - sq * sq) / (2.0 * g);
    }
    cos_theta = clamp(cos_theta, -1.0, 1.0);
    float sin_theta = sqrt(max(0.0, 1.0 - cos_theta * cos_theta));
    float phi = 2.0 * PI * u.y;
    vec3 t;
    vec3 b;
    orthonormal_basis(d, t, b);
    return normalize(sin_theta * cos(phi) * t + sin_theta * sin(phi) * b + cos_theta * d);
}

// Sample a cosine-weighted direction about unit n; the (cos/pi)/pdf ratio is 1.
vec3 sample_cosine_hemisphere(vec3 n, vec2 u) {
    float r = sqrt(u.x);
    float phi = 2.0 * PI * u.y;
    vec3 t;
    vec3 b;
    orthonormal_basis(n, t, b);
    float z = sqrt(max(0.0, 1.0 - u.x));
    return normalize(r * cos(phi) * t + r * sin(phi) * b + z * n);
}

#endif
