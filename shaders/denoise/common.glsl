// Shared by the denoiser's stages (prepare, variance, atrous, final): the push constants,
// the pixel helpers and the edge-stopping weights. src/denoise/mod.rs describes the
// algorithm (SVGF: Schied et al. 2017, "Spatiotemporal Variance-Guided Filtering") and
// its parameters; the buffers are bound at the DENOISE_* numbers of
// src/shader_data/contract/bindings.rs, the flags are the DENOISE_* constants of
// src/shader_data/contract/records.rs.
#ifndef NIMBUS_DENOISE_COMMON_GLSL
#define NIMBUS_DENOISE_COMMON_GLSL

#include "features.glsl"
#include "bindings.glsl"
#include "gpu_records.glsl"

layout(local_size_x = GROUP_SIZE_X, local_size_y = GROUP_SIZE_Y) in;

layout(push_constant) uniform PushBlock {
    DenoisePush u_push;
};

bool has(uint flag) {
    return (u_push.flags & flag) != 0u;
}

bool inside(ivec2 p) {
    return p.x >= 0 && p.y >= 0 && p.x < int(u_push.width) && p.y < int(u_push.height);
}

uint pixel_index(ivec2 p) {
    return uint(p.y) * u_push.width + uint(p.x);
}

// Rec. 709 luminance of linear RGB.
float luminance(vec3 c) {
    return dot(c, vec3(0.2126, 0.7152, 0.0722));
}

// What the colour is divided by before filtering and multiplied by after: the albedo
// per channel where it is at least albedo_epsilon (1 elsewhere, and without an albedo).
vec3 albedo_factor(vec3 albedo) {
    bvec3 use = greaterThanEqual(albedo, vec3(u_push.albedo_epsilon));
    return vec3(use.x ? albedo.x : 1.0, use.y ? albedo.y : 1.0, use.z ? albedo.z : 1.0);
}

// The edge-stopping weight of pixel q seen from pixel p, `offset` = q - p in pixels, from
// the guides (normal xyz, depth w; depth < 0: nothing there) and p's depth gradient:
//   depth: exp(-|z_p - z_q| / (sigma_depth |grad z_p . offset| + depth_relative z_p |offset|)),
//          0 between a pixel with a depth and one without;
//   normal: max(0, n_p . n_q)^sigma_normal, 1 where either normal is zero (unknown).
float geometry_weight(vec4 gp, vec2 grad_p, vec4 gq, vec2 offset) {
    float w = 1.0;
    if (has(DENOISE_HAS_DEPTH)) {
        bool dp = gp.w >= 0.0;
        bool dq = gq.w >= 0.0;
        if (dp != dq) {
            return 0.0;
        }
        if (dp) {
            float scale = u_push.sigma_depth * abs(dot(grad_p, offset))
                + u_push.depth_relative * gp.w * length(offset) + 1e-6;
            w *= exp(-abs(gp.w - gq.w) / scale);
        }
    }
    if (has(DENOISE_HAS_NORMAL)) {
        float lp = dot(gp.xyz, gp.xyz);
        float lq = dot(gq.xyz, gq.xyz);
        if (lp > 0.0 && lq > 0.0) {
            float c = max(0.0, dot(gp.xyz, gq.xyz) * inversesqrt(lp * lq));
            w *= pow(c, u_push.sigma_normal);
        }
    }
    return w;
}

// 0 for NaN and infinities: one bad input pixel must not spread over the image.
float finite_or_zero(float x) {
    return (isnan(x) || isinf(x)) ? 0.0 : x;
}

vec4 finite_or_zero(vec4 v) {
    return vec4(finite_or_zero(v.x), finite_or_zero(v.y), finite_or_zero(v.z), finite_or_zero(v.w));
}

#endif
