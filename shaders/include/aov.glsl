// The output layers beside the beauty (AOVs; `src/plan/aovs.rs` plans them, the scene
// format's "Output layers (AOVs)" defines them). film.glsl includes this file, so every
// per-pixel pass declares the AOV constants and buffers; with every constant off (a
// render without AOVs) all of it specializes away and the buffers are one-element
// dummies.
//
// Geometric AOVs (SC_AOV_GEOMETRY: depth, normal, albedo, motion) come from the
// pixel-centre camera ray, once per frame, and overwrite the last frame's:
//   aov_geometry[AOV_GEOMETRY_VEC4S * pixel + 0] = (N, Z)
//   aov_geometry[AOV_GEOMETRY_VEC4S * pixel + 1] = (albedo, 0)
//   aov_geometry[AOV_GEOMETRY_VEC4S * pixel + 2] = (motion, 0, 0)
// - aov_write_geometry(pixel, z, normal, albedo, motion) writes them;
// - aov_geometry_pixel(pixel) traces the pixel-centre ray with aov_geometry_point (which
//   the includer defines, usually by including aov_trace.glsl after its scene code) and
//   writes them, motion for static geometry; film_take_samples calls it for the path
//   tracers;
// - aov_motion(p, p_prev) is the screen-space motion (pixels per frame, x right, y down)
//   of a point at p now and at p_prev in the previous scene frame (p - velocity(p) in a
//   moving medium: the velocity grid's units, metres per frame, as restir/temporal.comp
//   reprojects; p for static geometry); 0 at scene frame 0 or off screen.
//
// Path AOVs (SC_AOV_PATHS: emission, direct, indirect; SC_AOV_GROUPS > 0: light groups)
// are estimates accumulated like the beauty. Every `L += c` of an integrator has a twin
// `aov_add(kind, group, c)` with exactly the same c:
//   kind  AOV_EMISSION: emitted radiance reaching the camera with no scattering between
//         (aov_kind_emitted(0)); AOV_DIRECT: light that scattered once (NEE at the first
//         vertex: aov_kind_nee(0); emission reached after one scattering:
//         aov_kind_emitted(1)); AOV_INDIRECT: everything else;
//   group light_group(index) for a [[light]] record (lights.glsl / the pass's lights;
//         LIGHT_ENV gives the environment's), AOV_GROUP_ENV for the environment,
//         AOV_GROUP_DEFAULT for media emission and emitting shapes.
// The per-sample sums live in g_aov_sample (aov_sample_begin clears them);
// film_take_samples averages the finite samples of a frame and accumulates the frame's
// estimate per slot exactly as it does the beauty, and carries a frame's partial sums in
// aov_partial between the dispatches that share its samples. A pass that accumulates
// itself (ReSTIR's shade pass) calls aov_sample_begin() before its sample,
// aov_add(...) beside each `L +=`, and aov_accumulate(pixel, weight) where it calls
// film_accumulate(pixel, weight * L, ...): the frame's estimate is weight x the sums.
//
// Slots (slot-major buffers of u_frame.width * u_frame.height vec4 each):
//   aov_accum[slot * pixels + pixel] += frame estimate, aov_accum_sq[...] += its square;
//   slots 0, 1, 2 = emission, direct, indirect (with SC_AOV_PATHS), then the groups.
#ifndef NIMBUS_AOV_GLSL
#define NIMBUS_AOV_GLSL

#include "bindings.glsl"
#include "features.glsl"
#include "scene.glsl"

layout(constant_id = SC_ID_AOV_GEOMETRY) const bool SC_AOV_GEOMETRY = false;
layout(constant_id = SC_ID_AOV_PATHS) const bool SC_AOV_PATHS = false;
layout(constant_id = SC_ID_AOV_GROUPS) const uint SC_AOV_GROUPS = 0u;

layout(std430, set = 0, binding = BINDING_AOV_GEOMETRY) buffer AovGeometryBlock {
    vec4 aov_geometry[];
};
layout(std430, set = 0, binding = BINDING_AOV_ACCUM) buffer AovAccumBlock {
    vec4 aov_accum[];
};
layout(std430, set = 0, binding = BINDING_AOV_ACCUM_SQ) buffer AovAccumSqBlock {
    vec4 aov_accum_sq[];
};
layout(std430, set = 0, binding = BINDING_AOV_PARTIAL) buffer AovPartialBlock {
    vec4 aov_partial[];
};
layout(std430, set = 0, binding = BINDING_AOV_UNIFORMS) readonly buffer AovUniformsBlock {
    AovUniforms u_aov;
};

// The light groups of what has no light record.
#define AOV_GROUP_ENV (u_aov.env_group)
#define AOV_GROUP_DEFAULT (u_aov.default_group)

// Whether any path AOV is estimated.
bool aov_paths_on() {
    return SC_AOV_PATHS || SC_AOV_GROUPS > 0u;
}

// Path-AOV slots: emission, direct, indirect (SC_AOV_PATHS), then the groups.
uint aov_slots() {
    return (SC_AOV_PATHS ? 3u : 0u) + min(SC_AOV_GROUPS, AOV_MAX_GROUPS);
}

// The kind of emitted radiance reaching the camera after `scatterings` scatterings
// (surface bounces or medium collisions) between the emitter and the camera.
uint aov_kind_emitted(uint scatterings) {
    return min(scatterings, AOV_INDIRECT);
}

// The kind of next-event estimation at the path's vertex `vertex` (0: the first
// scattering vertex seen by the camera ray): the light scatters vertex + 1 times.
uint aov_kind_nee(uint vertex) {
    return min(vertex + 1u, AOV_INDIRECT);
}

// The current sample's sums per slot, and the frame's over its finite samples so far.
vec3 g_aov_sample[AOV_MAX_SLOTS];
vec3 g_aov_frame[AOV_MAX_SLOTS];

// Clears the current sample's sums.
void aov_sample_begin() {
    if (!aov_paths_on()) {
        return;
    }
    for (uint k = 0u; k < aov_slots(); ++k) {
        g_aov_sample[k] = vec3(0.0);
    }
}

// Adds c to the kind slot only (emission, direct or indirect): with aov_add_group, for a
// contribution whose light groups are split finer than its kind (their parts summing to
// c).
void aov_add_kind(uint kind, vec3 c) {
    if (SC_AOV_PATHS) {
        g_aov_sample[min(kind, AOV_INDIRECT)] += c;
    }
}

// Adds c to light group `group`'s slot only.
void aov_add_group(uint group, vec3 c) {
    if (SC_AOV_GROUPS > 0u) {
        uint base = SC_AOV_PATHS ? 3u : 0u;
        g_aov_sample[base + min(group, min(SC_AOV_GROUPS, AOV_MAX_GROUPS) - 1u)] += c;
    }
}

// Adds a contribution c of kind `kind` from light group `group` to the current sample:
// the twin of the integrator's `L += c`.
void aov_add(uint kind, uint group, vec3 c) {
    aov_add_kind(kind, c);
    aov_add_group(group, c);
}

// Per-group parts of one estimate whose samples come from several lights (the box
// estimators pick a light per sample): cleared by aov_parts_clear, filled by
// aov_parts_add(group, part), then given to the sample scaled by `w` by aov_parts_flush.
vec3 g_aov_parts[AOV_MAX_GROUPS];

void aov_parts_clear() {
    if (SC_AOV_GROUPS > 0u) {
        for (uint g = 0u; g < min(SC_AOV_GROUPS, AOV_MAX_GROUPS); ++g) {
            g_aov_parts[g] = vec3(0.0);
        }
    }
}

void aov_parts_add(uint group, vec3 part) {
    if (SC_AOV_GROUPS > 0u) {
        g_aov_parts[min(group, min(SC_AOV_GROUPS, AOV_MAX_GROUPS) - 1u)] += part;
    }
}

// Scales every part by `scale` (per channel), e.g. a mean's 1 / n.
void aov_parts_scale(vec3 scale) {
    if (SC_AOV_GROUPS > 0u) {
        for (uint g = 0u; g < min(SC_AOV_GROUPS, AOV_MAX_GROUPS); ++g) {
            g_aov_parts[g] *= scale;
        }
    }
}

// Adds w x each part to its group of the current sample.
void aov_parts_flush(vec3 w) {
    if (SC_AOV_GROUPS > 0u) {
        for (uint g = 0u; g < min(SC_AOV_GROUPS, AOV_MAX_GROUPS); ++g) {
            aov_add_group(g, w * g_aov_parts[g]);
        }
    }
}

// The frame's sums start from zero (sample_base == 0) or from the partial sums the
// previous dispatch of the frame left.
void aov_frame_begin(uint index, uint sample_base) {
    if (!aov_paths_on()) {
        return;
    }
    uint pixels = u_frame.width * u_frame.height;
    for (uint k = 0u; k < aov_slots(); ++k) {
        g_aov_frame[k] = sample_base > 0u ? aov_partial[k * pixels + index].rgb : vec3(0.0);
    }
}

// A finite sample joins the frame's sums.
void aov_sample_keep() {
    if (!aov_paths_on()) {
        return;
    }
    for (uint k = 0u; k < aov_slots(); ++k) {
        g_aov_frame[k] += g_aov_sample[k];
    }
}

// A dispatch that does not end the frame leaves the frame's sums for the next.
void aov_frame_store(uint index) {
    if (!aov_paths_on()) {
        return;
    }
    uint pixels = u_frame.width * u_frame.height;
    for (uint k = 0u; k < aov_slots(); ++k) {
        aov_partial[k * pixels + index] = vec4(g_aov_frame[k], 0.0);
    }
}

// Adds one frame's estimate per slot, `estimate(k)`, to the running sums.
void aov_accumulate_slot(uint index, uint k, vec3 estimate) {
    uint at = k * u_frame.width * u_frame.height + index;
    vec4 x = vec4(estimate, 0.0);
    aov_accum[at] += x;
    aov_accum_sq[at] += x * x;
}

// The frame ends: its estimate per slot is the mean of its finite samples (`kept`), as
// the beauty's.
void aov_frame_end(uint index, float kept) {
    if (!aov_paths_on()) {
        return;
    }
    for (uint k = 0u; k < aov_slots(); ++k) {
        // Domain: kept >= 1 where divided.
        aov_accumulate_slot(index, k, kept > 0.0 ? g_aov_frame[k] / kept : vec3(0.0));
    }
}

// For passes that accumulate themselves: the current sample's sums times `weight` are
// the frame's estimate of `pixel` (call it where film_accumulate(pixel, weight * L, ..)
// is called; with weight 0 for a dropped, non-finite sample the frame adds zeros).
void aov_accumulate(uvec2 pixel, float weight) {
    if (!aov_paths_on()) {
        return;
    }
    uint index = pixel.y * u_frame.width + pixel.x;
    for (uint k = 0u; k < aov_slots(); ++k) {
        aov_accumulate_slot(index, k, weight * g_aov_sample[k]);
    }
}

// ---------------------------------------------------------------------------------------
// Geometric AOVs.

// +inf: the depth where the pixel-centre ray meets neither a surface nor dense medium.
float aov_infinity() {
    return uintBitsToFloat(0x7f800000u);
}

// Overwrites the geometric AOVs of `pixel`.
void aov_write_geometry(uvec2 pixel, float z, vec3 normal, vec3 albedo, vec2 motion) {
    if (!SC_AOV_GEOMETRY) {
        return;
    }
    uint at = (pixel.y * u_frame.width + pixel.x) * AOV_GEOMETRY_VEC4S;
    aov_geometry[at] = vec4(normal, z);
    aov_geometry[at + 1u] = vec4(albedo, 0.0);
    aov_geometry[at + 2u] = vec4(motion, 0.0, 0.0);
}

// Screen-space motion in pixels per frame (x right, y down) of a point at p in this
// frame that was at p_prev in the previous scene frame: its pixel position now minus
// its pixel position in the previous frame's camera. 0 without a previous frame (scene
// frame 0) or where either projection is behind its camera.
vec2 aov_motion(vec3 p, vec3 p_prev) {
    if (u_aov.has_prev == 0u) {
        return vec2(0.0);
    }
    vec2 now;
    vec2 before;
    if (!camera_project(u_frame, p, now) || !camera_project(u_aov.prev, p_prev, before)) {
        return vec2(0.0);
    }
    vec2 m = now - before;
    return (any(isnan(m)) || any(isinf(m))) ? vec2(0.0) : m;
}

// The geometric point of the camera ray o + t d (d unit): the nearer of the first surface
// and the point where the ray's transmittance through the media first falls to 0.5.
// Returns false if there is neither; else t, the normal there (a surface's shading
// normal facing the ray; in a medium the normalised negative density gradient, a box's
// face normal at its boundary, 0 where it vanishes) and the albedo (the surface's, or the
// media's single-scattering albedo weighted by their extinction at the point). Defined by
// the includer: aov_trace.glsl for the grid passes (grid, box media, shapes, sphere
// lights) and for the box pass (box media, shapes; AOV_TRACE_NO_GRID).
bool aov_geometry_point(vec3 o, vec3 d, out float t, out vec3 normal, out vec3 albedo);

// Traces `pixel`'s centre ray and writes its geometric AOVs (motion of static
// geometry: the point where it is).
void aov_geometry_pixel(uvec2 pixel) {
    if (!SC_AOV_GEOMETRY) {
        return;
    }
    vec3 o = u_frame.cam_position;
    vec3 d = camera_direction(u_frame, vec2(pixel) + 0.5);
    float t;
    vec3 normal;
    vec3 albedo;
    if (aov_geometry_point(o, d, t, normal, albedo)) {
        vec3 p = o + t * d;
        aov_write_geometry(pixel, t * dot(d, u_frame.cam_forward), normal, albedo,
                           aov_motion(p, p));
    } else {
        aov_write_geometry(pixel, aov_infinity(), vec3(0.0), vec3(0.0), vec2(0.0));
    }
}

#endif
