// Reservoirs of Volumetric ReSTIR (Lin, Wyman and Yuksel 2021): the header type, its
// packing into a uint buffer, octahedral directions, and the one streaming-RIS update
// (Algorithm 2's updateReservoir) that initial sampling and every combination use.
//
// The includer declares `uint reservoirs[]` (a storage buffer) and says where a pixel's
// reservoir starts (restir/resources.glsl: res_at). A reservoir at uint `at` is
//   [0] w_sum  [1] M  [2] p_hat (all float bits)  [3] info
//   [4..6] light point (sphere lights)  [7] light direction (octahedral, 2 x 16 bits)
//   [8 + 2(i-1)] z_i  [9 + 2(i-1)] omega_i (octahedral), i = 1..K
// so RESERVOIR_HEADER_UINTS + RESERVOIR_VERTEX_UINTS K uints (features.glsl).
// info: bits 0-4 k', bit 5 emission path, bit 6 holds a path, bit 7 p_hat is the reuse
// target at the owner's pixel and frame (set by a combination, not by initial sampling),
// bits 8-15 light index, bits 16-31 the sub-pixel jitter code (camera.glsl).
#ifndef NIMBUS_RESERVOIR_GLSL
#define NIMBUS_RESERVOIR_GLSL

#include "features.glsl"
#include "rng.glsl"

#define INFO_VERTICES 0x1fu
#define INFO_EMISSION 0x20u
#define INFO_VALID 0x40u
#define INFO_REUSE_TARGET 0x80u

// A reservoir's header: the RIS sums and the selected path's light vertex. The path's
// (z_i, omega_i) stay in the buffer (res_z, res_omega).
struct Reservoir {
    float w_sum;
    float M;
    float p_hat;
    uint info;
    vec3 light_point;
    uint light_dir;
};

uint res_vertices(Reservoir r) {
    return r.info & INFO_VERTICES;
}
bool res_valid(Reservoir r) {
    return (r.info & INFO_VALID) != 0u;
}
bool res_emission(Reservoir r) {
    return (r.info & INFO_EMISSION) != 0u;
}
uint res_light(Reservoir r) {
    return (r.info >> 8u) & 0xffu;
}
uint res_jitter(Reservoir r) {
    return r.info >> 16u;
}

Reservoir res_empty() {
    Reservoir r;
    r.w_sum = 0.0;
    r.M = 0.0;
    r.p_hat = 0.0;
    r.info = 0u;
    r.light_point = vec3(0.0);
    r.light_dir = 0u;
    return r;
}

// ---------------------------------------------------------------------------------------
// Streaming RIS.

// Streams a candidate with resampling weight w into r: w_sum += w, and the candidate
// replaces r's sample with probability w / w_sum, taking its target p_hat, info and light
// vertex from `c` (the caller then copies its path vertices). A weight that is not a
// positive finite number is a null sample: nothing changes and no random number is drawn.
// Returns whether the candidate was selected.
bool res_update(inout Reservoir r, Reservoir c, float w, inout uint rng) {
    if (!(w > 0.0) || isinf(w)) {
        return false;
    }
    r.w_sum += w;
    // Domain: r.w_sum >= w > 0.
    if (rng_next(rng) * r.w_sum < w) {
        r.p_hat = c.p_hat;
        r.info = c.info;
        r.light_point = c.light_point;
        r.light_dir = c.light_dir;
        return true;
    }
    return false;
}

// ---------------------------------------------------------------------------------------
// Packing.

Reservoir res_load(uint at) {
    Reservoir r;
    r.w_sum = uintBitsToFloat(reservoirs[at]);
    r.M = uintBitsToFloat(reservoirs[at + 1u]);
    r.p_hat = uintBitsToFloat(reservoirs[at + 2u]);
    r.info = reservoirs[at + 3u];
    r.light_point = vec3(uintBitsToFloat(reservoirs[at + 4u]), uintBitsToFloat(reservoirs[at + 5u]),
                         uintBitsToFloat(reservoirs[at + 6u]));
    r.light_dir = reservoirs[at + 7u];
    return r;
}

// M alone, without loading the header.
float res_load_M(uint at) {
    return uintBitsToFloat(reservoirs[at + 1u]);
}

void res_store_header(uint at, Reservoir r) {
    reservoirs[at] = floatBitsToUint(r.w_sum);
    reservoirs[at + 1u] = floatBitsToUint(r.M);
    reservoirs[at + 2u] = floatBitsToUint(r.p_hat);
    reservoirs[at + 3u] = r.info;
    reservoirs[at + 4u] = floatBitsToUint(r.light_point.x);
    reservoirs[at + 5u] = floatBitsToUint(r.light_point.y);
    reservoirs[at + 6u] = floatBitsToUint(r.light_point.z);
    reservoirs[at + 7u] = r.light_dir;
}

// Where vertex i (1..K) of the reservoir at `at` is stored.
uint res_vertex_at(uint at, uint i) {
    return at + RESERVOIR_HEADER_UINTS + RESERVOIR_VERTEX_UINTS * (i - 1u);
}
float res_z(uint at, uint i) {
    return uintBitsToFloat(reservoirs[res_vertex_at(at, i)]);
}
uint res_omega(uint at, uint i) {
    return reservoirs[res_vertex_at(at, i) + 1u];
}
void res_store_vertex(uint at, uint i, float z, uint omega) {
    reservoirs[res_vertex_at(at, i)] = floatBitsToUint(z);
    reservoirs[res_vertex_at(at, i) + 1u] = omega;
}

// Octahedral encoding of a unit vector in 2 x 16-bit snorm (Cigolle et al. 2014); the
// angular error is below 6e-5 rad.
vec2 oct_wrap(vec2 v) {
    return (1.0 - abs(v.yx)) * vec2(v.x >= 0.0 ? 1.0 : -1.0, v.y >= 0.0 ? 1.0 : -1.0);
}
uint oct_encode(vec3 n) {
    // Domain: |n| = 1, so the L1 norm is >= 1.
    vec2 p = n.xy / (abs(n.x) + abs(n.y) + abs(n.z));
    p = n.z >= 0.0 ? p : oct_wrap(p);
    return packSnorm2x16(p);
}
vec3 oct_decode(uint e) {
    vec2 p = unpackSnorm2x16(e);
    vec3 n = vec3(p, 1.0 - abs(p.x) - abs(p.y));
    if (n.z < 0.0) {
        n.xy = oct_wrap(n.xy);
    }
    return normalize(n);
}

#endif
