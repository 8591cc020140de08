// Heterogeneous grid media, walked by dual cells: regular tracking over the dual cells of
// the trilinear field (grid.glsl) with empty bricks skipped, the closed-form optical depth
// and transmittance, the inversion of the optical depth (regular tracking by exact
// inversion), and ratio tracking with the global majorant (Volumetric ReSTIR secs. 2.1
// and 5.1).
#ifndef NIMBUS_GRID_DUAL_GLSL
#define NIMBUS_GRID_DUAL_GLSL

#include "grid.glsl"
#include "grid_dda.glsl"

// ---------------------------------------------------------------------------------------
// The dual-cell walk.

// Crossing of dual cell `c` (cells lo - 1 .. hi of a lattice lo .. hi) along one axis.
float grid_dual_crossing(float q0, float dq, int c, int lo, int hi, float s_now) {
    return grid_cell_crossing(q0, dq, c, 1, lo - 1, hi, s_now);
}

// A walk over the dual cells along o + t d, t in [t0, t1] clipped to the box, in the
// parameter s = t - t_a from the entry point t_a (so precision does not depend on the
// distance of o): q(s) = q0 + dq s are the dual-cell coordinates. Cells whose brick is
// empty are skipped a brick at a time.
struct GridDualDda {
    vec3 q0;
    vec3 dq;
    ivec3 cell;
    ivec3 step_dir;
    vec3 s_next;  // s at which each axis leaves the current cell
    float s;      // start of the current span
    float len;    // t_b - t_a
    float t_a;
    int left;     // steps the walk may still take (guards a runaway loop)
};

// Starts a dual-cell walk; false if the clipped interval is empty (or NaN).
bool grid_dual_begin(vec3 o, vec3 d, float t0, float t1, out GridDualDda it) {
    vec2 span = grid_span(o, d);
    it.t_a = max(t0, span.x);
    it.len = min(t1, span.y) - it.t_a;
    it.s = 0.0;
    ivec3 lo = u_grid.space.lattice_min;
    ivec3 hi = u_grid.space.lattice_max;
    ivec3 n = hi - lo + 1;
    it.left = n.x + n.y + n.z + 8;
    if (!(it.len > 0.0)) {
        it.len = 0.0;
        return false;
    }
    it.q0 = space_to_index(u_grid.space, o + it.t_a * d) - 0.5;
    it.dq = space_index_dir(u_grid.space, d);
    for (int a = 0; a < 3; ++a) {
        float fl = floor(it.q0[a]);
        int c = int(fl);
        // On a boundary while moving down, start in the cell below (saves an empty span).
        if (it.dq[a] < -GRID_PARALLEL_EPS && it.q0[a] == fl) {
            c -= 1;
        }
        it.cell[a] = clamp(c, lo[a] - 1, hi[a]);
        it.step_dir[a] = it.dq[a] > 0.0 ? 1 : -1;
        it.s_next[a] = grid_dual_crossing(it.q0[a], it.dq[a], it.cell[a], lo[a], hi[a], 0.0);
    }
    return true;
}

// Moves the walk past the brick of its current cell (whose values are all 0): to where the
// ray leaves the brick's cells, recomputing each axis's cell there.
void grid_dual_skip_brick(inout GridDualDda it) {
    grid_dda_skip_brick(it.q0, it.dq, 1, u_grid.space.lattice_min - 1, u_grid.space.lattice_max, it.step_dir,
                        it.len, it.cell, it.s_next, it.s);
}

// The current span [s0, s1], its dual cell and the slot of the cell's brick (never
// NO_BRICK: empty bricks are skipped); advances. False when the walk is over.
bool grid_dual_next(inout GridDualDda it, out float s0, out float s1, out ivec3 cell) {
    ivec3 lo = u_grid.space.lattice_min;
    ivec3 hi = u_grid.space.lattice_max;
    for (;;) {
        if (!(it.s < it.len) || it.left <= 0) {
            return false;
        }
        it.left -= 1;
        COUNT_STEP();
        ivec3 corner = clamp(it.cell, lo, hi);
        if (grid_slot(u_grid.space.bricks_offset, u_grid.space.brick_dims, corner >> 3) == NO_BRICK) {
            grid_dual_skip_brick(it);
            continue;
        }
        int a = it.s_next.x <= it.s_next.y ? (it.s_next.x <= it.s_next.z ? 0 : 2)
                                           : (it.s_next.y <= it.s_next.z ? 1 : 2);
        s0 = it.s;
        s1 = min(it.s_next[a], it.len);
        cell = it.cell;
        it.s = s1;
        if (it.s_next[a] >= it.len) {
            it.s = it.len;
        } else {
            it.cell[a] += it.step_dir[a];
            if (it.cell[a] < lo[a] - 1 || it.cell[a] > hi[a]) {
                it.s = it.len;
            } else {
                it.s_next[a] = grid_dual_crossing(it.q0[a], it.dq[a], it.cell[a], lo[a], hi[a], s1);
            }
        }
        return true;
    }
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
    vec3 p0 = space_to_index(u_grid.space, o + t_a * d);
    vec3 dp = space_index_dir(u_grid.space, d);
    float len = t_b - t_a;
    float T = 1.0;
    float s = 0.0;
    for (int it = 0; it < GRID_MAX_STEPS; ++it) {
        // Exponential step with rate sigma_maj. Domain: sigma_maj > 0.
        s += sample_exponential(rng_next(rng), sigma_maj);
        if (s >= len || T == 0.0) {
            return T;
        }
        COUNT(CTR_COLLISIONS, 1);
        // Domain: sigma_maj > 0.
        T *= 1.0 - grid_sigma_index(p0 + dp * s) / sigma_maj;
    }
    g_step_cap_hits += 1u;
    return T;
}

#endif
