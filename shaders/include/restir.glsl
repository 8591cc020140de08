// Volumetric ReSTIR (Lin, Wyman and Yuksel 2021): what the four passes share.
//
// Each pass (restir/initial, temporal, spatial, shade) includes this file alone. It
// declares the bindings, the specialization constants, and:
//   - reservoirs: packed storage of a path sample lambda = (z_i, omega_i) tuples, w_sum,
//     M and p_hat, in one buffer of three slots that the renderer rotates between frames;
//   - regular tracking through the conservative piecewise-constant grid at a mip level
//     (candidate generation, sec. 4.1, eq. 27-28);
//   - ray-marched trilinear transmittance T~ on a mip texture (target functions, sec. 5.1);
//   - path_value: the path's contribution for a camera ray, either the target function
//     p_hat (Algorithm 4) or the integrand F with unbiased transmittance (Algorithm 6);
//   - the Talbot-MIS combination of reservoirs (Algorithms 2 and 5).
//
// Paths. A stored path has k' medium vertices x_1..x_k' (k' = 0: the camera ray itself
// ends on a light, "direct"). x_1 = x_0 + z_1 omega_0 where omega_0 is the camera ray of
// the pixel that EVALUATES the path, so a path moves between pixels by keeping z_1
// (sec. 4.2). Then x_i = x_{i-1} + z_i omega_{i-1}, with omega_i stored (direction reuse);
// with vertex reuse x_2 is kept in world space instead (see path_value). A scattering path
// ends in a light vertex (a light index with a stored direction or point); an emission
// path ends at x_k', where the medium emits. Measures: (z, omega) per segment, solid angle
// for the environment, area for sphere lights, delta for directional and point lights.
#ifndef NIMBUS_RESTIR_GLSL
#define NIMBUS_RESTIR_GLSL

#extension GL_GOOGLE_include_directive : require

#include "features.glsl"
#include "bindings.glsl"
#include "constants.glsl"
#include "scene.glsl"
#include "rng.glsl"
#include "phase.glsl"
#include "sampling.glsl"
#include "geometry.glsl"
#include "grid_types.glsl"

layout(local_size_x = GROUP_SIZE_X, local_size_y = GROUP_SIZE_Y) in;

layout(constant_id = SC_ID_HAS_ENV) const bool SC_HAS_ENV = true;
layout(constant_id = SC_ID_MAX_BOUNCES) const uint SC_MAX_BOUNCES = 1u;
layout(constant_id = SC_ID_PIXEL_JITTER) const bool SC_PIXEL_JITTER = true;
layout(constant_id = SC_ID_HAS_EMISSION) const bool SC_HAS_EMISSION = false;
layout(constant_id = SC_ID_HAS_ENV_MAP) const bool SC_HAS_ENV_MAP = false;
// Vertex reuse (x_2 kept in world space) instead of direction reuse.
layout(constant_id = SC_ID_REUSE_VERTEX) const bool SC_REUSE_VERTEX = false;
// Final shading estimates transmittance by ratio tracking instead of the closed form.
layout(constant_id = SC_ID_FINAL_RATIO_TRACKING) const bool SC_FINAL_RATIO_TRACKING = false;
// The medium has a velocity grid (temporal reprojection follows it).
layout(constant_id = SC_ID_HAS_VELOCITY) const bool SC_HAS_VELOCITY = false;

// Settings of the ReSTIR passes (std140). Mirrored by RestirUniformsGpu. 128 bytes.
struct RestirUniforms {
    uvec4 pc_primary;    // xyz dims of the piecewise-constant level for camera rays, w offset
    uvec4 pc_indirect;   // xyz dims of the level for scattered rays, w offset
    uvec4 factors;       // voxels per block edge: x primary level, y indirect, z reuse march, w NEE march
    uvec4 march_dims;    // xyz dims of the reuse march texture (mip_reuse), w unused
    uvec4 nee_dims;      // xyz dims of the NEE march texture (mip_indirect), w unused
    uvec4 settings;      // x candidates M, y temporal limit Q, z spatial neighbours, w reservoir stride (uints)
    vec4 spatial;        // x radius (pixels), y reuse march step (m), z NEE march step (m), w unused
    uvec4 velocity_dims; // xyz dims of the velocity grid, w unused
};

// Push constants of every ReSTIR dispatch. 16 bytes.
struct RestirPush {
    uint frame;  // frame index within the render (0 = first)
    uint src;    // reservoir slot read
    uint dst;    // reservoir slot written
    uint aux;    // temporal: slot of the previous frame; spatial: the round
};

layout(std140, set = 0, binding = BINDING_FRAME_UNIFORMS) uniform FrameBlock {
    FrameUniforms u_frame;
};
layout(std140, set = 0, binding = BINDING_PREV_FRAME_UNIFORMS) uniform PrevFrameBlock {
    FrameUniforms u_prev_frame;
};
layout(push_constant) uniform PushBlock {
    RestirPush u_push;
};
layout(std430, set = 0, binding = BINDING_ACCUM) buffer AccumBlock {
    vec4 accum[];
};
layout(std430, set = 0, binding = BINDING_ACCUM_SQ) buffer AccumSqBlock {
    vec4 accum_sq[];
};
layout(std430, set = 0, binding = BINDING_STATS) buffer StatsBlock {
    uint stats[];
};
// The current frame's analytic lights, then the previous frame's (counts.z each).
layout(std430, set = 0, binding = BINDING_LIGHTS) readonly buffer LightsBlock {
    Light lights[];
};
layout(std140, set = 0, binding = BINDING_BASELINE_UNIFORMS) uniform BaselineBlock {
    BaselineUniforms u_base;
};
layout(std140, set = 0, binding = BINDING_RESTIR_UNIFORMS) uniform RestirBlock {
    RestirUniforms u_restir;
};
// Full-resolution density (unscaled, R32, texelFetch): this frame and the previous one.
layout(set = 0, binding = BINDING_GRID_DENSITY) uniform sampler3D u_density;
layout(set = 0, binding = BINDING_GRID_DENSITY_PREV) uniform sampler3D u_density_prev;
layout(set = 0, binding = BINDING_GRID_EMISSION) uniform sampler3D u_emission;
// Mip textures for ray marching (unscaled density, R16F, linear filtering).
layout(set = 0, binding = BINDING_MARCH_REUSE) uniform sampler3D u_march_reuse;
layout(set = 0, binding = BINDING_MARCH_REUSE_PREV) uniform sampler3D u_march_reuse_prev;
layout(set = 0, binding = BINDING_MARCH_NEE) uniform sampler3D u_march_nee;
// Velocity in metres per frame (RGBA16F, linear filtering).
layout(set = 0, binding = BINDING_VELOCITY) uniform sampler3D u_velocity;
layout(std430, set = 0, binding = BINDING_SUPER_VOXELS) readonly buffer SuperVoxelBlock {
    vec4 super_voxels[];
};
// Conservative piecewise-constant sigma_t* (scaled) of the two tracking levels.
layout(std430, set = 0, binding = BINDING_PC_GRID) readonly buffer PcGridBlock {
    float pc_grid[];
};
layout(std430, set = 0, binding = BINDING_RESERVOIRS) buffer ReservoirBlock {
    uint reservoirs[];
};
layout(std430, set = 0, binding = BINDING_ENV_TEXELS) readonly buffer EnvTexelBlock {
    vec4 env_texels[];
};
layout(std430, set = 0, binding = BINDING_ENV_CDF) readonly buffer EnvCdfBlock {
    float env_cdf[];
};

#define u_grid u_base.grid
#define ENV_SIZE u_base.env_size.xy
#include "grid.glsl"
#include "grid_emission.glsl"
#include "lights.glsl"

// Which frame a camera ray, density or light set belongs to.
#define SET_CURRENT 0u
#define SET_PREVIOUS 1u

// The first light record of a set.
uint light_base(uint set) {
    return set == SET_CURRENT ? 0u : u_frame.counts.z;
}

// Scalar target from an RGB contribution: luminance (positive weights, so > 0 exactly
// when some channel is > 0 for non-negative colours).
float luminance(vec3 c) {
    return dot(c, vec3(0.2126, 0.7152, 0.0722));
}

// ---------------------------------------------------------------------------------------
// Camera rays. The sub-pixel position is part of the path (the pixel's box filter is one
// more integration dimension): each random walk draws its own, the reservoir keeps it
// (8 + 8 bits, `info` bits 16-31), and a path moving to another pixel or frame keeps it,
// so temporal reuse re-evaluates a path on the same ray it was found on. Jitter code c
// per axis stands for the sub-pixel offset (c + 0.5) / 256 (a 256 x 256 midpoint grid
// over the pixel); without SC_PIXEL_JITTER every ray goes through the pixel centre.

struct CameraRay {
    vec3 o;
    vec3 d;
    uint set;
};

// Unit direction of the camera ray through pixel position px (pixels, (0, 0) top-left).
vec3 camera_direction(FrameUniforms cam, vec2 px) {
    float sx = (2.0 * px.x / float(cam.image.x) - 1.0) * cam.cam_position.w;
    float sy = (1.0 - 2.0 * px.y / float(cam.image.y)) * cam.cam_forward.w;
    return normalize(cam.cam_forward.xyz + sx * cam.cam_right.xyz + sy * cam.cam_up.xyz);
}

// A jitter code drawn uniformly: (x, y) in bits 0-7 and 8-15.
uint jitter_sample(inout uint rng) {
    uint x = min(uint(rng_next(rng) * 256.0), 255u);
    uint y = min(uint(rng_next(rng) * 256.0), 255u);
    return x | (y << 8u);
}

// The sub-pixel offset of a jitter code.
vec2 jitter_offset(uint code) {
    if (!SC_PIXEL_JITTER) {
        return vec2(0.5);
    }
    return (vec2(float(code & 0xffu), float((code >> 8u) & 0xffu)) + 0.5) / 256.0;
}

// The camera ray through `pixel` at sub-pixel jitter `code`, in a frame's set.
CameraRay camera_ray(uvec2 pixel, uint code, uint set) {
    CameraRay r;
    r.set = set;
    vec2 px = vec2(pixel) + jitter_offset(code);
    if (set == SET_CURRENT) {
        r.o = u_frame.cam_position.xyz;
        r.d = camera_direction(u_frame, px);
    } else {
        r.o = u_prev_frame.cam_position.xyz;
        r.d = camera_direction(u_prev_frame, px);
    }
    return r;
}

// Pixel position of world point x seen by `cam`; false if behind the camera.
bool camera_project(FrameUniforms cam, vec3 x, out vec2 px) {
    vec3 v = x - cam.cam_position.xyz;
    float z = dot(v, cam.cam_forward.xyz);
    if (!(z > 1e-6)) {
        return false;
    }
    // Domain: z > 0 and tan(fov / 2) > 0 (validated fov).
    float sx = dot(v, cam.cam_right.xyz) / (z * cam.cam_position.w);
    float sy = dot(v, cam.cam_up.xyz) / (z * cam.cam_forward.w);
    px = vec2((sx + 1.0) * 0.5 * float(cam.image.x), (1.0 - sy) * 0.5 * float(cam.image.y));
    return true;
}

// ---------------------------------------------------------------------------------------
// Reservoirs: slot s of pixel p starts at uint (s * pixels + p) * stride, stride = 8 + 2K:
//   [0] w_sum  [1] M  [2] p_hat (all float bits)  [3] info
//   [4..6] light point (sphere lights)  [7] light direction (octahedral, 2 x 16 bits)
//   [8 + 2(i-1)] z_i  [9 + 2(i-1)] omega_i (octahedral), i = 1..K
// info: bits 0-4 k', bit 5 emission path, bit 6 holds a path, bit 7 p_hat is the reuse
// target at the owner's pixel and frame (set by a combination, not by initial sampling),
// bits 8-15 light index, bits 16-31 the sub-pixel jitter code.

#define INFO_EMISSION 0x20u
#define INFO_VALID 0x40u
#define INFO_REUSE_TARGET 0x80u

struct Reservoir {
    float w_sum;
    float M;
    float p_hat;
    uint info;
    vec3 light_point;
    uint light_dir;
};

uint res_vertices(Reservoir r) {
    return r.info & 0x1fu;
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

uint res_stride() {
    return u_restir.settings.w;
}

uint res_at(uint slot, uvec2 pixel) {
    uint pixels = u_frame.image.x * u_frame.image.y;
    return (slot * pixels + pixel.y * u_frame.image.x + pixel.x) * res_stride();
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

float res_z(uint at, uint i) {
    return uintBitsToFloat(reservoirs[at + 8u + 2u * (i - 1u)]);
}
uint res_omega(uint at, uint i) {
    return reservoirs[at + 9u + 2u * (i - 1u)];
}
void res_store_vertex(uint at, uint i, float z, uint omega) {
    reservoirs[at + 8u + 2u * (i - 1u)] = floatBitsToUint(z);
    reservoirs[at + 9u + 2u * (i - 1u)] = omega;
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

// ---------------------------------------------------------------------------------------
// Media lookups for a frame's set.

float sigma_t_of(uint set, vec3 x) {
    return set == SET_CURRENT ? grid_sigma_t_in(u_density, x) : grid_sigma_t_in(u_density_prev, x);
}

// T~ along o + t d, t in [t0, t1]: midpoint ray marching of the mip texture `tex` (dims
// `dims`, blocks of `factor` voxels) with steps of at most `step` metres. Deterministic, so
// a target function is a function of the path (needed by the MIS weights).
float march_transmittance(sampler3D tex, uvec3 dims, uint factor, float step, vec3 o, vec3 d, float t0,
                          float t1) {
    vec2 span = grid_span(o, d);
    float a = max(t0, span.x);
    float b = min(t1, span.y);
    if (!(a < b)) {
        return 1.0;
    }
    // Domain: step > 0 (a voxel diagonal).
    int n = int(clamp(ceil((b - a) / step), 1.0, float(MARCH_MAX_STEPS)));
    float dt = (b - a) / float(n);
    // Texture coordinates: index space over the blocks' extent (dims * factor voxels).
    vec3 to_uvw = grid_index_scale() / (vec3(dims) * float(factor));
    vec3 uvw0 = (o + a * d - u_grid.bounds_min.xyz) * to_uvw;
    vec3 duvw = d * to_uvw;
    float sum = 0.0;
    for (int j = 0; j < n; ++j) {
        sum += textureLod(tex, uvw0 + duvw * ((float(j) + 0.5) * dt), 0.0).r;
    }
    // Domain: density_scale * sum * dt >= 0.
    return exp(-u_grid.bounds_min.w * sum * dt);
}

// T~ for target functions of reuse (mip_reuse) in a frame's set.
float reuse_transmittance(uint set, vec3 o, vec3 d, float t1) {
    uvec3 dims = u_restir.march_dims.xyz;
    uint factor = u_restir.factors.z;
    float step = u_restir.spatial.y;
    if (set == SET_CURRENT) {
        return march_transmittance(u_march_reuse, dims, factor, step, o, d, 0.0, t1);
    }
    return march_transmittance(u_march_reuse_prev, dims, factor, step, o, d, 0.0, t1);
}

// T~ of NEE segments of initial candidates (mip_indirect).
float nee_transmittance(vec3 o, vec3 d, float t1) {
    return march_transmittance(u_march_nee, u_restir.nee_dims.xyz, u_restir.factors.w, u_restir.spatial.z, o,
                               d, 0.0, t1);
}

// Unbiased T for final shading: the closed form through the trilinear grid, or ratio
// tracking with the global majorant.
float final_transmittance(vec3 o, vec3 d, float t1, inout uint rng) {
    if (SC_FINAL_RATIO_TRACKING) {
        return grid_ratio_tracking(o, d, 0.0, t1, rng);
    }
    return grid_transmittance(o, d, 0.0, t1);
}

// ---------------------------------------------------------------------------------------
// Regular tracking through the conservative piecewise-constant grid (eq. 27-28).

#define LEVEL_PRIMARY 0u
#define LEVEL_INDIRECT 1u

// Walks [0, t_end) from o along d through level `level` until the optical depth reaches
// tau_target. Returns the collision distance (FAR if the ray leaves first), sigma_t* there
// and tau = the optical depth walked (tau_target at a collision, the total otherwise).
float pc_track(uint level, vec3 o, vec3 d, float t_end, float tau_target, out float sigma_star, out float tau) {
    uvec4 lv = level == LEVEL_PRIMARY ? u_restir.pc_primary : u_restir.pc_indirect;
    int f = int(level == LEVEL_PRIMARY ? u_restir.factors.x : u_restir.factors.y);
    sigma_star = 0.0;
    tau = 0.0;
    GridSuperDda it;
    if (!grid_blocks_begin(o, d, 0.0, t_end, f, ivec3(lv.xyz), it)) {
        return FAR;
    }
    float s0;
    float s1;
    uint index;
    int steps = 0;
    while (grid_blocks_next(it, s0, s1, index) && steps < GRID_MAX_STEPS) {
        ++steps;
        float sigma = pc_grid[lv.w + index];
        float dtau = sigma * (s1 - s0);
        if (sigma > 0.0 && tau + dtau >= tau_target) {
            sigma_star = sigma;
            // Domain: sigma > 0; the result lies in [s0, s1].
            float s = min(s0 + (tau_target - tau) / sigma, s1);
            tau = tau_target;
            return it.t_a + s;
        }
        tau += dtau;
    }
    return FAR;
}

// ---------------------------------------------------------------------------------------
// Path values (Algorithm 4 for targets, Algorithm 6's F for final shading).

#define MODE_TARGET 0u
#define MODE_FINAL 1u

// True if an emitting sphere of the set cuts o + t d for t in (0, t1).
bool segment_hits_light(uint set, vec3 o, vec3 d, float t1) {
    uint index;
    return nearest_sphere_light(light_base(set), o, d, 1e-6, t1, index) < FAR;
}

// The RGB value of the path stored at `at` (header r) for camera ray `cam`:
//   MODE_TARGET: the target function with T~ ray marched on mip_reuse, in cam.set's frame;
//   MODE_FINAL:  the integrand F with unbiased transmittance (current frame).
// `src` is the camera ray of the pixel that owns the stored representation; only vertex
// reuse needs it, to rebuild x_2 in world space.
vec3 path_value(uint at, Reservoir r, CameraRay cam, CameraRay src, uint mode, inout uint rng) {
    if (!res_valid(r)) {
        return vec3(0.0);
    }
    uint set = cam.set;
    uint lbase = light_base(set);
    uint kp = res_vertices(r);
    if (kp == 0u) {
        // The camera ray ends on a light: L^s times the transmittance of the whole ray.
        float t_end;
        vec3 L = light_seen(lbase, cam.o, cam.d, t_end);
        float T = mode == MODE_FINAL ? final_transmittance(cam.o, cam.d, t_end, rng)
                                     : reuse_transmittance(set, cam.o, cam.d, t_end);
        return L * T;
    }
    vec3 albedo = u_base.albedo_g.rgb;
    float g = u_base.albedo_g.w;
    // Vertex reuse: x_2 of the owner's path, in world space.
    bool keep_x2 = SC_REUSE_VERTEX && kp >= 2u;
    vec3 x2_world = vec3(0.0);
    if (keep_x2) {
        vec3 x1_src = src.o + res_z(at, 1u) * src.d;
        x2_world = x1_src + res_z(at, 2u) * oct_decode(res_omega(at, 1u));
    }
    vec3 f = vec3(1.0);
    vec3 x = cam.o;
    vec3 w = cam.d;
    // The volume-measure geometry term of x_2 under vertex reuse, else 1.
    float geometry = 1.0;
    for (uint i = 1u; i <= kp; ++i) {
        float z = res_z(at, i);
        if (i >= 2u) {
            vec3 w_next;
            if (i == 2u && keep_x2) {
                vec3 to = x2_world - x;
                float z2 = dot(to, to);
                // Domain: x_2 != x_1 (G = 1 / z_2^2 is unbounded there).
                if (!(z2 > 0.0)) {
                    return vec3(0.0);
                }
                z = sqrt(z2);
                w_next = to / z;
                geometry = 1.0 / z2;
            } else {
                w_next = oct_decode(res_omega(at, i - 1u));
            }
            // Phase at x_{i-1}: from the travel direction w to w_next.
            f *= hg_phase(dot(w, w_next), g);
            w = w_next;
        }
        if (!(z >= 0.0 && z < FAR)) {
            return vec3(0.0);
        }
        if (segment_hits_light(set, x, w, z)) {
            return vec3(0.0);
        }
        float T = mode == MODE_FINAL ? final_transmittance(x, w, z, rng) : reuse_transmittance(set, x, w, z);
        x += z * w;
        float sigma_t = mode == MODE_FINAL ? grid_sigma_t_in(u_density, x) : sigma_t_of(set, x);
        f *= T;
        if (i == kp && res_emission(r)) {
            if (!SC_HAS_EMISSION) {
                return vec3(0.0);
            }
            // Emission path: sigma_a Le at x_k' (absorbed-emission convention).
            return f * (vec3(1.0) - albedo) * sigma_t * grid_emission(x) * geometry;
        }
        // Scattering at x_i: sigma_s = albedo sigma_t.
        f *= albedo * sigma_t;
        if (!any(greaterThan(f, vec3(0.0)))) {
            return vec3(0.0);
        }
    }
    // The light vertex, re-evaluated from x_k'.
    vec3 wi;
    float dist;
    vec3 L = light_eval(lbase, res_light(r), oct_decode(r.light_dir), r.light_point, x, wi, dist);
    if (!any(greaterThan(L, vec3(0.0)))) {
        return vec3(0.0);
    }
    if (light_blocked(lbase, x, wi, dist)) {
        return vec3(0.0);
    }
    f *= hg_phase(dot(w, wi), g) * L;
    float T = mode == MODE_FINAL ? final_transmittance(x, wi, dist, rng) : reuse_transmittance(set, x, wi, dist);
    return f * T * geometry;
}

// ---------------------------------------------------------------------------------------
// Combining reservoirs with Talbot MIS (Algorithm 5, with Algorithm 2's combineReservoir).

// The reservoirs taking part in a combination, as small private arrays (the shader's
// registers; passing structs of rays and headers by value costs far more): where each is
// stored, its pixel and frame (its owner: the representation is relative to that camera
// ray), and its M (the temporal limit may lower it, scaling w_sum by the same factor).
uint cand_at[MAX_CANDIDATES];
uvec2 cand_pixel[MAX_CANDIDATES];
uint cand_set[MAX_CANDIDATES];
float cand_M[MAX_CANDIDATES];
float cand_w_scale[MAX_CANDIDATES];

// Registers candidate `i` (its header's M unless clamped later).
void candidate_set(uint i, uint at, uvec2 pixel, uint set) {
    cand_at[i] = at;
    cand_pixel[i] = pixel;
    cand_set[i] = set;
    cand_M[i] = uintBitsToFloat(reservoirs[at + 1u]);
    cand_w_scale[i] = 1.0;
}

// The camera ray of candidate i's pixel and frame at jitter `code`.
CameraRay candidate_ray(uint i, uint code) {
    return camera_ray(cand_pixel[i], code, cand_set[i]);
}

// Streams candidates 0..n-1 into one reservoir for the pixel of candidate 0. Each
// candidate i's sample lambda_i gets the Talbot weight
//   m_i = M_i p_i(lambda_i) / sum_s M_s p_s(lambda_i)
// with p_s the target function at candidate s's pixel and frame (ray-marched T~), and the
// resampling weight w_i = m_i p_0(lambda_i) W_i, W_i = w_sum_i / (M_i p_hat_i) its
// unbiased contribution weight. Stored as in Algorithm 2: w_sum = sum_i w_i M and M =
// sum_i M_i, so f / p_hat * w_sum / M stays the estimator. Returns the index of the chosen
// candidate (n if none) and the combined header (its p_hat = p_0 of the chosen sample).
uint combine_candidates(uint n, inout uint rng, out Reservoir s) {
    s = res_empty();
    float k = 0.0;
    for (uint i = 0u; i < n; ++i) {
        k += cand_M[i];
    }
    uint chosen = n;
    for (uint i = 0u; i < n; ++i) {
        Reservoir ri = res_load(cand_at[i]);
        ri.M = cand_M[i];
        ri.w_sum *= cand_w_scale[i];
        if (!res_valid(ri) || !(ri.p_hat > 0.0) || !(ri.w_sum > 0.0) || !(ri.M > 0.0)) {
            continue;
        }
        uint code = res_jitter(ri);
        CameraRay owner = candidate_ray(i, code);
        // The target here (j = 0) first, then at the sample's own pixel (j = i): if either
        // is 0, w_i = 0 whatever the other pixels give, and they are not evaluated.
        float p_sum = 0.0;
        float p_own = 0.0;
        float p_here = 0.0;
        bool dead = false;
        for (uint step = 0u; step < n && !dead; ++step) {
            // Visit order: 0, i, then the others ascending (0, 1, 2, ... when i = 0).
            uint j = i == 0u ? step : (step == 0u ? 0u : (step == 1u ? i : (step <= i ? step - 1u : step)));
            if (!(cand_M[j] > 0.0)) {
                continue;
            }
            // The sample's own pixel: a combined reservoir already holds that target
            // (computed by the same function for the same ray, frame and path).
            bool stored = j == i && (ri.info & INFO_REUSE_TARGET) != 0u;
            float p = stored ? ri.p_hat
                             : luminance(path_value(cand_at[i], ri, candidate_ray(j, code), owner, MODE_TARGET, rng));
            p_sum += p * cand_M[j];
            if (j == i) {
                p_own = p;
                dead = !(p > 0.0);
            }
            if (j == 0u) {
                p_here = p;
                dead = dead || !(p > 0.0);
            }
        }
        // Domain: p_sum > 0 (else no pixel could have produced lambda_i: weight 0).
        if (!(p_sum > 0.0) || !(p_here > 0.0)) {
            continue;
        }
        float m = p_own * k / p_sum;
        // Domain: p_hat_i > 0 (checked above).
        float w = p_here / ri.p_hat * ri.w_sum * m;
        if (!(w > 0.0) || isinf(w)) {
            continue;
        }
        s.w_sum += w;
        // Domain: s.w_sum >= w > 0.
        if (rng_next(rng) * s.w_sum < w) {
            chosen = i;
            s.p_hat = p_here;
            s.info = ri.info | INFO_REUSE_TARGET;
            s.light_point = ri.light_point;
            s.light_dir = ri.light_dir;
        }
    }
    s.M = k;
    if (chosen == n) {
        s.w_sum = 0.0;
        s.p_hat = 0.0;
        s.info = 0u;
    }
    return chosen;
}

// Writes the combined reservoir to `dst` for the pixel whose camera ray is `here`, copying
// the chosen candidate's path (from `src_at`, owned by camera ray `owner`). Vertex reuse
// re-expresses segment 2 relative to the new x_1 (x_2 stays in world space).
void store_combined(uint dst, Reservoir s, uint src_at, CameraRay owner, CameraRay here) {
    res_store_header(dst, s);
    if (!res_valid(s)) {
        return;
    }
    uint kp = res_vertices(s);
    bool shift_x2 = SC_REUSE_VERTEX && kp >= 2u;
    if (src_at == dst && !shift_x2) {
        return;
    }
    float z2 = 0.0;
    uint omega1 = 0u;
    if (shift_x2) {
        vec3 x2 = owner.o + res_z(src_at, 1u) * owner.d + res_z(src_at, 2u) * oct_decode(res_omega(src_at, 1u));
        vec3 x1 = here.o + res_z(src_at, 1u) * here.d;
        z2 = length(x2 - x1);
        omega1 = z2 > 0.0 ? oct_encode((x2 - x1) / z2) : res_omega(src_at, 1u);
    }
    for (uint i = 1u; i <= kp; ++i) {
        float z = res_z(src_at, i);
        uint omega = res_omega(src_at, i);
        if (shift_x2 && i == 1u) {
            omega = omega1;
        }
        if (shift_x2 && i == 2u) {
            z = z2;
        }
        res_store_vertex(dst, i, z, omega);
    }
}

#endif
