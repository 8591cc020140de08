//! The scene's shapes in f64: opaque two-sided Lambertian surfaces. The intersection
//! here ([`Surface::hit`], rays from t > 0) is the Monte Carlo oracles'; the quadrature
//! intersects the same data its own way (`quadrature::shapes`). Meshes are the
//! exception: both ask the CPU BVH (`nimbus_scene::Bvh::closest_hit`, f32 vertices as
//! the scene stores them, its own watertight test with f64 edge functions), which is
//! independent of the GPU traversal it checks.

use std::sync::Arc;

use glam::DVec3;
use nimbus_scene::{MeshShape, Ray, Shape};

use super::geometry::{hit_sphere, OrientedBox};

pub(crate) enum ShapeGeometry {
    /// A parallelogram corner + a·edge_u + b·edge_v, a, b ∈ [0, 1].
    Quad {
        corner: DVec3,
        edge_u: DVec3,
        edge_v: DVec3,
        /// edge_u × edge_v, not normalized.
        cross: DVec3,
    },
    Box(OrientedBox),
    Sphere {
        center: DVec3,
        radius: f64,
    },
    /// A triangle mesh and its BVH (world space, f32).
    Mesh(Arc<MeshShape>),
}

/// An opaque two-sided Lambertian shape of the scene, in f64, and the radiance it emits
/// (zero for none; one-sided for quads and mesh triangles, outwards for boxes and
/// spheres: [`Surface::emitted`]).
pub(crate) struct Surface {
    pub(crate) geometry: ShapeGeometry,
    pub(crate) albedo: DVec3,
    pub(crate) emission: DVec3,
}

impl Surface {
    pub(crate) fn from_shape(shape: &Shape) -> Self {
        let emission = shape.emission().as_dvec3();
        match *shape {
            Shape::Mesh {
                ref mesh, albedo, ..
            } => Surface {
                geometry: ShapeGeometry::Mesh(Arc::clone(mesh)),
                albedo: albedo.as_dvec3(),
                emission,
            },
            Shape::Quad {
                corner,
                edge_u,
                edge_v,
                albedo,
                ..
            } => Surface {
                geometry: ShapeGeometry::Quad {
                    corner: corner.as_dvec3(),
                    edge_u: edge_u.as_dvec3(),
                    edge_v: edge_v.as_dvec3(),
                    cross: edge_u.as_dvec3().cross(edge_v.as_dvec3()),
                },
                albedo: albedo.as_dvec3(),
                emission,
            },
            Shape::Box {
                center,
                size,
                rotation_deg,
                albedo,
                ..
            } => Surface {
                geometry: ShapeGeometry::Box(OrientedBox::from_scene(center, size, rotation_deg)),
                albedo: albedo.as_dvec3(),
                emission,
            },
            Shape::Sphere {
                center,
                radius,
                albedo,
                ..
            } => Surface {
                geometry: ShapeGeometry::Sphere {
                    center: center.as_dvec3(),
                    radius: f64::from(radius),
                },
                albedo: albedo.as_dvec3(),
                emission,
            },
        }
    }

    /// The nearest intersection of o + t·d (|d| = 1) with t > 0: t and a unit normal of
    /// either orientation.
    pub(crate) fn hit(&self, o: DVec3, d: DVec3) -> Option<(f64, DVec3)> {
        match self.geometry {
            ShapeGeometry::Quad {
                corner,
                edge_u,
                edge_v,
                cross,
            } => {
                // Möller–Trumbore with the parallelogram's (a, b) ∈ [0, 1]² test.
                let p = d.cross(edge_v);
                let det = edge_u.dot(p);
                if det == 0.0 {
                    return None;
                }
                let s = o - corner;
                let a = s.dot(p) / det;
                let q = s.cross(edge_u);
                let b = d.dot(q) / det;
                let t = edge_v.dot(q) / det;
                ((0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b) && t > 0.0)
                    .then_some((t, cross.normalize()))
            }
            ShapeGeometry::Box(ref bounds) => {
                let hit = bounds.slab(o, d)?;
                if hit.t_near > 0.0 {
                    Some((hit.t_near, bounds.axis_world(hit.axis_near)))
                } else if hit.t_far > 0.0 {
                    // From inside: the exit face, whichever axis it is.
                    let x = bounds.local_point(o + hit.t_far * d);
                    let ratio = x.abs() / bounds.half;
                    let axis = if ratio.x >= ratio.y && ratio.x >= ratio.z {
                        0
                    } else if ratio.y >= ratio.z {
                        1
                    } else {
                        2
                    };
                    Some((hit.t_far, bounds.axis_world(axis)))
                } else {
                    None
                }
            }
            ShapeGeometry::Sphere { center, radius } => {
                let t = hit_sphere(center, radius, o, d)?;
                Some((t, (o + t * d - center) / radius))
            }
            ShapeGeometry::Mesh(ref mesh) => mesh_hit(mesh, o, d),
        }
    }
}

impl Surface {
    /// The radiance this surface emits from its point `p` back along a ray of direction
    /// `d` that hit it there with the unit normal `n_hit` (as [`Surface::hit`] gives it):
    /// its emission if `d` arrives on the emitting side (a quad's edge_u × edge_v side, a
    /// mesh triangle's counter-clockwise side, a box's or sphere's outside), else 0.
    pub(crate) fn emitted(&self, p: DVec3, n_hit: DVec3, d: DVec3) -> DVec3 {
        if self.emission == DVec3::ZERO {
            return DVec3::ZERO;
        }
        let outward = match self.geometry {
            ShapeGeometry::Quad { cross, .. } => cross,
            // mesh_hit's normal is the triangle's counter-clockwise one.
            ShapeGeometry::Mesh(_) => n_hit,
            ShapeGeometry::Sphere { center, .. } => p - center,
            ShapeGeometry::Box(ref bounds) => {
                let local = bounds.local_point(p);
                let ratio = local.abs() / bounds.half;
                let axis = if ratio.x >= ratio.y && ratio.x >= ratio.z {
                    0
                } else if ratio.y >= ratio.z {
                    1
                } else {
                    2
                };
                bounds.axis_world(axis) * local[axis].signum()
            }
        };
        if outward.dot(d) < 0.0 {
            self.emission
        } else {
            DVec3::ZERO
        }
    }
}

/// The nearest hit of o + t·d (t > 0) with a mesh: t and the hit triangle's unit
/// geometric normal, from the CPU BVH (the ray rounded to f32, as the mesh is stored).
pub(crate) fn mesh_hit(mesh: &MeshShape, o: DVec3, d: DVec3) -> Option<(f64, DVec3)> {
    let ray = Ray {
        origin: o.as_vec3(),
        dir: d.as_vec3(),
    };
    let hit = mesh.bvh.closest_hit(&ray, f32::INFINITY)?;
    let [p0, p1, p2] = mesh
        .mesh
        .triangle(hit.triangle as usize)?
        .map(|p| p.as_dvec3());
    let n = (p1 - p0).cross(p2 - p0);
    (n.length() > 0.0).then(|| (f64::from(hit.t), n.normalize()))
}

/// The nearest surface hit of o + t·d, t > 0: (t, unit normal, albedo).
pub(crate) fn nearest_surface(
    surfaces: &[Surface],
    o: DVec3,
    d: DVec3,
) -> Option<(f64, DVec3, DVec3)> {
    let mut best: Option<(f64, DVec3, DVec3)> = None;
    for surface in surfaces {
        if let Some((t, n)) = surface.hit(o, d) {
            if best.is_none_or(|(t_best, _, _)| t < t_best) {
                best = Some((t, n, surface.albedo));
            }
        }
    }
    best
}

/// Where a path that travelled along d and hit a surface at p (unit `normal`, either
/// side) goes on from: p lifted off the surface towards the incoming ray, and the
/// normal facing that ray.
pub(crate) fn leave_surface(p: DVec3, normal: DVec3, d: DVec3) -> (DVec3, DVec3) {
    let n = if normal.dot(d) < 0.0 { normal } else { -normal };
    (p + surface_offset(p) * n, n)
}

/// Offset that lifts a point off a surface (relative to its coordinates' size).
pub(crate) fn surface_offset(x: DVec3) -> f64 {
    1e-9 * (1.0 + x.abs().max_element())
}
