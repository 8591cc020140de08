// Volumetric ReSTIR: regular tracking through the conservative piecewise-constant grid
// at a mip level (candidate generation, sec. 4.1, eq. 27-28), and its sigma_t* at a point.
#ifndef NIMBUS_RESTIR_PC_TRACKING_GLSL
#define NIMBUS_RESTIR_PC_TRACKING_GLSL

#include "resources.glsl"
#include "counters.glsl"


#define LEVEL_PRIMARY 0u
#define LEVEL_INDIRECT 1u

// sigma_t* of texel t (0..8 per axis) of slot `slot` (not NO_BRICK), whose first atlas
// texel is `origin`: from the slot-major buffer where SC_PC_BUFFER, else the atlas.
float pc_texel(uint slot, ivec3 origin, ivec3 t) {
    if (SC_PC_BUFFER) {
        return pc_texels[int(slot) * 729 + (t.z * 9 + t.y) * 9 + t.x];
    }
    return texelFetch(u_pc, origin + t, 0).r;
}

// Whether the voxel at `local` (0..7 per axis) of slot `slot` lies in one of its brick's
// 2^3 blocks of 4^3 voxels that is empty throughout, from the occupancy mask in the
// slot's apron (texel (8, 0, 0), bit x + 2y + 4z of the block, an exact integer as a
// float: src/shader_data/sparse.rs, write_occupancy). `mask` caches it per brick (~0u
// until read).
bool pc_empty_block(uint slot, ivec3 origin, ivec3 local, inout uint mask) {
    if (mask == ~0u) {
        mask = uint(pc_texel(slot, origin, ivec3(8, 0, 0)));
        COUNT(CTR_MAJORANT, 1);
    }
    ivec3 q = local >> 2;
    return (mask & (1u << uint(q.x + 2 * q.y + 4 * q.z))) == 0u;
}

// Walks [0, t_end) from o along d through level `level` until the optical depth reaches
// tau_target. Returns the collision distance (FAR if the ray leaves first), sigma_t* there
// and tau = the optical depth walked (tau_target at a collision, the total otherwise).
// `through`: the walk goes on past the collision to t_end, and tau_all is the optical depth
// of all of [0, t_end) (the initial pass's direct candidate needs it of the same segment
// whose collision it samples: one walk instead of two); else tau_all = tau.
// Blocks are the level's voxels (2^mip density voxels per edge); empty bricks of the level
// (sigma_t* = 0 throughout) are crossed in one step, and so are a brick's empty blocks of
// 4^3 voxels (pc_empty_block): a cloud's bricks on its edge are mostly empty (57 % of the
// voxels the benchmark cloud's candidates visited held 0; 13 % fewer steps at K = 1).
// Crossing zeros adds nothing to tau, and a crossing is the same formula either way, so
// skipping changes no result. Both skips are one call: a second inlined skip made
// lavapipe's loop 20 % slower.
float pc_track_through(uint level, vec3 o, vec3 d, float t_end, float tau_target, bool through, out float sigma_star,
                       out float tau, out float tau_all) {
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
    tau_all = 0.0;
    // The collision, once found by a walk `through`.
    float z_hit = FAR;
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
    // The brick's occupancy mask, read at its first empty voxel (pc_empty_block).
    uint mask = ~0u;
    while (it.s < it.len && steps < GRID_MAX_STEPS) {
        ++steps;
        COUNT_STEP();
        ivec3 cell = it.cell;
        if ((cell >> 3) != brick_at) {
            brick_at = cell >> 3;
            slot = grid_slot(L.bricks_offset, L.brick_dims, brick_at);
            if (!SC_PC_BUFFER) {
                origin = grid_slot_origin(slot, L.slots_x, L.slots_y);
            }
            mask = ~0u;
        }
        // One skip for an empty brick (shift 3) or an empty block of it.
        int shift = 3;
        float sigma = 0.0;
        if (slot != NO_BRICK) {
            sigma = pc_texel(slot, origin, cell & 7);
            COUNT(CTR_MAJORANT, 1);
            shift = sigma > 0.0 || !pc_empty_block(slot, origin, cell & 7, mask) ? 0 : 2;
        }
        if (shift > 0) {
            grid_blocks_skip_aligned(it, shift);
            continue;
        }
        grid_blocks_next(it, s0, s1, index);
        float dtau = sigma * (s1 - s0);
        if (z_hit >= FAR && sigma > 0.0 && tau_all + dtau >= tau_target) {
            sigma_star = sigma;
            // Domain: sigma > 0; the result lies in [s0, s1].
            z_hit = it.t_a + min(s0 + (tau_target - tau_all) / sigma, s1);
            tau = tau_target;
            if (!through) {
                tau_all = tau_target;
                return z_hit;
            }
            // The walk goes on for tau_all alone (z_hit < FAR: no second collision).
        }
        tau_all += dtau;
    }
    if (z_hit >= FAR) {
        tau = tau_all;
    }
    return z_hit;
}

// pc_track_through without going on: a walk to the collision (or t_end) alone.
float pc_track(uint level, vec3 o, vec3 d, float t_end, float tau_target, out float sigma_star, out float tau) {
    float tau_all;
    return pc_track_through(level, o, d, t_end, tau_target, false, sigma_star, tau, tau_all);
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
    ivec3 origin = SC_PC_BUFFER ? ivec3(0) : grid_slot_origin(slot, L.slots_x, L.slots_y);
    return pc_texel(slot, origin, cell & 7);
}

#endif
