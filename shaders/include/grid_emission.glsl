// Emitted radiance and albedo of the grid medium. The includer declares `u_emission`
// (sampler3D: the emission grid's atlas, R32F for a scalar grid or RGBA32F for an rgb one,
// texelFetch only), `u_temperature` (R32F, the temperature grid's), `blackbody[]`
// (BINDING_BLACKBODY) and `u_albedo` (the albedo grid's atlas, R32F or RGBA32F), the bool
// constants SC_HAS_BLACKBODY and SC_HAS_ALBEDO_GRID, `u_base` (BaselineUniforms, whose
// `emission`, `temperature` and `albedo_grid` are those grids' GridSpaces) and `u_grid`.
#ifndef NIMBUS_GRID_EMISSION_GLSL
#define NIMBUS_GRID_EMISSION_GLSL

// Entries of the blackbody table and its coldest temperature (kelvin); the table holds
// RGB(T) / T at u = 1 / T = i / ((LEN - 1) * MIN_KELVIN) (crates/nimbus-scene/src/blackbody.rs).
#define BLACKBODY_TABLE_LEN 4096
#define BLACKBODY_MIN_KELVIN 400.0

// The grid `s` (atlas `atlas`) at world x: trilinear between lattice points, clamped to its
// lattice range (grid.glsl's rules, on the grid's own index space); 0 where no brick is.
vec4 grid_atlas_trilinear(GridSpace s, sampler3D atlas, vec3 x) {
    ivec3 cell;
    vec3 f;
    grid_locate(s, space_to_index(s, x), cell, f);
    ivec3 lo = clamp(cell, s.lattice_min, s.lattice_max);
    ivec3 o = clamp(cell + 1, s.lattice_min, s.lattice_max) - lo;
    uint slot = grid_slot(s.bricks_offset, s.brick_dims, lo >> 3);
    if (slot == NO_BRICK) {
        return vec4(0.0);
    }
    ivec3 b = grid_slot_origin(slot, s.slots_x, s.slots_y) + (lo & 7);
    vec4 c000 = texelFetch(atlas, b, 0);
    vec4 c100 = texelFetch(atlas, b + ivec3(o.x, 0, 0), 0);
    vec4 c010 = texelFetch(atlas, b + ivec3(0, o.y, 0), 0);
    vec4 c110 = texelFetch(atlas, b + ivec3(o.x, o.y, 0), 0);
    vec4 c001 = texelFetch(atlas, b + ivec3(0, 0, o.z), 0);
    vec4 c101 = texelFetch(atlas, b + ivec3(o.x, 0, o.z), 0);
    vec4 c011 = texelFetch(atlas, b + ivec3(0, o.y, o.z), 0);
    vec4 c111 = texelFetch(atlas, b + ivec3(o.x, o.y, o.z), 0);
    vec4 c00 = mix(c000, c100, f.x);
    vec4 c10 = mix(c010, c110, f.x);
    vec4 c01 = mix(c001, c101, f.x);
    vec4 c11 = mix(c011, c111, f.x);
    return mix(mix(c00, c10, f.y), mix(c01, c11, f.y), f.z);
}

// RGB(T) of a blackbody at `kelvin` in W/(m^2 sr): 0 below BLACKBODY_MIN_KELVIN (and for
// NaN), else the table's RGB/T, linear in 1/T, times T.
vec3 blackbody_rgb(float kelvin) {
    if (!(kelvin >= BLACKBODY_MIN_KELVIN)) {
        return vec3(0.0);
    }
    float x = BLACKBODY_MIN_KELVIN * float(BLACKBODY_TABLE_LEN - 1) / kelvin;
    int i = min(int(x), BLACKBODY_TABLE_LEN - 2);
    vec3 per_kelvin = mix(blackbody[i].rgb, blackbody[i + 1].rgb, x - float(i));
    return per_kelvin * kelvin;
}

// Le at world x: emission_scale times the emission grid (a scalar grid's R32F texel reads
// as (v, 0, 0): the same value in every channel; a medium without one has 0 channels),
// plus, with a temperature grid, blackbody_scale * RGB(temperature_offset +
// temperature_scale * its value).
vec3 grid_emission(vec3 x) {
    GridSpace s = u_base.emission;
    vec3 le = vec3(0.0);
    if (s.channels != 0u) {
        vec4 e = grid_atlas_trilinear(s, u_emission, x);
        le = u_base.emission_scale * (s.channels == 1u ? vec3(e.r) : e.rgb);
    }
    if (SC_HAS_BLACKBODY) {
        float t = grid_atlas_trilinear(u_base.temperature, u_temperature, x).r;
        float kelvin = u_base.temperature_offset + u_base.temperature_scale * t;
        le += u_base.blackbody_scale * blackbody_rgb(kelvin);
    }
    return le;
}

// The grid medium's single-scattering albedo at world x: its colour, times the albedo grid
// there (one channel: grey; three: rgb) where it has one. Trilinear values in [0, 1] stay
// in [0, 1].
vec3 grid_albedo(vec3 x) {
    if (!SC_HAS_ALBEDO_GRID) {
        return u_base.albedo;
    }
    GridSpace s = u_base.albedo_grid;
    vec4 a = grid_atlas_trilinear(s, u_albedo, x);
    return u_base.albedo * (s.channels == 1u ? vec3(a.r) : a.rgb);
}

#endif
