#version 460
// The equal-time baseline of Volumetric ReSTIR (Sec. 6): a path tracer for a grid
// medium with decomposition tracking (Kutz et al. 2017) for free flights and residual
// ratio tracking (Novak et al. 2014) for next-event transmittance, both on 8x
// super-voxels holding min/max/avg of sigma_t (grid.glsl).
//
// Homogeneous box media may sit beside the grid (SC_HAS_MEDIA): free flights take
// the earliest of independent first collisions in each (disjoint) medium, and shadow
// rays multiply the boxes' closed-form transmittance in.
//
// One invocation per pixel, `spp` paths per pixel per frame. A path scatters at most
// SC_MAX_BOUNCES = K times (real collisions in the medium or Lambertian reflections);
// at every scattering vertex one light is chosen in proportion to its power and
// connected by a shadow ray (next-event estimation), so every light reaches the
// camera through NEE only: escaping rays and rays hitting an emitting sphere or an
// emitting shape (an area light, SC_HAS_AREA_LIGHTS) add radiance only on the camera
// segment; a shape that emits still reflects by its albedo. Russian roulette by
// throughput from the 4th segment on.

#extension GL_GOOGLE_include_directive : require

#include "features.glsl"
#include "bindings.glsl"
#include "constants.glsl"
#include "scene.glsl"
#include "rng.glsl"
#include "phase.glsl"
#include "sampling.glsl"
#include "geometry.glsl"
#include "grid_types.glsl"
#include "path.glsl"

layout(constant_id = SC_ID_HAS_SHAPES) const bool SC_HAS_SHAPES = true;
layout(constant_id = SC_ID_HAS_ENV) const bool SC_HAS_ENV = true;
// Homogeneous box media beside the grid.
layout(constant_id = SC_ID_HAS_MEDIA) const bool SC_HAS_MEDIA = false;
layout(constant_id = SC_ID_MAX_BOUNCES) const uint SC_MAX_BOUNCES = 1u;
layout(constant_id = SC_ID_PIXEL_JITTER) const bool SC_PIXEL_JITTER = true;
layout(constant_id = SC_ID_HAS_EMISSION) const bool SC_HAS_EMISSION = false;
// A temperature grid glows as a blackbody (grid_emission.glsl).
layout(constant_id = SC_ID_HAS_BLACKBODY) const bool SC_HAS_BLACKBODY = false;
// The grid's albedo is a grid (grid_albedo in grid_emission.glsl).
layout(constant_id = SC_ID_HAS_ALBEDO_GRID) const bool SC_HAS_ALBEDO_GRID = false;
// The environment is an importance-sampled map (else a constant radiance).
layout(constant_id = SC_ID_HAS_ENV_MAP) const bool SC_HAS_ENV_MAP = false;
// Split next-event estimation: every delta light at every vertex, plus one sample of the
// other lights (else one light per vertex, chosen by power).
layout(constant_id = SC_ID_NEE_SPLIT) const bool SC_NEE_SPLIT = false;
// With SC_NEE_SPLIT where the other lights are a constant environment alone: its NEE
// direction at a vertex that scatters on is the path's next direction (both drawn from
// the vertex's phase or cosine lobe), and the next segment's walk estimates the sky's
// transmittance along it too (grid_collision_and_transmittance): one walk, not two.
layout(constant_id = SC_ID_SKY_ALONG_PATH) const bool SC_SKY_ALONG_PATH = false;

#include "film.glsl"

layout(push_constant) uniform PushBlock {
    PassPush u_push;
};

// Density reads from a storage buffer where the plan says so (grid.glsl).
#define NIMBUS_DENSITY_BUFFER 1
#include "grid_resources.glsl"
#include "shapes.glsl"
#include "box_media.glsl"
#include "aov_trace.glsl"

// The first real collision along o + t d in [0, t_end) among the grid and the boxes:
// the media are disjoint, so the first collision is the earliest of independent first
// collisions sampled in each. Returns FAR if none; `medium` is the box index, or
// NO_INDEX for the grid.
// With `sky`, the segment reaches infinity (t_end = FAR) and T_sky is also set to an
// unbiased estimate of its transmittance through the grid and the boxes, from the same
// walk (else it is 0).
float sample_collision(vec3 o, vec3 d, float t_end, bool sky, inout uint rng, out uint medium,
                       out float T_sky) {
    medium = NO_INDEX;
    T_sky = 0.0;
    vec2 span = grid_span(o, d);
    float t0 = max(span.x, 0.0);
    float t1 = min(span.y, t_end);
    float t_best;
    if (SC_SKY_ALONG_PATH && sky) {
        T_sky = 1.0;
        t_best = t1 > t0 ? grid_collision_and_transmittance(o, d, t0, t1, rng, T_sky) : FAR;
        if (SC_HAS_MEDIA) {
            T_sky *= exp(-box_optical_depth(o, d, 0.0, FAR));
        }
    } else {
        t_best = t1 > t0 ? grid_sample_collision(o, d, t0, t1, rng) : FAR;
    }
    if (SC_HAS_MEDIA) {
        uint count = u_frame.box_media_count;
        for (uint m = 0u; m < count; ++m) {
            vec2 s = box_medium_span(m, o, d);
            float a = max(s.x, 0.0);
            float b = min(s.y, min(t_end, t_best));
            float sigma_t = media[m].sigma_t;
            if (b <= a || !(sigma_t > 0.0)) {
                continue;
            }
            // A first collision at rate sigma_t. Domain: sigma_t > 0.
            float t = a + sample_exponential(rng_next(rng), sigma_t);
            if (t < b) {
                t_best = t;
                medium = m;
            }
        }
    }
    return t_best;
}

// Transmittance from x along unit w over [0, dist) through the grid, 0 if a shape blocks
// it before t_occlude (dist, or a little less when the light vertex lies on a shape) or
// another emitting sphere before dist.
float shadow_transmittance(vec3 x, vec3 w, float dist, float t_occlude, float t_min, uint target,
                           inout uint rng) {
    if (occluded_before(x, w, t_min, t_occlude)) {
        return 0.0;
    }
    uint blocker;
    float t_light = nearest_sphere_light(0u, x, w, t_min, dist, blocker);
    if (t_light < FAR && blocker != target) {
        return 0.0;
    }
    float T_boxes = exp(-box_optical_depth(x, w, 0.0, dist));
    vec2 span = grid_span(x, w);
    float t0 = max(span.x, 0.0);
    float t1 = min(span.y, dist);
    if (t1 <= t0) {
        return T_boxes;
    }
    COUNT_SHADOW_BEGIN();
    float T = T_boxes * grid_residual_ratio_tracking(x, w, t0, t1, rng);
    COUNT_SHADOW_END();
    return T;
}

// The light record (or LIGHT_ENV) the last sample_light drew: its light group is its
// contribution's (aov.glsl).
uint g_light_index = NO_INDEX;

// Sample a light for next-event estimation at x: the direction wi towards it, the
// distance along wi, how far shapes may block it (t_occlude), and the arriving radiance
// divided by the (selection x measure) pdf. Zero when the sample carries nothing. A point
// on an emitting shape lies on that shape: shapes block only up to dist (1 - 1e-4), so the
// emitter does not shadow itself. With SC_NEE_SPLIT the sample is one of the lights that
// are not delta lights (next_event adds the delta lights themselves).
//
// A constant environment's direction is drawn from the vertex's own scattering
// distribution instead of uniformly: the HG phase about the travel direction `d` (g) in
// a medium, the cosine lobe about the normal `n` on a surface. The radiance is the same
// from every direction, so the estimate then varies only with the transmittance: uniform
// directions under g = 0.8 had 35x the variance (the phase's second moment), which made
// the baseline 20x less efficient than Mitsuba's volpath (phase-sampled with MIS) on a
// forward-scattering cloud under a sky.
vec3 sample_light(vec3 x, vec3 d, float g, vec3 n, bool on_surface, inout uint rng, out vec3 wi,
                  out float dist, out float t_occlude, out uint target) {
    float u = rng_next(rng);
    vec2 u2 = vec2(rng_next(rng), rng_next(rng));
    float p_env = u_base.env_select;
    LightSample s;
    if (SC_NEE_SPLIT) {
        s = light_sample_rest(0u, u_frame.env_rotation, x, u, u2, p_env);
    } else {
        s = light_sample(0u, u_frame.env_rotation, x, u, u2);
    }
    g_light_index = s.index;
    wi = s.wi;
    dist = s.dist;
    t_occlude = light_is_area(0u, s.index) ? s.dist * (1.0 - 1e-4) : s.dist;
    target = s.index == LIGHT_ENV ? NO_INDEX : s.index;
    if (SC_HAS_ENV && !SC_HAS_ENV_MAP && s.index == LIGHT_ENV) {
        float pdf_dir;
        if (on_surface) {
            wi = sample_cosine_hemisphere(n, u2);
            pdf_dir = max(dot(wi, n), 0.0) * INV_PI;
        } else {
            wi = sample_hg(d, g, u2);
            pdf_dir = hg_phase(dot(wi, d), g);
        }
        // Domain: the selection probability and the direction's density are > 0 where
        // divided (a grazing cosine sample carries nothing).
        float pdf = p_env * pdf_dir;
        return pdf > 0.0 ? u_frame.env_radiance / pdf : vec3(0.0);
    }
    return s.L_over_pdf;
}

// One NEE term: `weight` x the vertex's scattering of light Li arriving along wi (cos / pi
// on a surface, the HG phase of g about the travel direction d in a medium) x T.
vec3 nee_term(vec3 weight, bool on_surface, float cos_i, vec3 d, float g, vec3 wi, vec3 Li, float T) {
    return on_surface ? weight * INV_PI * cos_i * Li * T : weight * hg_phase(dot(wi, d), g) * Li * T;
}

// What next-event estimation adds at a scattering vertex x reached along d: light arriving
// along wi times the vertex's scattering (`weight` x the HG phase of g in a medium, or
// `weight` x cos / pi about the normal n on a surface, `weight` holding the path's
// throughput and the albedo), each term also added to its AOV (NEE at vertex `bounce`, in
// its light's group). One light chosen by power, or with SC_NEE_SPLIT every delta light
// (directional, point: no sampling, one shadow ray each) plus one sample of the others:
// a sun and a sky then both reach every vertex, which removes the variance of choosing
// between them (half the per-sample variance on the benchmark cloud; at g = 0.8 the sun
// behind a back-scattering vertex had taken 57 % of the samples for 1 % of the light).
//
// With `sky_later` (SC_SKY_ALONG_PATH at a vertex the path leaves) the environment's term
// is left to the next segment's walk (radiance()).
vec3 next_event(vec3 x, vec3 d, float g, vec3 n, bool on_surface, vec3 weight, uint bounce,
                bool sky_later, inout uint rng) {
    vec3 L = vec3(0.0);
    // One shadow walk call for every term: the delta lights (j < count, with SC_NEE_SPLIT)
    // then the sampled light (j = count), in that order, so the random numbers are drawn
    // as before. A GPU compiler inlines every call: two call sites were two copies of the
    // whole transmittance walk in the path loop.
    uint count = SC_NEE_SPLIT ? u_frame.light_count : 0u;
    bool sampled = !(SC_SKY_ALONG_PATH && sky_later);
    for (uint j = 0u; j <= count; ++j) {
        vec3 wi;
        float dist;
        float t_occlude;
        uint target;
        uint group;
        vec3 Li;
        if (j < count) {
            if (!light_is_delta(0u, j)) {
                continue;
            }
            Li = light_eval(0u, u_frame.env_rotation, j, vec3(0.0, 1.0, 0.0), 0u, vec3(0.0), x, wi, dist);
            t_occlude = dist;
            target = j;
            group = light_group(j);
        } else {
            if (!sampled) {
                break;
            }
            Li = sample_light(x, d, g, n, on_surface, rng, wi, dist, t_occlude, target);
            group = light_group(g_light_index);
        }
        float cos_i = on_surface ? dot(n, wi) : 1.0;
        if (cos_i > 0.0 && any(greaterThan(Li, vec3(0.0)))) {
            float T = shadow_transmittance(x, wi, dist, t_occlude, 0.0, target, rng);
            vec3 c = nee_term(weight, on_surface, cos_i, d, g, wi, Li, T);
            L += c;
            aov_add(aov_kind_nee(bounce), group, c);
        }
    }
    return L;
}

// Radiance arriving at o from direction -d. Every `L += c` has its twin aov_add (aov.glsl)
// with the same c: emission seen after `bounce` scatterings (aov_kind_emitted), NEE at
// vertex `bounce` (aov_kind_nee), each with its light group.
vec3 radiance(vec3 o, vec3 d, inout uint rng) {
    vec3 L = vec3(0.0);
    vec3 beta = vec3(1.0);
    // SC_SKY_ALONG_PATH: the previous vertex's sky term, its weight (throughput x albedo x
    // radiance: the phase or cosine over the direction's density is 1) waiting for this
    // segment's transmittance, and that vertex's index.
    vec3 sky_weight = vec3(0.0);
    uint sky_vertex = 0u;

    for (uint bounce = 0u; bounce < SC_MAX_BOUNCES; ++bounce) {
        uint shape_index;
        float t_surface = nearest_shape(o, d, 0.0, FAR, shape_index);
        uint light_index;
        float t_light = nearest_sphere_light(0u, o, d, 0.0, t_surface, light_index);
        float t_end = min(t_surface, t_light);
        // The sky is seen along d unless a shape or a sphere blocks it.
        bool sky = SC_SKY_ALONG_PATH && bounce > 0u && t_end >= FAR;
        if (bounce == 0u && g_alpha_wanted) {
            // The film's alpha: the camera ray's closed-form transmittance through the box
            // media and the trilinear grid, 0 where it meets a surface or an emitter.
            g_camera_transmittance = t_end < FAR ? 0.0
                                                 : exp(-box_optical_depth(o, d, 0.0, FAR)) *
                                                       grid_transmittance(o, d, 0.0, FAR);
        }

        // Sample a real collision in the media before the segment's end.
        uint medium;
        float T_sky;
        float t_collision = sample_collision(o, d, t_end, sky, rng, medium, T_sky);
        if (sky) {
            vec3 c = sky_weight * T_sky;
            L += c;
            aov_add(aov_kind_nee(sky_vertex), light_group(LIGHT_ENV), c);
        }

        if (t_collision < FAR) {
            vec3 x = o + t_collision * d;
            vec3 albedo_medium;
            float g = u_base.g;
            if (medium != NO_INDEX) {
                BoxMedium bm = media[medium];
                // Domain: a collision happened, so sigma_t > 0.
                albedo_medium = bm.sigma_s / bm.sigma_t;
                g = bm.g;
            } else {
                albedo_medium = grid_albedo(x);
            }
            // A real collision: absorbed emission (sigma_a Le over sigma_t), next-event
            // estimation, then continue by HG.
            if (SC_HAS_EMISSION && medium == NO_INDEX) {
                vec3 c = beta * (1.0 - albedo_medium) * grid_emission(x);
                L += c;
                aov_add(aov_kind_emitted(bounce), AOV_GROUP_DEFAULT, c);
            }
            bool last = bounce + 1u >= SC_MAX_BOUNCES;
            L += next_event(x, d, g, vec3(0.0), false, beta * albedo_medium, bounce, !last, rng);
            if (last) {
                break;
            }
            beta *= albedo_medium;
            o = x;
            d = sample_hg(d, g, vec2(rng_next(rng), rng_next(rng)));
            sky_weight = beta * u_frame.env_radiance;
            sky_vertex = bounce;
        } else if (t_light < t_surface) {
            // An emitting sphere: seen directly only by the camera segment.
            if (bounce == 0u) {
                vec3 c = beta * lights[light_index].irradiance;
                L += c;
                aov_add(AOV_EMISSION, light_group(light_index), c);
            }
            break;
        } else if (t_surface < FAR) {
            // A Lambertian surface: its emission if the camera sees it, next-event
            // estimation, then continue by cosine sampling.
            Shape s = shapes[shape_index];
            vec3 x = o + t_surface * d;
            if (SC_HAS_AREA_LIGHTS && bounce == 0u) {
                vec3 c = beta * shape_emitted(shape_index, x, d);
                L += c;
                aov_add(AOV_EMISSION, AOV_GROUP_DEFAULT, c);
            }
            vec3 albedo = s.albedo;
            if (!any(greaterThan(albedo, vec3(0.0)))) {
                break;
            }
            vec3 n = shape_normal(s, x, d);
            vec3 x_off = offset_ray_origin(x, n);
            bool last = bounce + 1u >= SC_MAX_BOUNCES;
            L += next_event(x_off, d, 0.0, n, true, beta * albedo, bounce, !last, rng);
            if (last) {
                break;
            }
            beta *= albedo;
            o = x_off;
            d = sample_cosine_hemisphere(n, vec2(rng_next(rng), rng_next(rng)));
            sky_weight = beta * u_frame.env_radiance;
            sky_vertex = bounce;
        } else {
            // Escaped: the environment, seen directly by the camera segment only.
            if (SC_HAS_ENV && bounce == 0u) {
                vec3 c = beta * env_background_along(d, u_frame.env_rotation) * u_frame.background;
                L += c;
                aov_add(AOV_EMISSION, AOV_GROUP_ENV, c);
            }
            break;
        }
        // Russian roulette from the fourth segment on, by the path's throughput. The
        // vertex's sky term is NEE, not path: where the path ends here, its shadow ray.
        if (bounce >= 3u && !russian_roulette(beta, rng)) {
            if (SC_SKY_ALONG_PATH) {
                vec3 c = sky_weight * shadow_transmittance(o, d, FAR, FAR, 0.0, NO_INDEX, rng);
                L += c;
                aov_add(aov_kind_nee(sky_vertex), light_group(LIGHT_ENV), c);
            }
            break;
        }
    }
    return L;
}

void main() {
    film_load();
    grid_resources_load();
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (!film_contains(pixel)) {
        return;
    }
    film_take_samples(pixel, u_push.frame, u_push.sample_base, u_push.sample_count);
}
