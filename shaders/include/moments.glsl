// Moment shadow maps of the directional lights, for the ME estimator of the crepuscular
// pass (Velinov & Mitchell, Sec. 8, after Peters et al. 2017, "Improved moment shadow
// maps for translucent occluders, soft shadows and single scattering").
//
// Each light l has an orthographic map perpendicular to its travel direction omega over
// the box media's footprint (MomentFrame in scene.glsl, built on the host). A texel keeps
// the four moments b = (z, z², z³, z⁴) of the normalised depth z of the first shape the
// light meets there, averaged over MOMENT_MAP_RAYS² stratified rays (1 where nothing
// stops the light before the media's downstream end), and a mip chain of 2x2 averages
// prefilters it. Depth z = omega . x is normalised so that the media span [0.1, 0.9]:
// shapes upstream of every medium fall in [0, 0.1), clamped at 0.
//
// A point at normalised depth z is in shadow where an occluder lies upstream of it
// (z_occ < z); over a filter region the fraction in shadow is the probability of
// z_occ < z under the texels' depth distribution. From four moments that probability is
// not determined: Hamburger four-moment shadow mapping (Peters & Klein 2015, Alg. 2)
// returns its sharpest lower bound, after biasing the moments towards those of a
// uniform distribution (MSM_MOMENT_BIAS) so that the Hankel matrix stays invertible.
//
// The map's texels live in one storage buffer: light l's levels follow each other from
// l * moment_texels_per_light on, level k having (size >> k)² texels.
#ifndef NIMBUS_MOMENTS_GLSL
#define NIMBUS_MOMENTS_GLSL

#include "bindings.glsl"
#include "scene.glsl"

// Weight of the uniform distribution's moments mixed into every reconstruction. 3e-5 is
// Peters & Klein's choice for 32-bit float moments with depths in [0, 1]; smaller values
// sharpen shadows and let float rounding make the Hankel matrix singular.
#define MSM_MOMENT_BIAS 3e-4

layout(std430, set = 0, binding = BINDING_MOMENT_FRAMES) readonly buffer MomentFramesBlock {
    MomentFrame moment_frames[];
};

// The moments (z, z², z³, z⁴) of normalised depth z.
vec4 depth_moments(float z) {
    float z2 = z * z;
    return vec4(z, z2, z2 * z, z2 * z2);
}

// Normalised depth of world depth `depth` in light frame f: the media span [0.1, 0.9].
float moment_depth(MomentFrame f, float depth) {
    // Domain: depth_far > depth_near (the host keeps the span positive).
    return clamp(0.1 + 0.8 * (depth - f.depth_near) / (f.depth_far - f.depth_near), 0.05, 1.0);
}

// Level-0 texel coordinates (continuous, texel centres at k + 0.5) of point x in map f.
vec2 moment_texel(MomentFrame f, vec3 x) {
    return vec2((dot(x, f.u_axis) - f.u_min) * f.texels_u, (dot(x, f.v_axis) - f.v_min) * f.texels_v);
}

// Shadow intensity (0 lit .. 1 shadowed) of a point at normalised depth z given the
// filtered moments b: the sharpest lower bound of P(z_occ < z) compatible with b
// (Hamburger 4MSM). Always finite and in [0, 1]: where rounding breaks the
// reconstruction it falls back to comparing z with the mean depth. Exactly 0 where every
// filtered texel is unoccluded.
float msm_shadow_intensity(vec4 b, float z) {
    // Every texel unoccluded (depth 1; bilinear weights round the mean to 1 - 6e-8): no
    // shadow, without the bias's faint one, so that ME is the analytic integral wherever
    // nothing can shadow the medium. Occluders cover at most 1e-5 of such a footprint.
    if (b.x >= 1.0 - 1e-5) {
        return 0.0;
    }
    // Every filtered texel holds one occluder depth (variance at rounding level): a hard
    // comparison, without the bias's leak. Behind a wall with a window, most of a medium
    // lies in such full shadow, and the bias let about 1 % of its unoccluded radiance
    // through everywhere: +11 % on a whole image whose light comes through the window.
    if (fma(-b.x, b.x, b.y) <= 1e-6 * max(b.y, 1e-6)) {
        return z > b.x ? 1.0 : 0.0;
    }
    b = mix(b, vec4(0.5), MSM_MOMENT_BIAS);
    // Cholesky factorisation of the Hankel matrix B = [1 b1 b2; b1 b2 b3; b2 b3 b4].
    float L32D22 = fma(-b.x, b.y, b.z);
    float D22 = fma(-b.x, b.x, b.y);
    float squared_depth_variance = fma(-b.y, b.y, b.w);
    float D33D22 = dot(vec2(squared_depth_variance, -L32D22), vec2(D22, L32D22));
    float fallback = z > b.x ? 1.0 : 0.0;
    if (!(D22 > 0.0) || !(D33D22 > 0.0)) {
        return fallback;
    }
    float inv_D22 = 1.0 / D22;
    float L32 = L32D22 * inv_D22;
    // Solve B c = (1, z, z²) by forward substitution, scaling and back substitution.
    vec3 c = vec3(1.0, z, z * z);
    c.y -= b.x;
    c.z -= b.y + L32 * c.y;
    c.y *= inv_D22;
    c.z *= D22 / D33D22;
    c.y -= L32 * c.z;
    c.x -= dot(c.yz, b.xy);
    // The roots z1 <= z2 of c.x + c.y t + c.z t² (the other two support points).
    if (c.z == 0.0) {
        return fallback;
    }
    float p = c.y / c.z;
    float q = c.x / c.z;
    float r = sqrt(max(p * p * 0.25 - q, 0.0));
    float z1 = -p * 0.5 - r;
    float z2 = -p * 0.5 + r;
    vec4 s = (z2 < z) ? vec4(z1, z, 1.0, 1.0) : ((z1 < z) ? vec4(z, z1, 0.0, 1.0) : vec4(0.0));
    float denom = (z2 - s.y) * (z - z1);
    if (s.w == 0.0) {
        return 0.0;
    }
    float intensity = s.z + s.w * (s.x * z2 - b.x * (s.x + z2) + b.y) / denom;
    return (isnan(intensity) || isinf(intensity)) ? fallback : clamp(intensity, 0.0, 1.0);
}

#endif

// ---------------------------------------------------------------------------------------
// Lookups (the crepuscular pass); the moment-map pass declares the buffer writable itself.
#ifndef MOMENT_MAP_WRITER
#ifndef NIMBUS_MOMENT_LOOKUP_GLSL
#define NIMBUS_MOMENT_LOOKUP_GLSL

layout(std430, set = 0, binding = BINDING_MOMENT_MAP) readonly buffer MomentMapBlock {
    vec4 moment_map[];
};

// Index of the first texel of level k of map f.
uint moment_level_first(MomentFrame f, uint k) {
    uint first = f.first;
    for (uint i = 0u; i < k; ++i) {
        uint s = f.size >> i;
        first += s * s;
    }
    return first;
}

// The moments of map f at level k, bilinear between texel centres, at level-0 texel
// coordinates uv (clamped to the map's edge texels).
vec4 moment_fetch(MomentFrame f, uint k, vec2 uv) {
    uint size = max(f.size >> k, 1u);
    uint first = moment_level_first(f, k);
    vec2 p = uv / float(1u << k) - 0.5;
    vec2 base = floor(p);
    vec2 w = p - base;
    ivec2 i0 = clamp(ivec2(base), ivec2(0), ivec2(int(size) - 1));
    ivec2 i1 = clamp(ivec2(base) + 1, ivec2(0), ivec2(int(size) - 1));
    vec4 m00 = moment_map[first + uint(i0.y) * size + uint(i0.x)];
    vec4 m10 = moment_map[first + uint(i0.y) * size + uint(i1.x)];
    vec4 m01 = moment_map[first + uint(i1.y) * size + uint(i0.x)];
    vec4 m11 = moment_map[first + uint(i1.y) * size + uint(i1.x)];
    return mix(mix(m00, m10, w.x), mix(m01, m11, w.x), w.y);
}

#endif
#endif
