// Environment map: the equirectangular mapping of docs/scene-format.md, nearest-texel
// lookup and importance sampling, mirroring crates/nimbus-scene/src/envmap.rs
// (`direction_to_uv`, `uv_to_direction`, `EnvMap::lookup`, `EnvSampler::sample`/`pdf`).
//
// The includer declares, BEFORE including this file:
//   layout(set = 0, binding = BINDING_ENV_TEXELS) readonly buffer EnvTexelBlock { vec4 env_texels[]; };
//       rgb radiance (already × scale), row-major, row 0 = top (v = 0, +Y); W·H entries.
//   layout(set = 0, binding = BINDING_ENV_CDF) readonly buffer EnvCdfBlock { float env_cdf[]; };
//       `EnvSampler::to_gpu_tables`: the marginal CDF (H + 1 entries) followed by the H
//       conditional rows (W + 1 entries each, row y at H + 1 + y·(W + 1)).
//   #define ENV_SIZE <uvec2 expression giving (W, H)>
//
// Mapping: u = 0.5 + atan2(d.x, −d.z)/(2π) ∈ [0, 1), v = acos(d.y/|d|)/π ∈ [0, 1], v = 0
// top. θ is computed as atan2(|d.xz|, d.y), which equals acos(d.y/|d|) but is well
// conditioned at the poles. Sampling is pbrt's PiecewiseConstant2D: the row from the
// marginal CDF with u.y, the column from the row's conditional CDF with u.x, each by
// "last entry <= u" and linear interpolation inside the texel. The solid-angle pdf is
// p(u, v) / (2π² sin θ), p(u, v) = W·H·(m[y+1] − m[y])·(c[x+1] − c[x]); it is 0 at the
// poles (sin θ = 0) and in zero-weight texels, and a caller must then discard the sample.
//
// An all-black map still has valid (fallback, sin θ-weighted) tables, so everything here
// stays finite; the renderer should skip the light when `EnvSampler::is_black()`.
//
// Rotation (`rotation_deg` θ, `EnvRotation` of envmap.rs): the map turned about world +Y,
// right-handed (positive θ turns +X towards −Z), given as rot = (cos θ, sin θ). The
// *_rotated functions look up and evaluate the pdf of world direction d at
// d_map = R_y(−θ) d, and sample d_map from the tables and return R_y(θ) d_map (a turn
// keeps solid angle: the pdf is the map's). rot = (1, 0) exactly skips the turn, so an
// unturned map renders bit for bit as without these functions.
#ifndef NIMBUS_ENVMAP_GLSL
#define NIMBUS_ENVMAP_GLSL

#include "constants.glsl"

// The largest float below 1, where a sample in [0, 1) is clamped.
#define ENV_ONE_MINUS_EPSILON uintBitsToFloat(0x3f7fffffu)

// sin θ and the (u, v) of direction d (need not be normalized). A zero or non-finite d
// maps to (0.5, 0) (+Y) with sin θ = 0, so nothing here is ever NaN.
// At the poles (d.x = d.z = 0) u follows the CPU's atan2 on signed zeros: atan2(±0, −0)
// = ±π gives u = 0 when d.z = +0, atan2(±0, +0) = ±0 gives u = 0.5 when d.z = −0.
void env_direction_to_uv_sin(vec3 d, out vec2 uv, out float sin_theta) {
    uv = vec2(0.5, 0.0);
    sin_theta = 0.0;
    if (any(isnan(d)) || any(isinf(d))) {
        return;
    }
    float m = max(abs(d.x), max(abs(d.y), abs(d.z)));
    if (!(m > 0.0)) {
        return;
    }
    // m > 0 and finite: scaling by 1/m keeps |d| in [1, √3], so no overflow or underflow.
    d /= m;
    float r = length(d.xz);
    float len = length(d);  // >= 1
    sin_theta = r / len;    // len >= 1
    float theta;
    float u;
    if (r > 0.0) {
        // atan(y, x) is defined for (x, y) != (0, 0); here y = r > 0, so θ ∈ (0, π).
        theta = atan(r, d.y);
        // (d.x, −d.z) != (0, 0) since r > 0.
        u = 0.5 + atan(d.x, -d.z) * (0.5 * INV_PI);
    } else {
        theta = d.y > 0.0 ? 0.0 : PI;
        u = (floatBitsToUint(d.z) & 0x80000000u) == 0u ? 0.0 : 0.5;
    }
    if (u >= 1.0) {
        u -= 1.0;
    }
    uv = vec2(max(u, 0.0), clamp(theta * INV_PI, 0.0, 1.0));
}

vec2 env_direction_to_uv(vec3 d) {
    vec2 uv;
    float sin_theta;
    env_direction_to_uv_sin(d, uv, sin_theta);
    return uv;
}

// The unit direction with φ = 2π(u − 0.5), θ = πv: (sin θ sin φ, cos θ, −sin θ cos φ).
// u wraps (any u); v is clamped to [0, 1] (NaN → 0); v = 0 / 1 give exactly +Y / −Y.
vec3 env_uv_to_direction(vec2 uv) {
    float v = isnan(uv.y) ? 0.0 : clamp(uv.y, 0.0, 1.0);
    if (v == 0.0) {
        return vec3(0.0, 1.0, 0.0);
    }
    if (v == 1.0) {
        return vec3(0.0, -1.0, 0.0);
    }
    float u = isnan(uv.x) || isinf(uv.x) ? 0.5 : uv.x;
    // sin θ from the nearer pole keeps its relative precision near v = 1 too.
    float sin_theta = sin(PI * min(v, 1.0 - v));
    float cos_theta = cos(PI * v);
    float phi = 2.0 * PI * (fract(u) - 0.5);
    return vec3(sin_theta * sin(phi), cos_theta, -sin_theta * cos(phi));
}

// Texel (x, y) of (u, v) ∈ [0, 1) × [0, 1]: x = ⌊uW⌋, y = ⌊vH⌋ clamped to the last row.
// u < 1, so x < W except when u·W rounds up to W in f32; that is clamped to W − 1 (the
// CPU's f64 x for such u), not wrapped. Requires W, H >= 1.
uvec2 env_texel_of_uv(vec2 uv) {
    uvec2 size = ENV_SIZE;
    uint x = min(uint(max(floor(uv.x * float(size.x)), 0.0)), size.x - 1u);
    uint y = min(uint(max(floor(uv.y * float(size.y)), 0.0)), size.y - 1u);
    return uvec2(x, y);
}

vec3 env_texel(uvec2 t) {
    return env_texels[t.y * ENV_SIZE.x + t.x].rgb;
}

// Radiance seen along d (the escaping ray's direction): the nearest texel, as
// EnvMap::lookup. Black for an empty map.
vec3 env_lookup(vec3 d) {
    uvec2 size = ENV_SIZE;
    if (size.x == 0u || size.y == 0u) {
        return vec3(0.0);
    }
    return env_texel(env_texel_of_uv(env_direction_to_uv(d)));
}

// The background a camera ray sees along d: the map interpolated bilinearly between
// texel centres (wrapping in u, clamped at the first and last rows), as
// EnvMap::lookup_bilinear. Only the camera's own escaping rays use it; light reaching the
// scene keeps env_lookup, the piecewise-constant function the sampler's pdf follows.
vec3 env_lookup_bilinear(vec3 d) {
    uvec2 size = ENV_SIZE;
    if (size.x == 0u || size.y == 0u) {
        return vec3(0.0);
    }
    vec2 uv = env_direction_to_uv(d);
    float x = uv.x * float(size.x) - 0.5;
    float y = clamp(uv.y * float(size.y) - 0.5, 0.0, float(size.y - 1u));
    float x0 = floor(x);
    float y0 = floor(y);
    float fx = x - x0;
    float fy = y - y0;
    // x ∈ [−0.5, W − 0.5): the column left of the point is −1 (the last one, wrapped)
    // up to W − 1 (min: u·W rounding up in f32). No % on a negative int: GLSL leaves it
    // undefined.
    int xi = int(x0);
    uint xa = xi < 0 ? size.x - 1u : min(uint(xi), size.x - 1u);
    uint xb = xa + 1u == size.x ? 0u : xa + 1u;
    uint ya = min(uint(y0), size.y - 1u);
    uint yb = min(ya + 1u, size.y - 1u);
    vec3 top = mix(env_texel(uvec2(xa, ya)), env_texel(uvec2(xb, ya)), fx);
    vec3 bottom = mix(env_texel(uvec2(xa, yb)), env_texel(uvec2(xb, yb)), fx);
    return mix(top, bottom, fy);
}

// The segment o ∈ [0, n) of the CDF at env_cdf[base .. base + n] with cdf[o] <= u <
// cdf[o + 1] (the last entry <= u, so never a zero-width one), and the fraction du ∈
// [0, 1) of u inside it. cdf[base] = 0 and u >= 0, so o exists.
uint env_sample_cdf(uint base, uint n, float u, out float du) {
    u = clamp(u, 0.0, ENV_ONE_MINUS_EPSILON);
    // Invariant: cdf[lo] <= u, and cdf[i] > u for every i in [hi, n).
    uint lo = 0u;
    uint hi = n;
    while (hi - lo > 1u) {
        uint mid = (lo + hi) / 2u;
        if (env_cdf[base + mid] <= u) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    float c0 = env_cdf[base + lo];
    float width = env_cdf[base + lo + 1u] - c0;
    // width > 0: u lies in [c0, c0 + width) by the search.
    du = width > 0.0 ? min((u - c0) / width, ENV_ONE_MINUS_EPSILON) : 0.0;
    return lo;
}

// p(u, v) of texel t: W·H·(m[y+1] − m[y])·(c[x+1] − c[x]).
float env_pdf_uv_texel(uvec2 t) {
    uvec2 size = ENV_SIZE;
    uint row = size.y + 1u + t.y * (size.x + 1u);
    float dm = env_cdf[t.y + 1u] - env_cdf[t.y];
    float dc = env_cdf[row + t.x + 1u] - env_cdf[row + t.x];
    return float(size.x) * float(size.y) * dm * dc;
}

// Samples a direction from u ∈ [0, 1)² (u.y picks the row, u.x the column), as
// EnvSampler::sample. Returns the radiance of the sampled texel (the texel the pdf is
// computed for; env_lookup(dir) agrees except within f32 rounding of a texel edge),
// the unit direction and its solid-angle pdf. pdf = 0 (at an exact pole, or an empty
// map) ⇒ the caller discards the sample.
vec3 env_sample(vec2 u, out vec3 dir, out float pdf_solid_angle) {
    uvec2 size = ENV_SIZE;
    dir = vec3(0.0, 1.0, 0.0);
    pdf_solid_angle = 0.0;
    if (size.x == 0u || size.y == 0u) {
        return vec3(0.0);
    }
    float dv;
    uint y = env_sample_cdf(0u, size.y, u.y, dv);
    float du;
    uint x = env_sample_cdf(size.y + 1u + y * (size.x + 1u), size.x, u.x, du);
    // W, H >= 1.
    vec2 uv = vec2((float(x) + du) / float(size.x), (float(y) + dv) / float(size.y));
    dir = env_uv_to_direction(uv);
    // dir is unit length: sin θ = |dir.xz|.
    float sin_theta = length(dir.xz);
    if (!(sin_theta > 0.0)) {
        return env_texel(uvec2(x, y));
    }
    // dω = 2π² sin θ du dv; sin_theta > 0.
    pdf_solid_angle = env_pdf_uv_texel(uvec2(x, y)) / (2.0 * PI * PI * sin_theta);
    return env_texel(uvec2(x, y));
}

// The solid-angle pdf of env_sample returning d (need not be normalized), as
// EnvSampler::pdf: 0 at the poles, for zero or non-finite d, in zero-weight texels and
// for an empty map.
float env_pdf(vec3 d) {
    uvec2 size = ENV_SIZE;
    if (size.x == 0u || size.y == 0u) {
        return 0.0;
    }
    vec2 uv;
    float sin_theta;
    env_direction_to_uv_sin(d, uv, sin_theta);
    if (!(sin_theta > 0.0)) {
        return 0.0;
    }
    // sin_theta > 0.
    return env_pdf_uv_texel(env_texel_of_uv(uv)) / (2.0 * PI * PI * sin_theta);
}

// Whether rot = (cos θ, sin θ) turns anything (exactly (1, 0) does not).
bool env_turned(vec2 rot) {
    return rot.y != 0.0 || rot.x != 1.0;
}

// The map's direction of world direction d: R_y(−θ) d.
vec3 env_world_to_map(vec3 d, vec2 rot) {
    if (!env_turned(rot)) {
        return d;
    }
    return vec3(rot.x * d.x - rot.y * d.z, d.y, rot.y * d.x + rot.x * d.z);
}

// The world direction of the map's direction d: R_y(θ) d.
vec3 env_map_to_world(vec3 d, vec2 rot) {
    if (!env_turned(rot)) {
        return d;
    }
    return vec3(rot.x * d.x + rot.y * d.z, d.y, rot.x * d.z - rot.y * d.x);
}

// env_lookup of the map turned by rot.
vec3 env_lookup_rotated(vec3 d, vec2 rot) {
    return env_lookup(env_world_to_map(d, rot));
}

// env_lookup_bilinear of the map turned by rot: the camera's background.
vec3 env_background_rotated(vec3 d, vec2 rot) {
    return env_lookup_bilinear(env_world_to_map(d, rot));
}

// env_pdf of the map turned by rot.
float env_pdf_rotated(vec3 d, vec2 rot) {
    return env_pdf(env_world_to_map(d, rot));
}

// env_sample of the map turned by rot: dir is in the world.
vec3 env_sample_rotated(vec2 u, vec2 rot, out vec3 dir, out float pdf_solid_angle) {
    vec3 L = env_sample(u, dir, pdf_solid_angle);
    dir = env_map_to_world(dir, rot);
    return L;
}

#endif
