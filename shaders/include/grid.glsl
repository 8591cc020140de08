// Heterogeneous grid media stored sparsely: 8^3 bricks in a 3D atlas behind an indirection
// grid (GVDB / NanoVDB style), trilinear lookup, closed-form transmittance by regular
// tracking over the dual cells with empty bricks skipped, and ratio tracking with the global
// majorant (Volumetric ReSTIR secs. 2.1 and 5.1). The block walk and the super-voxel
// estimators are in grid_blocks.glsl.
//
// The includer declares, before including this file:
//   layout(...) uniform sampler3D u_density;   // R32F atlas of the density's slots (unscaled), texelFetch only
//   layout(std430, ...) readonly buffer ... { uint grid_bricks[]; };  // indirection sections
//   GridParams u_grid;  (or a #define making `u_grid` name one; GridParams is in grid_types.glsl)
//
// Index spaces of a grid (a GridSpace): values sit on an integer lattice; lattice point l
// is at p = l + 0.5 of the continuous p-space, and between lattice points the field is
// trilinear. A lookup at lattice point l reads clamp(l, lattice_min, lattice_max); brick b
// holds lattice points 8b .. 8b + 7 and is found through the indirection (NO_BRICK: all its
// values are 0). The grid fills the p-space box index_min .. index_max and is 0 outside.
// World x maps to p affinely: for axis-aligned grids through the world box box_min ..
// box_max (p = (x - box_min) * scale + index_min), else through world_to_index.
//
// - A dense grid of docs/scene-format.md (cell-centred, dims n, box bounds_min .. bounds_max) is
//   lattice 0 .. n - 1 in p-box [0, n]: within half a voxel of a face the clamp makes the
//   density constant along that axis.
// - An OpenVDB grid (node-centred) is lattice bmin - 1 .. bmax + 1 (its active voxels and one
//   layer of background) in p-box [bmin - 1, bmax + 1] + 0.5: nothing clamps inside it.
//
// The closed form walks the dual cells of q = p - 0.5 per axis: cell m = [m, m + 1] (between
// lattice points m and m + 1), from lattice_min - 1 to lattice_max (the border cells are the
// clamped half voxels of a dense grid). In each dual cell the density is one trilinear
// polynomial of the (possibly clamped, hence constant) coordinates, so along a ray it is a
// polynomial of degree <= 3 in t, which 2-point Gauss-Legendre integrates exactly. A dual
// cell reads one slot: its lower corner's brick, whose apron holds the upper corners.
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
// An indirection entry without a brick.
#define NO_BRICK 0xffffffffu

// ---------------------------------------------------------------------------------------
// Grid spaces: world <-> p-space.

// World -> index space per unit length of the axis-aligned path. Domain: the box is not
// empty (validated).
vec3 space_index_scale(GridSpace s) {
    return (s.index_max - s.index_min) / (s.box_max - s.box_min);
}

// The p-space point of world point x.
vec3 space_to_index(GridSpace s, vec3 x) {
    if (s.axis_aligned != 0u) {
        return (x - s.box_min) * space_index_scale(s) + s.index_min;
    }
    vec4 h = vec4(x, 1.0);
    return vec3(dot(s.world_to_index_x, h), dot(s.world_to_index_y, h), dot(s.world_to_index_z, h));
}

// The p-space direction of world direction d (per unit t).
vec3 space_index_dir(GridSpace s, vec3 d) {
    if (s.axis_aligned != 0u) {
        return d * space_index_scale(s);
    }
    return vec3(dot(s.world_to_index_x.xyz, d), dot(s.world_to_index_y.xyz, d), dot(s.world_to_index_z.xyz, d));
}

// (t_in, t_out) of the grid's closed box along o + t d; t_in > t_out on a miss. A slab test
// against the box's own planes (the world box on the axis-aligned path, the p-space box
// otherwise), so a ray lying in a face plane is inside exactly when it is within the box.
vec2 space_span(GridSpace s, vec3 o, vec3 d) {
    vec3 b_min = s.box_min;
    vec3 b_max = s.box_max;
    vec3 oo = o;
    vec3 dd = d;
    if (s.axis_aligned == 0u) {
        b_min = s.index_min;
        b_max = s.index_max;
        oo = space_to_index(s, o);
        dd = space_index_dir(s, d);
    }
    float t_in = -FAR;
    float t_out = FAR;
    for (int a = 0; a < 3; ++a) {
        if (abs(dd[a]) < 1e-30) {
            if (oo[a] < b_min[a] || oo[a] > b_max[a]) {
                return vec2(FAR, -FAR);
            }
            continue;
        }
        // Domain: |dd[a]| >= 1e-30.
        float inv_d = 1.0 / dd[a];
        float t_a = (b_min[a] - oo[a]) * inv_d;
        float t_b = (b_max[a] - oo[a]) * inv_d;
        t_in = max(t_in, min(t_a, t_b));
        t_out = min(t_out, max(t_a, t_b));
    }
    return vec2(t_in, t_out);
}

// Whether world point x lies in the grid's closed box.
bool space_contains(GridSpace s, vec3 x) {
    if (s.axis_aligned != 0u) {
        return all(greaterThanEqual(x, s.box_min)) && all(lessThanEqual(x, s.box_max));
    }
    vec3 p = space_to_index(s, x);
    return all(greaterThanEqual(p, s.index_min)) && all(lessThanEqual(p, s.index_max));
}

// ---------------------------------------------------------------------------------------
// Bricks.

// The bit of a section's offset that says the section is two-level.
#define INDIRECTION_TWO_LEVEL 0x80000000u
// Some section is two-level (the pass sets it from its grids): off, the tag is not read.
layout(constant_id = SC_ID_TWO_LEVEL_BRICKS) const bool SC_TWO_LEVEL_BRICKS = false;

// The slot of brick b in an indirection section (`offset`, `dims` bricks per axis), or
// NO_BRICK outside it or where no brick is stored (crates/nimbus-scene/src/bricks/
// indirection.rs). One-level: an entry per brick, x fastest. Two-level (the offset's
// INDIRECTION_TWO_LEVEL bit, for bounding boxes of more than 2^24 bricks): a top table
// with an entry per node of 8^3 bricks, x fastest (the offset of the node's 512-entry
// leaf table from the section's start, or NO_BRICK), then the leaf tables.
uint grid_slot(uint offset, uvec3 dims, ivec3 b) {
    if (any(lessThan(b, ivec3(0))) || any(greaterThanEqual(b, ivec3(dims)))) {
        return NO_BRICK;
    }
    if (!SC_TWO_LEVEL_BRICKS || (offset & INDIRECTION_TWO_LEVEL) == 0u) {
        return grid_bricks[offset + uint((b.z * int(dims.y) + b.y) * int(dims.x) + b.x)];
    }
    offset &= ~INDIRECTION_TWO_LEVEL;
    uvec3 top = (dims + 7u) >> 3;
    uvec3 n = uvec3(b) >> 3;
    uint leaf = grid_bricks[offset + (n.z * top.y + n.y) * top.x + n.x];
    if (leaf == NO_BRICK) {
        return NO_BRICK;
    }
    uvec3 l = uvec3(b) & 7u;
    return grid_bricks[offset + leaf + (l.z * 8u + l.y) * 8u + l.x];
}

// The first texel of slot `slot` in an atlas of slots_x x slots_y x ... slots of 9^3.
// slots_x and slots_y are powers of two (src/gpu/sparse.rs, atlas_slots): shifts and masks,
// no integer division (slow on GPUs, scalarized per lane on lavapipe).
ivec3 grid_slot_origin(uint slot, uint slots_x, uint slots_y) {
    int lx = findLSB(slots_x);
    int ly = findLSB(slots_y);
    return ivec3(int(slot & (slots_x - 1u)), int((slot >> uint(lx)) & (slots_y - 1u)), int(slot >> uint(lx + ly))) * 9;
}

// ---------------------------------------------------------------------------------------
// Trilinear lookup.

// Trilinear blend of the 8 corner values c[z][y][x] (packed x fastest) with fractions f.
float grid_trilinear(float c[8], vec3 f) {
    float x00 = mix(c[0], c[1], f.x);
    float x10 = mix(c[2], c[3], f.x);
    float x01 = mix(c[4], c[5], f.x);
    float x11 = mix(c[6], c[7], f.x);
    return mix(mix(x00, x10, f.y), mix(x01, x11, f.y), f.z);
}

// The 8 texels of a dual cell whose lower corner is texel b of its slot, upper corners b + o
// (o = 1 per axis, 0 where the lattice clamp bites).
void grid_fetch_corners(sampler3D atlas, ivec3 b, ivec3 o, out float c[8]) {
    c[0] = texelFetch(atlas, b, 0).r;
    c[1] = texelFetch(atlas, b + ivec3(o.x, 0, 0), 0).r;
    c[2] = texelFetch(atlas, b + ivec3(0, o.y, 0), 0).r;
    c[3] = texelFetch(atlas, b + ivec3(o.x, o.y, 0), 0).r;
    c[4] = texelFetch(atlas, b + ivec3(0, 0, o.z), 0).r;
    c[5] = texelFetch(atlas, b + ivec3(o.x, 0, o.z), 0).r;
    c[6] = texelFetch(atlas, b + ivec3(0, o.y, o.z), 0).r;
    c[7] = texelFetch(atlas, b + ivec3(o.x, o.y, o.z), 0).r;
}

// The 8 values of dual cell `cell` of grid `s` (atlas `atlas`, bricks from `offset`): lower
// corner clamp(cell), upper corner clamp(cell + 1) (equal where the clamp bites), both in the
// slot of the lower corner's brick.
void grid_cell_corners_at(sampler3D atlas, GridSpace s, uint offset, ivec3 cell, out float c[8]) {
    COUNT(CTR_DENSITY, 1);
    ivec3 lo = clamp(cell, s.lattice_min, s.lattice_max);
    ivec3 o = clamp(cell + 1, s.lattice_min, s.lattice_max) - lo;
    uint slot = grid_slot(offset, s.brick_dims, lo >> 3);
    if (slot == NO_BRICK) {
        for (int i = 0; i < 8; ++i) {
            c[i] = 0.0;
        }
        return;
    }
    grid_fetch_corners(atlas, grid_slot_origin(slot, s.slots_x, s.slots_y) + (lo & 7), o, c);
}

// The same for the grid's own density u_density.
void grid_cell_corners(ivec3 cell, out float c[8]) {
    grid_cell_corners_at(u_density, u_grid.space, u_grid.space.bricks_offset, cell, c);
}

// The dual cell and fractions of p-space point p (clamped to the lattice range).
void grid_locate(GridSpace s, vec3 p, out ivec3 cell, out vec3 f) {
    vec3 q = clamp(p - 0.5, vec3(s.lattice_min), vec3(s.lattice_max));
    cell = min(ivec3(floor(q)), s.lattice_max);
    f = clamp(q - vec3(cell), 0.0, 1.0);
}

// sigma_t of the density at p-space point p (any p is accepted: it clamps), its bricks in
// `atlas` from `offset` (the current frame's or the previous one's).
float grid_sigma_index_at(sampler3D atlas, uint offset, vec3 p) {
    ivec3 cell;
    vec3 f;
    grid_locate(u_grid.space, p, cell, f);
    float c[8];
    grid_cell_corners_at(atlas, u_grid.space, offset, cell, c);
    return u_grid.density_scale * grid_trilinear(c, f);
}

// sigma_t of u_density at p-space point p.
float grid_sigma_index(vec3 p) {
    return grid_sigma_index_at(u_density, u_grid.space.bricks_offset, p);
}

// sigma_t = density_scale * trilinear density at world x; 0 outside the closed box.
float grid_sigma_t_at(sampler3D atlas, uint offset, vec3 x) {
    if (!space_contains(u_grid.space, x)) {
        return 0.0;
    }
    return grid_sigma_index_at(atlas, offset, space_to_index(u_grid.space, x));
}

// The same for a density atlas with the current frame's bricks.
float grid_sigma_t_in(sampler3D atlas, vec3 x) {
    return grid_sigma_t_at(atlas, u_grid.space.bricks_offset, x);
}

// The same for the grid's own density u_density.
float grid_sigma_t(vec3 x) {
    return grid_sigma_t_in(u_density, x);
}

// (t_in, t_out) of the density's box along o + t d.
vec2 grid_span(vec3 o, vec3 d) {
    return space_span(u_grid.space, o, d);
}

// ---------------------------------------------------------------------------------------
// The dual-cell walk.

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

// Crossing of dual cell `c` (cells lo - 1 .. hi of a lattice lo .. hi) along one axis.
float grid_dual_crossing(float q0, float dq, int c, int lo, int hi, float s_now) {
    return grid_next_crossing(q0, dq, float(c), float(c + 1), c >= lo, c + 1 <= hi, s_now);
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
    ivec3 lo = u_grid.space.lattice_min;
    ivec3 hi = u_grid.space.lattice_max;
    ivec3 first = max((it.cell >> 3) * 8, lo - 1);
    ivec3 last = min((it.cell >> 3) * 8 + 7, hi);
    // Where each axis leaves the brick's range of cells.
    vec3 s_exit;
    for (int a = 0; a < 3; ++a) {
        int c = it.step_dir[a] > 0 ? last[a] : first[a];
        s_exit[a] = grid_dual_crossing(it.q0[a], it.dq[a], c, lo[a], hi[a], it.s);
    }
    int e = s_exit.x <= s_exit.y ? (s_exit.x <= s_exit.z ? 0 : 2) : (s_exit.y <= s_exit.z ? 1 : 2);
    float s = s_exit[e];
    if (!(s < it.len)) {
        it.s = it.len;
        return;
    }
    it.s = s;
    for (int a = 0; a < 3; ++a) {
        int c;
        if (a == e) {
            c = (it.step_dir[a] > 0 ? last[a] : first[a]) + it.step_dir[a];
        } else {
            // Still inside the brick along this axis.
            c = clamp(int(floor(it.q0[a] + it.dq[a] * s)), first[a], last[a]);
        }
        it.cell[a] = c;
        it.s_next[a] = grid_dual_crossing(it.q0[a], it.dq[a], c, lo[a], hi[a], s);
    }
    if (it.cell[e] < lo[e] - 1 || it.cell[e] > hi[e]) {
        it.s = it.len;
    }
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
