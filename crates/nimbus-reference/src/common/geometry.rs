//! Geometry in f64: the scene's rotation convention, oriented boxes, spheres and gobos.

use std::f64::consts::PI;

use anyhow::ensure;
use glam::{DMat3, DVec2, DVec3, Vec3};
use nimbus_scene::{ConvexMedium, Gobo, Medium};

/// Rotation `rotation_deg` (about X, then Y, then Z) in f64: world = Rz·Ry·Rx·local.
pub(crate) fn rotation_xyz_deg_f64(rotation_deg: Vec3) -> DMat3 {
    let r = rotation_deg.as_dvec3() * (PI / 180.0);
    DMat3::from_rotation_z(r.z) * DMat3::from_rotation_y(r.y) * DMat3::from_rotation_x(r.x)
}

/// `v` normalized, or an error naming `what` when it cannot be.
pub(crate) fn normalized(v: DVec3, what: &str) -> anyhow::Result<DVec3> {
    let n = v.normalize_or_zero();
    ensure!(
        n != DVec3::ZERO && n.is_finite(),
        "{what} {v} cannot be normalized"
    );
    Ok(n)
}

/// A box, world = center + R·local, local ∈ [−half, half].
#[derive(Clone, Copy, Debug)]
pub(crate) struct OrientedBox {
    pub(crate) center: DVec3,
    pub(crate) half: DVec3,
    /// R: its columns are the local axes in world space.
    world_from_local: DMat3,
    local_from_world: DMat3,
}

/// Where a line o + t·d is inside a box, with the local axis of the entry and exit face.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SlabInterval {
    pub(crate) t_near: f64,
    pub(crate) t_far: f64,
    pub(crate) axis_near: usize,
    pub(crate) axis_far: usize,
}

impl OrientedBox {
    pub(crate) fn new(center: DVec3, half: DVec3, world_from_local: DMat3) -> Self {
        Self {
            center,
            half,
            world_from_local,
            local_from_world: world_from_local.transpose(),
        }
    }

    /// A box as the scene gives it: center, full size and rotation in degrees.
    pub(crate) fn from_scene(center: Vec3, size: Vec3, rotation_deg: Vec3) -> Self {
        Self::new(
            center.as_dvec3(),
            0.5 * size.as_dvec3(),
            rotation_xyz_deg_f64(rotation_deg),
        )
    }

    /// Slab test in the box's local frame; t is shared with the world ray because R is
    /// a rotation. A direction component of exactly 0 keeps the line inside that slab
    /// only if its coordinate is.
    pub(crate) fn slab(&self, o: DVec3, d: DVec3) -> Option<SlabInterval> {
        let o_local = self.local_point(o);
        let d_local = self.local_from_world * d;
        let mut hit = SlabInterval {
            t_near: f64::NEG_INFINITY,
            t_far: f64::INFINITY,
            axis_near: 0,
            axis_far: 0,
        };
        for axis in 0..3 {
            let (h, o_a, d_a) = (self.half[axis], o_local[axis], d_local[axis]);
            if d_a == 0.0 {
                if o_a.abs() > h {
                    return None;
                }
                continue;
            }
            let (mut t0, mut t1) = ((-h - o_a) / d_a, (h - o_a) / d_a);
            if t0 > t1 {
                std::mem::swap(&mut t0, &mut t1);
            }
            if t0 > hit.t_near {
                hit.t_near = t0;
                hit.axis_near = axis;
            }
            if t1 < hit.t_far {
                hit.t_far = t1;
                hit.axis_far = axis;
            }
        }
        (hit.t_near <= hit.t_far).then_some(hit)
    }

    /// The part of [t_min, t_max] where o + t·d is inside, if longer than zero.
    pub(crate) fn clip(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<(f64, f64)> {
        let hit = self.slab(o, d)?;
        let (t0, t1) = (hit.t_near.max(t_min), hit.t_far.min(t_max));
        (t0 < t1).then_some((t0, t1))
    }

    /// Unit outward normal of the faces perpendicular to local `axis` (sign open).
    pub(crate) fn axis_world(&self, axis: usize) -> DVec3 {
        self.world_from_local.col(axis)
    }

    /// World point `x` in the box's local frame.
    pub(crate) fn local_point(&self, x: DVec3) -> DVec3 {
        self.local_from_world * (x - self.center)
    }
}

/// A convex polyhedron {x : n·x <= d for every plane}, from the scene's f32 planes
/// widened to f64 (the set does not depend on the normals' lengths, so the oracle sees
/// exactly the region the renderer's planes describe).
#[derive(Clone, Debug)]
pub(crate) struct ConvexF64 {
    planes: Vec<(DVec3, f64)>,
    /// The polyhedron's edges as vertex pairs (for the quadrature's hints).
    pub(crate) edges: Vec<(DVec3, DVec3)>,
}

impl ConvexF64 {
    pub(crate) fn from_scene(medium: &ConvexMedium) -> Self {
        let planes: Vec<(DVec3, f64)> = medium
            .planes
            .iter()
            .map(|p| {
                (
                    DVec3::new(p[0].into(), p[1].into(), p[2].into()),
                    p[3].into(),
                )
            })
            .collect();
        // Two vertices on the same two face planes bound an edge.
        let poly = &medium.polyhedron;
        let scale = poly
            .vertices
            .iter()
            .map(|v| v.abs().max_element())
            .fold(1e-30, f64::max);
        let on = |v: DVec3| -> Vec<usize> {
            poly.faces
                .iter()
                .copied()
                .filter(|&i| {
                    let (n, d) = poly.planes[i];
                    (n.dot(v) - d).abs() <= 1e-9 * scale
                })
                .collect()
        };
        let incident: Vec<Vec<usize>> = poly.vertices.iter().map(|v| on(*v)).collect();
        let mut edges = Vec::new();
        for a in 0..poly.vertices.len() {
            for b in a + 1..poly.vertices.len() {
                let shared = incident[a]
                    .iter()
                    .filter(|i| incident[b].contains(i))
                    .count();
                if shared >= 2 {
                    edges.push((poly.vertices[a], poly.vertices[b]));
                }
            }
        }
        Self { planes, edges }
    }

    /// The part of [t_min, t_max] where o + t·d is inside, if longer than zero: the
    /// ray clipped by every half-space in turn.
    pub(crate) fn clip(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = (t_min, t_max);
        for (n, offset) in &self.planes {
            let (num, denom) = (offset - n.dot(o), n.dot(d));
            if denom == 0.0 {
                if num < 0.0 {
                    return None;
                }
                continue;
            }
            let t = num / denom;
            if denom > 0.0 {
                t1 = t1.min(t);
            } else {
                t0 = t0.max(t);
            }
        }
        (t0 < t1).then_some((t0, t1))
    }
}

/// σt, albedo and g of a homogeneous (box or convex) medium; `None` for a grid.
pub(crate) fn homogeneous(medium: &Medium) -> Option<(f64, DVec3, f64)> {
    match medium {
        Medium::Box(m) => Some((m.sigma_t.into(), m.albedo.as_dvec3(), m.g.into())),
        Medium::Convex(m) => Some((m.sigma_t.into(), m.albedo.as_dvec3(), m.g.into())),
        Medium::Grid(_) => None,
    }
}

/// The region of a homogeneous medium: an oriented box or a convex polyhedron.
#[derive(Clone, Debug)]
pub(crate) enum Region {
    Box(OrientedBox),
    Convex(ConvexF64),
}

impl Region {
    /// The region of a box or convex medium; `None` for a grid.
    pub(crate) fn of(medium: &Medium) -> Option<Self> {
        match medium {
            Medium::Box(m) => Some(Self::Box(OrientedBox::from_scene(
                m.center,
                m.size,
                m.rotation_deg,
            ))),
            Medium::Convex(m) => Some(Self::Convex(ConvexF64::from_scene(m))),
            Medium::Grid(_) => None,
        }
    }

    /// The part of [t_min, t_max] where o + t·d is inside, if longer than zero.
    pub(crate) fn clip(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<(f64, f64)> {
        match self {
            Self::Box(b) => b.clip(o, d, t_min, t_max),
            Self::Convex(c) => c.clip(o, d, t_min, t_max),
        }
    }

    /// Length of o + t·d, t ∈ [t_min, t_max], inside the region.
    pub(crate) fn chord_length(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> f64 {
        self.clip(o, d, t_min, t_max)
            .map_or(0.0, |(t0, t1)| t1 - t0)
    }
}

/// The spans (t0, t1, index) of `media` along a ray, in order of entry (stable for
/// equal t0); `span` gives a medium's (t0, t1) on the ray, if any.
pub(crate) fn spans_by_entry<M>(
    media: &[M],
    span: impl Fn(&M) -> Option<(f64, f64)>,
) -> Vec<(f64, f64, usize)> {
    let mut spans: Vec<(f64, f64, usize)> = media
        .iter()
        .enumerate()
        .filter_map(|(i, m)| span(m).map(|(a, b)| (a, b, i)))
        .collect();
    spans.sort_by(|a, b| a.0.total_cmp(&b.0));
    spans
}

/// Nearest t > 0 where o + t·d (|d| = 1) meets the sphere's surface. Geometric
/// solution: closest approach along the ray, then the half chord.
pub(crate) fn hit_sphere(center: DVec3, radius: f64, o: DVec3, d: DVec3) -> Option<f64> {
    let to_center = center - o;
    let t_mid = to_center.dot(d);
    let closest_sq = (to_center - t_mid * d).length_squared();
    let half_chord_sq = radius * radius - closest_sq;
    if half_chord_sq < 0.0 {
        return None;
    }
    let half_chord = half_chord_sq.sqrt();
    if t_mid - half_chord > 0.0 {
        Some(t_mid - half_chord)
    } else if t_mid + half_chord > 0.0 {
        Some(t_mid + half_chord)
    } else {
        None
    }
}

/// A directional light's gobo in f64.
pub(crate) struct GoboF64 {
    origin: DVec3,
    u_axis: DVec3,
    v_axis: DVec3,
    /// Counter-clockwise convex polygon.
    polygon: Vec<DVec2>,
}

impl GoboF64 {
    /// The gobo `gobo` of a directional light travelling along `direction`.
    pub(crate) fn new(direction: Vec3, gobo: &Gobo) -> Self {
        let (u_axis, v_axis) = Gobo::basis(direction);
        Self {
            origin: gobo.origin.as_dvec3(),
            u_axis: u_axis.as_dvec3(),
            v_axis: v_axis.as_dvec3(),
            polygon: gobo.polygon.iter().map(|p| p.as_dvec2()).collect(),
        }
    }

    /// The polygon's edges (a, b), counter-clockwise.
    pub(crate) fn edges(&self) -> impl Iterator<Item = (DVec2, DVec2)> + '_ {
        let n = self.polygon.len();
        (0..n).map(move |i| (self.polygon[i], self.polygon[(i + 1) % n]))
    }

    /// Whether the beam through the polygon contains x (boundary included): x projects
    /// left of every edge.
    pub(crate) fn lets_through(&self, x: DVec3) -> bool {
        let rel = x - self.origin;
        let q = DVec2::new(rel.dot(self.u_axis), rel.dot(self.v_axis));
        self.edges().all(|(a, b)| (b - a).perp_dot(q - a) >= 0.0)
    }

    /// Gobo-plane point `p` in world space.
    pub(crate) fn to_world(&self, p: DVec2) -> DVec3 {
        self.origin + p.x * self.u_axis + p.y * self.v_axis
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f64_rotation_matches_the_scene_convention() {
        for deg in [
            Vec3::ZERO,
            Vec3::new(30.0, 0.0, 0.0),
            Vec3::new(0.0, -45.0, 0.0),
            Vec3::new(10.0, 20.0, 30.0),
            Vec3::new(-170.0, 95.0, 33.0),
        ] {
            let expected = nimbus_scene::rotation_xyz_deg(deg).as_dmat3();
            let actual = rotation_xyz_deg_f64(deg);
            assert!(
                actual.abs_diff_eq(expected, 1e-6),
                "{deg}: {actual} vs {expected}"
            );
        }
    }
}
