#version 460
// The equal-time baseline of Volumetric ReSTIR (Sec. 6): a path tracer for a grid
// medium with decomposition tracking (Kutz et al. 2017) for free flights and residual
// ratio tracking (Novak et al. 2014) for next-event transmittance, both on 8x
// super-voxels holding min/max/avg of sigma_t (grid.glsl).
//
// Homogeneous box media may sit beside the grid (SC_HAS_MEDIA): free flights take
// the earliest of independent first collisions in each (disjoint) medium, and shadow
// rays multiply the boxes' closed-form transmittance in.
//
// One invocation per pixel, `spp` paths per pixel per frame. A path scatters at most
// SC_MAX_BOUNCES = K times (real collisions in the medium or Lambertian reflections);
// at every scattering vertex one light is chosen in proportion to its power and
// connected by a shadow ray (next-event estimation), so every light reaches the
// camera through NEE only: escaping rays and rays hitting an emitting sphere add
// radiance only on the camera segment. Russian roulette by throughput from the 4th
// segment on.

#extension GL_GOOGLE_include_directive : require

#include "bindings.glsl"
#include "constants.glsl"
#include "scene.glsl"
#include "rng.glsl"
#include "phase.glsl"
#include "sampling.glsl"
#include "geometry.glsl"
#include "grid_types.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(constant_id = 0) const bool SC_HAS_SHAPES = true;
layout(constant_id = 2) const bool SC_HAS_ENV = true;
// Homogeneous box media beside the grid.
layout(constant_id = 4) const bool SC_HAS_MEDIA = false;
layout(constant_id = 5) const uint SC_MAX_BOUNCES = 1u;
layout(constant_id = 6) const bool SC_PIXEL_JITTER = true;
layout(constant_id = 7) const bool SC_HAS_EMISSION = false;
// The environment is an importance-sampled map (else a constant radiance).
layout(constant_id = 8) const bool SC_HAS_ENV_MAP = false;

#define LIGHT_POINT 1u
#define LIGHT_SPHERE 2u
#define NO_INDEX 0xffffffffu

struct BaselineUniforms {
    GridParams grid;
    vec4 albedo_g;    // rgb albedo, w HG g
    vec4 env_select;  // x: probability that NEE picks the environment
    vec4 emission_scale;   // rgb
    uvec4 emission_dims;   // xyz: the emission grid's own resolution
    uvec4 env_size;        // xy: environment map width and height
};

layout(std140, set = 0, binding = BINDING_FRAME_UNIFORMS) uniform FrameBlock {
    FrameUniforms u_frame;
};
layout(push_constant) uniform PushBlock {
    PassPush u_push;
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
layout(std430, set = 0, binding = BINDING_SHAPES) readonly buffer ShapesBlock {
    Shape shapes[];
};
// Analytic lights: direction_type = (direction or position or centre, type),
// irradiance = (E or I or L, sphere radius), gobo_v.w = selection CDF.
layout(std430, set = 0, binding = BINDING_LIGHTS) readonly buffer LightsBlock {
    Light lights[];
};
layout(std140, set = 0, binding = BINDING_BASELINE_UNIFORMS) uniform BaselineBlock {
    BaselineUniforms u_base;
};
layout(std430, set = 0, binding = BINDING_BOX_MEDIA) readonly buffer MediaBlock {
    BoxMedium media[];
};
layout(set = 0, binding = BINDING_GRID_DENSITY) uniform sampler3D u_density;
layout(set = 0, binding = BINDING_GRID_EMISSION) uniform sampler3D u_emission;
layout(std430, set = 0, binding = BINDING_SUPER_VOXELS) readonly buffer SuperVoxelBlock {
    vec4 super_voxels[];
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
#include "envmap.glsl"
#include "shapes.glsl"

// Emitted radiance Le at world x: emission_scale times the emission grid, trilinear
// between cell centres and clamped within half a voxel of a face (as the density).
vec3 grid_emission(vec3 x) {
    vec3 size = u_grid.bounds_max.xyz - u_grid.bounds_min.xyz;
    vec3 n = vec3(u_base.emission_dims.xyz);
    // Domain: size > 0 (validated bounds).
    vec3 p = clamp((x - u_grid.bounds_min.xyz) / size * n, vec3(0.5), n - 0.5) - 0.5;
    ivec3 i0 = ivec3(floor(p));
    ivec3 hi = ivec3(u_base.emission_dims.xyz) - 1;
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
    return u_base.emission_scale.rgb * mix(mix(c00, c10, f.y), mix(c01, c11, f.y), f.z);
}

// Span of o + t d inside box medium m: (t_in, t_out), t_in > t_out for a miss.
vec2 box_span(uint m, vec3 o, vec3 d) {
    BoxMedium bm = media[m];
    vec3 o_local;
    vec3 d_local;
    to_box_frame(bm.world_to_local, bm.center_sigma_t.xyz, o, d, o_local, d_local);
    return intersect_slabs(o_local, d_local, bm.half_size_g.xyz);
}

// Optical depth of the box media along o + t d, t in [t0, t1] (closed form).
float box_optical_depth(vec3 o, vec3 d, float t0, float t1) {
    float tau = 0.0;
    if (SC_HAS_MEDIA) {
        uint count = u_frame.counts.x;
        for (uint m = 0u; m < count; ++m) {
            tau += media[m].center_sigma_t.w * overlap_length(box_span(m, o, d), t0, t1);
        }
    }
    return tau;
}

// The first real collision along o + t d in [0, t_end) among the grid and the boxes:
// the media are disjoint, so the first collision is the earliest of independent first
// collisions sampled in each. Returns FAR if none; `medium` is the box index, or
// NO_INDEX for the grid.
float sample_collision(vec3 o, vec3 d, float t_end, inout uint rng, out uint medium) {
    medium = NO_INDEX;
    vec2 span = grid_span(o, d);
    float t0 = max(span.x, 0.0);
    float t1 = min(span.y, t_end);
    float t_best = t1 > t0 ? grid_sample_collision(o, d, t0, t1, rng) : FAR;
    if (SC_HAS_MEDIA) {
        uint count = u_frame.counts.x;
        for (uint m = 0u; m < count; ++m) {
            vec2 s = box_span(m, o, d);
            float a = max(s.x, 0.0);
            float b = min(s.y, min(t_end, t_best));
            float sigma_t = media[m].center_sigma_t.w;
            if (b <= a || !(sigma_t > 0.0)) {
                continue;
            }
            // Domain: sigma_t > 0; 1 - u in (0, 1].
            float t = a - log(1.0 - rng_next(rng)) / sigma_t;
            if (t < b) {
                t_best = t;
                medium = m;
            }
        }
    }
    return t_best;
}

// Nearest emitting sphere along o + t d in (t_min, t_max): distance (FAR if none).
float nearest_sphere_light(vec3 o, vec3 d, float t_min, float t_max, out uint index) {
    index = NO_INDEX;
    float t_hit = t_max;
    uint count = u_frame.counts.z;
    for (uint l = 0u; l < count; ++l) {
        Light light = lights[l];
        if (uint(light.direction_type.w) != LIGHT_SPHERE) {
            continue;
        }
        float t = intersect_sphere(light.direction_type.xyz, light.irradiance.w, o, d, t_min, t_hit);
        if (t < t_hit) {
            t_hit = t;
            index = l;
        }
    }
    return index == NO_INDEX ? FAR : t_hit;
}

// Transmittance from x along unit w over [0, dist) through the grid, 0 if a shape or
// another emitting sphere blocks it first.
float shadow_transmittance(vec3 x, vec3 w, float dist, float t_min, uint target, inout uint rng) {
    if (occluded_before(x, w, t_min, dist)) {
        return 0.0;
    }
    uint blocker;
    float t_light = nearest_sphere_light(x, w, t_min, dist, blocker);
    if (t_light < FAR && blocker != target) {
        return 0.0;
    }
    float T_boxes = exp(-box_optical_depth(x, w, 0.0, dist));
    vec2 span = grid_span(x, w);
    float t0 = max(span.x, 0.0);
    float t1 = min(span.y, dist);
    if (t1 <= t0) {
        return T_boxes;
    }
    return T_boxes * grid_residual_ratio_tracking(x, w, t0, t1, rng);
}

// Sample a light for next-event estimation at x: the direction wi towards it, the
// distance along wi, and the arriving radiance divided by the (selection x direction)
// pdf. Zero when the sample carries nothing.
vec3 sample_light(vec3 x, inout uint rng, out vec3 wi, out float dist, out uint target) {
    float u = rng_next(rng);
    vec2 u2 = vec2(rng_next(rng), rng_next(rng));
    wi = vec3(0.0, 1.0, 0.0);
    dist = FAR;
    target = NO_INDEX;
    float p_env = u_base.env_select.x;
    if (SC_HAS_ENV && SC_HAS_ENV_MAP && u >= 1.0 - p_env) {
        // Environment map: importance sampled by luminance x sin(theta).
        float pdf;
        vec3 Le = env_sample(u2, wi, pdf);
        // Domain: pdf > 0 for a usable sample, p_env > 0 in this branch.
        return pdf > 0.0 ? Le / (pdf * p_env) : vec3(0.0);
    }
    if (SC_HAS_ENV && u >= 1.0 - p_env) {
        // Constant environment: uniform direction, pdf 1 / (4 pi).
        float z = 1.0 - 2.0 * u2.x;
        float r = sqrt(max(0.0, 1.0 - z * z));
        float phi = 2.0 * PI * u2.y;
        wi = vec3(r * cos(phi), z, r * sin(phi));
        // Domain: p_env > 0 when this branch is taken (u < 1).
        return u_frame.env_radiance.rgb * (4.0 * PI / p_env);
    }
    uint count = u_frame.counts.z;
    uint chosen = NO_INDEX;
    float cdf_before = 0.0;
    for (uint l = 0u; l < count; ++l) {
        float cdf = lights[l].gobo_v.w;
        if (u < cdf) {
            chosen = l;
            break;
        }
        cdf_before = cdf;
    }
    if (chosen == NO_INDEX) {
        return vec3(0.0);
    }
    Light light = lights[chosen];
    float p_select = light.gobo_v.w - cdf_before;
    if (!(p_select > 0.0)) {
        return vec3(0.0);
    }
    uint type = uint(light.direction_type.w);
    target = chosen;
    if (type == LIGHT_DIRECTIONAL) {
        wi = -light.direction_type.xyz;
        return light.irradiance.rgb / p_select;
    }
    vec3 to_light = light.direction_type.xyz - x;
    float d2 = dot(to_light, to_light);
    if (type == LIGHT_POINT) {
        // Domain: a point light off the shading point (d2 > 0).
        if (!(d2 > 0.0)) {
            return vec3(0.0);
        }
        dist = sqrt(d2);
        wi = to_light / dist;
        return light.irradiance.rgb / (d2 * p_select);
    }
    // Emitting sphere: uniform in the cone it subtends, pdf 1 / (2 pi (1 - cos_max)).
    float radius = light.irradiance.w;
    if (d2 <= radius * radius) {
        return vec3(0.0);
    }
    float d_center = sqrt(d2);
    vec3 axis = to_light / d_center;
    float sin2_max = radius * radius / d2;
    float cos_max = sqrt(max(0.0, 1.0 - sin2_max));
    // 1 - cos_max computed without cancellation: sin2 / (1 + cos).
    float one_minus_cos_max = sin2_max / (1.0 + cos_max);
    float cos_theta = 1.0 - u2.x * one_minus_cos_max;
    float sin_theta = sqrt(max(0.0, 1.0 - cos_theta * cos_theta));
    float phi = 2.0 * PI * u2.y;
    vec3 t;
    vec3 b;
    orthonormal_basis(axis, t, b);
    wi = normalize(sin_theta * cos(phi) * t + sin_theta * sin(phi) * b + cos_theta * axis);
    float t_hit = intersect_sphere(light.direction_type.xyz, radius, x, wi, 0.0, FAR);
    if (t_hit >= FAR) {
        return vec3(0.0);
    }
    dist = t_hit;
    // Domain: one_minus_cos_max > 0 since radius > 0, and p_select > 0.
    return light.irradiance.rgb * (2.0 * PI * one_minus_cos_max / p_select);
}

// Radiance arriving at o from direction -d.
vec3 radiance(vec3 o, vec3 d, inout uint rng) {
    vec3 L = vec3(0.0);
    vec3 beta = vec3(1.0);

    for (uint bounce = 0u; bounce < SC_MAX_BOUNCES; ++bounce) {
        uint shape_index;
        float t_surface = nearest_shape(o, d, 0.0, FAR, shape_index);
        uint light_index;
        float t_light = nearest_sphere_light(o, d, 0.0, t_surface, light_index);
        float t_end = min(t_surface, t_light);

        // Sample a real collision in the media before the segment's end.
        uint medium;
        float t_collision = sample_collision(o, d, t_end, rng, medium);

        if (t_collision < FAR) {
            vec3 albedo_medium = u_base.albedo_g.rgb;
            float g = u_base.albedo_g.w;
            if (medium != NO_INDEX) {
                BoxMedium bm = media[medium];
                // Domain: a collision happened, so sigma_t > 0.
                albedo_medium = bm.sigma_s.rgb / bm.center_sigma_t.w;
                g = bm.half_size_g.w;
            }
            // A real collision: absorbed emission (sigma_a Le over sigma_t), next-event
            // estimation, then continue by HG.
            vec3 x = o + t_collision * d;
            if (SC_HAS_EMISSION && medium == NO_INDEX) {
                L += beta * (1.0 - albedo_medium) * grid_emission(x);
            }
            vec3 wi;
            float dist;
            uint target;
            vec3 Li = sample_light(x, rng, wi, dist, target);
            if (any(greaterThan(Li, vec3(0.0)))) {
                float T = shadow_transmittance(x, wi, dist, 0.0, target, rng);
                L += beta * albedo_medium * hg_phase(dot(wi, d), g) * Li * T;
            }
            if (bounce + 1u >= SC_MAX_BOUNCES) {
                break;
            }
            beta *= albedo_medium;
            o = x;
            d = sample_hg(d, g, vec2(rng_next(rng), rng_next(rng)));
        } else if (t_light < t_surface) {
            // An emitting sphere: seen directly only by the camera segment.
            if (bounce == 0u) {
                L += beta * lights[light_index].irradiance.rgb;
            }
            break;
        } else if (t_surface < FAR) {
            // A Lambertian surface: next-event estimation, then continue by cosine sampling.
            Shape s = shapes[shape_index];
            vec3 albedo = s.albedo_type.rgb;
            if (!any(greaterThan(albedo, vec3(0.0)))) {
                break;
            }
            vec3 x = o + t_surface * d;
            vec3 n = shape_normal(s, x, d);
            float eps = 1e-4 * (1.0 + max(max(abs(x.x), abs(x.y)), abs(x.z)));
            vec3 x_off = x + eps * n;
            vec3 wi;
            float dist;
            uint target;
            vec3 Li = sample_light(x_off, rng, wi, dist, target);
            float cos_i = dot(n, wi);
            if (cos_i > 0.0 && any(greaterThan(Li, vec3(0.0)))) {
                float T = shadow_transmittance(x_off, wi, dist, 0.0, target, rng);
                L += beta * albedo * INV_PI * cos_i * Li * T;
            }
            if (bounce + 1u >= SC_MAX_BOUNCES) {
                break;
            }
            beta *= albedo;
            o = x_off;
            d = sample_cosine_hemisphere(n, vec2(rng_next(rng), rng_next(rng)));
        } else {
            // Escaped: the environment, seen directly by the camera segment only.
            if (SC_HAS_ENV && bounce == 0u) {
                L += beta * (SC_HAS_ENV_MAP ? env_lookup(d) : u_frame.env_radiance.rgb);
            }
            break;
        }
        // Russian roulette from the fourth segment on, by the path's throughput.
        if (bounce >= 3u) {
            float survive = clamp(max(beta.r, max(beta.g, beta.b)), 0.05, 1.0);
            if (rng_next(rng) >= survive) {
                break;
            }
            // Domain: survive >= 0.05.
            beta /= survive;
        }
    }
    return L;
}

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    uint width = u_frame.image.x;
    uint height = u_frame.image.y;
    if (pixel.x >= width || pixel.y >= height) {
        return;
    }
    uint spp = u_frame.image.z;
    vec3 sum = vec3(0.0);
    uint kept = 0u;
    for (uint s = 0u; s < spp; ++s) {
        uint rng = rng_init(pixel, u_push.frame, u_push.sample_base + s, u_frame.image.w);
        vec2 jitter = SC_PIXEL_JITTER ? vec2(rng_next(rng), rng_next(rng)) : vec2(0.5);
        vec2 px = vec2(pixel) + jitter;
        float sx = (2.0 * px.x / float(width) - 1.0) * u_frame.cam_position.w;
        float sy = (1.0 - 2.0 * px.y / float(height)) * u_frame.cam_forward.w;
        vec3 d = normalize(u_frame.cam_forward.xyz + sx * u_frame.cam_right.xyz + sy * u_frame.cam_up.xyz);
        vec3 L = radiance(u_frame.cam_position.xyz, d, rng);
        // Count non-finite samples instead of writing them.
        if (any(isnan(L)) || any(isinf(L))) {
            atomicAdd(stats[STAT_NON_FINITE], 1u);
        } else {
            sum += L;
            kept += 1u;
        }
    }
    uint index = pixel.y * width + pixel.x;
    vec3 estimate = kept > 0u ? sum / float(kept) : vec3(0.0);
    accum[index] += vec4(estimate, 1.0);
    accum_sq[index] += vec4(estimate * estimate, 0.0);
}
