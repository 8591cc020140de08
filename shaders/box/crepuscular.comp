#version 460
// Crepuscular rays in homogeneous box media under collimated light (Velinov &
// Mitchell). One invocation per pixel; `spp` camera paths per pixel per frame, each
// jittered over the pixel footprint, accumulate into the running sums.
//
// Along every path segment inside a box the single-scattered light is estimated with
// N = `box_samples` samples by one of the paper's estimators (SC_ESTIMATOR):
//   MCWVDS  Monte Carlo with whole-volume distance sampling (Sec. 5-6): distances
//           drawn in proportion to the unoccluded integrand, so the estimate is the
//           analytic unoccluded radiance times the mean visibility.
//   REDS    ratio estimator, distance sampling: analytic unoccluded radiance times
//           (occluded estimate / unoccluded estimate) from the same samples.
//   REES    ratio estimator, equidistant jittered samples.
//   RM      ray marching: equidistant jittered samples.
//   MCDS    Monte Carlo with distance sampling along the camera ray only.
// Each sample picks one directional light in proportion to its analytic unoccluded
// radiance along this segment (Sec. 4, multiple lights). A gobo offsets and limits the
// integration to the part of the segment inside its prism, for every estimator.
//
// With SC_MAX_BOUNCES = K > 1 the camera ray continues as a path: a free-flight
// collision (or a Lambertian surface) starts the next segment, whose single-scattered
// light again comes from the estimator, so scattering orders 1..K are summed.

#extension GL_GOOGLE_include_directive : require

#include "features.glsl"
#include "bindings.glsl"
#include "constants.glsl"
#include "scene.glsl"
#include "rng.glsl"
#include "phase.glsl"
#include "sampling.glsl"
#include "geometry.glsl"
#include "box_analytic.glsl"
#include "path.glsl"

layout(local_size_x = GROUP_SIZE_X, local_size_y = GROUP_SIZE_Y) in;

// Features the render plan switches per scene.
layout(constant_id = SC_ID_HAS_SHAPES) const bool SC_HAS_SHAPES = true;
layout(constant_id = SC_ID_HAS_GOBOS) const bool SC_HAS_GOBOS = true;
layout(constant_id = SC_ID_HAS_ENV) const bool SC_HAS_ENV = true;
layout(constant_id = SC_ID_ESTIMATOR) const uint SC_ESTIMATOR = 0u;
layout(constant_id = SC_ID_HAS_MEDIA) const bool SC_HAS_MEDIA = true;
layout(constant_id = SC_ID_MAX_BOUNCES) const uint SC_MAX_BOUNCES = 1u;
layout(constant_id = SC_ID_PIXEL_JITTER) const bool SC_PIXEL_JITTER = true;

layout(std140, set = 0, binding = BINDING_FRAME_UNIFORMS) uniform FrameBlock {
    FrameUniforms u_frame;
};
layout(push_constant) uniform PushBlock {
    PassPush u_push;
};
layout(std430, set = 0, binding = BINDING_BOX_MEDIA) readonly buffer MediaBlock {
    BoxMedium media[];
};
layout(std430, set = 0, binding = BINDING_SHAPES) readonly buffer ShapesBlock {
    Shape shapes[];
};
layout(std430, set = 0, binding = BINDING_LIGHTS) readonly buffer LightsBlock {
    Light lights[];
};
layout(std430, set = 0, binding = BINDING_GOBO_PLANES) readonly buffer GoboBlock {
    vec4 gobo_planes[]; // (a, b, c, 0): a point (u, v) is inside when a u + b v + c >= 0
};

#include "film.glsl"
#include "shapes.glsl"
#include "box_media.glsl"

// Whether x lies inside light l's gobo prism (always true without a gobo).
bool inside_gobo(Light l, vec3 x) {
    if (!SC_HAS_GOBOS) {
        return true;
    }
    uint count = uint(l.gobo_origin.w);
    uint first = uint(l.gobo_u.w);
    vec3 p = x - l.gobo_origin.xyz;
    vec2 uv = vec2(dot(p, l.gobo_u.xyz), dot(p, l.gobo_v.xyz));
    for (uint i = 0u; i < count; ++i) {
        vec4 plane = gobo_planes[first + i];
        if (plane.x * uv.x + plane.y * uv.y + plane.z < 0.0) {
            return false;
        }
    }
    return true;
}

// Irradiance from light l arriving unscattered at x: E · gobo · visibility · T to the
// light. `t_min` offsets the shadow ray's start (0 inside media, > 0 on surfaces).
vec3 light_arriving(Light l, vec3 x, float t_min) {
    vec3 omega = l.direction_type.xyz;
    if (!inside_gobo(l, x)) {
        return vec3(0.0);
    }
    if (occluded(x, -omega, t_min)) {
        return vec3(0.0);
    }
    float tau = box_optical_depth(x, -omega, 0.0, FAR);
    return l.irradiance.rgb * exp(-tau);
}


// A direction in the frame of box medium bm.
vec3 to_local_dir(BoxMedium bm, vec3 v) {
    return vec3(dot(bm.world_to_local[0].xyz, v), dot(bm.world_to_local[1].xyz, v), dot(bm.world_to_local[2].xyz, v));
}

// A point in the frame of box medium bm.
vec3 to_local_point(BoxMedium bm, vec3 x) {
    return to_local_dir(bm, x - bm.center_sigma_t.xyz);
}

// The part of [t_a, t_b] where o + t d lies inside light l's gobo prism: each gobo
// half-plane is linear in t, alpha + beta t >= 0. Empty intervals have x > y.
vec2 gobo_interval(Light l, vec3 o, vec3 d, float t_a, float t_b) {
    if (!SC_HAS_GOBOS) {
        return vec2(t_a, t_b);
    }
    uint count = uint(l.gobo_origin.w);
    uint first = uint(l.gobo_u.w);
    vec3 p = o - l.gobo_origin.xyz;
    vec2 uv0 = vec2(dot(p, l.gobo_u.xyz), dot(p, l.gobo_v.xyz));
    vec2 uv_d = vec2(dot(d, l.gobo_u.xyz), dot(d, l.gobo_v.xyz));
    for (uint i = 0u; i < count; ++i) {
        vec4 plane = gobo_planes[first + i];
        float alpha = plane.x * uv0.x + plane.y * uv0.y + plane.z;
        float beta = plane.x * uv_d.x + plane.y * uv_d.y;
        if (abs(beta) < 1e-12) {
            // Parallel to this edge: wholly inside or wholly outside.
            if (alpha < 0.0) {
                return vec2(FAR, -FAR);
            }
            continue;
        }
        // Domain: |beta| >= 1e-12.
        float t_edge = -alpha / beta;
        if (beta > 0.0) {
            t_a = max(t_a, t_edge);
        } else {
            t_b = min(t_b, t_edge);
        }
    }
    return vec2(t_a, t_b);
}

// Shadow-ray factor at x towards light direction -omega: 0 behind a shape, else the
// transmittance of the box media other than `skip` (medium `skip` is analytic).
float light_visibility(vec3 x, vec3 omega, uint skip) {
    if (occluded(x, -omega, 0.0)) {
        return 0.0;
    }
    return exp(-box_optical_depth_except(x, -omega, 0.0, FAR, skip));
}

// The part of [t_enter, t_b] light l can reach (its gobo interval), empty as a
// zero-length interval at t_enter.
vec2 light_interval(Light l, vec3 o, vec3 d, float t_enter, float t_b) {
    vec2 iv = gobo_interval(l, o, d, t_enter, t_b);
    return iv.y > iv.x ? iv : vec2(t_enter, t_enter);
}

// The trapezoid pieces of light l along o + t d in box medium bm over the interval iv
// (camera transmittance from t_enter).
BoxPieces light_pieces(BoxMedium bm, Light l, vec3 o_local, vec3 d_local, float t_enter, vec2 iv) {
    vec3 omega_local = to_local_dir(bm, l.direction_type.xyz);
    return box_pieces(o_local, d_local, omega_local, bm.half_size_g.xyz, bm.center_sigma_t.w, t_enter, iv.x, iv.y);
}

// Pick a light in proportion to the weights `w` (sum `w_sum` > 0) with u in [0, 1).
uint select_light(float u, float w[MAX_LIGHTS], uint count, float w_sum, out float prob) {
    float target = u * w_sum;
    float acc = 0.0;
    uint chosen = NO_INDEX;
    for (uint l = 0u; l < count; ++l) {
        if (w[l] <= 0.0) {
            continue;
        }
        chosen = l;
        acc += w[l];
        if (target < acc) {
            break;
        }
    }
    // Domain: w_sum > 0, and the chosen light has w > 0.
    prob = w[chosen] / w_sum;
    return chosen;
}

// Single-scattered radiance towards o from box medium m along o + t d, t in
// [t_enter, t_b], by the estimator SC_ESTIMATOR with `box_samples` samples. Excludes
// the transmittance of other media between o and t_enter.
vec3 single_scatter_box(uint m, vec3 o, vec3 d, float t_enter, float t_b, inout uint rng) {
    BoxMedium bm = media[m];
    float sigma_t = bm.center_sigma_t.w;
    float g = bm.half_size_g.w;
    vec3 o_local = to_local_point(bm, o);
    vec3 d_local = to_local_dir(bm, d);

    // Analytic unoccluded radiance of every light (Eq. 6), the light-selection weights.
    uint light_count = min(u_frame.counts.z, MAX_LIGHTS);
    vec3 U[MAX_LIGHTS];
    float w[MAX_LIGHTS];
    vec2 interval[MAX_LIGHTS];
    vec3 U_total = vec3(0.0);
    float w_sum = 0.0;
    // MCWVDS keeps the pieces of the light it last sampled; start with the first.
    uint cached = NO_INDEX;
    BoxPieces pieces;
    for (uint l = 0u; l < light_count; ++l) {
        Light light = lights[l];
        interval[l] = light_interval(light, o, d, t_enter, t_b);
        BoxPieces p = light_pieces(bm, light, o_local, d_local, t_enter, interval[l]);
        if (l == 0u) {
            pieces = p;
            cached = 0u;
        }
        float phase = hg_phase(dot(light.direction_type.xyz, -d), g);
        U[l] = bm.sigma_s.rgb * phase * light.irradiance.rgb * p.total;
        w[l] = U[l].r + U[l].g + U[l].b;
        U_total += U[l];
        w_sum += w[l];
    }
    if (!(w_sum > 0.0)) {
        return vec3(0.0);
    }

    uint n = max(u_frame.counts.w, 1u);
    vec3 sum = vec3(0.0);
    vec3 num = vec3(0.0);
    vec3 den = vec3(0.0);
    for (uint k = 0u; k < n; ++k) {
        float prob;
        uint l = select_light(rng_next(rng), w, light_count, w_sum, prob);
        Light light = lights[l];
        vec3 omega = light.direction_type.xyz;
        // Stratified sample number k of n.
        float r = (float(k) + rng_next(rng)) / float(n);

        if (SC_ESTIMATOR == ESTIMATOR_MCWVDS) {
            // Whole-volume distance sampling: f / pdf = U_l, only visibility remains.
            if (l != cached) {
                pieces = light_pieces(bm, light, o_local, d_local, t_enter, interval[l]);
                cached = l;
            }
            // Domain: U[l] > 0 for a chosen light, so its pieces have total > 0; prob > 0.
            float t = sample_wvds_distance(pieces, r);
            sum += U[l] / prob * light_visibility(o + t * d, omega, m);
            continue;
        }

        // Draw t within the light's interval (the gobo offsets and limits the
        // integration) by equidistant strata (RM, REES) or by distance sampling (MCDS,
        // REDS). A selected light has U > 0, so its interval is not empty.
        float t_start = interval[l].x;
        float span = interval[l].y - interval[l].x;
        float t;
        float pdf;
        if (SC_ESTIMATOR == ESTIMATOR_RM || SC_ESTIMATOR == ESTIMATOR_REES) {
            t = t_start + r * span;
            // Domain: span > 0 for a selected light.
            pdf = 1.0 / span;
        } else {
            // Truncated exponential on [0, span]: pdf = sigma_t e^{-sigma_t s} / (1 - e^{-sigma_t span}).
            float x = sigma_t * span;
            if (x < 1e-6) {
                t = t_start + r * span;
                pdf = 1.0 / span;
            } else {
                float norm = x * one_minus_exp_over_x(x); // 1 - e^{-x}, in (0, 1]
                // Domain: 1 - r norm in [e^{-x}, 1], > 0 unless e^{-x} underflows and r -> 1.
                float s = -log(max(1.0 - r * norm, 1e-37)) / sigma_t;
                s = min(s, span);
                t = t_start + s;
                pdf = sigma_t * exp(-sigma_t * s) / norm;
            }
        }
        if (!(pdf > 0.0)) {
            continue;
        }
        vec3 x_world = o + t * d;
        // Unoccluded integrand of the chosen light: sigma_s p E T_cam T_light, gobo-masked.
        float gobo = (SC_HAS_GOBOS && !inside_gobo(light, x_world)) ? 0.0 : 1.0;
        float d_light = box_light_distance(o_local + t * d_local, to_local_dir(bm, omega), bm.half_size_g.xyz);
        float T = exp(-sigma_t * ((t - t_enter) + d_light));
        vec3 f = bm.sigma_s.rgb * hg_phase(dot(omega, -d), g) * light.irradiance.rgb * T * gobo;
        // Domain: pdf > 0 (checked) and prob > 0.
        vec3 f_over_pdf = f / (pdf * prob);
        float v = gobo > 0.0 ? light_visibility(x_world, omega, m) : 0.0;
        if (SC_ESTIMATOR == ESTIMATOR_RM || SC_ESTIMATOR == ESTIMATOR_MCDS) {
            sum += f_over_pdf * v;
        } else {
            num += f_over_pdf * v;
            den += f_over_pdf;
        }
    }
    if (SC_ESTIMATOR == ESTIMATOR_REES || SC_ESTIMATOR == ESTIMATOR_REDS) {
        // Ratio estimator: analytic unoccluded term times occluded / unoccluded
        // estimates; a channel whose unoccluded estimate is zero contributes zero.
        vec3 ratio = vec3(den.r > 0.0 ? num.r / den.r : 0.0, den.g > 0.0 ? num.g / den.g : 0.0, den.b > 0.0 ? num.b / den.b : 0.0);
        return U_total * ratio;
    }
    return sum / float(n);
}

// Direct light reflected by the Lambertian shape hit at x towards -d.
vec3 surface_direct(Shape s, vec3 x, vec3 n) {
    // Shadow rays leave from just off the surface.
    vec3 x_off = offset_ray_origin(x, n);
    vec3 E = vec3(0.0);
    uint light_count = u_frame.counts.z;
    for (uint l = 0u; l < light_count; ++l) {
        Light light = lights[l];
        float cos_i = dot(n, -light.direction_type.xyz);
        if (cos_i > 0.0) {
            E += cos_i * light_arriving(light, x_off, 0.0);
        }
    }
    return s.albedo_type.rgb * INV_PI * E;
}

// Sample a free-flight collision along o + t d before t_surface through the box media
// (analog: a collision in medium m at t with probability sigma_t T). Returns t, or
// FAR when the ray reaches t_surface (probability T(o -> t_surface)) unscattered.
float sample_collision(vec3 o, vec3 d, float t_surface, inout uint rng, out uint medium) {
    medium = NO_INDEX;
    // Domain: 1 - u in (0, 1].
    float tau_target = -log(1.0 - rng_next(rng));
    float tau_acc = 0.0;
    uint count = min(u_frame.counts.x, MAX_MEDIA);
    float last_entry = -FAR;
    // Visit the media spans in order of entry (media are disjoint, so entries differ).
    for (uint visited = 0u; visited < count; ++visited) {
        uint next = NO_INDEX;
        vec2 next_span = vec2(FAR, -FAR);
        for (uint m = 0u; m < count; ++m) {
            vec2 span = box_medium_span(m, o, d);
            float entry = max(span.x, 0.0);
            if (span.y > entry && entry > last_entry && entry < next_span.x) {
                next = m;
                next_span = vec2(entry, span.y);
            }
        }
        if (next == NO_INDEX) {
            break;
        }
        last_entry = next_span.x;
        float t_a = next_span.x;
        float t_b = min(next_span.y, t_surface);
        if (t_b <= t_a) {
            break;
        }
        float sigma_t = media[next].center_sigma_t.w;
        float d_tau = sigma_t * (t_b - t_a);
        if (tau_acc + d_tau >= tau_target) {
            medium = next;
            // Domain: sigma_t > 0 here, since d_tau > 0 was needed to reach the target.
            return t_a + (tau_target - tau_acc) / sigma_t;
        }
        tau_acc += d_tau;
    }
    return FAR;
}

// Radiance arriving at o from direction -d: scattering orders 1..SC_MAX_BOUNCES.
vec3 radiance(vec3 o, vec3 d, inout uint rng) {
    vec3 L = vec3(0.0);
    vec3 beta = vec3(1.0);
    for (uint bounce = 0u; bounce < SC_MAX_BOUNCES; ++bounce) {
        uint shape_index;
        float t_surface = nearest_shape(o, d, 0.0, FAR, shape_index);

        // Add single scattering from every box medium the segment crosses.
        uint media_count = SC_HAS_MEDIA ? min(u_frame.counts.x, MAX_MEDIA) : 0u;
        for (uint m = 0u; m < media_count; ++m) {
            vec2 span = box_medium_span(m, o, d);
            float t_enter = max(span.x, 0.0);
            float t_b = min(span.y, t_surface);
            if (t_b > t_enter && media[m].center_sigma_t.w > 0.0) {
                float T_before = exp(-box_optical_depth_except(o, d, 0.0, t_enter, m));
                L += beta * T_before * single_scatter_box(m, o, d, t_enter, t_b, rng);
            }
        }

        vec3 n = vec3(0.0);
        if (t_surface < FAR) {
            // Add the Lambertian reflection of direct light at the surface.
            Shape s = shapes[shape_index];
            vec3 x = o + t_surface * d;
            n = shape_normal(s, x, d);
            if (any(greaterThan(s.albedo_type.rgb, vec3(0.0)))) {
                L += beta * exp(-box_optical_depth(o, d, 0.0, t_surface)) * surface_direct(s, x, n);
            }
        } else if (SC_HAS_ENV && bounce == 0u) {
            // Add the environment seen through the media by the camera ray.
            L += exp(-box_optical_depth(o, d, 0.0, FAR)) * u_frame.env_radiance.rgb;
        }
        if (bounce + 1u >= SC_MAX_BOUNCES) {
            break;
        }

        // Continue the path: a collision in a medium, else a reflection at the surface.
        uint medium;
        float t_collision = SC_HAS_MEDIA ? sample_collision(o, d, t_surface, rng, medium) : FAR;
        if (t_collision < FAR) {
            BoxMedium bm = media[medium];
            // Domain: sigma_t > 0 in a medium where a collision happened.
            beta *= bm.sigma_s.rgb / bm.center_sigma_t.w;
            o = o + t_collision * d;
            d = sample_hg(d, bm.half_size_g.w, vec2(rng_next(rng), rng_next(rng)));
        } else if (t_surface < FAR) {
            vec3 albedo = shapes[shape_index].albedo_type.rgb;
            if (!any(greaterThan(albedo, vec3(0.0)))) {
                break;
            }
            beta *= albedo;
            o = offset_ray_origin(o + t_surface * d, n);
            d = sample_cosine_hemisphere(n, vec2(rng_next(rng), rng_next(rng)));
        } else {
            break;
        }
        // Russian roulette from the fourth segment on, by the path's throughput.
        if (bounce >= 3u && !russian_roulette(beta, rng)) {
            break;
        }
    }
    return L;
}

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (!film_contains(pixel)) {
        return;
    }
    film_accumulate(pixel, film_pixel_estimate(pixel, u_push.frame, u_push.sample_base));
}
