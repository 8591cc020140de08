//! Hints for the quadrature: where a camera ray crosses a plane or cylinder swept along
//! the light's travel direction ω by an edge of a box, quad, gobo or sphere silhouette,
//! which is where V_ω and T_ω may jump or kink. They only help the adaptive scheme;
//! correctness does not depend on them.

use glam::DVec3;

use crate::common::geometry::{GoboF64, OrientedBox, Region};

/// Pushes the t where o + t·d crosses the plane through `point` with normal `normal`
/// (skipped when the normal vanishes or the ray is parallel to the plane).
pub(super) fn push_plane_crossing(
    o: DVec3,
    d: DVec3,
    point: DVec3,
    normal: DVec3,
    cuts: &mut Vec<f64>,
) {
    let denom = d.dot(normal);
    if normal.length_squared() > 0.0 && denom.abs() > 1e-12 * normal.length() {
        let t = (point - o).dot(normal) / denom;
        if t.is_finite() {
            cuts.push(t);
        }
    }
}

/// Pushes the t where o + t·d crosses each plane that contains ω and one of the box's
/// 12 edges.
pub(super) fn push_box_edge_crossings(
    bounds: &OrientedBox,
    o: DVec3,
    d: DVec3,
    omega: DVec3,
    cuts: &mut Vec<f64>,
) {
    for axis in 0..3 {
        let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
        let edge = bounds.axis_world(axis);
        for (s1, s2) in [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)] {
            let point = bounds.center
                + s1 * bounds.half[a1] * bounds.axis_world(a1)
                + s2 * bounds.half[a2] * bounds.axis_world(a2);
            push_plane_crossing(o, d, point, edge.cross(omega), cuts);
        }
    }
}

/// Pushes the t where o + t·d crosses each plane that contains ω and an edge of the
/// medium's region (a box's 12, a convex polyhedron's).
pub(super) fn push_region_edge_crossings(
    region: &Region,
    o: DVec3,
    d: DVec3,
    omega: DVec3,
    cuts: &mut Vec<f64>,
) {
    match region {
        Region::Box(bounds) => push_box_edge_crossings(bounds, o, d, omega, cuts),
        Region::Convex(convex) => {
            for (a, b) in &convex.edges {
                push_plane_crossing(o, d, *a, (*b - *a).cross(omega), cuts);
            }
        }
    }
}

/// Pushes the t where o + t·d crosses the planes swept along ω by the gobo's edges.
pub(super) fn push_gobo_crossings(
    gobo: &GoboF64,
    o: DVec3,
    d: DVec3,
    omega: DVec3,
    cuts: &mut Vec<f64>,
) {
    for (a, b) in gobo.edges() {
        let edge = gobo.to_world(b) - gobo.to_world(a);
        push_plane_crossing(o, d, gobo.to_world(a), edge.cross(omega), cuts);
    }
}
