// Volumetric ReSTIR: how a path's medium vertex scatters, with the homogeneous box media
// beside the grid, and their transmittance.
#ifndef NIMBUS_RESTIR_VERTEX_MEDIA_GLSL
#define NIMBUS_RESTIR_VERTEX_MEDIA_GLSL

#include "resources.glsl"
#include "phase.glsl"

// Scalar target from an RGB contribution: luminance (positive weights, so > 0 exactly
// when some channel is > 0 for non-negative colours).
float luminance(vec3 c) {
    return dot(c, vec3(0.2126, 0.7152, 0.0722));
}

// The target function's scalar of an RGB contribution (`target`, SC_TARGET_SCALAR):
// luminance (the paper's), the channels' sum or their maximum. Each is positive exactly
// where some channel is (non-negative colours) and positively homogeneous, so a
// candidate's weight p_hat / p is the scalar of its RGB weight, and every estimate stays
// unbiased. Sum and max keep each channel's f_c / p_hat at most 1, where luminance lets a
// blue-lit path weigh up to 1 / 0.0722.
float target_scalar(vec3 c) {
    if (SC_TARGET_SCALAR == SC_TARGET_SUM) {
        return c.r + c.g + c.b;
    }
    if (SC_TARGET_SCALAR == SC_TARGET_MAX) {
        return max(c.r, max(c.g, c.b));
    }
    return luminance(c);
}

// Homogeneous box media beside the grid (SC_HAS_MEDIA). They are disjoint from each other
// and may overlap the grid, where the extinctions add; their transmittance is the closed
// form everywhere (targets, NEE and final shading alike), and a box is its own
// piecewise-constant majorant in tracking (sigma* = sigma_t).

// Whether box or convex medium m holds x.
bool box_medium_holds(uint m, vec3 x) {
    BoxMedium bm = media[m];
    vec3 p = x - bm.center;
    vec3 local = vec3(dot(bm.world_to_local[0].xyz, p), dot(bm.world_to_local[1].xyz, p),
                      dot(bm.world_to_local[2].xyz, p));
    return all(lessThanEqual(abs(local), bm.half_size)) && medium_contains_local(bm, local);
}

// The first box or convex medium holding x, NO_INDEX if none (the grid or vacuum).
uint box_medium_at(vec3 x) {
    uint count = SC_HAS_MEDIA ? u_frame.box_media_count : 0u;
    for (uint m = 0u; m < count; ++m) {
        if (box_medium_holds(m, x)) {
            return m;
        }
    }
    return NO_INDEX;
}

// How a medium vertex at x scatters: the grid's sigma_s (albedo there times its sigma_t,
// `sigma_t_grid`, 0 outside the grid) and g, and the box and convex media holding x.
// Where media overlap, all of them scatter: a path vertex there is a collision with any
// one, at the summed density (docs/scene-format.md, "Overlapping media"), so its value
// is the sum of the media's sigma_s rho. One box is kept in the struct (its g); with
// several, the functions below visit the media holding x again.
struct VertexMedium {
    vec3 x;
    uint box_count;         // box or convex media holding x
    vec3 sigma_s_grid;
    float g_grid;
    vec3 sigma_s_box;       // their summed sigma_s ...
    float g_box;            // ... and, with one, its g
    float sigma_t_box;      // their summed sigma_t
};

// No medium (a surface vertex).
VertexMedium vertex_medium_none() {
    VertexMedium m;
    m.x = vec3(0.0);
    m.box_count = 0u;
    m.sigma_s_grid = vec3(0.0);
    m.g_grid = 0.0;
    m.sigma_s_box = vec3(0.0);
    m.g_box = 0.0;
    m.sigma_t_box = 0.0;
    return m;
}

// The media at x, the grid's sigma_t (`sigma_t_grid`) and albedo there given.
VertexMedium vertex_medium(vec3 x, float sigma_t_grid, vec3 albedo_grid) {
    VertexMedium m = vertex_medium_none();
    m.x = x;
    m.sigma_s_grid = albedo_grid * sigma_t_grid;
    m.g_grid = u_base.g;
    uint count = SC_HAS_MEDIA ? u_frame.box_media_count : 0u;
    for (uint b = 0u; b < count; ++b) {
        if (box_medium_holds(b, x)) {
            m.box_count += 1u;
            m.sigma_s_box += media[b].sigma_s;
            m.g_box = media[b].g;
            m.sigma_t_box += media[b].sigma_t;
        }
    }
    return m;
}

// sum over the media at the vertex of sigma_s rho(cos), rho the HG phase function.
vec3 medium_scatter(VertexMedium m, float cos_theta) {
    vec3 s = m.sigma_s_grid * hg_phase(cos_theta, m.g_grid);
    if (SC_HAS_MEDIA) {
        if (m.box_count <= 1u) {
            s += m.sigma_s_box * hg_phase(cos_theta, m.g_box);
        } else {
            for (uint b = 0u; b < u_frame.box_media_count; ++b) {
                if (box_medium_holds(b, m.x)) {
                    s += media[b].sigma_s * hg_phase(cos_theta, media[b].g);
                }
            }
        }
    }
    return s;
}

// The probability that the vertex's next direction follows the box's phase function
// (in proportion to the luminance of its sigma_s), 0 without a box.
float medium_box_share(VertexMedium m) {
    float lb = SC_HAS_MEDIA ? luminance(m.sigma_s_box) : 0.0;
    float lg = luminance(m.sigma_s_grid);
    return lb > 0.0 ? lb / (lg + lb) : 0.0;
}

// The g of the box medium the next direction follows, once a box is chosen (share
// medium_box_share): with several at the vertex, one drawn in proportion to the
// luminance of its sigma_s (one random number more, only there).
float medium_pick_box_g(VertexMedium m, inout uint rng) {
    if (m.box_count <= 1u) {
        return m.g_box;
    }
    float u = rng_next(rng) * luminance(m.sigma_s_box);
    float acc = 0.0;
    float g = m.g_box;
    for (uint b = 0u; b < u_frame.box_media_count; ++b) {
        if (box_medium_holds(b, m.x)) {
            g = media[b].g;
            acc += luminance(media[b].sigma_s);
            if (u < acc) {
                break;
            }
        }
    }
    return g;
}

// The density (solid angle) at cos_theta of the direction drawn with box share q_box
// and medium_pick_box_g: the mixture of the media's phase functions.
float medium_phase_pdf(VertexMedium m, float q_box, float cos_theta) {
    float p = (1.0 - q_box) * hg_phase(cos_theta, m.g_grid);
    if (m.box_count <= 1u) {
        return p + q_box * hg_phase(cos_theta, m.g_box);
    }
    float lb = luminance(m.sigma_s_box);
    for (uint b = 0u; b < u_frame.box_media_count; ++b) {
        if (box_medium_holds(b, m.x)) {
            // Domain: lb > 0 wherever q_box > 0; a box of luminance 0 weighs 0.
            float share = lb > 0.0 ? q_box * luminance(media[b].sigma_s) / lb : 0.0;
            p += share * hg_phase(cos_theta, media[b].g);
        }
    }
    return p;
}

// Transmittance of the box media along o + t d, t in [0, t1] (1 without them).
float boxes_transmittance(vec3 o, vec3 d, float t1) {
    if (!SC_HAS_MEDIA) {
        return 1.0;
    }
    return exp(-box_optical_depth(o, d, 0.0, t1));
}

#endif
