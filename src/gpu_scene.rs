//! The scene as GPU records: `#[repr(C)]` mirrors of `shaders/include/scene.glsl`.
//!
//! All records are made of 16-byte vectors so that std140 / std430 and `repr(C)` agree;
//! `tests/layout.rs` checks the sizes against the GLSL declarations.

use anyhow::{bail, Result};
use bytemuck::{Pod, Zeroable};
use glam::{Mat3, Vec3};
use nimbus_scene::{rotation_xyz_deg, CameraFrame, Gobo, Light, Medium, Scene, Shape};

/// `BoxMedium` in scene.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct BoxMediumGpu {
    pub world_to_local: [[f32; 4]; 3],
    pub center_sigma_t: [f32; 4],
    pub half_size_g: [f32; 4],
    pub sigma_s: [f32; 4],
}

pub const SHAPE_QUAD: u32 = 0;
pub const SHAPE_BOX: u32 = 1;
pub const SHAPE_SPHERE: u32 = 2;

/// `Shape` in scene.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct ShapeGpu {
    pub p: [[f32; 4]; 5],
    pub albedo_type: [f32; 4],
}

pub const LIGHT_DIRECTIONAL: u32 = 0;

/// `Light` in scene.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct LightGpu {
    pub direction_type: [f32; 4],
    pub irradiance: [f32; 4],
    pub gobo_origin: [f32; 4],
    pub gobo_u: [f32; 4],
    pub gobo_v: [f32; 4],
}

/// `FrameUniforms` in scene.glsl (std140).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FrameUniforms {
    pub cam_position: [f32; 4],
    pub cam_forward: [f32; 4],
    pub cam_right: [f32; 4],
    pub cam_up: [f32; 4],
    pub env_radiance: [f32; 4],
    pub image: [u32; 4],
    pub counts: [u32; 4],
    pub reserved: [f32; 4],
}

/// `PassPush` in scene.glsl: the push constants of every dispatch.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct PassPush {
    pub frame: u32,
    pub sample_base: u32,
    pub pad0: u32,
    pub pad1: u32,
}

/// Every record of a scene the box pass reads. Storage buffers cannot be empty, so an
/// empty list still uploads one zeroed record; the counts say how many are real.
#[derive(Clone, Debug)]
pub struct GpuScene {
    pub media: Vec<BoxMediumGpu>,
    pub shapes: Vec<ShapeGpu>,
    pub lights: Vec<LightGpu>,
    /// Gobo edges as half-planes (a, b, c, 0): inside when a·u + b·v + c >= 0.
    pub gobo_planes: Vec<[f32; 4]>,
    pub env_radiance: Vec3,
    pub any_gobo: bool,
}

fn v4(v: Vec3, w: f32) -> [f32; 4] {
    [v.x, v.y, v.z, w]
}

/// Rows of Rᵀ for a rotation R: the box's local axes in world space.
fn world_to_local_rows(rotation: Mat3) -> [[f32; 4]; 3] {
    [
        v4(rotation.x_axis, 0.0),
        v4(rotation.y_axis, 0.0),
        v4(rotation.z_axis, 0.0),
    ]
}

impl GpuScene {
    /// Convert the parts of `scene` the box pass renders. Media other than boxes and
    /// lights other than directional and constant environment are rejected by the
    /// render plan before this is called; here they are an internal error.
    pub fn build(scene: &Scene) -> Result<GpuScene> {
        let mut media = Vec::new();
        for medium in &scene.media {
            let Medium::Box(b) = medium else {
                bail!("internal: the box pass was given a grid medium");
            };
            let rotation = rotation_xyz_deg(b.rotation_deg);
            let sigma_s = b.albedo * b.sigma_t;
            media.push(BoxMediumGpu {
                world_to_local: world_to_local_rows(rotation),
                center_sigma_t: v4(b.center, b.sigma_t),
                half_size_g: v4(b.size * 0.5, b.g),
                sigma_s: v4(sigma_s, 0.0),
            });
        }

        let shapes = scene.shapes.iter().map(shape_record).collect();

        let mut lights = Vec::new();
        let mut gobo_planes = Vec::new();
        let mut env_radiance = Vec3::ZERO;
        let mut any_gobo = false;
        for light in &scene.lights {
            match light {
                Light::Directional {
                    direction,
                    irradiance,
                    gobo,
                } => {
                    let (origin, u, v, first, count) = match gobo {
                        Some(gobo) => {
                            any_gobo = true;
                            let (u, v) = Gobo::basis(*direction);
                            let first = gobo_planes.len() as f32;
                            gobo_planes.extend(gobo_half_planes(&gobo.polygon));
                            let count = gobo.polygon.len() as f32;
                            (gobo.origin, u, v, first, count)
                        }
                        None => (Vec3::ZERO, Vec3::X, Vec3::Y, 0.0, 0.0),
                    };
                    lights.push(LightGpu {
                        direction_type: v4(*direction, LIGHT_DIRECTIONAL as f32),
                        irradiance: v4(*irradiance, 0.0),
                        gobo_origin: v4(origin, count),
                        gobo_u: v4(u, first),
                        gobo_v: v4(v, 0.0),
                    });
                }
                Light::Environment {
                    radiance,
                    file: None,
                    scale,
                } => env_radiance += *radiance * *scale,
                other => bail!("internal: the box pass was given an unsupported light {other:?}"),
            }
        }
        Ok(GpuScene {
            media,
            shapes,
            lights,
            gobo_planes,
            env_radiance,
            any_gobo,
        })
    }

    /// The per-frame uniforms for camera frame `camera` of `scene`.
    pub fn frame_uniforms(
        &self,
        scene: &Scene,
        camera: &CameraFrame,
        samples_along_ray: u32,
    ) -> FrameUniforms {
        let r = &scene.render;
        let tan_y = camera.tan_half_fov_x * r.height as f32 / r.width as f32;
        FrameUniforms {
            cam_position: v4(camera.position, camera.tan_half_fov_x),
            cam_forward: v4(camera.forward, tan_y),
            cam_right: v4(camera.right, 0.0),
            cam_up: v4(camera.up, 0.0),
            env_radiance: v4(self.env_radiance, 0.0),
            image: [r.width, r.height, r.spp, (r.seed ^ (r.seed >> 32)) as u32],
            counts: [
                self.media.len() as u32,
                self.shapes.len() as u32,
                self.lights.len() as u32,
                samples_along_ray,
            ],
            reserved: [0.0; 4],
        }
    }
}

/// The GPU record of one shape.
fn shape_record(shape: &Shape) -> ShapeGpu {
    let mut p = [[0.0f32; 4]; 5];
    let (albedo, kind) = match shape {
        Shape::Quad {
            corner,
            edge_u,
            edge_v,
            albedo,
        } => {
            // w = n / (n·n) lets the shader solve the parallelogram coordinates.
            let n = edge_u.cross(*edge_v);
            let w = n / n.length_squared();
            p[0] = v4(*corner, 0.0);
            p[1] = v4(*edge_u, 0.0);
            p[2] = v4(*edge_v, 0.0);
            p[3] = v4(w, 0.0);
            (*albedo, SHAPE_QUAD)
        }
        Shape::Box {
            center,
            size,
            rotation_deg,
            albedo,
        } => {
            let rows = world_to_local_rows(rotation_xyz_deg(*rotation_deg));
            p[0] = rows[0];
            p[1] = rows[1];
            p[2] = rows[2];
            p[3] = v4(*center, 0.0);
            p[4] = v4(*size * 0.5, 0.0);
            (*albedo, SHAPE_BOX)
        }
        Shape::Sphere {
            center,
            radius,
            albedo,
        } => {
            p[0] = v4(*center, *radius);
            (*albedo, SHAPE_SPHERE)
        }
    };
    ShapeGpu {
        p,
        albedo_type: v4(albedo, kind as f32),
    }
}

/// Half-planes of a counter-clockwise convex polygon: for the edge a → b the inside is
/// to the left, cross(b − a, p − a) >= 0, i.e. (a_y − b_y)·u + (b_x − a_x)·v + c >= 0.
pub fn gobo_half_planes(polygon: &[glam::Vec2]) -> Vec<[f32; 4]> {
    (0..polygon.len())
        .map(|i| {
            let a = polygon[i];
            let b = polygon[(i + 1) % polygon.len()];
            let e = b - a;
            let (na, nb) = (-e.y, e.x);
            [na, nb, -(na * a.x + nb * a.y), 0.0]
        })
        .collect()
}

/// A one-record placeholder for an empty storage buffer.
pub fn non_empty<T: Pod + Zeroable>(records: &[T]) -> Vec<T> {
    if records.is_empty() {
        vec![T::zeroed()]
    } else {
        records.to_vec()
    }
}
