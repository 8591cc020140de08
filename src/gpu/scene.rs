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

/// A grid medium ready for upload: the density in bricks (unscaled) with the slots its
/// atlas gets and their super-voxel records, the emission grid, and the uniforms.
pub struct GpuGrid {
    pub density: BrickGrid,
    /// The density's slots: every brick whose super-voxel holds density, in the order of
    /// `super_voxels`.
    pub density_layout: SparseLayout,
    /// Per density slot: (min, max, avg, 0) of sigma_t over its super-voxel.
    pub super_voxels: Vec<[f32; 4]>,
    /// The emission grid (unscaled), its slots and atlas format, if the medium emits.
    pub emission: Option<(BrickGrid, SparseLayout, TexelFormat)>,
    /// The temperature grid (R32F) and its slots, if the medium glows as a blackbody.
    pub temperature: Option<(BrickGrid, SparseLayout)>,
    /// The albedo grid, its slots and atlas format, if the medium's albedo is a grid.
    pub albedo_grid: Option<(BrickGrid, SparseLayout, TexelFormat)>,
    /// The density's p-space → world map.
    pub p_to_world: DMat4,
    /// The world box of an axis-aligned (`type = "grid"`) medium.
    pub world_box: Option<(Vec3, Vec3)>,
    /// The uniforms; the density's indirection section is first (offset 0), the
    /// emission's second, the temperature's third, the albedo's fourth (see
    /// [`GpuGrid::indirection`]).
    pub uniforms: BaselineUniformsGpu,
    /// Analytic lights (directional, point, sphere), each with its selection CDF, and
    /// the constant environment radiance.
    pub lights: Vec<LightGpu>,
    /// The directional lights' gobo half-planes (one zeroed plane without gobos: a
    /// storage buffer cannot be empty).
    pub gobo_planes: Vec<[f32; 4]>,
    pub env_radiance: Vec3,
    /// The environment map, if the environment has a `file`.
    pub env_map: Option<GpuEnvMap>,
    /// The radius of the medium's bounding sphere (light selection weights).
    pub light_radius: f32,
    /// Mean luminance of the environment map over the sphere, if there is one.
    pub env_map_luminance: Option<f32>,
    /// The emitting shapes' primitives (empty without area lights); `lights` ends with
    /// their `LIGHT_AREA` record when there are some.
    pub emitters: super::EmitterTable,
}

/// An environment map as `shaders/include/envmap.glsl` reads it.
#[derive(Clone, Debug)]
pub struct GpuEnvMap {
    /// Texels (rgb radiance times `radiance · scale`, w unused), row-major from the top.
    pub texels: Vec<[f32; 4]>,
    /// The sampling tables: the marginal CDF, then the conditional rows.
    pub tables: Vec<f32>,
    /// Width and height in texels.
    pub size: [u32; 2],
    /// Mean luminance of the radiance over the sphere.
    pub mean_luminance: f32,
}

impl GpuEnvMap {
    /// Loads the map of the scene's environment light with a `file`, if there is one
    /// (the plans refuse a map beside another environment light).
    pub fn load(scene: &Scene) -> Result<Option<GpuEnvMap>> {
        let mut found = None;
        for light in &scene.lights {
            if let Light::Environment {
                radiance,
                scale,
                file: Some(file),
                ..
            } = light
            {
                let map = nimbus_scene::EnvMap::load_exr(file, *radiance * *scale)?;
                let sampler = nimbus_scene::EnvSampler::new(&map);
                // Mean radiance luminance over the sphere: integral() is the mean of
                // luminance x sin(theta) over the texel grid, which covers 2 pi^2 in
                // (phi, theta); the sphere is 4 pi.
                let mean_luminance = (sampler.integral() * 2.0 * std::f64::consts::PI.powi(2)
                    / (4.0 * std::f64::consts::PI)) as f32;
                let (marginal, conditional) = sampler.to_gpu_tables();
                found = Some(GpuEnvMap {
                    texels: map.texels.iter().map(|t| [t[0], t[1], t[2], 0.0]).collect(),
                    tables: [marginal, conditional].concat(),
                    size: [map.width, map.height],
                    mean_luminance,
                });
            }
        }
        Ok(found)
    }
}

/// The analytic lights of one frame with their selection CDF (`select_cdf`), the
/// probability that next-event estimation picks the environment, and the constant
/// environment radiance.
pub struct LightSet {
    pub lights: Vec<LightGpu>,
    /// The gobos' half-planes (`LightGpu::gobo_first_plane` indexes them). They depend on
    /// the polygons only, which do not animate, so every frame's set has the same ones.
    pub gobo_planes: Vec<[f32; 4]>,
    pub env_select: f32,
    pub env_radiance: Vec3,
}

impl LightSet {
    /// Lights are selected in proportion to the power they bring to the medium's
    /// bounding sphere (radius R): directional E·πR², point 4π·I, sphere 4π²r²·L,
    /// environment 4π²R²·L (luminance of each; `env_map_luminance` replaces the constant
    /// radiance's when the environment has a map), and the emitting shapes, if
    /// `area_power` (their total π·A·L, [`EmitterTable`](super::EmitterTable)) is positive,
    /// as one `LIGHT_AREA` light after the analytic ones.
    pub fn build(
        scene_lights: &[Light],
        radius: f32,
        env_map_luminance: Option<f32>,
        area_power: f64,
    ) -> LightSet {
        let pi = std::f32::consts::PI;
        let mut lights = Vec::new();
        let mut weights = Vec::new();
        let mut env_radiance = Vec3::ZERO;
        let mut gobo_planes = Vec::new();
        for light in scene_lights {
            // The gobo's origin, (u, v) axes, first half-plane and half-plane count.
            let mut gobo_fields = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, 0, 0);
            let (p0, kind, power_rgb, radius_l, weight) = match light {
                Light::Directional {
                    direction,
                    irradiance,
                    gobo,
                } => {
                    if let Some(gobo) = gobo {
                        let (u, v) = Gobo::basis(*direction);
                        let first = gobo_planes.len() as u32;
                        gobo_planes.extend(gobo_half_planes(&gobo.polygon));
                        gobo_fields = (gobo.origin, u, v, first, gobo.polygon.len() as u32);
                    }
                    (
                        *direction,
                        LIGHT_DIRECTIONAL,
                        *irradiance,
                        0.0,
                        luminance(*irradiance) * pi * radius * radius,
                    )
                }
                Light::Point {
                    position,
                    intensity,
                } => (
                    *position,
                    LIGHT_POINT,
                    *intensity,
                    0.0,
                    luminance(*intensity) * 4.0 * pi,
                ),
                Light::Sphere {
                    center,
                    radius: r,
                    radiance,
                } => (
                    *center,
                    LIGHT_SPHERE,
                    *radiance,
                    *r,
                    luminance(*radiance) * 4.0 * pi * pi * r * r,
                ),
                Light::Environment {
                    radiance,
                    scale,
                    file,
                    ..
                } => {
                    if file.is_none() {
                        env_radiance += *radiance * *scale;
                    }
                    continue;
                }
            };
            lights.push(LightGpu {
                direction_or_position: p0.to_array(),
                r#type: kind,
                irradiance: power_rgb.to_array(),
                radius: radius_l,
                gobo_origin: gobo_fields.0.to_array(),
                gobo_plane_count: gobo_fields.4,
                gobo_u: gobo_fields.1.to_array(),
                gobo_first_plane: gobo_fields.3,
                gobo_v: gobo_fields.2.to_array(),
                select_cdf: 0.0,
            });
            weights.push(weight.max(0.0));
        }
        if area_power > 0.0 {
            lights.push(LightGpu {
                direction_or_position: [0.0; 3],
                r#type: LIGHT_AREA,
                irradiance: [0.0; 3],
                radius: 0.0,
                gobo_origin: [0.0; 3],
                gobo_plane_count: 0,
                gobo_u: [0.0; 3],
                gobo_first_plane: 0,
                gobo_v: [0.0; 3],
                select_cdf: 0.0,
            });
            weights.push(area_power as f32);
        }
        let env_luminance = env_map_luminance.unwrap_or_else(|| luminance(env_radiance));
        let env_weight = env_luminance * 4.0 * pi * pi * radius * radius;
        let total: f32 = weights.iter().sum::<f32>() + env_weight;
        let mut env_select = 0.0;
        if total > 0.0 {
            env_select = env_weight / total;
            let mut cdf = 0.0;
            for (light, w) in lights.iter_mut().zip(&weights) {
                cdf += w / total;
                light.select_cdf = cdf;
            }
        }
        LightSet {
            lights,
            gobo_planes,
            env_select,
            env_radiance,
        }
    }
}

/// Whether super-voxel tracking with residual majorants `majorant_scale` x (max - min)
/// can meet a span too hot for null collisions (`GRID_EXACT_SPAN_STEPS` tentative
/// collisions on average) in any of `super_voxels` ((min, max, avg, _) of sigma_t) of a
/// grid whose p-space maps to world by `p_to_world`: the residual majorant times the
/// longest chord of a super-voxel (at most the sum of its three edge lengths) is checked
/// for each. Where none can, `SC_EXACT_SPANS` compiles the exact branches out.
pub fn needs_exact_spans(
    super_voxels: &[[f32; 4]],
    p_to_world: &DMat4,
    majorant_scale: f32,
) -> bool {
    let edges = p_to_world.x_axis.truncate().length()
        + p_to_world.y_axis.truncate().length()
        + p_to_world.z_axis.truncate().length();
    let chord = 8.0 * edges;
    let limit = f64::from(super::features::GRID_EXACT_SPAN_STEPS);
    super_voxels.iter().any(|v| {
        let residual = f64::from(majorant_scale) * f64::from(v[1] - v[0]);
        // A NaN bound is refused at load; count it as hot all the same.
        residual.is_nan() || residual * chord > limit
    })
}

impl GpuGrid {
    /// Whether the baseline's super-voxel tracking needs its exact branches
    /// ([`needs_exact_spans`] with the tight residual majorant).
    pub fn needs_exact_spans(&self) -> bool {
        needs_exact_spans(&self.super_voxels, &self.p_to_world, 1.0)
    }

    /// Whether a brick indirection section of the grid is two-level.
    pub fn two_level_bricks(&self) -> Result<bool> {
        Ok(self.density_layout.indirection.two_level
            || self.static_sections()?.iter().any(|s| s.two_level))
    }

    /// The indirection sections of the grids that do not change per frame: the
    /// emission's, the temperature's and the albedo's (one empty entry for a grid the
    /// medium lacks).
    pub fn static_sections(&self) -> Result<[nimbus_scene::bricks::Indirection; 3]> {
        let section = |layout: Option<&SparseLayout>| match layout {
            Some(layout) => Ok(layout.indirection.clone()),
            None => nimbus_scene::bricks::Indirection::new([1, 1, 1]),
        };
        Ok([
            section(self.emission.as_ref().map(|(_, layout, _)| layout))?,
            section(self.temperature.as_ref().map(|(_, layout)| layout))?,
            section(self.albedo_grid.as_ref().map(|(_, layout, _)| layout))?,
        ])
    }

    /// The indirection sections of the baseline: the density's (at offset 0, as
    /// `uniforms.grid.space` says), then the [`GpuGrid::static_sections`].
    pub fn indirection(&self) -> Result<Vec<u32>> {
        let mut out = Indirection::default();
        out.push(&self.density_layout.indirection)?;
        for section in &self.static_sections()? {
            out.push(section)?;
        }
        Ok(out.finish())
    }
}

/// Luminance of a linear RGB colour.
fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

impl GpuGrid {
    /// Load the scene's grid medium into bricks and build what the grid passes read.
    /// Lights are selected in proportion to the power they bring to the medium's
    /// bounding sphere (radius R): directional E·πR², point 4π·I, sphere 4π²r²·L,
    /// environment 4π²R²·L (luminance of each).
    pub fn build(scene: &Scene) -> Result<GpuGrid> {
        let Some((index, grid)) = scene.media.iter().enumerate().find_map(|(i, m)| match m {
            Medium::Grid(g) => Some((i, g)),
            _ => None,
        }) else {
            bail!("internal: the baseline pass was given no grid medium");
        };
        let what = format!(
            "{}: [[medium]] #{} > density",
            scene.source.display(),
            index + 1
        );
        let density = BrickGrid::load(&grid.density, 1, &what)?;
        grid.check_density_bricks(&density, &scene.position_scale(), &what)?;
        let p_to_world = grid.p_to_world(&density)?;
        let world_box = grid
            .vdb
            .is_none()
            .then_some((grid.bounds_min, grid.bounds_max));
        let scale = grid.density_scale;
        let (bricks, super_voxels): (Vec<_>, Vec<_>) = density
            .super_voxels()
            .into_iter()
            .map(|(b, v)| (b, [v[0] * scale, v[1] * scale, v[2] * scale, 0.0]))
            .unzip();
        let max_sigma = super_voxels.iter().fold(0.0f32, |m, s| m.max(s[1]));
        let density_layout = SparseLayout::new(&density, bricks, 1)?;
        let space = grid_space(&density, &density_layout, 0, p_to_world, world_box);
        let emission = match &grid.emission {
            Some(source) => {
                let what = format!(
                    "{}: [[medium]] #{} > emission",
                    scene.source.display(),
                    index + 1
                );
                let e = BrickGrid::load(source, 0, &what)?;
                let layout = SparseLayout::new(&e, e.slot_bricks(), 1)?;
                let format = if e.channels == 3 {
                    TexelFormat::Rgba32
                } else {
                    TexelFormat::R32
                };
                Some((e, layout, format))
            }
            None => None,
        };
        let temperature = match &grid.temperature {
            Some(t) => {
                let what = format!(
                    "{}: [[medium]] #{} > temperature",
                    scene.source.display(),
                    index + 1
                );
                let tg = BrickGrid::load(&t.source, 1, &what)?;
                let (max, at) = tg.max_value();
                t.check_brightest(max, &format!("lattice point {}", at + tg.origin), &what)?;
                let layout = SparseLayout::new(&tg, tg.slot_bricks(), 1)?;
                Some((tg, layout))
            }
            None => None,
        };
        // The sections follow the density's: the emission's, then the temperature's
        // (one empty entry where a grid is missing), as `indirection` lays them out. A
        // missing grid has 0 channels: grid_emission.glsl does not read it.
        let no_grid = |offset: usize| GridSpaceGpu {
            brick_dims: [1, 1, 1],
            channels: 0,
            slots_x: 1,
            slots_y: 1,
            bricks_offset: offset as u32,
            ..GridSpaceGpu::default()
        };
        let emission_offset = super::sparse::head_len(&density_layout.indirection);
        let emission_space = match &emission {
            Some((e, layout, _)) => grid_space(
                e,
                layout,
                emission_offset as u32,
                grid.p_to_world(e)?,
                world_box,
            ),
            None => no_grid(emission_offset),
        };
        let temperature_offset = emission_offset
            + emission.as_ref().map_or(1, |(_, layout, _)| {
                super::sparse::head_len(&layout.indirection)
            });
        let temperature_space = match &temperature {
            Some((t, layout)) => grid_space(
                t,
                layout,
                temperature_offset as u32,
                grid.p_to_world(t)?,
                world_box,
            ),
            None => no_grid(temperature_offset),
        };
        let albedo_grid = match &grid.albedo_grid {
            Some(source) => {
                let what = format!(
                    "{}: [[medium]] #{} > albedo",
                    scene.source.display(),
                    index + 1
                );
                let a = BrickGrid::load(source, 0, &what)?;
                let (max, at) = a.max_any_channel();
                if max > 1.0 {
                    bail!("{what}: value {max} at lattice point {at}: an albedo must be in [0, 1]");
                }
                let layout = SparseLayout::new(&a, a.slot_bricks(), 1)?;
                let format = if a.channels == 3 {
                    TexelFormat::Rgba32
                } else {
                    TexelFormat::R32
                };
                Some((a, layout, format))
            }
            None => None,
        };
        let albedo_offset = temperature_offset
            + temperature.as_ref().map_or(1, |(_, layout)| {
                super::sparse::head_len(&layout.indirection)
            });
        let albedo_space = match &albedo_grid {
            Some((a, layout, _)) => grid_space(
                a,
                layout,
                albedo_offset as u32,
                grid.p_to_world(a)?,
                world_box,
            ),
            None => no_grid(albedo_offset),
        };
        let pyro = grid.temperature.as_ref();
        let uniforms = BaselineUniformsGpu {
            grid: GridParamsGpu {
                bounds_min: grid.bounds_min.to_array(),
                density_scale: scale,
                bounds_max: grid.bounds_max.to_array(),
                sigma_t_max: max_sigma,
                space,
            },
            albedo: grid.albedo.to_array(),
            g: grid.g,
            emission_scale: grid.emission_scale.to_array(),
            emission: emission_space,
            temperature_offset: pyro.map_or(0.0, |t| t.offset),
            temperature_scale: pyro.map_or(0.0, |t| t.scale),
            blackbody_scale: pyro.map_or(0.0, |t| t.blackbody_scale),
            temperature: temperature_space,
            albedo_grid: albedo_space,
            env_size: [1, 1],
            ..BaselineUniformsGpu::default()
        };

        let radius = 0.5 * (grid.bounds_max - grid.bounds_min).length();
        let env_map = GpuEnvMap::load(scene)?;
        let env_map_luminance = env_map.as_ref().map(|m| m.mean_luminance);
        let mut uniforms = uniforms;
        if let Some(map) = &env_map {
            uniforms.env_size = map.size;
        }
        let emitters = super::EmitterTable::build(scene);
        uniforms.emitter_count = emitters.len() as u32;
        let set = LightSet::build(
            &scene.lights,
            radius,
            env_map_luminance,
            emitters.total_power,
        );
        uniforms.env_select = set.env_select;
        Ok(GpuGrid {
            emitters,
            density,
            density_layout,
            super_voxels: non_empty(&super_voxels),
            emission,
            temperature,
            albedo_grid,
            p_to_world,
            world_box,
            uniforms,
            lights: set.lights,
            gobo_planes: non_empty(&set.gobo_planes),
            env_radiance: set.env_radiance,
            env_map,
            light_radius: radius,
            env_map_luminance,
        })
    }
}
