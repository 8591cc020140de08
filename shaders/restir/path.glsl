// Volumetric ReSTIR (Lin, Wyman and Yuksel 2021): a stored path and its value.
//
//   - camera rays of a pixel and frame, at the sub-pixel position the path keeps;
//   - regular tracking through the conservative piecewise-constant grid at a mip level
//     (candidate generation, sec. 4.1, eq. 27-28);
//   - ray-marched trilinear transmittance T~ on a mip texture (target functions, sec. 5.1);
//   - path_value: the path's contribution for a camera ray, either the target function
//     p_hat (Algorithm 4) or the integrand F with unbiased transmittance (Algorithm 6).
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
// negative (see "Surface vertices" below), so a reservoir holds the same bytes with
// surfaces as without.
//
// (Not to be confused with include/path.glsl, the path bookkeeping of every integrator;
// an #include "path.glsl" from this folder finds this file first.)
#ifndef NIMBUS_RESTIR_PATH_GLSL
#define NIMBUS_RESTIR_PATH_GLSL

#extension GL_GOOGLE_include_directive : require

#include "resources.glsl"
#include "camera.glsl"
#include "counters.glsl"
#include "phase.glsl"
// offset_ray_origin and Russian roulette (not this folder's path.glsl).
#include "../include/path.glsl"

// Scalar target from an RGB contribution: luminance (positive weights, so > 0 exactly
// when some channel is > 0 for non-negative colours).
float luminance(vec3 c) {
    return dot(c, vec3(0.2126, 0.7152, 0.0722));
}

// ---------------------------------------------------------------------------------------
// Camera rays. The sub-pixel position is part of the path: each random walk draws its
// own jitter code (camera.glsl), the reservoir keeps it (`info` bits 16-31), and a path
// moving to another pixel or frame keeps it, so temporal reuse re-evaluates a path on the
// same ray it was found on.

struct CameraRay {
    vec3 o;
    vec3 d;
    uint set;
    // The ray's depth anchor (m): a path owned by ray a keeps its first medium vertex's
    // depth past the anchor on ray b, z_1' = z_1 - a.anchor + b.anchor (a translation:
    // Jacobian 1). Temporal reuse anchors both pixels' rays where they enter the medium,
    // so that a moving camera's history lands at the depth it was found at (keeping z_1
    // itself put every reused vertex of a dollying camera deeper, where the canonical
    // samples' MIS weights collapsed); 0 elsewhere.
    float anchor;
};

// The camera ray through `pixel` at sub-pixel jitter `code`, in a frame's set.
CameraRay camera_ray(uvec2 pixel, uint code, uint set) {
    CameraRay r;
    r.set = set;
    r.anchor = 0.0;
    vec2 px = vec2(pixel) + jitter_code_offset(code);
    if (set == SET_CURRENT) {
        r.o = u_frame.cam_position;
        r.d = camera_direction(u_frame, px);
    } else {
        r.o = u_prev_frame.cam_position;
        r.d = camera_direction(u_prev_frame, px);
    }
    return r;
}

// ---------------------------------------------------------------------------------------
// Media lookups for a frame's set.

float sigma_t_of(uint set, vec3 x) {
    return set == SET_CURRENT ? grid_sigma_t_in(u_density, x)
                              : grid_sigma_t_at(u_density_prev, u_restir.density_prev_offset, x);
}

// The largest optical depth a ray-marched T~ reports (T~ >= e^-64, a normal float).
#define MARCH_MAX_TAU 64.0

// T~ along o + t d, t in [t0, t1]: midpoint ray marching of the mip level L (its atlas
// `tex`, indirection section at `offset`) with steps of at most `step` metres, the texture
// filtered linearly inside a slot (the apron holds the upper neighbours). Samples in an
// empty brick read 0, so the march jumps over such bricks to the first sample past them
// (the same sum). Deterministic, so a target function is a function of the path (needed by
// the MIS weights).
float march_transmittance(sampler3D tex, GridLevel L, uint offset, float step, vec3 o, vec3 d,
                          float t0, float t1) {
    vec2 span = grid_span(o, d);
    float a = max(t0, span.x);
    float b = min(t1, span.y);
    if (!(a < b)) {
        return 1.0;
    }
    // Domain: step > 0 (a voxel diagonal).
    int n = int(clamp(ceil((b - a) / step), 1.0, float(MARCH_MAX_STEPS)));
    float dt = (b - a) / float(n);
    // The level's lattice coordinate u = p / factor - 0.5 along the ray. Domain: factor >= 1.
    float inv_f = 1.0 / float(L.factor);
    vec3 u0 = space_to_index(u_grid.space, o + a * d) * inv_f - 0.5;
    vec3 du = space_index_dir(u_grid.space, d) * inv_f;
    vec3 lo = vec3(L.lattice_min);
    vec3 hi = vec3(L.lattice_max);
    // Domain: the atlas has at least one slot.
    vec3 inv_size = 1.0 / vec3(textureSize(tex, 0));
    // The sum at which the optical depth reaches MARCH_MAX_TAU: past it T~ is e^-64
    // whatever the rest of the segment holds, so the march stops there (deep in a dense
    // cloud, most of a light segment). Domain: density_scale * dt > 0, else no cap.
    float scale_dt = u_grid.density_scale * dt;
    float sum_cap = scale_dt > 0.0 ? MARCH_MAX_TAU / scale_dt : FAR;
    float sum = 0.0;
    // The brick of the previous sample and its slot's first texel: consecutive samples
    // mostly share a brick, whose indirection lookup and slot arithmetic (three integer
    // divisions) are then not repeated.
    ivec3 brick_at = ivec3(-1);
    uint slot = NO_BRICK;
    vec3 origin = vec3(0.0);
    for (int j = 0; j < n; ++j) {
        float t = (float(j) + 0.5) * dt;
        vec3 u = clamp(u0 + du * t, lo, hi);
        ivec3 brick = ivec3(floor(u)) >> 3;
        if (brick != brick_at) {
            brick_at = brick;
            slot = grid_slot(offset, L.brick_dims, brick);
            origin = vec3(grid_slot_origin(slot, L.slots_x, L.slots_y) - brick * 8);
        }
        if (slot == NO_BRICK) {
            // Jump to the last sample before the ray leaves the brick (clamped samples
            // stay in it: no exit on that side).
            float t_exit = FAR;
            for (int k = 0; k < 3; ++k) {
                float edge = du[k] > 0.0 ? float(brick[k] * 8 + 8) : float(brick[k] * 8);
                bool exits = du[k] > 0.0 ? edge <= hi[k] : edge > lo[k];
                if (abs(du[k]) > GRID_PARALLEL_EPS && exits) {
                    // Domain: |du| > 0.
                    t_exit = min(t_exit, (edge - u0[k]) / du[k]);
                }
            }
            // Domain: dt > 0. floor keeps the jump from passing a sample in the next brick.
            float next = floor(min(t_exit / dt - 0.5, float(n)));
            j = max(j, int(next) - 1);
            continue;
        }
        vec3 texel = origin + u + 0.5;
        COUNT_STEP();
        COUNT(CTR_DENSITY, 1);
        sum += textureLod(tex, texel * inv_size, 0.0).r;
        if (sum >= sum_cap) {
            return exp(-MARCH_MAX_TAU);
        }
    }
    // Domain: density_scale * sum * dt >= 0. Capped at MARCH_MAX_TAU so T~ (and with it
    // every target function) stays > 0 wherever the path contributes: RIS is unbiased
    // only if p^ > 0 wherever f > 0, and an approximate T~ may exceed the true depth.
    return exp(-min(u_grid.density_scale * sum * dt, MARCH_MAX_TAU));
}

// T~ for target functions of reuse (mip_reuse) in a frame's set.
float reuse_transmittance(uint set, vec3 o, vec3 d, float t1) {
    float step = u_restir.march_reuse_step;
    COUNT_SHADOW_BEGIN();
    float T;
    if (set == SET_CURRENT) {
        T = march_transmittance(u_march_reuse, u_restir.march_reuse, u_restir.march_reuse.bricks_offset, step,
                                o, d, 0.0, t1);
    } else {
        T = march_transmittance(u_march_reuse_prev, u_restir.march_reuse, u_restir.march_reuse_prev_offset,
                                step, o, d, 0.0, t1);
    }
    COUNT_SHADOW_END();
    return T;
}

// T~ of NEE segments of initial candidates (mip_indirect).
float nee_transmittance(vec3 o, vec3 d, float t1) {
    COUNT_SHADOW_BEGIN();
    float T = march_transmittance(u_march_nee, u_restir.march_nee, u_restir.march_nee.bricks_offset,
                                  u_restir.march_nee_step, o, d, 0.0, t1);
    COUNT_SHADOW_END();
    return T;
}

// The residual majorant's multiple in final ratio tracking: the paper's advice is a large
// majorant ("forcing a smaller average step"); the tight global one it replaced gave
// 7-27x the per-frame RMSE of the closed form.
#define FINAL_RATIO_MAJORANT_SCALE 4.0

// Unbiased T for final shading: the closed form through the trilinear grid, or residual
// ratio tracking per super-voxel with a 4x majorant.
float final_transmittance(vec3 o, vec3 d, float t1, inout uint rng) {
    COUNT_SHADOW_BEGIN();
    float T = SC_FINAL_RATIO_TRACKING
                  ? grid_residual_ratio_tracking_scaled(o, d, 0.0, t1, FINAL_RATIO_MAJORANT_SCALE, rng)
                  : grid_transmittance(o, d, 0.0, t1);
    COUNT_SHADOW_END();
    return T;
}

// ---------------------------------------------------------------------------------------
// Regular tracking through the conservative piecewise-constant grid (eq. 27-28).

#define LEVEL_PRIMARY 0u
#define LEVEL_INDIRECT 1u

// Walks [0, t_end) from o along d through level `level` until the optical depth reaches
// tau_target. Returns the collision distance (FAR if the ray leaves first), sigma_t* there
// and tau = the optical depth walked (tau_target at a collision, the total otherwise).
// Blocks are the level's voxels (2^mip density voxels per edge); empty bricks of the level
// (sigma_t* = 0 throughout) are crossed in one step.
float pc_track(uint level, vec3 o, vec3 d, float t_end, float tau_target, out float sigma_star, out float tau) {
    // An if, not ?: — glslang's ?: on two block members stores a value of the
    // block's struct type into the local one, which the SPIR-V optimiser rejects.
    GridLevel L;
    if (level == LEVEL_PRIMARY) {
        L = u_restir.pc_primary;
    } else {
        L = u_restir.pc_indirect;
    }
    sigma_star = 0.0;
    tau = 0.0;
    GridSuperDda it;
    if (!grid_blocks_begin(o, d, 0.0, t_end, int(L.factor), L.lattice_max + 1, it)) {
        return FAR;
    }
    float s0;
    float s1;
    uint index;
    int steps = 0;
    // The brick of the previous cell, its slot and first texel (see march_transmittance).
    ivec3 brick_at = ivec3(-1);
    uint slot = NO_BRICK;
    ivec3 origin = ivec3(0);
    while (it.s < it.len && steps < GRID_MAX_STEPS) {
        ++steps;
        COUNT_STEP();
        ivec3 cell = it.cell;
        if ((cell >> 3) != brick_at) {
            brick_at = cell >> 3;
            slot = grid_slot(L.bricks_offset, L.brick_dims, brick_at);
            origin = grid_slot_origin(slot, L.slots_x, L.slots_y);
        }
        if (slot == NO_BRICK) {
            grid_blocks_skip_brick(it);
            continue;
        }
        grid_blocks_next(it, s0, s1, index);
        float sigma = texelFetch(u_pc, origin + (cell & 7), 0).r;
        COUNT(CTR_MAJORANT, 1);
        float dtau = sigma * (s1 - s0);
        if (sigma > 0.0 && tau + dtau >= tau_target) {
            sigma_star = sigma;
            // Domain: sigma > 0; the result lies in [s0, s1].
            float s = min(s0 + (tau_target - tau) / sigma, s1);
            tau = tau_target;
            return it.t_a + s;
        }
        tau += dtau;
    }
    return FAR;
}

// sigma_t* of level `level` (the conservative piecewise-constant grid pc_track walks) at
// x: 0 outside the density's box and in empty bricks.
float pc_sigma_star_at(uint level, vec3 x) {
    GridLevel L;
    if (level == LEVEL_PRIMARY) {
        L = u_restir.pc_primary;
    } else {
        L = u_restir.pc_indirect;
    }
    GridSpace s = u_grid.space;
    vec3 p = space_to_index(s, x);
    if (!(all(greaterThanEqual(p, s.index_min)) && all(lessThanEqual(p, s.index_max)))) {
        return 0.0;
    }
    // Domain: factor >= 1.
    float f = max(float(L.factor), 1.0);
    ivec3 cell = clamp(ivec3(floor(p / f)), ivec3(0), L.lattice_max);
    uint slot = grid_slot(L.bricks_offset, L.brick_dims, cell >> 3);
    if (slot == NO_BRICK) {
        return 0.0;
    }
    return texelFetch(u_pc, grid_slot_origin(slot, L.slots_x, L.slots_y) + (cell & 7), 0).r;
}

// ---------------------------------------------------------------------------------------
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

// ---------------------------------------------------------------------------------------
// Surface vertices. A stored vertex with z < 0 lies on a surface: it is where the ray from
// the previous vertex along the stored direction first meets a shape, found again by ray
// casting at every evaluation, so under direction reuse it moves with the path as a medium
// vertex does and the shift's Jacobian stays 1 (|z| is the distance it was found at, kept
// for inspection only). In the (z, omega) measure a surface vertex has no z: the walk
// reaches it with probability T* (no collision before it), and the path's value gains the
// transmittance up to it (no sigma_s) and then the Lambertian BRDF times the cosine of the
// direction that leaves it (albedo cos / pi, solid angle). Every segment is checked for
// visibility: a medium vertex must be seen from the previous vertex, a light vertex from
// the last. Vertex reuse with surfaces is refused by the plan (x_2 on a surface would need
// an area-measure geometry term).

// A surface point a ray arrives at.
struct SurfacePoint {
    vec3 x;       // origin of rays leaving it (moved off the surface along n)
    float t;      // distance along the ray (FAR: none)
    vec3 n;       // unit geometric normal on the side the ray arrived from
    uint shape;   // shape index, NO_INDEX if the ray meets none
    vec3 albedo;  // Lambertian albedo
};

// No surface: a ray from o along d that meets no shape.
SurfacePoint surface_none(vec3 o, vec3 d) {
    SurfacePoint s;
    s.x = o;
    s.t = FAR;
    s.n = -d;
    s.shape = NO_INDEX;
    s.albedo = vec3(0.0);
    return s;
}

// The nearest shape along o + t d for t in (0, t_max).
SurfacePoint surface_along(vec3 o, vec3 d, float t_max) {
    SurfacePoint s = surface_none(o, d);
    if (!SC_HAS_SHAPES) {
        return s;
    }
    uint index;
    float t = nearest_shape(o, d, 0.0, t_max, index);
    if (index == NO_INDEX) {
        return s;
    }
    // shape_normal reads the triangle nearest_shape just hit (meshes).
    Shape shape = shapes[index];
    vec3 p = o + t * d;
    s.n = shape_normal(shape, p, d);
    s.x = offset_ray_origin(p, s.n);
    s.t = t;
    s.shape = index;
    s.albedo = shape.albedo;
    return s;
}

// The Lambertian BRDF times the cosine towards the leaving direction wo: albedo cos / pi,
// 0 for a direction into the surface.
vec3 surface_reflect(SurfacePoint s, vec3 wo) {
    float c = dot(s.n, wo);
    return c > 0.0 ? s.albedo * (INV_PI * c) : vec3(0.0);
}

// True if a shape cuts x + t wi for t in (0, dist), short of a vertex at dist (a light
// vertex on a shape lies at dist itself; FAR: the whole ray).
bool shapes_block(vec3 x, vec3 wi, float dist) {
    if (!SC_HAS_SHAPES) {
        return false;
    }
    float t_max = dist >= FAR ? FAR : dist * (1.0 - 1e-4);
    return occluded_before(x, wi, 0.0, t_max);
}

// What a camera ray from o along d sees where it leaves the media: the radiance arriving
// from its end (an emitting sphere or the environment, both weighted as light_seen does,
// or the emission of a shape on its emitting side) and where it ends (t_end, FAR if it
// escapes).
vec3 camera_end(uint set, vec3 o, vec3 d, out float t_end) {
    vec3 L = light_seen(light_base(set), env_rotation_of(set), o, d, t_end);
    SurfacePoint s = surface_along(o, d, t_end);
    if (s.shape != NO_INDEX) {
        t_end = s.t;
        // Right after the nearest_shape of surface_along (a mesh's hit triangle).
        return shape_emitted(s.shape, o + s.t * d, d);
    }
    return L;
}

// x_1 of the path stored at `at` (header r) on camera ray `cam`: on the ray at z_1, or the
// surface the ray meets. False if it has none (no vertex, or the surface is gone).
bool path_x1(uint at, Reservoir r, CameraRay cam, out vec3 x1) {
    x1 = cam.o;
    if (!res_valid(r) || res_vertices(r) < 1u) {
        return false;
    }
    float z = res_z(at, 1u);
    if (z >= 0.0) {
        x1 = cam.o + z * cam.d;
        return true;
    }
    SurfacePoint s = surface_along(cam.o, cam.d, FAR);
    x1 = cam.o + s.t * cam.d;
    return s.shape != NO_INDEX;
}

// ---------------------------------------------------------------------------------------
// Split next-event estimation (SC_NEE_SPLIT). The paper's paths end in ONE light, picked by
// power at each vertex, so under the scalar (luminance) target a pixel's selected path is
// lit either by the sun or by the sky and carries that light's colour: colour noise that
// no amount of reuse removes (on the benchmark cloud it was 88 % of the per-frame MSE).
// Split NEE ends a path in one sample omega of the environment, drawn with density q, and
// its value at the last vertex v adds every delta (directional, point) light:
//   g(v, omega) = f_env(v, omega) + q(omega) sum_d f_d(v),
// whose integral over omega is the whole next-event contribution of v (q integrates to 1),
// so the path space gains nothing and loses nothing. The plan allows it only where the
// other lights are the environment alone, whose sampler never fails (q > 0 wherever it
// draws), and the reservoir's light vertex is the environment direction (LIGHT_ENV).

// Folded emission (SC_FOLD_EMISSION, with split NEE, or where the environment is the only
// light: its one-light NEE is the same sampler). Emission paths are candidates
// of their own in the paper; a pixel's one selected path is then either lit or glowing,
// and emission seen after 0, 1 or 2 bounces has other hues than the light scattered
// there, so under the scalar target the hue of a pixel flips with its selection. Folded,
// the split-NEE value of a medium vertex adds its emission weighted by q:
//   g(v, omega) = f_env(v, omega) + q(omega) (sum_d f_d(v) + sigma_a Le(v)),
// whose integral over omega is all the vertex's NEE plus its emission (q integrates to 1
// and never vanishes where it draws), so the emission paths need no candidates.

// The density q the environment sample is drawn with (solid angle), the map turned by
// env_rot (the turn keeps the density's values, at turned directions).
float env_sample_pdf(vec3 wi, vec2 env_rot) {
    return SC_HAS_ENV_MAP ? env_pdf_rotated(wi, env_rot) : uniform_sphere_pdf();
}

// How a vertex scatters light arriving from wi into the travel direction: the surface's
// BRDF x cosine on a surface, sigma_s times the phase function (w: the travel direction
// into the vertex) of each medium there.
vec3 vertex_scatter(SurfacePoint surface, vec3 w, VertexMedium vm, vec3 wi) {
    return surface.shape != NO_INDEX ? surface_reflect(surface, wi) : medium_scatter(vm, dot(w, wi));
}

// The light terms a path's last vertex adds up: 1, the stored light vertex; with split
// NEE also one per light of the set, of which the delta lights count (light_term).
uint light_terms() {
    return SC_NEE_SPLIT ? 1u + u_frame.light_count : 1u;
}

// Term k >= 1 of split NEE at x: delta light k - 1 of the set at `base` (its radiance,
// direction and distance; zero for a light that is not a delta light). env_rot is the
// set's environment turn (light_eval's; a delta light does not read it).
vec3 light_term(uint base, vec2 env_rot, uint k, vec3 x, out vec3 wi, out float dist) {
    uint l = k - 1u;
    uint type = lights[base + l].type;
    if (type != LIGHT_DIRECTIONAL && type != LIGHT_POINT) {
        wi = vec3(0.0, 1.0, 0.0);
        dist = FAR;
        return vec3(0.0);
    }
    return light_eval(base, env_rot, l, vec3(0.0, 1.0, 0.0), 0u, vec3(0.0), x, wi, dist);
}

// ---------------------------------------------------------------------------------------
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
vec3 path_value(uint at, Reservoir r, CameraRay cam, CameraRay src, uint mode, inout uint rng) {
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
        float sigma_t = mode == MODE_FINAL ? grid_sigma_t_in(u_density, x) : sigma_t_of(set, x);
        vec3 albedo = grid_albedo(x);
        vm = vertex_medium(x, sigma_t, albedo);
        if (i == kp && res_emission(r)) {
            if (!SC_HAS_EMISSION || !(sigma_t > 0.0)) {
                return vec3(0.0);
            }
            // Emission path: the grid's sigma_a Le at x_k' (absorbed-emission convention;
            // a box does not emit).
            return f * (vec3(1.0) - albedo) * sigma_t * grid_emission(x) * geometry;
        }
        // Folded emission: the last vertex's sigma_a Le joins its light terms.
        if (SC_FOLD_EMISSION && i == kp && sigma_t > 0.0) {
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
        light += s * T * boxes_transmittance(x, wi, dist);
    }
    // Folded emission, weighted by q as the delta lights are: its integral over the
    // environment sample is sigma_a Le (without split NEE the environment is the only
    // light, drawn with probability 1: q is its density).
    float q_fold = SC_NEE_SPLIT ? q : env_sample_pdf(stored_dir, env_rot);
    light += q_fold * last_emitted;
    return f * light * geometry;
}

#endif
