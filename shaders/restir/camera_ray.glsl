// Volumetric ReSTIR: the camera rays a stored path is evaluated on. A path's first vertex
// is a depth along the camera ray of the pixel that evaluates it (path_value.glsl), so
// the ray carries the frame it belongs to and a depth anchor.
#ifndef NIMBUS_RESTIR_CAMERA_RAY_GLSL
#define NIMBUS_RESTIR_CAMERA_RAY_GLSL

#include "resources.glsl"
#include "camera.glsl"

// Camera rays. The sub-pixel position is part of the path: each random walk draws its
// own jitter code (camera.glsl), the reservoir keeps it (`info` bits 16-31), and a path
// moving to another pixel or frame keeps it, so temporal reuse re-evaluates a path on the
// same ray it was found on.

struct CameraRay {
    vec3 o;
    vec3 d;
    uint set;
    // The ray's depth anchor (m): a path owned by ray a keeps its first medium vertex's
    // depth past the anchor on ray b, z_1' = z_1 - a.anchor + b.anchor (a translation:
    // Jacobian 1). Temporal reuse anchors both pixels' rays where they enter the medium,
    // so that a moving camera's history lands at the depth it was found at (keeping z_1
    // itself put every reused vertex of a dollying camera deeper, where the canonical
    // samples' MIS weights collapsed); 0 elsewhere.
    float anchor;
};

// The camera ray through `pixel` at sub-pixel jitter `code`, in a frame's set.
CameraRay camera_ray(uvec2 pixel, uint code, uint set) {
    CameraRay r;
    r.set = set;
    r.anchor = 0.0;
    vec2 px = vec2(pixel) + jitter_code_offset(code);
    if (set == SET_CURRENT) {
        r.o = u_frame.cam_position;
        r.d = camera_direction(u_frame, px);
    } else {
        r.o = u_prev_frame.cam_position;
        r.d = camera_direction(u_prev_frame, px);
    }
    return r;
}

#endif
