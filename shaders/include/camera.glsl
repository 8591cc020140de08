// The pinhole camera of FrameUniforms: the ray through a pixel position, the projection
// of a world point back to the image, and the pixel jitter (the pixel's box filter is
// one more integration dimension). Pixel positions are in pixels, (0, 0) top-left.
// The includer declares the bool constant SC_PIXEL_JITTER (without it every ray goes
// through the pixel centre).
#ifndef NIMBUS_CAMERA_GLSL
#define NIMBUS_CAMERA_GLSL

#include "rng.glsl"
#include "scene.glsl"

// Unit direction of the camera ray through pixel position px.
vec3 camera_direction(FrameUniforms cam, vec2 px) {
    float sx = (2.0 * px.x / float(cam.width) - 1.0) * cam.tan_half_fov_x;
    float sy = (1.0 - 2.0 * px.y / float(cam.height)) * cam.tan_half_fov_y;
    return normalize(cam.cam_forward + sx * cam.cam_right + sy * cam.cam_up);
}

// Pixel position of world point x seen by `cam`; false if behind the camera.
bool camera_project(FrameUniforms cam, vec3 x, out vec2 px) {
    vec3 v = x - cam.cam_position;
    float z = dot(v, cam.cam_forward);
    if (!(z > 1e-6)) {
        return false;
    }
    // Domain: z > 0 and tan(fov / 2) > 0 (validated fov).
    float sx = dot(v, cam.cam_right) / (z * cam.tan_half_fov_x);
    float sy = dot(v, cam.cam_up) / (z * cam.tan_half_fov_y);
    px = vec2((sx + 1.0) * 0.5 * float(cam.width), (1.0 - sy) * 0.5 * float(cam.height));
    return true;
}

// A sub-pixel offset drawn uniformly over the pixel footprint (two random numbers), or
// the centre without jitter (none drawn).
vec2 pixel_jitter(inout uint rng) {
    return SC_PIXEL_JITTER ? vec2(rng_next(rng), rng_next(rng)) : vec2(0.5);
}

// ---------------------------------------------------------------------------------------
// Jitter codes, for paths that keep their sub-pixel position (ReSTIR stores it in 16 bits
// of a reservoir): code c per axis stands for the offset (c + 0.5) / 256, a 256 x 256
// midpoint grid over the pixel.

// A jitter code drawn uniformly: (x, y) in bits 0-7 and 8-15.
uint jitter_code_sample(inout uint rng) {
    uint x = min(uint(rng_next(rng) * 256.0), 255u);
    uint y = min(uint(rng_next(rng) * 256.0), 255u);
    return x | (y << 8u);
}

// The sub-pixel offset of a jitter code (the centre without jitter).
vec2 jitter_code_offset(uint code) {
    if (!SC_PIXEL_JITTER) {
        return vec2(0.5);
    }
    return (vec2(float(code & 0xffu), float((code >> 8u) & 0xffu)) + 0.5) / 256.0;
}

#endif
