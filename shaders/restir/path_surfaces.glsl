// Volumetric ReSTIR: the surface vertices of a stored path (SC_HAS_SHAPES), what a camera
// ray sees where it leaves the media, and a stored path's first vertex on a camera ray.
#ifndef NIMBUS_RESTIR_PATH_SURFACES_GLSL
#define NIMBUS_RESTIR_PATH_SURFACES_GLSL

#include "resources.glsl"
#include "camera_ray.glsl"
// offset_ray_origin (include/path.glsl).
#include "path.glsl"

// Surface vertices. A stored vertex with z < 0 lies on a surface: it is where the ray from
// the previous vertex along the stored direction first meets a shape, found again by ray
// casting at every evaluation, so under direction reuse it moves with the path as a medium
// vertex does and the shift's Jacobian stays 1 (|z| is the distance it was found at, kept
// for inspection only). In the (z, omega) measure a surface vertex has no z: the walk
// reaches it with probability T* (no collision before it), and the path's value gains the
// transmittance up to it (no sigma_s) and then the Lambertian BRDF times the cosine of the
// direction that leaves it (albedo cos / pi, solid angle). Every segment is checked for
// visibility: a medium vertex must be seen from the previous vertex, a light vertex from
// the last. Vertex reuse with surfaces is refused by the plan (x_2 on a surface would need
// an area-measure geometry term).

// A surface point a ray arrives at.
struct SurfacePoint {
    vec3 x;       // origin of rays leaving it (moved off the surface along n)
    float t;      // distance along the ray (FAR: none)
    vec3 n;       // unit geometric normal on the side the ray arrived from
    uint shape;   // shape index, NO_INDEX if the ray meets none
    vec3 albedo;  // Lambertian albedo
};

// No surface: a ray from o along d that meets no shape.
SurfacePoint surface_none(vec3 o, vec3 d) {
    SurfacePoint s;
    s.x = o;
    s.t = FAR;
    s.n = -d;
    s.shape = NO_INDEX;
    s.albedo = vec3(0.0);
    return s;
}

// The nearest shape along o + t d for t in (0, t_max).
SurfacePoint surface_along(vec3 o, vec3 d, float t_max) {
    SurfacePoint s = surface_none(o, d);
    if (!SC_HAS_SHAPES) {
        return s;
    }
    uint index;
    float t = nearest_shape(o, d, 0.0, t_max, index);
    if (index == NO_INDEX) {
        return s;
    }
    // shape_normal reads the triangle nearest_shape just hit (meshes).
    Shape shape = shapes[index];
    vec3 p = o + t * d;
    s.n = shape_normal(shape, p, d);
    s.x = offset_ray_origin(p, s.n);
    s.t = t;
    s.shape = index;
    s.albedo = shape.albedo;
    return s;
}

// The Lambertian BRDF times the cosine towards the leaving direction wo: albedo cos / pi,
// 0 for a direction into the surface.
vec3 surface_reflect(SurfacePoint s, vec3 wo) {
    float c = dot(s.n, wo);
    return c > 0.0 ? s.albedo * (INV_PI * c) : vec3(0.0);
}

// True if a shape cuts x + t wi for t in (0, dist), short of a vertex at dist (a light
// vertex on a shape lies at dist itself; FAR: the whole ray).
bool shapes_block(vec3 x, vec3 wi, float dist) {
    if (!SC_HAS_SHAPES) {
        return false;
    }
    float t_max = dist >= FAR ? FAR : dist * (1.0 - 1e-4);
    return occluded_before(x, wi, 0.0, t_max);
}

// What a camera ray from o along d sees where it leaves the media: the radiance arriving
// from its end (an emitting sphere or the environment, both weighted as light_seen does,
// or the emission of a shape on its emitting side) and where it ends (t_end, FAR if it
// escapes).
vec3 camera_end(uint set, vec3 o, vec3 d, out float t_end) {
    vec3 L = light_seen(light_base(set), env_rotation_of(set), o, d, t_end);
    SurfacePoint s = surface_along(o, d, t_end);
    if (s.shape != NO_INDEX) {
        t_end = s.t;
        // Right after the nearest_shape of surface_along (a mesh's hit triangle).
        return shape_emitted(s.shape, o + s.t * d, d);
    }
    return L;
}

// Where the ray o + t d (t > 0) meets the nearest opaque thing of a frame's scene (`base`:
// light_base of its set): an emitting sphere (`sphere`, else NO_INDEX) or a shape
// (`surface`, else surface_none). Returns its distance (FAR if nothing).
float opaque_end(uint base, vec3 o, vec3 d, out uint sphere, out SurfacePoint surface) {
    float t_sphere = nearest_sphere_light(base, o, d, 1e-6, FAR, sphere);
    surface = surface_along(o, d, t_sphere);
    return min(t_sphere, surface.t);
}

// x_1 of the path stored at `at` (header r) on camera ray `cam`: on the ray at z_1, or the
// surface the ray meets. False if it has none (no vertex, or the surface is gone).
bool path_x1(uint at, Reservoir r, CameraRay cam, out vec3 x1) {
    x1 = cam.o;
    if (!res_valid(r) || res_vertices(r) < 1u) {
        return false;
    }
    float z = res_z(at, 1u);
    if (z >= 0.0) {
        x1 = cam.o + z * cam.d;
        return true;
    }
    SurfacePoint s = surface_along(cam.o, cam.d, FAR);
    x1 = cam.o + s.t * cam.d;
    return s.shape != NO_INDEX;
}

#endif
