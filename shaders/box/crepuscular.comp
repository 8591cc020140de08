#version 460
// Crepuscular rays in homogeneous box media under collimated light (Velinov &
// Mitchell). One invocation per pixel; `spp` camera paths per pixel per frame, each
// jittered over the pixel footprint, accumulate into the running sums.
//
// Along every path segment inside a box the single-scattered light is estimated with
// N = `box_samples` samples by one of the paper's estimators (SC_ESTIMATOR), each a
// distance sampler times a combiner (estimators.glsl):
//   MCWVDS  Monte Carlo with whole-volume distance sampling (Sec. 5-6): distances
//           drawn in proportion to the unoccluded integrand, so the estimate is the
//           analytic unoccluded radiance times the mean visibility.
//   REDS    ratio estimator, distance sampling: analytic unoccluded radiance times
//           (occluded estimate / unoccluded estimate) from the same samples.
//   REES    ratio estimator, equidistant jittered samples.
//   RM      ray marching: equidistant jittered samples.
//   MCDS    Monte Carlo with distance sampling along the camera ray only.
//   ME      moment-based estimation (Peters et al. 2017): the analytic unoccluded
//           radiance times a visibility ratio reconstructed from the lights' moment
//           shadow maps (moments.comp renders them first); deterministic, approximate.
// Each sample picks one directional light in proportion to its analytic unoccluded
// radiance along this segment (Sec. 4, multiple lights). A gobo offsets and limits the
// integration to the part of the segment inside its prism, for every estimator.
//
// With SC_MAX_BOUNCES = K > 1 the camera ray continues as a path: a free-flight
// collision (or a Lambertian surface) starts the next segment, whose single-scattered
// light again comes from the estimator, so scattering orders 1..K are summed.
//
// With an environment (SC_HAS_ENV; a map with SC_HAS_ENV_MAP) camera rays that escape
// see it through the media, and every segment adds its light scattered in the media
// and reflected by the surface it ends on, by next-event estimation (environment.glsl).

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

// Features the render plan switches per scene.
layout(constant_id = SC_ID_HAS_SHAPES) const bool SC_HAS_SHAPES = true;
layout(constant_id = SC_ID_HAS_ENV) const bool SC_HAS_ENV = true;
layout(constant_id = SC_ID_ESTIMATOR) const uint SC_ESTIMATOR = 0u;
layout(constant_id = SC_ID_HAS_MEDIA) const bool SC_HAS_MEDIA = true;
layout(constant_id = SC_ID_MAX_BOUNCES) const uint SC_MAX_BOUNCES = 1u;
layout(constant_id = SC_ID_PIXEL_JITTER) const bool SC_PIXEL_JITTER = true;
layout(constant_id = SC_ID_HAS_ENV_MAP) const bool SC_HAS_ENV_MAP = false;

// The box media's camera-ray transmittance is a cheap closed form: every sample's coverage.
#define FILM_ALPHA_EVERY_SAMPLE
#include "film.glsl"

layout(push_constant) uniform PushBlock {
    PassPush u_push;
};
// Directional lights.
layout(std430, set = 0, binding = BINDING_LIGHTS) readonly buffer LightsBlock {
    Light lights[];
};

// The light group (aov.glsl) of directional light `index`.
uint light_group(uint index) {
    return SC_AOV_GROUPS == 0u ? 0u : lights[index].group;
}

#include "shapes.glsl"
#include "box_media.glsl"
#define AOV_TRACE_NO_GRID
#include "aov_trace.glsl"
#include "directional.glsl"
#include "moments.glsl"
#include "estimators.glsl"
#include "environment.glsl"

// Direct light reflected by the Lambertian shape hit at x towards -d (with light groups,
// each light's part also added to aov.glsl's g_aov_parts).
vec3 surface_direct(Shape s, vec3 x, vec3 n) {
    // Shadow rays leave from just off the surface.
    vec3 x_off = offset_ray_origin(x, n);
    vec3 E = vec3(0.0);
    uint light_count = u_frame.light_count;
    for (uint l = 0u; l < light_count; ++l) {
        Light light = lights[l];
        float cos_i = dot(n, -light.direction_or_position);
        if (cos_i > 0.0) {
            vec3 e = cos_i * light_arriving(light, x_off, 0.0);
            E += e;
            aov_parts_add(light_group(l), s.albedo * INV_PI * e);
        }
    }
    return s.albedo * INV_PI * E;
}

// Sample a free-flight collision along o + t d before t_surface through the box media
// (analog: a collision in medium m at t with probability sigma_t T). Returns t, or
// FAR when the ray reaches t_surface (probability T(o -> t_surface)) unscattered.
float sample_collision(vec3 o, vec3 d, float t_surface, inout uint rng, out uint medium) {
    medium = NO_INDEX;
    // The optical depth of the collision, exponential with rate 1.
    float tau_target = sample_exponential(rng_next(rng), 1.0);
    float tau_acc = 0.0;
    uint count = min(u_frame.box_media_count, MAX_MEDIA);
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
        float sigma_t = media[next].sigma_t;
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
        if (bounce == 0u && g_alpha_wanted) {
            // The film's alpha: the camera ray's closed-form transmittance, 0 on a surface.
            g_camera_transmittance =
                t_surface < FAR ? 0.0 : exp(-box_optical_depth(o, d, 0.0, FAR));
        }

        // Add single scattering from every box medium the segment crosses.
        uint media_count = SC_HAS_MEDIA ? min(u_frame.box_media_count, MAX_MEDIA) : 0u;
        for (uint m = 0u; m < media_count; ++m) {
            vec2 span = box_medium_span(m, o, d);
            float t_enter = max(span.x, 0.0);
            float t_b = min(span.y, t_surface);
            if (t_b > t_enter && media[m].sigma_t > 0.0) {
                float T_before = exp(-box_optical_depth_except(o, d, 0.0, t_enter, m));
                aov_parts_clear();
                vec3 L_m = single_scatter_box(m, o, d, t_enter, t_b, rng);
                vec3 L_sky = vec3(0.0);
                if (SC_HAS_ENV) {
                    L_sky = sky_scatter_box(m, o, d, t_enter, t_b, rng);
                    L_m += L_sky;
                }
                L += beta * T_before * L_m;
                // Light scattered once here, after `bounce` earlier scatterings.
                aov_add_kind(aov_kind_nee(bounce), beta * T_before * L_m);
                aov_parts_flush(beta * T_before);
                aov_add_group(AOV_GROUP_ENV, beta * T_before * L_sky);
            }
        }

        vec3 n = vec3(0.0);
        if (t_surface < FAR) {
            // Add the Lambertian reflection of direct light and the environment at the surface.
            Shape s = shapes[shape_index];
            vec3 x = o + t_surface * d;
            n = shape_normal(s, x, d);
            if (any(greaterThan(s.albedo, vec3(0.0)))) {
                aov_parts_clear();
                vec3 L_s = surface_direct(s, x, n);
                vec3 L_sky = vec3(0.0);
                if (SC_HAS_ENV) {
                    L_sky = sky_reflect(s, x, n, rng);
                    L_s += L_sky;
                }
                vec3 w = beta * exp(-box_optical_depth(o, d, 0.0, t_surface));
                L += w * L_s;
                aov_add_kind(aov_kind_nee(bounce), w * L_s);
                aov_parts_flush(w);
                aov_add_group(AOV_GROUP_ENV, w * L_sky);
            }
        } else if (SC_HAS_ENV && bounce == 0u) {
            // Add the environment seen through the media by the camera ray (after a
            // scattering it arrives by next-event estimation only).
            vec3 c = exp(-box_optical_depth(o, d, 0.0, FAR)) * sky_background(d) * u_frame.background;
            L += c;
            aov_add(AOV_EMISSION, AOV_GROUP_ENV, c);
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
            beta *= bm.sigma_s / bm.sigma_t;
            o = o + t_collision * d;
            d = sample_hg(d, bm.g, vec2(rng_next(rng), rng_next(rng)));
        } else if (t_surface < FAR) {
            vec3 albedo = shapes[shape_index].albedo;
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
    film_load();
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (!film_contains(pixel)) {
        return;
    }
    film_take_samples(pixel, u_push.frame, u_push.sample_base, u_push.sample_count);
}
