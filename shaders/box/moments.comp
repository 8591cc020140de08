#version 460
// The moment shadow maps of the ME estimator (moments.glsl): one dispatch per directional
// light and mip level, one invocation per texel. Level 0 traces MOMENT_MAP_RAYS²
// stratified rays per texel along the light through the shapes and keeps the mean
// moments of the first hit's normalised depth (1 where the light reaches the media's
// downstream end unstopped); level k > 0 averages level k - 1's 2x2 texels. The render
// plan runs this pass only for ME in scenes with shapes, once before the first frame's
// crepuscular dispatch (lights and shapes are static in a crepuscular render).

#extension GL_GOOGLE_include_directive : require

#define MOMENT_MAP_WRITER

#include "features.glsl"
#include "bindings.glsl"
#include "constants.glsl"
#include "scene.glsl"

layout(constant_id = SC_ID_HAS_SHAPES) const bool SC_HAS_SHAPES = true;
layout(constant_id = SC_ID_PIXEL_JITTER) const bool SC_PIXEL_JITTER = false;

#include "film.glsl"
#include "shapes.glsl"
#include "moments.glsl"

layout(push_constant) uniform PushBlock {
    MomentPush u_push;
};
layout(std430, set = 0, binding = BINDING_MOMENT_MAP) buffer MomentMapBlock {
    vec4 moment_map[];
};

// The mean moments of the rays of level-0 texel `texel` of map f.
vec4 trace_texel(MomentFrame f, uvec2 texel) {
    // Domain: the host keeps texels_u, texels_v > 0 and depth_far > trace_start.
    float t_max = f.depth_far - f.trace_start;
    vec4 sum = vec4(0.0);
    for (uint j = 0u; j < MOMENT_MAP_RAYS; ++j) {
        for (uint i = 0u; i < MOMENT_MAP_RAYS; ++i) {
            vec2 offset = (vec2(i, j) + 0.5) / float(MOMENT_MAP_RAYS);
            float u = f.u_min + (float(texel.x) + offset.x) / f.texels_u;
            float v = f.v_min + (float(texel.y) + offset.y) / f.texels_v;
            vec3 origin = u * f.u_axis + v * f.v_axis + f.trace_start * f.omega;
            uint index;
            float t = SC_HAS_SHAPES ? nearest_shape(origin, f.omega, 0.0, t_max, index) : FAR;
            float z = t < FAR ? moment_depth(f, f.trace_start + t) : 1.0;
            sum += depth_moments(z);
        }
    }
    return sum / float(MOMENT_MAP_RAYS * MOMENT_MAP_RAYS);
}

void main() {
    film_load();
    uvec2 texel = gl_GlobalInvocationID.xy;
    uint size = u_push.size;
    if (texel.x >= size || texel.y >= size) {
        return;
    }
    vec4 m;
    if (u_push.level == 0u) {
        m = trace_texel(moment_frames[u_push.light], texel);
    } else {
        uint src_size = 2u * size;
        uint s = u_push.src + 2u * texel.y * src_size + 2u * texel.x;
        m = 0.25 * (moment_map[s] + moment_map[s + 1u] + moment_map[s + src_size] + moment_map[s + src_size + 1u]);
    }
    moment_map[u_push.dst + texel.y * size + texel.x] = m;
    film_flush_counters();
}
