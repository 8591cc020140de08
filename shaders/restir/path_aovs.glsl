// Volumetric ReSTIR: the path AOVs (emission / direct / indirect, light groups) of final
// shading, on the slots of include/aov.glsl. Final shading adds f(x) W of the pixel's
// selected path; f is a sum of terms (the light vertex's, with split NEE one per delta
// light, with folded emission the last vertex's sigma_a Le), each of one kind and one
// light group:
//   - a direct path (k' = 0: the camera ray ends on a light, the environment or an
//     emitting shape): emission, the group of what it ends on;
//   - an emission path ending at x_k': emitted after k' - 1 scatterings, group default;
//   - a light term at the last vertex x_k': NEE at the k'-th scattering vertex (surface
//     vertices scatter too), the light's group;
//   - folded emission at x_k': emitted after k' - 1 scatterings, group default.
// Each term is non-negative and f > 0 wherever one is, and the target covers f, so
// E[f_j(Y) W] is term j's integral: every component is as unbiased as the beauty is.
//
// Only where the render asks for them (aov_paths_on(): SC_AOV_PATHS, SC_AOV_GROUPS > 0)
// does path_value's final mode split its value: it adds each term to its slots of the
// sample's sums (aov_add), scales the slots by the path's throughput and geometry term as
// it scales the value, and returns their sum; shade.comp scales the slots by W and forms
// the pixel's RGB as the sum of the weighted slots (the kinds' where they are estimated,
// else the groups'), so that the RGB the film adds is exactly the sum of what the AOVs
// add, and the other family sums to it up to rounding. Without path AOVs none of this is
// compiled in and final shading is what it was.
#ifndef NIMBUS_RESTIR_PATH_AOVS_GLSL
#define NIMBUS_RESTIR_PATH_AOVS_GLSL

#include "resources.glsl"
#include "path_surfaces.glsl"

// The light group of what camera_end sees along o + t d: an emitting shape (the default
// group), else the nearest emitting sphere, else the environment (the same tests in the
// same order as camera_end and light_seen).
uint camera_end_group(uint set, vec3 o, vec3 d) {
    uint sphere;
    float t_sphere = nearest_sphere_light(light_base(set), o, d, 0.0, FAR, sphere);
    if (surface_along(o, d, t_sphere).shape != NO_INDEX) {
        return AOV_GROUP_DEFAULT;
    }
    return sphere == NO_INDEX ? AOV_GROUP_ENV : light_group(light_base(set) + sphere);
}

// The light group of light `index` of a set (LIGHT_ENV: the environment).
uint restir_light_group(uint set, uint index) {
    return index == LIGHT_ENV ? AOV_GROUP_ENV : light_group(light_base(set) + index);
}

// Scales every slot of the sample's sums as path_value scales its light terms: f x slot
// x geometry.
void restir_aov_finish(vec3 f, float geometry) {
    for (uint k = 0u; k < aov_slots(); ++k) {
        g_aov_sample[k] = f * g_aov_sample[k] * geometry;
    }
}

// Scales every slot of the sample's sums by the resampling weight W.
void restir_aov_weigh(float W) {
    for (uint k = 0u; k < aov_slots(); ++k) {
        g_aov_sample[k] *= W;
    }
}

// The sum of the sample's slots of one family: emission + direct + indirect where they
// are estimated, else the light groups in order.
vec3 restir_aov_sum() {
    if (SC_AOV_PATHS) {
        return g_aov_sample[AOV_EMISSION] + g_aov_sample[AOV_DIRECT] + g_aov_sample[AOV_INDIRECT];
    }
    vec3 sum = vec3(0.0);
    for (uint k = 0u; k < aov_slots(); ++k) {
        sum += g_aov_sample[k];
    }
    return sum;
}

#endif
