// Volumetric ReSTIR: the path AOVs (emission / direct / indirect, light groups) of final
// shading. Final shading adds f(x) W of the pixel's selected path; f is a sum of terms
// (the light vertex's, with split NEE one per delta light, with folded emission the last
// vertex's sigma_a Le), each of one kind and one light group:
//   - a direct path (k' = 0: the camera ray ends on a light, the environment or an
//     emitting shape): emission, the group of what it ends on;
//   - an emission path ending at x_k': emitted after k' - 1 scatterings, group default;
//   - a light term at the last vertex x_k': after k' scatterings (surface vertices scatter
//     too), the light's group;
//   - folded emission at x_k': after k' - 1 scatterings, group default.
// 0 scatterings is emission, 1 direct, more indirect. Each term is non-negative and F > 0
// wherever one is, so E[f_j(Y) W] is term j's integral: every component is as unbiased as
// the beauty is.
//
// Only where the render asks for them (SC_AOV_PATHS, SC_AOV_GROUPS > 0) does path_value's
// final mode split its value: it then forms each component as f x part x G and returns
// their sum, and shade.comp scales each by W and forms the pixel's RGB as the sum of the
// scaled kinds, so that emission + direct + indirect is the RGB the film adds, bit for
// bit, and the light groups sum to it up to rounding. Without path AOVs none of this is
// compiled in and path_value is what it was.
#ifndef NIMBUS_RESTIR_PATH_AOVS_GLSL
#define NIMBUS_RESTIR_PATH_AOVS_GLSL

#include "resources.glsl"
#include "path_surfaces.glsl"

// PROTOTYPE SHIM until shaders/include/aov.glsl lands (engineer A).
const bool SC_AOV_PATHS = false;
const uint SC_AOV_GROUPS = 0u;
#define AOV_MAX_GROUPS 8
#define AOV_EMISSION 0u
#define AOV_DIRECT 1u
#define AOV_INDIRECT 2u
#define AOV_GROUP_DEFAULT 0u
uint light_group(uint index) { return 0u; }
uint aov_environment_group() { return 0u; }

// Whether final shading splits its value into components.
const bool RESTIR_AOV_SPLIT = SC_AOV_PATHS || SC_AOV_GROUPS > 0u;

// The components of the last final evaluation: per kind (AOV_EMISSION, AOV_DIRECT,
// AOV_INDIRECT) and per light group, before W (path_value) and after it (shade.comp).
vec3 g_aov_kind[3];
vec3 g_aov_group[AOV_MAX_GROUPS];

void restir_aov_clear() {
    for (uint k = 0u; k < 3u; ++k) {
        g_aov_kind[k] = vec3(0.0);
    }
    for (uint g = 0u; g < SC_AOV_GROUPS; ++g) {
        g_aov_group[g] = vec3(0.0);
    }
}

// The kind of light that reached the camera after `scatterings` scattering events.
uint restir_aov_kind(uint scatterings) {
    return scatterings == 0u ? AOV_EMISSION : (scatterings == 1u ? AOV_DIRECT : AOV_INDIRECT);
}

// The light group of light `index` of the current set (LIGHT_ENV: the environment).
uint restir_aov_light_group(uint index) {
    return index == LIGHT_ENV ? aov_environment_group() : light_group(index);
}

// The light group of what camera_end sees along o + t d: an emitting shape (the default
// group), else the nearest emitting sphere, else the environment (the same tests in the
// same order as camera_end and light_seen).
uint camera_end_group(uint set, vec3 o, vec3 d) {
    uint sphere;
    float t_sphere = nearest_sphere_light(light_base(set), o, d, 0.0, FAR, sphere);
    if (surface_along(o, d, t_sphere).shape != NO_INDEX) {
        return AOV_GROUP_DEFAULT;
    }
    return restir_aov_light_group(sphere == NO_INDEX ? LIGHT_ENV : sphere);
}

// Adds term v of kind `kind` and group `group`.
void restir_aov_part(uint kind, uint group, vec3 v) {
    g_aov_kind[kind] += v;
    if (SC_AOV_GROUPS > 0u) {
        g_aov_group[min(group, SC_AOV_GROUPS - 1u)] += v;
    }
}

// Scales every part by the path's throughput f and geometry term (f x part x G, as
// path_value forms its value) and returns the sum of the kinds: the path's value.
vec3 restir_aov_finish(vec3 f, float geometry) {
    for (uint k = 0u; k < 3u; ++k) {
        g_aov_kind[k] = f * g_aov_kind[k] * geometry;
    }
    for (uint g = 0u; g < SC_AOV_GROUPS; ++g) {
        g_aov_group[g] = f * g_aov_group[g] * geometry;
    }
    return g_aov_kind[AOV_EMISSION] + g_aov_kind[AOV_DIRECT] + g_aov_kind[AOV_INDIRECT];
}

// The sum of the kinds as they stand: the value of a one-term path.
vec3 restir_aov_sum() {
    return g_aov_kind[AOV_EMISSION] + g_aov_kind[AOV_DIRECT] + g_aov_kind[AOV_INDIRECT];
}

// Scales the components by the resampling weight W and returns the RGB estimate: the
// sum of the scaled kinds.
vec3 restir_aov_weigh(float W) {
    for (uint k = 0u; k < 3u; ++k) {
        g_aov_kind[k] *= W;
    }
    for (uint g = 0u; g < SC_AOV_GROUPS; ++g) {
        g_aov_group[g] *= W;
    }
    return restir_aov_sum();
}

#endif
