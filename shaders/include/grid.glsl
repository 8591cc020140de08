// Heterogeneous grid media: trilinear density lookup, closed-form transmittance by regular
// tracking, and ratio tracking with the global majorant (Volumetric ReSTIR secs. 2.1 and
// 5.1). The block walk and the super-voxel estimators are in grid_blocks.glsl.
//
// The includer declares, before including this file:
//   layout(...) uniform sampler3D u_density;   // R32_SFLOAT density (unscaled), texelFetch only
//   GridParams u_grid;  (or a #define making `u_grid` name one; GridParams is in grid_types.glsl)
//
// Index space (SCENE_FORMAT.md): a world point x maps to p = (x - bounds_min) / size * dims;
// voxel (i, j, k) is the cell [i, i+1] x [j, j+1] x [k, k+1] with its centre at (i, j, k) + 0.5.
// The density is trilinear between centres, and each coordinate clamps to [0.5, n - 0.5],
// so within half a voxel of a face it is constant along that axis.
//
// The closed form walks the "dual" cells of q = p - 0.5 per axis: cell -1 = [-0.5, 0] (the
// clamped border), cell m = [m, m + 1] for 0 <= m < n - 1 (between centres m and m + 1),
// cell n - 1 = [n - 1, n - 0.5] (the other border). In each dual cell the density is one
// trilinear polynomial of the (possibly clamped, hence constant) coordinates, so along a
// ray it is a polynomial of degree <= 3 in t, which 2-point Gauss-Legendre integrates
// exactly.
#ifndef NIMBUS_GRID_GLSL
#define NIMBUS_GRID_GLSL

#include "constants.glsl"
#include "features.glsl"
#include "rng.glsl"
#include "sampling.glsl"
#include "grid_types.glsl"
#include "counters.glsl"

// Below this |direction component| (in voxels per metre) a ray counts as parallel to
// that axis's planes.
#define GRID_PARALLEL_EPS 1e-30

// (t_in, t_out) of the closed bounds box along o + t d; t_in > t_out on a miss. A slab
// test against bounds_min / bounds_max themselves (not centre +- half size), so a ray
// lying in a face plane is inside exactly when its coordinate is within the bounds.
vec2 grid_span(vec3 o, vec3 d) {
    vec3 b_min = u_grid.bounds_min;
    vec3 b_max = u_grid.bounds_max;
    float t_in = -FAR;
    float t_out = FAR;
    for (int a = 0; a < 3; ++a) {
        if (abs(d[a]) < 1e-30) {
            if (o[a] < b_min[a] || o[a] > b_max[a]) {
                return vec2(FAR, -FAR);
            }
            continue;
        }
        // Domain: |d[a]| >= 1e-30.
        float inv_d = 1.0 / d[a];
        float t_a = (b_min[a] - o[a]) * inv_d;
        float t_b = (b_max[a] - o[a]) * inv_d;
        t_in = max(t_in, min(t_a, t_b));
        t_out = min(t_out, max(t_a, t_b));
    }
    return vec2(t_in, t_out);
}

// World -> index space per unit length: dims / size. Domain: size > 0 (scenes are
// validated to non-empty boxes).
vec3 grid_index_scale() {
    return vec3(u_grid.dims) / (u_grid.bounds_max - u_grid.bounds_min);
}

// Trilinear blend of the 8 corner values c[z][y][x] (packed x fastest) with fractions f.
float grid_trilinear(float c[8], vec3 f) {
    float x00 = mix(c[0], c[1], f.x);
    float x10 = mix(c[2], c[3], f.x);
    float x01 = mix(c[4], c[5], f.x);
    float x11 = mix(c[6], c[7], f.x);
    return mix(mix(x00, x10, f.y), mix(x01, x11, f.y), f.z);
}

// The 8 voxel values of dual cell `cell` (per axis in [-1, n - 1]) of a density texture
// with the grid's dims: lower corner clamp(cell, 0, n - 1), upper corner
// clamp(cell + 1, 0, n - 1) (equal in border cells).
void grid_cell_corners_in(sampler3D density, ivec3 cell, out float c[8]) {
    ivec3 n_minus_1 = ivec3(u_grid.dims) - 1;
    ivec3 lo = clamp(cell, ivec3(0), n_minus_1);
    ivec3 hi = clamp(cell + 1, ivec3(0), n_minus_1);
    c[0] = texelFetch(density, ivec3(lo.x, lo.y, lo.z), 0).r;
    c[1] = texelFetch(density, ivec3(hi.x, lo.y, lo.z), 0).r;
    c[2] = texelFetch(density, ivec3(lo.x, hi.y, lo.z), 0).r;
    c[3] = texelFetch(density, ivec3(hi.x, hi.y, lo.z), 0).r;
    c[4] = texelFetch(density, ivec3(lo.x, lo.y, hi.z), 0).r;
    c[5] = texelFetch(density, ivec3(hi.x, lo.y, hi.z), 0).r;
    c[6] = texelFetch(density, ivec3(lo.x, hi.y, hi.z), 0).r;
    c[7] = texelFetch(density, ivec3(hi.x, hi.y, hi.z), 0).r;
}

// The same for the grid's own density u_density.
void grid_cell_corners(ivec3 cell, out float c[8]) {
    grid_cell_corners_in(u_density, cell, c);
}

// sigma_t of a density texture (the grid's dims, unscaled) at index-space point p
// (clamped per SCENE_FORMAT.md; any p is accepted).
float grid_sigma_index_in(sampler3D density, vec3 p) {
    vec3 n = vec3(u_grid.dims);
    // Shifted so centres sit at integers, clamped to the outermost centres.
    vec3 q = clamp(p - 0.5, vec3(0.0), n - 1.0);
    ivec3 cell = min(ivec3(floor(q)), ivec3(u_grid.dims) - 1);
    float c[8];
    grid_cell_corners_in(density, cell, c);
    return u_grid.density_scale * grid_trilinear(c, clamp(q - vec3(cell), 0.0, 1.0));
}

// sigma_t of u_density at index-space point p.
float grid_sigma_index(vec3 p) {
    return grid_sigma_index_in(u_density, p);
}

// sigma_t = density_scale * trilinear density (of a texture with the grid's dims) at world
// x; 0 outside the closed bounds.
float grid_sigma_t_in(sampler3D density, vec3 x) {
    if (any(lessThan(x, u_grid.bounds_min)) || any(greaterThan(x, u_grid.bounds_max))) {
        return 0.0;
    }
    return grid_sigma_index_in(density, (x - u_grid.bounds_min) * grid_index_scale());
}

// The same for the grid's own density u_density.
float grid_sigma_t(vec3 x) {
    return grid_sigma_t_in(u_density, x);
}

// Parameter s >= s_now at which an axis-aligned DDA leaves its current cell along one
// axis: the ray coordinate is x(s) = x0 + dx s; the cell's lower / upper boundaries are
// `lower` / `upper`, and a boundary that is the grid's end (has_* false) is never crossed
// (the caller's span length stops the walk there). FAR when parallel.
float grid_next_crossing(float x0, float dx, float lower, float upper, bool has_lower,
                         bool has_upper, float s_now) {
    if (dx > GRID_PARALLEL_EPS && has_upper) {
        // Domain: dx > 0.
        return max(s_now, (upper - x0) / dx);
    }
    if (dx < -GRID_PARALLEL_EPS && has_lower) {
        // Domain: dx < 0.
        return max(s_now, (lower - x0) / dx);
    }
    return FAR;
}

// Crossing of dual cell `c` (q space, cells -1 .. n-1) along one axis.
float grid_dual_crossing(float q0, float dq, int c, int n, float s_now) {
    return grid_next_crossing(q0, dq, float(c), float(c + 1), c >= 0, c + 1 <= n - 1, s_now);
}

// A walk over the dual cells along o + t d, t in [t0, t1] clipped to the bounds, in the
// parameter s = t - t_a from the entry point t_a (so precision does not depend on the
// distance of o): q(s) = q0 + dq s are the dual-cell coordinates.
struct GridDualDda {
    vec3 q0;
    vec3 dq;
    ivec3 cell;
    ivec3 step_dir;
    vec3 s_next;  // s at which each axis leaves the current cell
    float s;      // start of the current span
    float len;    // t_b - t_a
    float t_a;
    int left;     // cells the walk may still visit (guards a runaway loop)
};

// Starts a dual-cell walk; false if the clipped interval is empty (or NaN).
bool grid_dual_begin(vec3 o, vec3 d, float t0, float t1, out GridDualDda it) {
    vec2 span = grid_span(o, d);
    it.t_a = max(t0, span.x);
    it.len = min(t1, span.y) - it.t_a;
    it.s = 0.0;
    ivec3 n = ivec3(u_grid.dims);
    it.left = n.x + n.y + n.z + 8;
    if (!(it.len > 0.0)) {
        it.len = 0.0;
        return false;
    }
    vec3 scale = grid_index_scale();
    it.q0 = (o + it.t_a * d - u_grid.bounds_min) * scale - 0.5;
    it.dq = d * scale;
    for (int a = 0; a < 3; ++a) {
        float fl = floor(it.q0[a]);
        int c = int(fl);
        // On a boundary while moving down, start in the cell below (saves an empty span).
        if (it.dq[a] < -GRID_PARALLEL_EPS && it.q0[a] == fl) {
            c -= 1;
        }
        it.cell[a] = clamp(c, -1, n[a] - 1);
        it.step_dir[a] = it.dq[a] > 0.0 ? 1 : -1;
        it.s_next[a] = grid_dual_crossing(it.q0[a], it.dq[a], it.cell[a], n[a], 0.0);
    }
    return true;
}

// The current span [s0, s1] and its dual cell; advances. False when the walk is over.
bool grid_dual_next(inout GridDualDda it, out float s0, out float s1, out ivec3 cell) {
    if (!(it.s < it.len) || it.left <= 0) {
        return false;
    }
    it.left -= 1;
    int a = it.s_next.x <= it.s_next.y ? (it.s_next.x <= it.s_next.z ? 0 : 2)
                                       : (it.s_next.y <= it.s_next.z ? 1 : 2);
    s0 = it.s;
    s1 = min(it.s_next[a], it.len);
    cell = it.cell;
    it.s = s1;
    if (it.s_next[a] >= it.len) {
        it.s = it.len;
    } else {
        ivec3 n = ivec3(u_grid.dims);
        it.cell[a] += it.step_dir[a];
        if (it.cell[a] < -1 || it.cell[a] > n[a] - 1) {
            it.s = it.len;
        } else {
            it.s_next[a] = grid_dual_crossing(it.q0[a], it.dq[a], it.cell[a], n[a], s1);
        }
    }
    return true;
}

// The trilinear density (unscaled) of a dual cell with corners c at the walk's s.
float grid_dual_density(GridDualDda it, ivec3 cell, float c[8], float s) {
    return grid_trilinear(c, clamp(it.q0 + it.dq * s - vec3(cell), 0.0, 1.0));
}

// The integral of the unscaled density over [s0, s1] inside one dual cell: a cubic in s,
// integrated exactly by 2-point Gauss-Legendre (nodes at mid +- half / sqrt(3)).
float grid_dual_integral(GridDualDda it, ivec3 cell, float c[8], float s0, float s1) {
    const float GL_NODE = 0.57735026918962576451;
    float half_len = 0.5 * (s1 - s0);
    float mid = s0 + half_len;
    return half_len * (grid_dual_density(it, cell, c, mid - GL_NODE * half_len)
                       + grid_dual_density(it, cell, c, mid + GL_NODE * half_len));
}

// The integral of sigma_t along o + t d over [t0, t1] (d unit): regular tracking through
// the dual cells, each span integrated exactly.
float grid_optical_depth(vec3 o, vec3 d, float t0, float t1) {
    GridDualDda it;
    if (!grid_dual_begin(o, d, t0, t1, it)) {
        return 0.0;
    }
    float tau = 0.0;
    float s0;
    float s1;
    ivec3 cell;
    while (grid_dual_next(it, s0, s1, cell)) {
        if (s1 > s0) {
            float c[8];
            grid_cell_corners(cell, c);
            tau += grid_dual_integral(it, cell, c, s0, s1);
        }
    }
    return u_grid.density_scale * tau;
}

// Regular tracking by exact inversion: the t in [t0, t1) at which the optical depth from
// t0 reaches `target` (> 0), or FAR if the interval's optical depth is smaller. The cell
// where the depth crosses the target is found by the walk; inside it the cubic depth is
// inverted by Newton steps kept inside a bisection bracket. Sampling t with target =
// -ln(1 - u) gives pdf sigma_t(t) T(t0, t) exactly.
float grid_invert_optical_depth(vec3 o, vec3 d, float t0, float t1, float target) {
    GridDualDda it;
    if (!grid_dual_begin(o, d, t0, t1, it) || !(u_grid.density_scale > 0.0)) {
        return FAR;
    }
    // In unscaled density units. Domain: density_scale > 0 (checked above).
    float remaining = target / u_grid.density_scale;
    float s0;
    float s1;
    ivec3 cell;
    while (grid_dual_next(it, s0, s1, cell)) {
        if (!(s1 > s0)) {
            continue;
        }
        float c[8];
        grid_cell_corners(cell, c);
        float cell_tau = grid_dual_integral(it, cell, c, s0, s1);
        if (cell_tau < remaining) {
            remaining -= cell_tau;
            continue;
        }
        // Solve tau(s0, s) = remaining for s in [s0, s1]; tau is increasing in s.
        float lo = s0;
        float hi = s1;
        float s = s0 + (s1 - s0) * clamp(remaining / max(cell_tau, 1e-30), 0.0, 1.0);
        for (int i = 0; i < 32 && hi - lo > 1e-7 * max(abs(s1), 1e-30); ++i) {
            float f = grid_dual_integral(it, cell, c, s0, s) - remaining;
            if (f > 0.0) {
                hi = s;
            } else {
                lo = s;
            }
            float sigma = grid_dual_density(it, cell, c, s);
            // Newton step where the density allows it, else bisection.
            float next = sigma > 0.0 ? s - f / sigma : 0.5 * (lo + hi);
            s = (next > lo && next < hi) ? next : 0.5 * (lo + hi);
        }
        return it.t_a + s;
    }
    return FAR;
}

// exp(-optical depth). Domain: tau >= 0, so T in (0, 1].
float grid_transmittance(vec3 o, vec3 d, float t0, float t1) {
    return exp(-grid_optical_depth(o, d, t0, t1));
}

// Unbiased T estimate by ratio tracking [Novák et al. 2014] with the global majorant
// sigma_t_max: T = prod over tentative collisions of (1 - sigma_t / sigma_maj). A walk that
// reaches GRID_MAX_STEPS is counted (g_step_cap_hits), never silently cut.
float grid_ratio_tracking(vec3 o, vec3 d, float t0, float t1, inout uint rng) {
    vec2 span = grid_span(o, d);
    float t_a = max(t0, span.x);
    float t_b = min(t1, span.y);
    float sigma_maj = u_grid.sigma_t_max;
    if (!(t_a < t_b) || !(sigma_maj > 0.0)) {
        return 1.0;
    }
    vec3 scale = grid_index_scale();
    vec3 p0 = (o + t_a * d - u_grid.bounds_min) * scale;
    vec3 dp = d * scale;
    float len = t_b - t_a;
    float T = 1.0;
    float s = 0.0;
    for (int it = 0; it < GRID_MAX_STEPS; ++it) {
        // Exponential step with rate sigma_maj. Domain: sigma_maj > 0.
        s += sample_exponential(rng_next(rng), sigma_maj);
        if (s >= len || T == 0.0) {
            return T;
        }
        // Domain: sigma_maj > 0.
        T *= 1.0 - grid_sigma_index(p0 + dp * s) / sigma_maj;
    }
    g_step_cap_hits += 1u;
    return T;
}

#endif
