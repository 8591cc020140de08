// Volumetric ReSTIR: the light vertex that ends a stored path, with split next-event
// estimation and folded emission, and how a path's vertex scatters the light it receives.
#ifndef NIMBUS_RESTIR_PATH_LIGHTS_GLSL
#define NIMBUS_RESTIR_PATH_LIGHTS_GLSL

#include "resources.glsl"
#include "vertex_media.glsl"
#include "path_surfaces.glsl"

// Split next-event estimation (SC_NEE_SPLIT). The paper's paths end in ONE light, picked by
// power at each vertex, so under a scalar target a pixel's selected path is
// lit either by the sun or by the sky and carries that light's colour: colour noise that
// no amount of reuse removes (on the benchmark cloud it was 88 % of the per-frame MSE).
// Split NEE ends a path in one sample omega of the environment, drawn with density q, and
// its value at the last vertex v adds every delta (directional, point) light:
//   g(v, omega) = f_env(v, omega) + q(omega) sum_d f_d(v),
// whose integral over omega is the whole next-event contribution of v (q integrates to 1),
// so the path space gains nothing and loses nothing. The plan allows it only where the
// other lights are the environment alone, whose sampler never fails (q > 0 wherever it
// draws), and the reservoir's light vertex is the environment direction (LIGHT_ENV).

// Folded emission (SC_FOLD_EMISSION, with split NEE, or where the environment is the only
// light: its one-light NEE is the same sampler). Emission paths are candidates
// of their own in the paper; a pixel's one selected path is then either lit or glowing,
// and emission seen after 0, 1 or 2 bounces has other hues than the light scattered
// there, so under the scalar target the hue of a pixel flips with its selection. Folded,
// the split-NEE value of a medium vertex adds its emission weighted by q:
//   g(v, omega) = f_env(v, omega) + q(omega) (sum_d f_d(v) + sigma_a Le(v)),
// whose integral over omega is all the vertex's NEE plus its emission (q integrates to 1
// and never vanishes where it draws), so the emission paths need no candidates.

// The density q the environment sample is drawn with (solid angle), the map turned by
// env_rot (the turn keeps the density's values, at turned directions).
// The direction a reservoir stores for an environment sample drawn along world_dir, and
// the world direction of a stored one when the map is turned by env_rot: in the map's
// frame with env_reuse = "map" (a reused sample turns with a turning map, so a small sun
// keeps its samples: the shift is a rotation, Jacobian 1), else the world direction.
vec3 env_stored_dir(vec3 world_dir, vec2 env_rot) {
    return SC_ENV_REUSE_MAP ? env_world_to_map(world_dir, env_rot) : world_dir;
}
vec3 env_reused_dir(vec3 stored_dir, vec2 env_rot) {
    return SC_ENV_REUSE_MAP ? env_map_to_world(stored_dir, env_rot) : stored_dir;
}

float env_sample_pdf(vec3 wi, vec2 env_rot) {
    return SC_HAS_ENV_MAP ? env_pdf_rotated(wi, env_rot) : uniform_sphere_pdf();
}

// How a vertex scatters light arriving from wi into the travel direction: the surface's
// BRDF x cosine on a surface, sigma_s times the phase function (w: the travel direction
// into the vertex) of each medium there.
vec3 vertex_scatter(SurfacePoint surface, vec3 w, VertexMedium vm, vec3 wi) {
    return surface.shape != NO_INDEX ? surface_reflect(surface, wi) : medium_scatter(vm, dot(w, wi));
}

// The light terms a path's last vertex adds up: 1, the stored light vertex; with split
// NEE also one per light of the set, of which the delta lights count (light_term).
uint light_terms() {
    return SC_NEE_SPLIT ? 1u + u_frame.light_count : 1u;
}

// Term k >= 1 of split NEE at x: delta light k - 1 of the set at `base` (its radiance,
// direction and distance; zero for a light that is not a delta light). env_rot is the
// set's environment turn (light_eval's; a delta light does not read it).
vec3 light_term(uint base, vec2 env_rot, uint k, vec3 x, out vec3 wi, out float dist) {
    uint l = k - 1u;
    uint type = lights[base + l].type;
    if (type != LIGHT_DIRECTIONAL && type != LIGHT_POINT) {
        wi = vec3(0.0, 1.0, 0.0);
        dist = FAR;
        return vec3(0.0);
    }
    return light_eval(base, env_rot, l, vec3(0.0, 1.0, 0.0), 0u, vec3(0.0), x, wi, dist);
}

#endif
