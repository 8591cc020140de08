#version 460
// Crepuscular rays in homogeneous box media under collimated light (Velinov &
// Mitchell). One invocation per pixel; `spp` camera rays per pixel per frame, each
// jittered over the pixel footprint, accumulate into the running sums.
//
// Estimator (SC_ESTIMATOR): ray marching (RM), the paper's baseline: N jittered
// equidistant samples along each camera segment inside a box; at each, a shadow ray
// against the shapes and the closed-form transmittance to the box boundary.

#extension GL_GOOGLE_include_directive : require

#include "bindings.glsl"
#include "constants.glsl"
#include "scene.glsl"
#include "rng.glsl"
#include "phase.glsl"
#include "geometry.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Features the render plan switches per scene.
layout(constant_id = 0) const bool SC_HAS_SHAPES = true;
layout(constant_id = 1) const bool SC_HAS_GOBOS = true;
layout(constant_id = 2) const bool SC_HAS_ENV = true;
layout(constant_id = 3) const uint SC_ESTIMATOR = 3u;
layout(constant_id = 4) const bool SC_HAS_MEDIA = true;

#define ESTIMATOR_RM 3u

layout(std140, set = 0, binding = BINDING_FRAME_UNIFORMS) uniform FrameBlock {
    FrameUniforms u_frame;
};
layout(push_constant) uniform PushBlock {
    PassPush u_push;
};
layout(std430, set = 0, binding = BINDING_ACCUM) buffer AccumBlock {
    vec4 accum[]; // rgb: sum over frames of the frame's pixel estimate, a: frames
};
layout(std430, set = 0, binding = BINDING_ACCUM_SQ) buffer AccumSqBlock {
    vec4 accum_sq[]; // rgb: sum of squares of the frame estimates
};
layout(std430, set = 0, binding = BINDING_STATS) buffer StatsBlock {
    uint stats[];
};
layout(std430, set = 0, binding = BINDING_BOX_MEDIA) readonly buffer MediaBlock {
    BoxMedium media[];
};
layout(std430, set = 0, binding = BINDING_SHAPES) readonly buffer ShapesBlock {
    Shape shapes[];
};
layout(std430, set = 0, binding = BINDING_LIGHTS) readonly buffer LightsBlock {
    Light lights[];
};
layout(std430, set = 0, binding = BINDING_GOBO_PLANES) readonly buffer GoboBlock {
    vec4 gobo_planes[]; // (a, b, c, 0): a point (u, v) is inside when a u + b v + c >= 0
};

#include "shapes.glsl"

// Span of o + t d inside box medium m: (t_in, t_out), t_in > t_out for a miss.
vec2 medium_span(uint m, vec3 o, vec3 d) {
    BoxMedium bm = media[m];
    vec3 o_local;
    vec3 d_local;
    to_box_frame(bm.world_to_local, bm.center_sigma_t.xyz, o, d, o_local, d_local);
    return intersect_slabs(o_local, d_local, bm.half_size_g.xyz);
}

// Optical depth of all box media along o + t d, t in [t_min, t_max].
float optical_depth(vec3 o, vec3 d, float t_min, float t_max) {
    float tau = 0.0;
    uint count = SC_HAS_MEDIA ? u_frame.counts.x : 0u;
    for (uint m = 0u; m < count; ++m) {
        vec2 span = medium_span(m, o, d);
        tau += media[m].center_sigma_t.w * overlap_length(span, t_min, t_max);
    }
    return tau;
}

// Nearest shape hit along o + t d in (t_min, t_max): distance (FAR if none) and index.
float nearest_shape(vec3 o, vec3 d, float t_min, float t_max, out uint index) {
    float t_hit = t_max;
    index = 0xffffffffu;
    if (SC_HAS_SHAPES) {
        uint count = u_frame.counts.y;
        for (uint s = 0u; s < count; ++s) {
            float t = intersect_shape(shapes[s], o, d, t_min, t_hit);
            if (t < t_hit) {
                t_hit = t;
                index = s;
            }
        }
    }
    return index == 0xffffffffu ? FAR : t_hit;
}

// Whether any shape blocks o + t d for t in (t_min, FAR).
bool occluded(vec3 o, vec3 d, float t_min) {
    if (!SC_HAS_SHAPES) {
        return false;
    }
    uint count = u_frame.counts.y;
    for (uint s = 0u; s < count; ++s) {
        if (intersect_shape(shapes[s], o, d, t_min, FAR) < FAR) {
            return true;
        }
    }
    return false;
}

// Whether x lies inside light l's gobo prism (always true without a gobo).
bool inside_gobo(Light l, vec3 x) {
    if (!SC_HAS_GOBOS) {
        return true;
    }
    uint count = uint(l.gobo_origin.w);
    uint first = uint(l.gobo_u.w);
    vec3 p = x - l.gobo_origin.xyz;
    vec2 uv = vec2(dot(p, l.gobo_u.xyz), dot(p, l.gobo_v.xyz));
    for (uint i = 0u; i < count; ++i) {
        vec4 plane = gobo_planes[first + i];
        if (plane.x * uv.x + plane.y * uv.y + plane.z < 0.0) {
            return false;
        }
    }
    return true;
}

// Irradiance from light l arriving unscattered at x: E · gobo · visibility · T to the
// light. `t_min` offsets the shadow ray's start (0 inside media, > 0 on surfaces).
vec3 light_arriving(Light l, vec3 x, float t_min) {
    vec3 omega = l.direction_type.xyz;
    if (!inside_gobo(l, x)) {
        return vec3(0.0);
    }
    if (occluded(x, -omega, t_min)) {
        return vec3(0.0);
    }
    float tau = optical_depth(x, -omega, 0.0, FAR);
    return l.irradiance.rgb * exp(-tau);
}

// Single scattering inside box medium m along o + t d, t in [t_a, t_b], by ray
// marching: N equidistant strata, one jittered sample in each.
vec3 march_medium_rm(uint m, vec3 o, vec3 d, float t_a, float t_b, inout uint rng) {
    BoxMedium bm = media[m];
    uint n = max(u_frame.counts.w, 1u);
    float dt = (t_b - t_a) / float(n);
    float g = bm.half_size_g.w;
    vec3 L = vec3(0.0);
    for (uint i = 0u; i < n; ++i) {
        float t = t_a + (float(i) + rng_next(rng)) * dt;
        vec3 x = o + t * d;
        float T_cam = exp(-optical_depth(o, d, 0.0, t));
        vec3 Ls = vec3(0.0);
        uint light_count = u_frame.counts.z;
        for (uint l = 0u; l < light_count; ++l) {
            Light light = lights[l];
            float phase = hg_phase(dot(light.direction_type.xyz, -d), g);
            Ls += phase * light_arriving(light, x, 0.0);
        }
        L += T_cam * bm.sigma_s.rgb * Ls * dt;
    }
    return L;
}

// Radiance arriving at o from direction -d.
vec3 radiance(vec3 o, vec3 d, inout uint rng) {
    uint shape_index;
    float t_surface = nearest_shape(o, d, 0.0, FAR, shape_index);
    vec3 L = vec3(0.0);

    // Add single scattering from every box medium the ray crosses before the surface.
    uint media_count = SC_HAS_MEDIA ? u_frame.counts.x : 0u;
    for (uint m = 0u; m < media_count; ++m) {
        vec2 span = medium_span(m, o, d);
        float t_a = max(span.x, 0.0);
        float t_b = min(span.y, t_surface);
        if (t_b > t_a && media[m].center_sigma_t.w > 0.0) {
            L += march_medium_rm(m, o, d, t_a, t_b, rng);
        }
    }

    if (t_surface < FAR) {
        // Add the Lambertian reflection of direct light at the surface.
        Shape s = shapes[shape_index];
        vec3 x = o + t_surface * d;
        vec3 n = shape_normal(s, x, d);
        vec3 albedo = s.albedo_type.rgb;
        if (any(greaterThan(albedo, vec3(0.0)))) {
            // Offset the shadow ray by a distance relative to the hit's magnitude.
            float eps = 1e-4 * (1.0 + max(max(abs(x.x), abs(x.y)), abs(x.z)));
            vec3 x_off = x + eps * n;
            vec3 E = vec3(0.0);
            uint light_count = u_frame.counts.z;
            for (uint l = 0u; l < light_count; ++l) {
                Light light = lights[l];
                float cos_i = dot(n, -light.direction_type.xyz);
                if (cos_i > 0.0) {
                    E += cos_i * light_arriving(light, x_off, 0.0);
                }
            }
            L += exp(-optical_depth(o, d, 0.0, t_surface)) * albedo * INV_PI * E;
        }
    } else if (SC_HAS_ENV) {
        // Add the environment seen through the media.
        L += exp(-optical_depth(o, d, 0.0, FAR)) * u_frame.env_radiance.rgb;
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
    uint frame = u_push.frame;
    vec3 sum = vec3(0.0);
    uint kept = 0u;
    for (uint s = 0u; s < spp; ++s) {
        uint rng = rng_init(pixel, frame, u_push.sample_base + s, u_frame.image.w);
        // Jitter the ray over the pixel footprint (box filter), (0,0) top-left.
        vec2 px = vec2(pixel) + vec2(rng_next(rng), rng_next(rng));
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
