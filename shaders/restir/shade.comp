#version 460
// Volumetric ReSTIR pass 4, final shading (Algorithm 6): the selected path's integrand F
// with unbiased transmittance (the closed form through the trilinear grid, or ratio
// tracking with SC_FINAL_RATIO_TRACKING), weighted f / p_hat * w_sum / M. Non-finite
// values are counted and dropped, never written. Reads slot u_push.src.

#extension GL_GOOGLE_include_directive : require
#include "path_value.glsl"
// aov_geometry_point: the geometric AOVs' point, shared by every integrator.
#include "aov_trace.glsl"

void restir_main();

// The geometric AOVs of `pixel` (aov.glsl's definition): the point P of the pixel-centre
// camera ray that every integrator finds (aov_geometry_point, exact transmittance: not
// the conservative grid the walks track), and P's motion as temporal reuse reprojects it:
// a point of the grid medium moves back by the velocity field (metres per frame), a
// surface, an emitting sphere or a box medium's point stays where it is.
void restir_geometry_aovs(uvec2 pixel) {
    vec3 o = u_frame.cam_position;
    vec3 d = camera_direction(u_frame, vec2(pixel) + 0.5);
    float t;
    vec3 normal;
    vec3 albedo;
    if (!aov_geometry_point(o, d, t, normal, albedo)) {
        aov_write_geometry(pixel, aov_infinity(), vec3(0.0), vec3(0.0), vec2(0.0));
        return;
    }
    vec3 p = o + t * d;
    vec3 p_prev = p;
    if (SC_HAS_VELOCITY) {
        // P lies in the media where it is nearer than everything opaque on the ray.
        uint sphere;
        float t_opaque = min(nearest_sphere_light(0u, o, d, 0.0, FAR, sphere), surface_along(o, d, FAR).t);
        if (t < t_opaque && box_medium_at(p) == NO_INDEX) {
            p_prev = p - velocity_at(p);
        }
    }
    aov_write_geometry(pixel, t * dot(d, u_frame.cam_forward), normal, albedo, aov_motion(p, p_prev));
}

// Stratified samples of the camera segment's emission (SC_CAMERA_EMISSION).
#define CAMERA_EMISSION_SAMPLES 8u

// The emission the camera ray through `pixel` (a fresh, uniform sub-pixel jitter: the
// reservoir's was chosen by resampling) sees in the grid up to its first opaque end: the
// integral of T(t) sigma_a(t) Le(t) over the ray's span in the grid. Its points are drawn
// with density sigma_t(t) T(t0, t) / P (P = 1 - T across the span), stratified in that
// distribution: CAMERA_EMISSION_SAMPLES quantiles (k + u) / N of it, each found by exact
// inversion of the closed-form optical depth through the trilinear grid, so each sample
// weighs P / N (sigma_a / sigma_t) Le times the boxes' transmittance. Unbiased (every
// sample is exact at a point distributed as its stratum of the density), and where the
// glow is uniform its only noise is the albedo's and emission's variation along the ray.
vec3 camera_emission(uvec2 pixel, inout uint rng) {
    uint code = SC_PIXEL_JITTER ? jitter_code_sample(rng) : 0u;
    CameraRay cam = camera_ray(pixel, code, SET_CURRENT);
    uint sphere;
    SurfacePoint surface;
    float t_end = opaque_end(light_base(SET_CURRENT), cam.o, cam.d, sphere, surface);
    vec2 span = grid_span(cam.o, cam.d);
    float t0 = max(span.x, 0.0);
    float t1 = min(span.y, t_end);
    if (!(t1 > t0)) {
        return vec3(0.0);
    }
    float tau_span = grid_optical_depth(cam.o, cam.d, t0, t1);
    // P = 1 - exp(-tau_span), by its series for small depths. Domain: tau_span >= 0.
    float P = tau_span < 1e-4 ? tau_span * (1.0 - 0.5 * tau_span) : 1.0 - exp(-tau_span);
    if (!(P > 0.0)) {
        return vec3(0.0);
    }
    float u = rng_next(rng);
    float t_prev = t0;
    float tau_prev = 0.0;
    vec3 sum = vec3(0.0);
    for (uint k = 0u; k < CAMERA_EMISSION_SAMPLES; ++k) {
        // The quantile (k + u) / N of the distribution: optical depth -ln(1 - q P) from
        // t0, reached past t_prev by the remaining difference. Domain: q P < 1.
        float q = (float(k) + u) / float(CAMERA_EMISSION_SAMPLES);
        float tau_k = -log(max(1.0 - q * P, 1e-30));
        float t = grid_invert_optical_depth(cam.o, cam.d, t_prev, t1, max(tau_k - tau_prev, 1e-12));
        if (t >= FAR) {
            break;
        }
        t_prev = t;
        tau_prev = tau_k;
        vec3 x = cam.o + t * cam.d;
        float T_box = SC_HAS_MEDIA ? exp(-box_optical_depth(cam.o, cam.d, 0.0, t)) : 1.0;
        sum += T_box * (vec3(1.0) - grid_albedo(x)) * grid_emission(x);
    }
    return sum * (P / float(CAMERA_EMISSION_SAMPLES));
}

// The stage, then its counters into the stats buffer.
void main() {
    restir_load();
    restir_main();
    film_flush_counters();
}

void restir_main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (!film_contains(pixel)) {
        return;
    }
    COUNT(CTR_SAMPLES, 1);
    uint at = res_at(u_push.src, pixel);
    uint rng = rng_init(pixel, u_push.frame, 3u, u_frame.seed);
    Reservoir r = res_load(at);
    CameraRay cam = camera_ray(pixel, res_jitter(r), SET_CURRENT);
    vec3 L = vec3(0.0);
    if (aov_paths_on()) {
        aov_sample_begin();
    }
    // The shade cache (restir/resources.glsl: shade_cache_at), where F is a function of
    // the path alone (no path AOVs, the closed-form transmittance, direction reuse; the
    // pass allocates it only then, keeps_shade_cache): u_push.aux = 1 on a still frame
    // after a frame that shaded its history, where a set flag says that the temporal
    // stage kept this pixel's path, whose F the previous frame evaluated.
    bool cache = !aov_paths_on() && !SC_FINAL_RATIO_TRACKING && !SC_REUSE_VERTEX && u_restir.shade_cache_base != 0u;
    uint cache_at = cache ? shade_cache_at(pixel) : 0u;
    // An empty reservoir (no candidate with a positive target) estimates 0.
    if (res_valid(r) && r.p_hat > 0.0 && r.M > 0.0 && r.w_sum > 0.0) {
        vec3 f = vec3(0.0);
        bool evaluate = true;
        if (cache && u_push.aux == 1u && reservoirs[cache_at + 3u] == 1u) {
            f = uintBitsToFloat(uvec3(reservoirs[cache_at], reservoirs[cache_at + 1u], reservoirs[cache_at + 2u]));
            evaluate = false;
        }
        // A loop, not an if: on lavapipe code outside loops runs for every lane of a SIMD
        // row whether its branch is taken or not (docs/performance.md, "The temporal pass
        // of a still frame"), and a loop that no lane enters is skipped.
        while (evaluate) {
            f = path_value(at, r, cam, cam, MODE_FINAL, rng);
            if (cache) {
                uvec3 bits = floatBitsToUint(f);
                reservoirs[cache_at] = bits.x;
                reservoirs[cache_at + 1u] = bits.y;
                reservoirs[cache_at + 2u] = bits.z;
                reservoirs[cache_at + 3u] = 1u;
            }
            evaluate = false;
        }
        // Domain: p_hat > 0 and M > 0 (checked).
        if (aov_paths_on()) {
            // The terms times W; the RGB is the sum of the weighted slots.
            restir_aov_weigh(r.w_sum / (r.p_hat * r.M));
            L = restir_aov_sum();
        } else {
            L = f * (r.w_sum / (r.p_hat * r.M));
        }
    } else if (cache) {
        reservoirs[cache_at + 3u] = 0u;
    }
    if (SC_CAMERA_EMISSION) {
        // Emitted with no scattering: the emission AOV's slot (and the default group).
        vec3 e = camera_emission(pixel, rng);
        if (aov_paths_on()) {
            aov_add(aov_kind_emitted(0u), AOV_GROUP_DEFAULT, e);
            L = restir_aov_sum();
        } else {
            L += e;
        }
    }
    // A non-finite estimate counts as 0: the frame still counts (uniform mean weights).
    if (!film_sample_finite(L)) {
        L = vec3(0.0);
        if (aov_paths_on()) {
            aov_sample_begin();
        }
    }
    // The film's alpha: 1 - the camera ray's closed-form transmittance through the media,
    // 1 where it meets an emitting sphere or a shape (opaque where nothing reads alpha).
    float T_camera = 0.0;
    if (SC_ALPHA) {
        uint light_index;
        bool opaque = nearest_sphere_light(light_base(SET_CURRENT), cam.o, cam.d, 1e-6, FAR, light_index) < FAR ||
                      occluded(cam.o, cam.d, 0.0);
        T_camera = opaque ? 0.0 : grid_transmittance(cam.o, cam.d, 0.0, FAR) * boxes_transmittance(cam.o, cam.d, FAR);
    }
    film_accumulate(pixel, L, 1.0 - clamp(T_camera, 0.0, 1.0));
    // The weighted slots are the frame's estimates (a dropped sample's are 0).
    aov_accumulate(pixel, 1.0);
    if (SC_AOV_GEOMETRY) {
        restir_geometry_aovs(pixel);
    }
}
