// Volumetric ReSTIR (Lin, Wyman and Yuksel 2021): a stored path and its value.
// path_value is the path's contribution for a camera ray, either the target function
// p_hat (Algorithm 4) or the integrand F with unbiased transmittance (Algorithm 6).
//
// Paths. A stored path has k' medium vertices x_1..x_k' (k' = 0: the camera ray itself
// ends on a light, "direct"). x_1 = x_0 + z_1 omega_0 where omega_0 is the camera ray of
// the pixel that EVALUATES the path, so a path moves between pixels by keeping z_1
// (sec. 4.2). Then x_i = x_{i-1} + z_i omega_{i-1}, with omega_i stored (direction reuse);
// with vertex reuse x_2 is kept in world space instead (see path_value). A scattering path
// ends in a light vertex (a light index with a stored direction or point); an emission
// path ends at x_k', where the medium emits. Measures: (z, omega) per segment, solid angle
// for the environment, area for sphere lights, delta for directional and point lights.
//
// Surfaces (SC_HAS_SHAPES): a vertex may lie on an opaque Lambertian shape; its stored z is
// negative (path_surfaces.glsl), so a reservoir holds the same bytes with surfaces as
// without.
//
// The parts: camera_ray.glsl (the camera rays), transmittance.glsl (T~ and T),
// pc_tracking.glsl (candidate generation's tracking), vertex_media.glsl (the media at a
// vertex), path_surfaces.glsl (surface vertices) and path_lights.glsl (the light vertex).
// This file includes them in that order.
#ifndef NIMBUS_RESTIR_PATH_VALUE_GLSL
#define NIMBUS_RESTIR_PATH_VALUE_GLSL

#include "resources.glsl"
#include "camera.glsl"
#include "counters.glsl"
#include "phase.glsl"
// offset_ray_origin and Russian roulette (include/path.glsl).
#include "path.glsl"
#include "camera_ray.glsl"
#include "transmittance.glsl"
#include "pc_tracking.glsl"
#include "vertex_media.glsl"
#include "path_surfaces.glsl"
#include "path_lights.glsl"
#include "path_aovs.glsl"

// Path values (Algorithm 4 for targets, Algorithm 6's F for final shading).

#define MODE_TARGET 0u
#define MODE_FINAL 1u

// True if an emitting sphere of the set cuts o + t d for t in (0, t1).
bool segment_hits_light(uint set, vec3 o, vec3 d, float t1) {
    uint index;
    return nearest_sphere_light(light_base(set), o, d, 1e-6, t1, index) < FAR;
}

// The RGB value of the path stored at `at` (header r) for camera ray `cam`:
//   MODE_TARGET: the target function with T~ ray marched on mip_reuse, in cam.set's frame;
//   MODE_FINAL:  the integrand F with unbiased transmittance (current frame).
// `src` is the camera ray of the pixel that owns the stored representation; only vertex
// reuse needs it, to rebuild x_2 in world space.
// With path AOVs (aov_paths_on()), the final mode also leaves the value's terms in the
// sample's AOV slots (path_aovs.glsl) and returns their sum.
vec3 path_value(uint at, Reservoir r, CameraRay cam, CameraRay src, uint mode, inout uint rng) {
    bool split = aov_paths_on() && mode == MODE_FINAL;
    if (split) {
        aov_sample_begin();
    }
    if (!res_valid(r)) {
        return vec3(0.0);
    }
    uint set = cam.set;
    uint lbase = light_base(set);
    // The environment as the set's frame turns it: a path reused from the previous frame
    // sees this frame's map along its stored direction when evaluated in this frame.
    vec2 env_rot = env_rotation_of(set);
    uint kp = res_vertices(r);
    if (kp == 0u) {
        // The camera ray ends on a light: L^s times the transmittance of the whole ray.
        float t_end;
        vec3 L = camera_end(set, cam.o, cam.d, t_end);
        if (!any(greaterThan(L, vec3(0.0)))) {
            return vec3(0.0);
        }
        float T = mode == MODE_FINAL ? final_transmittance(cam.o, cam.d, t_end, rng)
                                     : reuse_transmittance(set, cam.o, cam.d, t_end);
        if (split) {
            // Emission seen directly: the group of the sphere light or the environment
            // it ends on (an emitting shape's is the default group).
            aov_add(aov_kind_emitted(0u), camera_end_group(set, cam.o, cam.d),
                    L * T * boxes_transmittance(cam.o, cam.d, t_end));
            return restir_aov_sum();
        }
        return L * T * boxes_transmittance(cam.o, cam.d, t_end);
    }
    // The medium vertex's scattering, set at each medium vertex.
    VertexMedium vm = vertex_medium_none();
    // Vertex reuse: x_2 of the owner's path, in world space.
    bool keep_x2 = SC_REUSE_VERTEX && kp >= 2u;
    vec3 x2_world = vec3(0.0);
    if (keep_x2) {
        vec3 x1_src = src.o + res_z(at, 1u) * src.d;
        x2_world = x1_src + res_z(at, 2u) * oct_decode(res_omega(at, 1u));
    }
    vec3 f = vec3(1.0);
    vec3 x = cam.o;
    vec3 w = cam.d;
    // The volume-measure geometry term of x_2 under vertex reuse, else 1.
    float geometry = 1.0;
    // The surface the last vertex lies on (shape NO_INDEX: a medium vertex).
    SurfacePoint surface = surface_none(x, w);
    // sigma_a Le of the last vertex under folded emission (0 otherwise).
    vec3 last_emitted = vec3(0.0);
    for (uint i = 1u; i <= kp; ++i) {
        float z = res_z(at, i);
        if (i == 1u && z >= 0.0) {
            // The owner's depth past its anchor, on this ray (a vertex before the camera
            // is not on it).
            z += cam.anchor - src.anchor;
            if (!(z >= 0.0)) {
                return vec3(0.0);
            }
        }
        if (i >= 2u) {
            vec3 w_next;
            if (i == 2u && keep_x2) {
                vec3 to = x2_world - x;
                float z2 = dot(to, to);
                // Domain: x_2 != x_1 (G = 1 / z_2^2 is unbounded there).
                if (!(z2 > 0.0)) {
                    return vec3(0.0);
                }
                z = sqrt(z2);
                w_next = to / z;
                geometry = 1.0 / z2;
            } else {
                w_next = oct_decode(res_omega(at, i - 1u));
            }
            // Scattering at x_{i-1} from the travel direction w to w_next: the BRDF on a
            // surface, sigma_s times the phase function of each medium there.
            f *= vertex_scatter(surface, w, vm, w_next);
            w = w_next;
        }
        bool on_surface = SC_HAS_SHAPES && z < 0.0;
        if (on_surface) {
            // The vertex is where the ray meets a shape (none: the path is gone).
            surface = surface_along(x, w, FAR);
            if (surface.shape == NO_INDEX) {
                return vec3(0.0);
            }
            z = surface.t;
        } else {
            if (!(z >= 0.0 && z < FAR)) {
                return vec3(0.0);
            }
            // A medium vertex behind a shape is not on this path.
            if (shapes_block(x, w, z)) {
                return vec3(0.0);
            }
            surface.shape = NO_INDEX;
        }
        if (segment_hits_light(set, x, w, z)) {
            return vec3(0.0);
        }
        float T = mode == MODE_FINAL ? final_transmittance(x, w, z, rng) : reuse_transmittance(set, x, w, z);
        f *= T * boxes_transmittance(x, w, z);
        if (on_surface) {
            // Surfaces emit nothing along stored paths; they reflect by their albedo.
            if (res_emission(r) && i == kp) {
                return vec3(0.0);
            }
            x = surface.x;
            if (!any(greaterThan(f * surface.albedo, vec3(0.0)))) {
                return vec3(0.0);
            }
            continue;
        }
        x += z * w;
        float sigma_t = mode == MODE_FINAL ? grid_sigma_t(x) : sigma_t_of(set, x);
        vec3 albedo = grid_albedo(x);
        vm = vertex_medium(x, sigma_t, albedo);
        if (i == kp && res_emission(r)) {
            // Under SC_CAMERA_EMISSION the camera segment's emission is shade.comp's own
            // estimate, outside the reservoirs: no path of the integrand ends there.
            if (!SC_HAS_EMISSION || !(sigma_t > 0.0) || (SC_CAMERA_EMISSION && i == 1u)) {
                return vec3(0.0);
            }
            // Emission path: the grid's sigma_a Le at x_k' (absorbed-emission convention;
            // a box does not emit).
            if (split) {
                // Emitted after the k' - 1 scatterings before x_k'.
                aov_add(aov_kind_emitted(kp - 1u), AOV_GROUP_DEFAULT,
                        f * (vec3(1.0) - albedo) * sigma_t * grid_emission(x) * geometry);
                return restir_aov_sum();
            }
            return f * (vec3(1.0) - albedo) * sigma_t * grid_emission(x) * geometry;
        }
        // Folded emission: the last vertex's sigma_a Le joins its light terms.
        if (SC_FOLD_EMISSION && i == kp && sigma_t > 0.0 && !(SC_CAMERA_EMISSION && i == 1u)) {
            last_emitted = (vec3(1.0) - albedo) * sigma_t * grid_emission(x);
        }
        // Scattering at x_i by the media there (sigma_s rho, applied with the next
        // direction).
        if (!any(greaterThan(f * (vm.sigma_s_grid + vm.sigma_s_box + last_emitted), vec3(0.0)))) {
            return vec3(0.0);
        }
    }
    // The light vertex re-evaluated from x_k' and, with split NEE, every delta light
    // weighted by the environment sample's density q (one loop: the transmittance code is
    // compiled once).
    vec3 stored_dir = oct_decode(r.light_dir);
    if (res_light(r) == LIGHT_ENV) {
        stored_dir = env_reused_dir(stored_dir, env_rot);
    }
    float q = SC_NEE_SPLIT ? env_sample_pdf(stored_dir, env_rot) : 1.0;
    vec3 light = vec3(0.0);
    uint terms = light_terms();
    for (uint k = 0u; k < terms; ++k) {
        vec3 wi;
        float dist;
        vec3 L = k == 0u ? light_eval(lbase, env_rot, res_light(r), stored_dir, r.light_dir, r.light_point, x, wi, dist)
                         : q * light_term(lbase, env_rot, k, x, wi, dist);
        vec3 s = vertex_scatter(surface, w, vm, wi) * L;
        if (!any(greaterThan(s, vec3(0.0))) || light_blocked(lbase, x, wi, dist) || shapes_block(x, wi, dist)) {
            continue;
        }
        float T = mode == MODE_FINAL ? final_transmittance(x, wi, dist, rng) : reuse_transmittance(set, x, wi, dist);
        if (split) {
            // Light scattered at each of the k' vertices; term 0 is the stored light's,
            // term k the delta light k - 1's.
            vec3 term = s * T * boxes_transmittance(x, wi, dist);
            aov_add(aov_kind_nee(kp - 1u), restir_light_group(set, k == 0u ? res_light(r) : k - 1u), term);
            light += term;
            continue;
        }
        light += s * T * boxes_transmittance(x, wi, dist);
    }
    // Folded emission, weighted by q as the delta lights are: its integral over the
    // environment sample is sigma_a Le (without split NEE the environment is the only
    // light, drawn with probability 1: q is its density).
    float q_fold = SC_NEE_SPLIT ? q : env_sample_pdf(stored_dir, env_rot);
    if (split) {
        // Folded emission: emitted at x_k', after the k' - 1 scatterings before it.
        if (SC_FOLD_EMISSION) {
            aov_add(aov_kind_emitted(kp - 1u), AOV_GROUP_DEFAULT, q_fold * last_emitted);
        }
        restir_aov_finish(f, geometry);
        return restir_aov_sum();
    }
    light += q_fold * last_emitted;
    return f * light * geometry;
}

#endif
