#version 460
// Denoiser stage 1, one invocation per pixel: demodulates the noisy colour by the albedo
// guide, derives the depth gradient, accumulates the colour and its luminance moments
// over time through the motion guide (when the temporal history is on), and takes the
// per-pixel luminance variance from the film (two or more estimates) or from the
// temporal moments (four or more frames of history); elsewhere it writes -1 and
// variance.comp estimates it spatially.

#extension GL_GOOGLE_include_directive : require

#include "common.glsl"

layout(std430, set = 0, binding = BINDING_DENOISE_NOISY) readonly buffer NoisyBlock {
    vec4 noisy[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_FILM_VARIANCE) readonly buffer FilmVarianceBlock {
    vec4 film_variance[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_GUIDES) readonly buffer GuidesBlock {
    vec4 guides[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_ALBEDO) readonly buffer AlbedoBlock {
    vec4 albedo[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_MOTION) readonly buffer MotionBlock {
    vec2 motion[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_GRADIENT) writeonly buffer GradientBlock {
    vec2 gradient[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_COLOR_DST) writeonly buffer ColorDstBlock {
    vec4 color_dst[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_VARIANCE_DST) writeonly buffer VarianceDstBlock {
    float variance_dst[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_HISTORY) readonly buffer HistoryBlock {
    vec4 history[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_MOMENTS) writeonly buffer MomentsBlock {
    vec4 moments_out[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_MOMENTS_PREV) readonly buffer MomentsPrevBlock {
    vec4 moments_prev[];
};
layout(std430, set = 0, binding = BINDING_DENOISE_GUIDES_PREV) readonly buffer GuidesPrevBlock {
    vec4 guides_prev[];
};

// The depth at q, or -1 outside the image.
float depth_at(ivec2 q) {
    return inside(q) ? guides[pixel_index(q)].w : -1.0;
}

// The depth's change per pixel along `axis`: of the one-sided differences towards both
// neighbours with a depth, the smaller (so that an edge does not make its own side look
// steep); 0 where neither neighbour has one.
float depth_slope(ivec2 p, float z, ivec2 axis) {
    float a = depth_at(p + axis);
    float b = depth_at(p - axis);
    float da = a >= 0.0 ? a - z : 1e30;
    float db = b >= 0.0 ? z - b : 1e30;
    float d = abs(da) < abs(db) ? da : db;
    return abs(d) < 1e29 ? d : 0.0;
}

// Whether the previous frame's pixel q shows the same surface as this frame's pixel i.
bool consistent(vec4 g, ivec2 q) {
    vec4 h = guides_prev[pixel_index(q)];
    if (has(DENOISE_HAS_DEPTH)) {
        if ((g.w >= 0.0) != (h.w >= 0.0)) {
            return false;
        }
        if (g.w >= 0.0 && abs(g.w - h.w) > 0.1 * max(g.w, 1e-6)) {
            return false;
        }
    }
    if (has(DENOISE_HAS_NORMAL)) {
        float lg = dot(g.xyz, g.xyz);
        float lh = dot(h.xyz, h.xyz);
        if ((lg > 0.0) != (lh > 0.0)) {
            return false;
        }
        if (lg > 0.0 && dot(g.xyz, h.xyz) * inversesqrt(lg * lh) < 0.9) {
            return false;
        }
    }
    return true;
}

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (!inside(p)) {
        return;
    }
    uint i = pixel_index(p);
    vec3 a = has(DENOISE_HAS_ALBEDO) ? albedo_factor(finite_or_zero(albedo[i]).rgb) : vec3(1.0);
    vec4 c = finite_or_zero(noisy[i]);
    vec4 d = vec4(c.rgb / a, c.a);
    float l = luminance(d.rgb);

    vec4 g = has(DENOISE_HAS_DEPTH) || has(DENOISE_HAS_NORMAL) ? guides[i] : vec4(0.0, 0.0, 0.0, -1.0);
    if (has(DENOISE_HAS_DEPTH)) {
        vec2 grad = g.w >= 0.0
            ? vec2(depth_slope(p, g.w, ivec2(1, 0)), depth_slope(p, g.w, ivec2(0, 1)))
            : vec2(0.0);
        gradient[i] = grad;
    }

    // Temporal accumulation: the history reprojected bilinearly, taps that show another
    // surface left out; no usable tap restarts the pixel's history.
    float len = 1.0;
    // The weight of this frame in the integrated colour (1: no history).
    float alpha = 1.0;
    vec4 integrated = d;
    vec2 m = vec2(l, l * l);
    if (has(DENOISE_TEMPORAL)) {
        if (has(DENOISE_HISTORY)) {
            vec2 mv = has(DENOISE_HAS_MOTION) ? motion[i] : vec2(0.0);
            vec2 previous = vec2(p) - finite_or_zero(vec4(mv, 0.0, 0.0)).xy;
            ivec2 base = ivec2(floor(previous));
            vec2 f = previous - vec2(base);
            float w_sum = 0.0;
            vec4 h_color = vec4(0.0);
            vec3 h_moments = vec3(0.0);
            for (int k = 0; k < 4; ++k) {
                ivec2 o = ivec2(k & 1, k >> 1);
                ivec2 q = base + o;
                float w = (o.x == 1 ? f.x : 1.0 - f.x) * (o.y == 1 ? f.y : 1.0 - f.y);
                if (w <= 0.0 || !inside(q) || !consistent(g, q)) {
                    continue;
                }
                uint j = pixel_index(q);
                h_color += w * history[j];
                h_moments += w * moments_prev[j].xyz;
                w_sum += w;
            }
            if (w_sum > 0.01) {
                h_color /= w_sum;
                h_moments /= w_sum;
                len = min(h_moments.z + 1.0, u_push.max_history);
                alpha = max(u_push.temporal_alpha, 1.0 / len);
                float alpha_m = max(u_push.moments_alpha, 1.0 / len);
                integrated = mix(h_color, d, alpha);
                m = mix(h_moments.xy, m, alpha_m);
            }
        }
        moments_out[i] = vec4(m, len, 0.0);
    }
    color_dst[i] = integrated;

    float variance = -1.0;
    if (has(DENOISE_FILM_VARIANCE)) {
        // Standard errors of the demodulated channels, combined as if fully correlated
        // (a grey medium's channels are): an upper bound of the luminance's.
        vec4 v = finite_or_zero(film_variance[i]);
        vec3 s = sqrt(max(v.rgb, vec3(0.0))) / a;
        float sl = luminance(s);
        variance = sl * sl;
    } else if (has(DENOISE_TEMPORAL) && len >= 4.0) {
        // The moments give one frame's variance; the moving average's is
        // alpha / (2 - alpha) of it (the steady state of an exponential average).
        variance = max(0.0, m.y - m.x * m.x) * alpha / (2.0 - alpha);
    }
    variance_dst[i] = variance;
}
