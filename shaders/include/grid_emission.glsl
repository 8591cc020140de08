// Emitted radiance of the grid medium. The includer declares `u_emission` (sampler3D: the
// emission grid's atlas, R32F for a scalar grid or RGBA32F for an rgb one, texelFetch only),
// `u_base` (BaselineUniforms, whose `emission` is the grid's GridSpace) and `u_grid`.
#ifndef NIMBUS_GRID_EMISSION_GLSL
#define NIMBUS_GRID_EMISSION_GLSL

// Le at world x: emission_scale times the emission grid, trilinear between lattice points
// and clamped to its lattice range (grid.glsl's rules, on the emission grid's own index space).
vec3 grid_emission(vec3 x) {
    GridSpace s = u_base.emission;
    ivec3 cell;
    vec3 f;
    grid_locate(s, space_to_index(s, x), cell, f);
    ivec3 lo = clamp(cell, s.lattice_min, s.lattice_max);
    ivec3 o = clamp(cell + 1, s.lattice_min, s.lattice_max) - lo;
    uint slot = grid_slot(s.bricks_offset, s.brick_dims, lo >> 3);
    if (slot == NO_BRICK) {
        return vec3(0.0);
    }
    ivec3 b = grid_slot_origin(slot, s.slots_x, s.slots_y) + (lo & 7);
    vec3 c000 = texelFetch(u_emission, b, 0).rgb;
    vec3 c100 = texelFetch(u_emission, b + ivec3(o.x, 0, 0), 0).rgb;
    vec3 c010 = texelFetch(u_emission, b + ivec3(0, o.y, 0), 0).rgb;
    vec3 c110 = texelFetch(u_emission, b + ivec3(o.x, o.y, 0), 0).rgb;
    vec3 c001 = texelFetch(u_emission, b + ivec3(0, 0, o.z), 0).rgb;
    vec3 c101 = texelFetch(u_emission, b + ivec3(o.x, 0, o.z), 0).rgb;
    vec3 c011 = texelFetch(u_emission, b + ivec3(0, o.y, o.z), 0).rgb;
    vec3 c111 = texelFetch(u_emission, b + ivec3(o.x, o.y, o.z), 0).rgb;
    vec3 c00 = mix(c000, c100, f.x);
    vec3 c10 = mix(c010, c110, f.x);
    vec3 c01 = mix(c001, c101, f.x);
    vec3 c11 = mix(c011, c111, f.x);
    vec3 e = mix(mix(c00, c10, f.y), mix(c01, c11, f.y), f.z);
    // A scalar (R32F) texel reads as (v, 0, 0): the same value in every channel.
    return u_base.emission_scale * (s.channels == 1u ? vec3(e.r) : e);
}

#endif
