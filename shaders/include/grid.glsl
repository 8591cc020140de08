// Heterogeneous grid media stored sparsely: 8^3 bricks in a 3D atlas behind an indirection
// grid (GVDB / NanoVDB style), trilinear lookup, closed-form transmittance by regular
// tracking over the dual cells with empty bricks skipped, and ratio tracking with the global
// majorant (Volumetric ReSTIR secs. 2.1 and 5.1). This file holds the index spaces, the
// bricks and the lookup; the walks are in grid_dda.glsl (the step both walks share),
// grid_dual.glsl (the dual-cell walk and the closed form, included at the end of this
// file) and grid_blocks.glsl (the block walk and the super-voxel estimators).
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
// slots_x and slots_y are powers of two (src/shader_data/sparse.rs, atlas_slots): shifts and masks,
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

// The slot holding dual cell `cell` of grid `s` (bricks from `offset`), or NO_BRICK: its
// lower corner clamp(cell) is texel `local` of the slot, its upper corners `o` further
// (o = clamp(cell + 1) - clamp(cell): 1 per axis, 0 where the clamp bites), all in the
// slot of the lower corner's brick. Counts a density fetch.
uint grid_cell_slot(GridSpace s, uint offset, ivec3 cell, out ivec3 local, out ivec3 o) {
    COUNT(CTR_DENSITY, 1);
    ivec3 lo = clamp(cell, s.lattice_min, s.lattice_max);
    o = clamp(cell + 1, s.lattice_min, s.lattice_max) - lo;
    local = lo & 7;
    return grid_slot(offset, s.brick_dims, lo >> 3);
}

void grid_zero_corners(out float c[8]) {
    for (int i = 0; i < 8; ++i) {
        c[i] = 0.0;
    }
}

// The 8 values of dual cell `cell` of grid `s` (atlas `atlas`, bricks from `offset`).
void grid_cell_corners_at(sampler3D atlas, GridSpace s, uint offset, ivec3 cell, out float c[8]) {
    ivec3 local;
    ivec3 o;
    uint slot = grid_cell_slot(s, offset, cell, local, o);
    if (slot == NO_BRICK) {
        grid_zero_corners(c);
        return;
    }
    grid_fetch_corners(atlas, grid_slot_origin(slot, s.slots_x, s.slots_y) + local, o, c);
}

#ifdef NIMBUS_DENSITY_BUFFER
// The includer (the baseline, ReSTIR) also binds the density's slots as a storage buffer, slot
// after slot, each slot's 10^3 texels from lattice point 8 b - 1 x fastest (the brick, its
// high-side apron and a low-side one: every dual cell of a point of the brick's
// super-voxel lies in the slot, grid_sigma_index_in_brick), and reads u_density's values from it where
// SC_DENSITY_BUFFER: on lavapipe a texelFetch is a call into the sampler's code with its
// bounds checks and per-lane level strides (a third of the baseline's time on the
// benchmark cloud), a buffer load a loop over the lanes. Each texel holds a quad: its value
// and its +x, +y and +x+y neighbours' in the slot (src/shader_data/sparse.rs,
// slot_major_quads), so a trilinear lookup is two loads of 16 bytes, not eight of 4
// (lavapipe runs one lane loop per load: eight cost half the benchmark's frame).
layout(constant_id = SC_ID_DENSITY_BUFFER) const bool SC_DENSITY_BUFFER = false;
layout(std430, set = 0, binding = BINDING_GRID_DENSITY_TEXELS) readonly buffer DensityTexelBlock {
    vec4 density_quads[];
};

// The index of texel t (0..9 per axis) of slot `slot` in density_quads.
int grid_density_quad(uint slot, ivec3 t) {
    return int(slot) * 1000 + (t.z * 10 + t.y) * 10 + t.x;
}

// The 4 corners (x fastest) of one z plane of a dual cell from the quad q of its lower
// texel, the upper corners o further (o = 0 where the lattice clamp bites: the texel itself).
void grid_quad_plane(vec4 q, ivec2 o, out float c0, out float c1, out float c2, out float c3) {
    c0 = q.x;
    c1 = o.x > 0 ? q.y : q.x;
    c2 = o.y > 0 ? q.z : q.x;
    c3 = o.x > 0 ? (o.y > 0 ? q.w : q.y) : (o.y > 0 ? q.z : q.x);
}

// The 8 values (x fastest) of the dual cell whose lower corner is texel t of slot `slot`,
// its upper corners o further (grid_quad_plane): two quad loads.
void grid_buffer_corners(uint slot, ivec3 t, ivec3 o, out float c[8]) {
    int b = grid_density_quad(slot, t);
    grid_quad_plane(density_quads[b], o.xy, c[0], c[1], c[2], c[3]);
    grid_quad_plane(density_quads[b + o.z * 100], o.xy, c[4], c[5], c[6], c[7]);
}
#endif

// The same for the grid's own density u_density (or its buffer, SC_DENSITY_BUFFER).
void grid_cell_corners(ivec3 cell, out float c[8]) {
#ifdef NIMBUS_DENSITY_BUFFER
    if (SC_DENSITY_BUFFER) {
        ivec3 t;
        ivec3 o;
        uint slot = grid_cell_slot(u_grid.space, u_grid.space.bricks_offset, cell, t, o);
        if (slot == NO_BRICK) {
            grid_zero_corners(c);
            return;
        }
        // Texel lo sits at (lo & 7) + 1 in its brick's slot (which starts at 8 b - 1).
        grid_buffer_corners(slot, t + 1, o, c);
        return;
    }
#endif
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

#ifdef NIMBUS_DENSITY_BUFFER
// sigma_t at p-space point p of the super-voxel of brick `brick`, whose slot is `slot`
// (not NO_BRICK), from the density buffer (SC_DENSITY_BUFFER): the point's dual cell lies
// in the brick's slot, so no brick-table lookup (on lavapipe a loop over the lanes; the
// super-voxel walk looked the slot up once for its span). The same values as
// grid_sigma_index.
float grid_sigma_index_in_brick(vec3 p, ivec3 brick, uint slot) {
    ivec3 cell;
    vec3 f;
    grid_locate(u_grid.space, p, cell, f);
    COUNT(CTR_DENSITY, 1);
    ivec3 lo = clamp(cell, u_grid.space.lattice_min, u_grid.space.lattice_max);
    ivec3 o = clamp(cell + 1, u_grid.space.lattice_min, u_grid.space.lattice_max) - lo;
    // p in [8 brick, 8 brick + 8] puts lo in [8 brick - 1, 8 brick + 7]: texels 0..8 of the
    // slot (the clamp only guards against a point outside the super-voxel).
    ivec3 t = clamp(lo - (brick * 8 - 1), ivec3(0), ivec3(8));
    float c[8];
    grid_buffer_corners(slot, t, o, c);
    return u_grid.density_scale * grid_trilinear(c, f);
}
#endif

// sigma_t of the grid's own density at p-space point p.
float grid_sigma_index(vec3 p) {
    ivec3 cell;
    vec3 f;
    grid_locate(u_grid.space, p, cell, f);
    float c[8];
    grid_cell_corners(cell, c);
    return u_grid.density_scale * grid_trilinear(c, f);
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

// The same for the grid's own density.
float grid_sigma_t(vec3 x) {
    return space_contains(u_grid.space, x) ? grid_sigma_index(space_to_index(u_grid.space, x)) : 0.0;
}

// (t_in, t_out) of the density's box along o + t d.
vec2 grid_span(vec3 o, vec3 d) {
    return space_span(u_grid.space, o, d);
}

// The walks over the grid: the DDA step they share, then the dual-cell walk and its
// closed-form estimators.
#include "grid_dda.glsl"
#include "grid_dual.glsl"

#endif
