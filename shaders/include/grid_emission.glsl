// Emitted radiance of the grid medium. The includer declares `u_emission` (sampler3D,
// R32 emission values, texelFetch only), `u_base` (BaselineUniforms) and `u_grid`.
#ifndef NIMBUS_GRID_EMISSION_GLSL
#define NIMBUS_GRID_EMISSION_GLSL

// Le at world x: emission_scale times the emission grid, trilinear between cell centres
// and clamped within half a voxel of a face (as the density).
vec3 grid_emission(vec3 x) {
    vec3 size = u_grid.bounds_max - u_grid.bounds_min;
    vec3 n = vec3(u_base.emission_dims);
    // Domain: size > 0 (validated bounds).
    vec3 p = clamp((x - u_grid.bounds_min) / size * n, vec3(0.5), n - 0.5) - 0.5;
    ivec3 i0 = ivec3(floor(p));
    ivec3 hi = ivec3(u_base.emission_dims) - 1;
    ivec3 i1 = min(i0 + 1, hi);
    vec3 f = p - vec3(i0);
    float c000 = texelFetch(u_emission, ivec3(i0.x, i0.y, i0.z), 0).r;
    float c100 = texelFetch(u_emission, ivec3(i1.x, i0.y, i0.z), 0).r;
    float c010 = texelFetch(u_emission, ivec3(i0.x, i1.y, i0.z), 0).r;
    float c110 = texelFetch(u_emission, ivec3(i1.x, i1.y, i0.z), 0).r;
    float c001 = texelFetch(u_emission, ivec3(i0.x, i0.y, i1.z), 0).r;
    float c101 = texelFetch(u_emission, ivec3(i1.x, i0.y, i1.z), 0).r;
    float c011 = texelFetch(u_emission, ivec3(i0.x, i1.y, i1.z), 0).r;
    float c111 = texelFetch(u_emission, ivec3(i1.x, i1.y, i1.z), 0).r;
    float c00 = mix(c000, c100, f.x);
    float c10 = mix(c010, c110, f.x);
    float c01 = mix(c001, c101, f.x);
    float c11 = mix(c011, c111, f.x);
    return u_base.emission_scale * mix(mix(c00, c10, f.y), mix(c01, c11, f.y), f.z);
}

#endif
