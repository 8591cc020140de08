//! The scene as GPU records (the types are in [`super::records`]): box media, shapes,
//! lights with their selection CDF, gobo half-planes, frame uniforms, and a grid medium
//! with its super-voxel majorants and environment-map tables.

use anyhow::{bail, Result};
use bytemuck::{Pod, Zeroable};

use super::records::*;
use super::sparse::{grid_space, Indirection, SparseLayout, TexelFormat};
use glam::{DMat4, Mat3, Vec3};
use nimbus_scene::{
    rotation_xyz_deg, BrickGrid, CameraFrame, EnvRotation, Gobo, Light, Medium, Scene, Shape,
};

mod grid;
mod lights;

pub use grid::{needs_exact_spans, GpuGrid};
pub use lights::{GpuEnvMap, LightSet};

/// Every record of a scene the box pass reads. Storage buffers cannot be empty, so an
/// empty list still uploads one zeroed record; the counts say how many are real.
#[derive(Clone, Debug)]
pub struct GpuScene {
    pub media: Vec<BoxMediumGpu>,
    /// The convex media's planes (n, d) in their local frames (see `BoxMediumGpu`).
    pub medium_planes: Vec<[f32; 4]>,
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
    /// lights other than directional and environment are rejected by the render plan
    /// before this is called; here they are an internal error. An environment map is
    /// loaded separately ([`GpuEnvMap::load`]); `env_radiance` sums the constant ones.
    pub fn build(scene: &Scene) -> Result<GpuScene> {
        if scene.media.iter().any(|m| matches!(m, Medium::Grid(_))) {
            bail!("internal: the box pass was given a grid medium");
        }
        let MediumRecords {
            media,
            planes: medium_planes,
        } = medium_records(scene);

        let shapes = shape_records(scene);

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
                            let first = gobo_planes.len() as u32;
                            gobo_planes.extend(gobo_half_planes(&gobo.polygon));
                            let count = gobo.polygon.len() as u32;
                            (gobo.origin, u, v, first, count)
                        }
                        None => (Vec3::ZERO, Vec3::X, Vec3::Y, 0, 0),
                    };
                    lights.push(LightGpu {
                        direction_or_position: direction.to_array(),
                        r#type: LIGHT_DIRECTIONAL,
                        irradiance: irradiance.to_array(),
                        radius: 0.0,
                        gobo_origin: origin.to_array(),
                        gobo_plane_count: count,
                        gobo_u: u.to_array(),
                        gobo_first_plane: first,
                        gobo_v: v.to_array(),
                        select_cdf: 0.0,
                        group: 0,
                        _pad0: 0,
                        _pad1: 0,
                        _pad2: 0,
                    });
                }
                Light::Environment {
                    radiance,
                    file: None,
                    scale,
                    ..
                } => env_radiance += *radiance * *scale,
                // The map's radiance lives in its texels (`GpuEnvMap`).
                Light::Environment { file: Some(_), .. } => {}
                other => bail!("internal: the box pass was given an unsupported light {other:?}"),
            }
        }
        Ok(GpuScene {
            media,
            medium_planes,
            shapes,
            lights,
            gobo_planes,
            env_radiance,
            any_gobo,
        })
    }
}

/// The records of a scene's box and convex media and the convex media's planes.
#[derive(Clone, Debug, Default)]
pub struct MediumRecords {
    pub media: Vec<BoxMediumGpu>,
    pub planes: Vec<[f32; 4]>,
}

/// The records of a scene's box and convex media (grid media are skipped). A convex
/// medium's local frame is its vertices' centroid with the world's axes; its planes
/// (n, d − n·centroid) go to `planes`, and `half_size` bounds its vertices.
pub fn medium_records(scene: &Scene) -> MediumRecords {
    let mut out = MediumRecords::default();
    for medium in &scene.media {
        match medium {
            Medium::Box(b) => out.media.push(BoxMediumGpu {
                world_to_local: world_to_local_rows(rotation_xyz_deg(b.rotation_deg)),
                center: b.center.to_array(),
                sigma_t: b.sigma_t,
                half_size: (b.size * 0.5).to_array(),
                g: b.g,
                sigma_s: (b.albedo * b.sigma_t).to_array(),
                plane_count: 0,
                plane_first: 0,
                _pad0: 0,
                _pad1: 0,
                _pad2: 0,
            }),
            Medium::Convex(c) => {
                let center = c.polyhedron.centroid();
                let (lo, hi) = c.polyhedron.bounds();
                // The bounding box about the centroid, a little wider than the vertices
                // so that rounding never cuts the polyhedron.
                let half = (hi - center).max(center - lo) * (1.0 + 1e-5);
                let first = out.planes.len() as u32;
                out.planes.extend(c.planes.iter().map(|p| {
                    let n = glam::DVec3::new(p[0].into(), p[1].into(), p[2].into());
                    [p[0], p[1], p[2], (f64::from(p[3]) - n.dot(center)) as f32]
                }));
                out.media.push(BoxMediumGpu {
                    world_to_local: world_to_local_rows(Mat3::IDENTITY),
                    center: center.as_vec3().to_array(),
                    sigma_t: c.sigma_t,
                    half_size: half.as_vec3().to_array(),
                    g: c.g,
                    sigma_s: (c.albedo * c.sigma_t).to_array(),
                    plane_count: c.planes.len() as u32,
                    plane_first: first,
                    _pad0: 0,
                    _pad1: 0,
                    _pad2: 0,
                });
            }
            Medium::Grid(_) => {}
        }
    }
    out
}

/// The records of a scene's box and convex media (without their planes).
pub fn box_records(scene: &Scene) -> Vec<BoxMediumGpu> {
    medium_records(scene).media
}

/// What a pass's frame uniforms count: the records of its buffers, and the samples the
/// box estimators take along a camera segment.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RecordCounts {
    pub box_media: u32,
    pub shapes: u32,
    /// Analytic lights in one light set.
    pub lights: u32,
    pub ray_samples: u32,
}

/// The per-frame uniforms: camera frame `camera`, environment radiance `env`, the
/// environment map's turn `env_rotation` and the record counts of the pass.
pub fn frame_uniforms(
    scene: &Scene,
    camera: &CameraFrame,
    env: Vec3,
    env_rotation: EnvRotation,
    counts: RecordCounts,
) -> FrameUniforms {
    let r = &scene.render;
    let tan_y = camera.tan_half_fov_x * r.height as f32 / r.width as f32;
    FrameUniforms {
        cam_position: camera.position.to_array(),
        tan_half_fov_x: camera.tan_half_fov_x,
        cam_forward: camera.forward.to_array(),
        tan_half_fov_y: tan_y,
        cam_right: camera.right.to_array(),
        _pad0: 0.0,
        cam_up: camera.up.to_array(),
        _pad1: 0.0,
        env_radiance: env.to_array(),
        background: if r.transparent_background { 0.0 } else { 1.0 },
        width: r.width,
        height: r.height,
        spp: r.spp,
        seed: (r.seed ^ (r.seed >> 32)) as u32,
        box_media_count: counts.box_media,
        shape_count: counts.shapes,
        light_count: counts.lights,
        ray_samples: counts.ray_samples,
        env_size: [1, 1],
        env_rotation: [env_rotation.cos as f32, env_rotation.sin as f32],
    }
}

/// The shape records of a scene. A mesh's record names where its BVH lies in the
/// scene's mesh buffers ([`MeshPlacement`]): meshes are concatenated in shape order; an
/// emitting shape's names its first primitive in the emitter table
/// ([`EmitterTable`](super::emitters::EmitterTable), built in the same order).
pub fn shape_records(scene: &Scene) -> Vec<ShapeGpu> {
    let mut next = MeshPlacement::default();
    let mut next_emitter = 0u32;
    scene
        .shapes
        .iter()
        .map(|shape| {
            let placement = next;
            if let Shape::Mesh { mesh, .. } = shape {
                // No wrap: the budget refuses buffers beyond maxStorageBufferRange first.
                next.first_node = next
                    .first_node
                    .saturating_add(mesh.bvh.nodes().len() as u32);
                next.first_triangle = next
                    .first_triangle
                    .saturating_add(mesh.triangle_count() as u32);
            }
            let primitives = super::emitters::emitter_primitives(shape);
            let emitter_first = if primitives > 0 {
                next_emitter
            } else {
                NO_INDEX
            };
            next_emitter = next_emitter.saturating_add(primitives);
            ShapeGpu {
                emission: shape.emission().to_array(),
                emitter_first,
                ..shape_record(shape, placement)
            }
        })
        .collect()
}

/// `NO_INDEX` of constants.glsl: no light, medium, shape or emitter.
pub const NO_INDEX: u32 = u32::MAX;

/// Where a mesh's BVH starts in the scene's concatenated node and triangle buffers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MeshPlacement {
    /// Its root node's index in the node buffer.
    pub first_node: u32,
    /// Its first leaf triangle's index in the triangle buffer.
    pub first_triangle: u32,
}

/// The GPU record of one shape; `mesh` places a mesh's BVH (ignored for other shapes).
fn shape_record(shape: &Shape, mesh_at: MeshPlacement) -> ShapeGpu {
    let mut p = [[0.0f32; 4]; 5];
    let (albedo, kind) = match shape {
        Shape::Quad {
            corner,
            edge_u,
            edge_v,
            albedo,
            ..
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
            ..
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
            ..
        } => {
            p[0] = v4(*center, *radius);
            (*albedo, SHAPE_SPHERE)
        }
        Shape::Mesh { mesh, albedo, .. } => {
            // Indices bit-cast into floats: root node, first triangle, counts.
            p[0] = [
                f32::from_bits(mesh_at.first_node),
                f32::from_bits(mesh_at.first_triangle),
                f32::from_bits(mesh.triangle_count() as u32),
                f32::from_bits(mesh.bvh.nodes().len() as u32),
            ];
            (*albedo, SHAPE_MESH)
        }
    };
    ShapeGpu {
        p,
        albedo: albedo.to_array(),
        r#type: kind,
        emission: [0.0; 3],
        emitter_first: NO_INDEX,
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

/// Luminance of a linear RGB colour.
fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}
