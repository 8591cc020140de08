//! The emitter table: every primitive of the scene's emitting shapes (area lights) with
//! its power CDF, as `shaders/include/emitters.glsl` samples it for next-event
//! estimation.
//!
//! Primitives follow the shapes in scene order: a quad is 2 triangles, a box 12 (its
//! faces, wound to emit outwards), a mesh its triangles in BVH leaf order (the order of
//! [`MeshBuffers`](super::MeshBuffers), so a mesh hit's emitter is the shape's
//! `emitter_first` plus the leaf index minus the mesh's first), a sphere 1. A triangle's
//! power is π·area·luminance(Le) (one-sided), a sphere's π·4πr²·luminance(Le); a
//! triangle of zero area gets zero power and is never sampled.

use glam::{DVec3, Vec3};
use nimbus_scene::{rotation_xyz_deg, Scene, Shape};

use super::records::{EmitterGpu, EMITTER_SPHERE, EMITTER_TRIANGLE};

/// Bytes of one emitter record on the GPU.
pub const EMITTER_BYTES: u64 = std::mem::size_of::<EmitterGpu>() as u64;

/// The emitting shapes' primitives, with their power CDF.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EmitterTable {
    /// One record per primitive, `cdf` filled in (the last is exactly 1).
    pub records: Vec<EmitterGpu>,
    /// Σ π·area·luminance(Le) over the primitives (W, as luminance).
    pub total_power: f64,
}

/// How many primitives `shape` adds to the table: 0 unless it emits.
pub fn emitter_primitives(shape: &Shape) -> u32 {
    if !shape.emits() {
        return 0;
    }
    match shape {
        Shape::Quad { .. } => 2,
        Shape::Box { .. } => 12,
        Shape::Sphere { .. } => 1,
        Shape::Mesh { mesh, .. } => mesh.triangle_count() as u32,
    }
}

/// Luminance of a linear RGB colour (f64).
fn luminance(c: DVec3) -> f64 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// A triangle record (its CDF entry later) and its area.
fn triangle(p: [Vec3; 3], shape: u32, radiance: Vec3) -> EmitterGpu {
    let [a, b, c] = p.map(|v| v.as_dvec3());
    let area = 0.5 * (b - a).cross(c - a).length();
    EmitterGpu {
        p0: p[0].to_array(),
        r#type: EMITTER_TRIANGLE,
        p1: p[1].to_array(),
        shape,
        p2: p[2].to_array(),
        area: area as f32,
        radiance: radiance.to_array(),
        cdf: 0.0,
    }
}

/// The two triangles of the parallelogram corner + [0,1]·u + [0,1]·v, emitting towards
/// u × v.
fn parallelogram(corner: Vec3, u: Vec3, v: Vec3) -> [[Vec3; 3]; 2] {
    [
        [corner, corner + u, corner + u + v],
        [corner, corner + u + v, corner + v],
    ]
}

impl EmitterTable {
    /// The table of `scene`'s emitting shapes (empty if none emits).
    pub fn build(scene: &Scene) -> EmitterTable {
        let mut records = Vec::new();
        for (i, shape) in scene.shapes.iter().enumerate() {
            if !shape.emits() {
                continue;
            }
            let (index, le) = (i as u32, shape.emission());
            match shape {
                Shape::Quad {
                    corner,
                    edge_u,
                    edge_v,
                    ..
                } => records.extend(
                    parallelogram(*corner, *edge_u, *edge_v).map(|t| triangle(t, index, le)),
                ),
                Shape::Box {
                    center,
                    size,
                    rotation_deg,
                    ..
                } => {
                    // Face a = ±axis: the parallelogram spanned by the next two axes,
                    // in the order that makes its normal point out of the box.
                    let r = rotation_xyz_deg(*rotation_deg);
                    let half = *size * 0.5;
                    let axes = [r.x_axis * half.x, r.y_axis * half.y, r.z_axis * half.z];
                    for a in 0..3 {
                        let (b, c) = (axes[(a + 1) % 3], axes[(a + 2) % 3]);
                        for sign in [1.0f32, -1.0] {
                            let face = *center + sign * axes[a];
                            let (u, v) = if sign > 0.0 { (b, c) } else { (c, b) };
                            let corner = face - u - v;
                            records.extend(
                                parallelogram(corner, 2.0 * u, 2.0 * v)
                                    .map(|t| triangle(t, index, le)),
                            );
                        }
                    }
                }
                Shape::Sphere { center, radius, .. } => {
                    let r = f64::from(*radius);
                    records.push(EmitterGpu {
                        p0: center.to_array(),
                        r#type: EMITTER_SPHERE,
                        p1: [*radius, 0.0, 0.0],
                        shape: index,
                        p2: [0.0; 3],
                        area: (4.0 * std::f64::consts::PI * r * r) as f32,
                        radiance: le.to_array(),
                        cdf: 0.0,
                    });
                }
                Shape::Mesh { mesh, .. } => records.extend(
                    mesh.bvh
                        .leaf_triangles()
                        .iter()
                        .map(|p| triangle(*p, index, le)),
                ),
            }
        }
        // The power CDF, summed in f64.
        let powers: Vec<f64> = records
            .iter()
            .map(|e| {
                std::f64::consts::PI
                    * f64::from(e.area)
                    * luminance(Vec3::from(e.radiance).as_dvec3())
            })
            .collect();
        let total_power: f64 = powers.iter().sum();
        if total_power > 0.0 {
            let mut sum = 0.0;
            for (e, p) in records.iter_mut().zip(&powers) {
                sum += p;
                e.cdf = (sum / total_power) as f32;
            }
            // The last entry is 1 exactly, whatever the rounding (and so are any
            // zero-power entries after the last positive one).
            let last_positive = powers.iter().rposition(|p| *p > 0.0).unwrap_or(0);
            for e in &mut records[last_positive..] {
                e.cdf = 1.0;
            }
        }
        EmitterTable {
            records,
            total_power,
        }
    }

    /// Primitives in the table.
    pub fn len(&self) -> usize {
        self.records.len()
    }

    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene_with(shapes: Vec<Shape>) -> Scene {
        let mut scene = nimbus_scene::parse_str(
            "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n",
            std::path::Path::new("emitters.toml"),
        )
        .unwrap();
        scene.shapes = shapes;
        scene
    }

    fn normal(e: &EmitterGpu) -> Vec3 {
        let [a, b, c] = [e.p0, e.p1, e.p2].map(Vec3::from);
        (b - a).cross(c - a)
    }

    #[test]
    fn a_box_emits_outwards_from_twelve_triangles_covering_its_surface() {
        let (center, size) = (Vec3::new(0.3, -0.2, 1.0), Vec3::new(1.0, 2.0, 0.5));
        let table = EmitterTable::build(&scene_with(vec![Shape::Box {
            center,
            size,
            rotation_deg: Vec3::new(20.0, -35.0, 50.0),
            albedo: Vec3::ZERO,
            emission: Vec3::ONE,
        }]));
        assert_eq!(table.len(), 12);
        let area: f64 = table.records.iter().map(|e| f64::from(e.area)).sum();
        let expected = 2.0 * (1.0 * 2.0 + 2.0 * 0.5 + 1.0 * 0.5);
        assert!((area - expected).abs() < 1e-5, "{area} vs {expected}");
        for e in &table.records {
            let centroid = (Vec3::from(e.p0) + Vec3::from(e.p1) + Vec3::from(e.p2)) / 3.0;
            assert!(
                normal(e).dot(centroid - center) > 0.0,
                "{e:?} faces inwards"
            );
        }
        assert!((table.total_power - std::f64::consts::PI * expected).abs() < 1e-4);
        assert_eq!(table.records.last().unwrap().cdf, 1.0);
        assert!(table.records.windows(2).all(|w| w[0].cdf <= w[1].cdf));
    }

    #[test]
    fn a_quad_emits_towards_edge_u_cross_edge_v_and_dark_shapes_add_nothing() {
        let (u, v) = (Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.0));
        let table = EmitterTable::build(&scene_with(vec![
            Shape::Sphere {
                center: Vec3::ZERO,
                radius: 0.5,
                albedo: Vec3::ONE,
                emission: Vec3::ZERO,
            },
            Shape::Quad {
                corner: Vec3::ZERO,
                edge_u: u,
                edge_v: v,
                albedo: Vec3::ZERO,
                emission: Vec3::new(1.0, 2.0, 3.0),
            },
            Shape::Sphere {
                center: Vec3::ZERO,
                radius: 0.5,
                albedo: Vec3::ONE,
                emission: Vec3::splat(2.0),
            },
        ]));
        assert_eq!(table.len(), 3);
        for e in &table.records[..2] {
            assert_eq!(e.shape, 1);
            assert!(normal(e).normalize().dot(u.cross(v).normalize()) > 0.999);
            assert!((e.area - 1.0).abs() < 1e-6);
        }
        let sphere = &table.records[2];
        assert_eq!((sphere.shape, sphere.r#type), (2, EMITTER_SPHERE));
        let lum_quad = 0.2126 + 0.7152 * 2.0 + 0.0722 * 3.0;
        let p_quad = std::f64::consts::PI * 2.0 * lum_quad;
        let p_sphere = std::f64::consts::PI * std::f64::consts::PI * 2.0;
        let expected = p_quad / (p_quad + p_sphere);
        assert!((f64::from(table.records[1].cdf) - expected).abs() < 1e-6);
    }
}
