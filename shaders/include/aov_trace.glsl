// The geometric AOVs' tracing function, aov_geometry_point (declared in aov.glsl): the
// nearer of the camera ray's first surface and the point where its transmittance through
// every medium first falls to 0.5 (optical depth ln 2), with the normal and albedo there.
//
// The media's optical depth along the ray is piecewise: the box and convex media are
// constant between the ray's entries into and exits from them (where they overlap their
// extinctions add), the grid is the exact trilinear field (grid_dual.glsl). The ray is cut
// at every entry and exit; each piece's depth is the boxes' sigma_t times its length plus
// the grid's closed-form integral, and the piece where the running depth passes ln 2 is
// inverted exactly: linearly for boxes alone, by the grid's exact inversion
// (grid_invert_optical_depth) where the grid alone is there, by bisection on the sum
// where both overlap. No sampling: the depth is exact to float rounding.
//
// Include it after the scene code the pass uses:
// - the grid passes (baseline, ReSTIR): grid_resources.glsl (grid, lights), shapes.glsl,
//   box_media.glsl (SC_HAS_MEDIA), with u_grid / u_base loaded;
// - the box pass: define AOV_TRACE_NO_GRID first; box_media.glsl and shapes.glsl.
#ifndef NIMBUS_AOV_TRACE_GLSL
#define NIMBUS_AOV_TRACE_GLSL

#include "constants.glsl"

// Optical depth at which the transmittance is 0.5.
#define AOV_LN2 0.69314718055994530942

// The box media's span along o + t d clipped to [0, t_end]; empty (x >= y) if missed.
vec2 aov_box_span(uint m, vec3 o, vec3 d, float t_end) {
    vec2 s = box_medium_span(m, o, d);
    return vec2(max(s.x, 0.0), min(s.y, t_end));
}

uint aov_box_count() {
    return SC_HAS_MEDIA ? u_frame.box_media_count : 0u;
}

#ifndef AOV_TRACE_NO_GRID
// The grid's span along o + t d clipped to [0, t_end] (empty without density).
vec2 aov_grid_span(vec3 o, vec3 d, float t_end) {
    if (!(u_grid.density_scale > 0.0)) {
        return vec2(FAR, -FAR);
    }
    vec2 s = grid_span(o, d);
    return vec2(max(s.x, 0.0), min(s.y, t_end));
}

// The grid's optical depth over [a, b] plus sigma_boxes (b' - a) ... inverted: the t in
// [a, b] where sigma_b (t - a) + tau_grid(a, t) = target, by bisection (both increase).
float aov_invert_mixed(vec3 o, vec3 d, float a, float b, float sigma_b, float target) {
    float lo = a;
    float hi = b;
    for (int i = 0; i < 40; ++i) {
        float mid = 0.5 * (lo + hi);
        float tau = sigma_b * (mid - a) + grid_optical_depth(o, d, a, mid);
        if (tau < target) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return 0.5 * (lo + hi);
}
#endif

// The t in [0, t_end) where the transmittance of o + t d through the media first falls to
// 0.5, or FAR if it stays above.
float aov_medium_point(vec3 o, vec3 d, float t_end) {
    uint count = aov_box_count();
#ifndef AOV_TRACE_NO_GRID
    vec2 g = aov_grid_span(o, d, t_end);
#endif
    float tau = 0.0;
    float t = 0.0;
    // Each piece ends at the next entry or exit: at most two per medium and the grid's.
    for (uint piece = 0u; piece < 2u * count + 3u; ++piece) {
        float next = t_end;
        for (uint m = 0u; m < count; ++m) {
            vec2 s = aov_box_span(m, o, d, t_end);
            if (s.y > s.x) {
                next = s.x > t ? min(next, s.x) : next;
                next = s.y > t ? min(next, s.y) : next;
            }
        }
#ifndef AOV_TRACE_NO_GRID
        if (g.y > g.x) {
            next = g.x > t ? min(next, g.x) : next;
            next = g.y > t ? min(next, g.y) : next;
        }
#endif
        if (!(next > t) || next >= FAR) {
            return FAR;
        }
        float mid = 0.5 * (t + next);
        float sigma_b = 0.0;
        for (uint m = 0u; m < count; ++m) {
            vec2 s = aov_box_span(m, o, d, t_end);
            if (s.x <= mid && mid < s.y) {
                sigma_b += media[m].sigma_t;
            }
        }
        float piece_tau = sigma_b * (next - t);
#ifndef AOV_TRACE_NO_GRID
        bool in_grid = g.x <= mid && mid < g.y;
        if (in_grid) {
            piece_tau += grid_optical_depth(o, d, t, next);
        }
#endif
        if (tau + piece_tau >= AOV_LN2 && piece_tau > 0.0) {
            float remaining = AOV_LN2 - tau;
#ifndef AOV_TRACE_NO_GRID
            if (in_grid) {
                if (sigma_b > 0.0) {
                    return aov_invert_mixed(o, d, t, next, sigma_b, remaining);
                }
                float x = grid_invert_optical_depth(o, d, t, next, remaining);
                return x < FAR ? x : next;
            }
#endif
            // Domain: sigma_b > 0, since piece_tau > 0 without the grid.
            return min(t + remaining / sigma_b, next);
        }
        tau += piece_tau;
        t = next;
        if (t >= t_end) {
            break;
        }
    }
    return FAR;
}

// The extinction-weighted single-scattering albedo of the media at x (on the ray at t),
// and the normal there: a box's face normal where x lies at its entry (within 1e-3 of
// the distance), else the normalised negative gradient of the grid's density (0 where it
// vanishes; a box's is 0 inside).
void aov_medium_surface(vec3 o, vec3 d, float t, out vec3 normal, out vec3 albedo) {
    vec3 x = o + t * d;
    float sigma_t = 0.0;
    vec3 sigma_s = vec3(0.0);
    normal = vec3(0.0);
    uint count = aov_box_count();
    float eps = 1e-3 * t + 1e-6;
    for (uint m = 0u; m < count; ++m) {
        vec2 s = box_medium_span(m, o, d);
        if (!(s.x <= t + eps && t <= s.y + eps) || !(s.y > s.x)) {
            continue;
        }
        BoxMedium bm = media[m];
        sigma_t += bm.sigma_t;
        sigma_s += bm.sigma_s;
        if (s.x > 0.0 && t - s.x <= eps && normal == vec3(0.0)) {
            // The face the ray entered by, in the medium's frame.
            vec3 rel = x - bm.center;
            vec3 local = vec3(dot(bm.world_to_local[0].xyz, rel), dot(bm.world_to_local[1].xyz, rel),
                              dot(bm.world_to_local[2].xyz, rel));
            vec3 n_local = vec3(0.0);
            if (medium_is_convex(bm)) {
                float best = -FAR;
                for (uint i = 0u; i < bm.plane_count; ++i) {
                    vec4 plane = medium_planes[bm.plane_first + i];
                    float dist = dot(plane.xyz, local) - plane.w;
                    if (dist > best) {
                        best = dist;
                        n_local = plane.xyz;
                    }
                }
            } else {
                vec3 q = abs(local) / bm.half_size;
                int axis = (q.x >= q.y && q.x >= q.z) ? 0 : ((q.y >= q.z) ? 1 : 2);
                n_local[axis] = local[axis] < 0.0 ? -1.0 : 1.0;
            }
            vec3 n = n_local.x * bm.world_to_local[0].xyz + n_local.y * bm.world_to_local[1].xyz +
                     n_local.z * bm.world_to_local[2].xyz;
            normal = length(n) > 0.0 ? normalize(n) : vec3(0.0);
        }
    }
#ifndef AOV_TRACE_NO_GRID
    float sigma_g = grid_sigma_t(x);
    if (sigma_g > 0.0) {
        sigma_t += sigma_g;
        sigma_s += sigma_g * grid_albedo(x);
    }
    if (normal == vec3(0.0) && space_contains(u_grid.space, x)) {
        // Central differences half a voxel either side in index space, mapped to world:
        // grad_world_i = grad_p . (dp / dx_i).
        vec3 p = space_to_index(u_grid.space, x);
        const float h = 0.5;
        vec3 grad_p = vec3(grid_sigma_index(p + vec3(h, 0.0, 0.0)) - grid_sigma_index(p - vec3(h, 0.0, 0.0)),
                           grid_sigma_index(p + vec3(0.0, h, 0.0)) - grid_sigma_index(p - vec3(0.0, h, 0.0)),
                           grid_sigma_index(p + vec3(0.0, 0.0, h)) - grid_sigma_index(p - vec3(0.0, 0.0, h)));
        vec3 grad = vec3(dot(grad_p, space_index_dir(u_grid.space, vec3(1.0, 0.0, 0.0))),
                         dot(grad_p, space_index_dir(u_grid.space, vec3(0.0, 1.0, 0.0))),
                         dot(grad_p, space_index_dir(u_grid.space, vec3(0.0, 0.0, 1.0))));
        float len = length(grad);
        normal = len > 1e-20 ? -grad / len : vec3(0.0);
    }
#endif
    // Domain: sigma_t > 0 where divided.
    albedo = sigma_t > 0.0 ? sigma_s / sigma_t : vec3(0.0);
}

bool aov_geometry_point(vec3 o, vec3 d, out float t, out vec3 normal, out vec3 albedo) {
    uint shape_index;
    float t_surface = nearest_shape(o, d, 0.0, FAR, shape_index);
    float t_end = t_surface;
#ifndef AOV_TRACE_NO_GRID
    uint light_index;
    float t_light = nearest_sphere_light(0u, o, d, 0.0, t_surface, light_index);
    t_end = min(t_end, t_light);
#endif
    float t_medium = aov_medium_point(o, d, t_end);
    normal = vec3(0.0);
    albedo = vec3(0.0);
    t = FAR;
    if (t_medium < FAR) {
        t = t_medium;
        aov_medium_surface(o, d, t, normal, albedo);
        return true;
    }
#ifndef AOV_TRACE_NO_GRID
    if (t_light < t_surface) {
        // An emitting sphere: its outward normal, no albedo.
        t = t_light;
        vec3 n = o + t * d - lights[light_index].direction_or_position;
        normal = length(n) > 0.0 ? normalize(n) : -d;
        return true;
    }
#endif
    if (t_surface < FAR) {
        t = t_surface;
        Shape s = shapes[shape_index];
        normal = shape_normal(s, o + t * d, d);
        albedo = s.albedo;
        return true;
    }
    return false;
}

#endif
