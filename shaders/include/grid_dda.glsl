// Axis-aligned DDA over a lattice of cells, the step both walks over the grid take: the
// dual-cell walk (grid_dual.glsl, cells of one voxel) and the block walk (grid_blocks.glsl,
// blocks of f voxels). Along one axis the walk's coordinate is x(s) = x0 + dx s; cell c
// covers [c f, (c + 1) f], and the walk's cells are c_min .. c_max.
#ifndef NIMBUS_GRID_DDA_GLSL
#define NIMBUS_GRID_DDA_GLSL

#include "constants.glsl"

// Below this |direction component| (in voxels per metre) a ray counts as parallel to
// that axis's planes.
#define GRID_PARALLEL_EPS 1e-30

// Parameter s >= s_now at which the walk leaves cell c along one axis. The walk's first
// and last cells' outer boundaries (the grid's ends) are never crossed: the caller's span
// length stops the walk there. FAR when parallel.
float grid_cell_crossing(float x0, float dx, int c, int f, int c_min, int c_max, float s_now) {
    if (dx > GRID_PARALLEL_EPS && c < c_max) {
        // Domain: dx > 0.
        return max(s_now, (float((c + 1) * f) - x0) / dx);
    }
    if (dx < -GRID_PARALLEL_EPS && c > c_min) {
        // Domain: dx < 0.
        return max(s_now, (float(c * f) - x0) / dx);
    }
    return FAR;
}

// Moves a walk past the aligned block of (2^shift)^3 cells holding its current cell (a
// block whose values are all 0; shift 3: a brick): to where the ray leaves the block's
// cells, recomputing each axis's cell there. The walk is at parameter s (its span ends at
// len: s = len ends it), in cell `cell`, stepping step_dir (+-1 per axis), and leaves the
// cell along each axis at s_next.
void grid_dda_skip_block(int shift, vec3 x0, vec3 dx, int f, ivec3 c_min, ivec3 c_max, ivec3 step_dir,
                         float len, inout ivec3 cell, inout vec3 s_next, inout float s) {
    ivec3 first = max((cell >> shift) << shift, c_min);
    ivec3 last = min(((cell >> shift) << shift) + ((1 << shift) - 1), c_max);
    // Where each axis leaves the brick's range of cells.
    vec3 s_exit;
    for (int a = 0; a < 3; ++a) {
        int c = step_dir[a] > 0 ? last[a] : first[a];
        s_exit[a] = grid_cell_crossing(x0[a], dx[a], c, f, c_min[a], c_max[a], s);
    }
    int e = s_exit.x <= s_exit.y ? (s_exit.x <= s_exit.z ? 0 : 2) : (s_exit.y <= s_exit.z ? 1 : 2);
    float s_e = s_exit[e];
    if (!(s_e < len)) {
        s = len;
        return;
    }
    s = s_e;
    for (int a = 0; a < 3; ++a) {
        int c;
        if (a == e) {
            c = (step_dir[a] > 0 ? last[a] : first[a]) + step_dir[a];
        } else {
            // Still inside the brick along this axis. Domain: f >= 1.
            c = clamp(int(floor((x0[a] + dx[a] * s) / float(f))), first[a], last[a]);
        }
        cell[a] = c;
        s_next[a] = grid_cell_crossing(x0[a], dx[a], c, f, c_min[a], c_max[a], s);
    }
    if (cell[e] < c_min[e] || cell[e] > c_max[e]) {
        s = len;
    }
}

// The same past the brick of 8^3 cells holding the current cell.
void grid_dda_skip_brick(vec3 x0, vec3 dx, int f, ivec3 c_min, ivec3 c_max, ivec3 step_dir, float len,
                         inout ivec3 cell, inout vec3 s_next, inout float s) {
    grid_dda_skip_block(3, x0, dx, f, c_min, c_max, step_dir, len, cell, s_next, s);
}

#endif
