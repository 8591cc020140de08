// Sampling routines in pbrt's families: sample_X draws from u in [0, 1)^n, X_pdf is the
// density of what sample_X returns (in its own measure), and invert_X maps a value back to
// the u that sample_X takes to it (its CDF), so invert_X(sample_X(u)) = u up to rounding.
// tests/suite/kernels/sampling_gpu/ checks every family on the GPU. The Henyey–Greenstein family sits
// with its phase function in phase.glsl, whole-volume distance sampling with its pieces in
// box_analytic.glsl and the environment map's in envmap.glsl.
#ifndef NIMBUS_SAMPLING_GLSL
#define NIMBUS_SAMPLING_GLSL

#include "constants.glsl"

// The largest float below 1.
#define ONE_MINUS_EPSILON 0.99999994

// An orthonormal basis (t, b) around unit n (Duff et al. 2017).
void orthonormal_basis(vec3 n, out vec3 t, out vec3 b) {
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    // Domain: s + n.z has magnitude >= 1, since s has the sign of n.z.
    float a = -1.0 / (s + n.z);
    float c = n.x * n.y * a;
    t = vec3(1.0 + s * n.x * n.x * a, s * c, -s * n.x);
    b = vec3(c, s + n.y * n.y * a, -n.y);
}

// The unit direction at polar angle theta (given by its cosine) and azimuth phi about unit
// `axis`, in the basis of orthonormal_basis(axis) (pbrt's SphericalDirection in a Frame).
vec3 spherical_direction(vec3 axis, float cos_theta, float phi) {
    float sin_theta = sqrt(max(0.0, 1.0 - cos_theta * cos_theta));
    vec3 t;
    vec3 b;
    orthonormal_basis(axis, t, b);
    return normalize(sin_theta * cos(phi) * t + sin_theta * sin(phi) * b + cos_theta * axis);
}

// The fraction of a turn of the azimuth atan2(y, x), in [0, 1); 0 for x = y = 0.
float azimuth_fraction(float y, float x) {
    if (x == 0.0 && y == 0.0) {
        return 0.0;
    }
    // atan is in [-pi, pi], so f is in [-0.5, 0.5]; negative turns wrap into [0.5, 1).
    float f = atan(y, x) * (0.5 * INV_PI);
    return f < 0.0 ? min(f + 1.0, ONE_MINUS_EPSILON) : f;
}

// The u of the azimuth of unit w about unit n in the basis of orthonormal_basis(n).
float invert_azimuth(vec3 n, vec3 w) {
    vec3 t;
    vec3 b;
    orthonormal_basis(n, t, b);
    return azimuth_fraction(dot(w, b), dot(w, t));
}

// ---------------------------------------------------------------------------------------
// Helpers of the exponential families.

// Stable (1 - exp(-x)) / x for any finite x (x -> 0 gives 1). For x < -88 the true value
// exceeds e^88 / 88 and the result saturates there (finite); callers here pass x >= 0.
float one_minus_exp_over_x(float x) {
    // Sum the Taylor series sum_n (-x)^n / (n + 1)! near 0: truncation < 1e-9 relative
    // for |x| <= 0.5, where 1 - exp(-x) would lose up to -log2(x) bits (and GPU exp may
    // be off by a few ulp of 1, i.e. 2e-4 relative at x = 1e-3).
    if (abs(x) <= 0.5) {
        return 1.0 + x * (-1.0 / 2.0 + x * (1.0 / 6.0 + x * (-1.0 / 24.0 + x * (1.0 / 120.0
            + x * (-1.0 / 720.0 + x * (1.0 / 5040.0 + x * (-1.0 / 40320.0 + x * (1.0 / 362880.0))))))));
    }
    // Domain: x > 0.5, so the division is safe and 1 - exp(-x) >= 0.39 keeps its digits.
    if (x > 0.0) {
        return (1.0 - exp(-x)) / x;
    }
    // Domain: x < -0.5; exp's argument is clamped to 88 (e^88 < FLT_MAX).
    return (exp(min(-x, 88.0)) - 1.0) / -x;
}

// -log(1 - a) for a in [0, 1): the atanh series near 0, log elsewhere.
float neg_log1m(float a) {
    // Sum 2 atanh(z) = 2 (z + z^3/3 + ... + z^17/17) with z = a / (2 - a) <= 1/3 for
    // a <= 0.5 (truncation < 2e-10 relative); GPU log has only absolute accuracy near 1.
    if (a <= 0.5) {
        // Domain: 2 - a >= 1.5.
        float z = a / (2.0 - a);
        float z2 = z * z;
        float series = 1.0 + z2 * (1.0 / 3.0 + z2 * (1.0 / 5.0 + z2 * (1.0 / 7.0 + z2 * (1.0 / 9.0
            + z2 * (1.0 / 11.0 + z2 * (1.0 / 13.0 + z2 * (1.0 / 15.0 + z2 * (1.0 / 17.0))))))));
        return 2.0 * z * series;
    }
    // Domain: 1 - a in (0, 0.5] (a < 1), where log is accurate to a few ulp.
    return -log(max(1.0 - a, 1.17549435e-38));
}

// ---------------------------------------------------------------------------------------
// Exponential distance: density a exp(-a t) on [0, inf), rate a > 0 (a free flight).

// Sample t from u (pbrt's SampleExponential). Domain: 1 - u in (0, 1], a > 0.
float sample_exponential(float u, float a) {
    return -log(1.0 - u) / a;
}

float exponential_pdf(float t, float a) {
    return a * exp(-a * t);
}

// The CDF 1 - exp(-a t), formed as (a t) f(a t) so that small a t keeps its digits.
float invert_exponential(float t, float a) {
    float x = a * t;
    return x * one_minus_exp_over_x(x);
}

// ---------------------------------------------------------------------------------------
// Truncated exponential on [0, 1]: density proportional to exp(-x v), x >= 0 (a distance
// drawn by its transmittance over a segment of optical depth x, as a fraction of it).

// Sample v from r in [0, 1): the inverse of the CDF, evaluated without cancellation.
float sample_truncated_exponential(float x, float r) {
    // Handle a nearly flat density: v = r (1 + x (r - 1) / 2), error O(x^2) < 1e-12.
    if (x < 1e-6) {
        return r * (1.0 + 0.5 * x * (r - 1.0));
    }
    float e = exp(-x); // Domain: x >= 1e-6 (+inf gives 0).
    // Invert CDF(v) = (1 - exp(-x v)) / (1 - exp(-x)): v = -log(1 - a) / x with
    // a = r (1 - exp(-x)).
    float neg_log;
    float a = r * ((x <= 0.5) ? x * one_minus_exp_over_x(x) : 1.0 - e);
    if (a <= 0.5) {
        neg_log = neg_log1m(a);
    } else {
        // Form 1 - a = (1 - r) + r exp(-x) without cancellation (1 - r is exact for
        // r >= 0.5, which a > 0.5 implies); Domain: it is >= 1 - r > 0 for r < 1.
        neg_log = -log(max((1.0 - r) + r * e, 1.17549435e-38));
    }
    // Domain: x >= 1e-6.
    return clamp(neg_log / x, 0.0, 1.0);
}


// Density of v: x exp(-x v) / (1 - exp(-x)) = exp(-x v) / f(x), f(x) = (1 - exp(-x)) / x.
// Domain: f(x) >= min(1, 0.39 / x) > 0 for finite x >= 0.
float truncated_exponential_pdf(float x, float v) {
    return exp(-x * v) / one_minus_exp_over_x(x);
}

// The CDF (1 - exp(-x v)) / (1 - exp(-x)) = v f(x v) / f(x), without cancellation.
float invert_truncated_exponential(float x, float v) {
    // Domain: f(x) > 0 as above.
    return v * one_minus_exp_over_x(x * v) / one_minus_exp_over_x(x);
}

// ---------------------------------------------------------------------------------------
// Cosine-weighted hemisphere about unit n: density cos(theta) / pi in solid angle.

// Sample a direction; the (cos / pi) / pdf ratio is 1.
vec3 sample_cosine_hemisphere(vec3 n, vec2 u) {
    float r = sqrt(u.x);
    float phi = 2.0 * PI * u.y;
    vec3 t;
    vec3 b;
    orthonormal_basis(n, t, b);
    float z = sqrt(max(0.0, 1.0 - u.x));
    return normalize(r * cos(phi) * t + r * sin(phi) * b + z * n);
}

// Density at a direction with cos(theta) = cos_theta about n.
float cosine_hemisphere_pdf(float cos_theta) {
    return max(cos_theta, 0.0) * INV_PI;
}

// u of unit w: u.x = sin^2(theta), the squared length of w's part across n.
vec2 invert_cosine_hemisphere(vec3 n, vec3 w) {
    vec3 t;
    vec3 b;
    orthonormal_basis(n, t, b);
    float x = dot(w, t);
    float y = dot(w, b);
    return vec2(min(x * x + y * y, 1.0), azimuth_fraction(y, x));
}

// ---------------------------------------------------------------------------------------
// Uniform sphere, Y up: cos(theta) = w.y = 1 - 2 u.x, phi = 2 pi u.y from +X towards +Z.

vec3 sample_uniform_sphere(vec2 u) {
    float z = 1.0 - 2.0 * u.x;
    float r = sqrt(max(0.0, 1.0 - z * z));
    float phi = 2.0 * PI * u.y;
    return vec3(r * cos(phi), z, r * sin(phi));
}

float uniform_sphere_pdf() {
    return INV_4PI;
}

vec2 invert_uniform_sphere(vec3 w) {
    return vec2(clamp(0.5 * (1.0 - w.y), 0.0, 1.0), azimuth_fraction(w.z, w.x));
}

// ---------------------------------------------------------------------------------------
// Uniform cone about unit `axis` with half-angle theta_max, given as
// one_minus_cos_max = 1 - cos(theta_max) in (0, 2] (narrow cones keep their digits).

vec3 sample_uniform_cone(vec3 axis, float one_minus_cos_max, vec2 u) {
    return spherical_direction(axis, 1.0 - u.x * one_minus_cos_max, 2.0 * PI * u.y);
}

// Density in solid angle inside the cone. Domain: one_minus_cos_max > 0.
float uniform_cone_pdf(float one_minus_cos_max) {
    return 1.0 / (2.0 * PI * one_minus_cos_max);
}

// u of unit w inside the cone: 1 - cos(theta) = |w - axis|^2 / 2 without cancellation.
vec2 invert_uniform_cone(vec3 axis, float one_minus_cos_max, vec3 w) {
    vec3 dw = w - axis;
    // Domain: one_minus_cos_max > 0.
    float ux = 0.5 * dot(dw, dw) / one_minus_cos_max;
    return vec2(clamp(ux, 0.0, 1.0), invert_azimuth(axis, w));
}

#endif
