//! The quadrature's own ray–shape intersections, from any t_min, and the edges of the
//! shapes' shadows. Deliberately not the Monte Carlo oracles' [`Surface::hit`]: here a
//! quad's plane is intersected and its coordinates solved for, a sphere by the
//! quadratic and a box's exit face taken from the slab test, where that uses
//! Möller–Trumbore, the geometric sphere test and the largest local coordinate, so
//! comparing the two kinds of oracle also checks their geometry.

use glam::DVec3;

use super::hints::{push_box_edge_crossings, push_plane_crossing};
use crate::common::surface::{mesh_hit, ShapeGeometry, Surface};

/// A ray–shape intersection: distance and a unit normal of either orientation.
pub(super) struct SurfaceHit {
    pub(super) t: f64,
    pub(super) normal: DVec3,
    pub(super) albedo: DVec3,
}

/// The nearest intersection of o + t·d (|d| = 1) with `shape`, t > t_min.
pub(super) fn intersect(shape: &Surface, o: DVec3, d: DVec3, t_min: f64) -> Option<SurfaceHit> {
    let (t, normal) = match shape.geometry {
        ShapeGeometry::Quad {
            corner,
            edge_u,
            edge_v,
            cross: normal,
        } => {
            // Intersect the plane, then solve p = a·edge_u + b·edge_v by cross products.
            let denom = d.dot(normal);
            if denom == 0.0 {
                return None;
            }
            let t = (corner - o).dot(normal) / denom;
            if !(t > t_min && t.is_finite()) {
                return None;
            }
            let p = o + t * d - corner;
            let n2 = normal.length_squared();
            let a = p.cross(edge_v).dot(normal) / n2;
            let b = edge_u.cross(p).dot(normal) / n2;
            if !((0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b)) {
                return None;
            }
            (t, normal / n2.sqrt())
        }
        ShapeGeometry::Box(bounds) => {
            let hit = bounds.slab(o, d)?;
            let (t, axis) = if hit.t_near > t_min {
                (hit.t_near, hit.axis_near)
            } else if hit.t_far > t_min {
                (hit.t_far, hit.axis_far)
            } else {
                return None;
            };
            (t, bounds.axis_world(axis))
        }
        ShapeGeometry::Sphere { center, radius } => {
            // Solve |o − c + t·d|² = r² with the cancellation-free root pair.
            let oc = o - center;
            let b = oc.dot(d);
            let c = oc.length_squared() - radius * radius;
            let disc = b * b - c;
            if disc < 0.0 {
                return None;
            }
            let q = -b - b.signum() * disc.sqrt();
            let (mut t0, mut t1) = (q, if q != 0.0 { c / q } else { 0.0 });
            if t0 > t1 {
                std::mem::swap(&mut t0, &mut t1);
            }
            let t = if t0 > t_min {
                t0
            } else if t1 > t_min {
                t1
            } else {
                return None;
            };
            (t, (o + t * d - center) / radius)
        }
        ShapeGeometry::Mesh(ref mesh) => {
            // From o + t_min·d on (the BVH's rays start at t > 0).
            let start = t_min.max(0.0);
            let (t, normal) = mesh_hit(mesh, o + start * d, d)?;
            (start + t, normal)
        }
    };
    Some(SurfaceHit {
        t,
        normal,
        albedo: shape.albedo,
    })
}

/// Pushes the t where o + t·d crosses the boundary of `shape`'s shadow along ω.
pub(super) fn push_shadow_crossings(
    shape: &Surface,
    o: DVec3,
    d: DVec3,
    omega: DVec3,
    cuts: &mut Vec<f64>,
) {
    match shape.geometry {
        ShapeGeometry::Quad {
            corner,
            edge_u,
            edge_v,
            cross,
        } => {
            // The quad's plane and the four planes swept along ω by its edges.
            push_plane_crossing(o, d, corner, cross, cuts);
            let far = corner + edge_u + edge_v;
            for (point, edge) in [
                (corner, edge_u),
                (corner, edge_v),
                (far, edge_u),
                (far, edge_v),
            ] {
                push_plane_crossing(o, d, point, edge.cross(omega), cuts);
            }
        }
        ShapeGeometry::Box(bounds) => push_box_edge_crossings(&bounds, o, d, omega, cuts),
        ShapeGeometry::Sphere { center, radius } => {
            // The cylinder of radius r around the line through the centre along ω.
            let a = d - d.dot(omega) * omega;
            let b = (o - center) - (o - center).dot(omega) * omega;
            let (qa, qb, qc) = (a.dot(a), a.dot(b), b.dot(b) - radius * radius);
            let disc = qb * qb - qa * qc;
            if qa > 0.0 && disc >= 0.0 {
                cuts.push((-qb - disc.sqrt()) / qa);
                cuts.push((-qb + disc.sqrt()) / qa);
            }
        }
        // A mesh's shadow edges are its silhouette's, one plane per edge: none are
        // given as hints, so the quadrature resolves them by refinement alone.
        ShapeGeometry::Mesh(_) => {}
    }
}
