//! Geometric checks used by validation: convex gobo polygons and medium overlap
//! (separating-axis test on oriented boxes, see [`crate::convex::Solid`]), computed in f64.

use glam::{DMat3, DVec2, DVec3};

use crate::convex::Solid;

/// Most vertices a gobo polygon may have.
pub const MAX_GOBO_POINTS: usize = 64;

/// Checks that `points` form a convex polygon with positive area and returns them
/// counter-clockwise (reversed when given clockwise). Consecutive collinear points are
/// allowed; repeated consecutive points are not.
pub fn convex_ccw_polygon(points: &[DVec2]) -> Result<Vec<DVec2>, String> {
    let n = points.len();
    if n < 3 {
        return Err(format!("needs at least 3 points, found {n}"));
    }
    if n > MAX_GOBO_POINTS {
        return Err(format!(
            "at most {MAX_GOBO_POINTS} points are supported, found {n}"
        ));
    }
    // Scale for relative tolerances: the bounding box's larger side.
    let (lo, hi) = points.iter().fold((points[0], points[0]), |(lo, hi), p| {
        (lo.min(*p), hi.max(*p))
    });
    let scale = (hi - lo).max_element();
    if scale <= 0.0 {
        return Err("has zero area (all points coincide)".into());
    }
    for i in 0..n {
        let (a, b) = (points[i], points[(i + 1) % n]);
        if (b - a).length() <= 1e-9 * scale {
            return Err(format!(
                "points {i} and {} coincide, polygon must not repeat a point",
                (i + 1) % n
            ));
        }
    }
    // Shoelace signed area: positive when counter-clockwise.
    let twice_area: f64 = (0..n)
        .map(|i| points[i].perp_dot(points[(i + 1) % n]))
        .sum();
    if twice_area.abs() <= 1e-9 * scale * scale {
        return Err("has zero area".into());
    }
    let mut ccw = points.to_vec();
    if twice_area < 0.0 {
        ccw.reverse();
    }
    // Convex and counter-clockwise: every vertex lies left of (or on) every edge.
    for i in 0..n {
        let (a, b) = (ccw[i], ccw[(i + 1) % n]);
        let edge = b - a;
        for p in &ccw {
            if edge.perp_dot(*p - a) < -1e-9 * edge.length() * scale {
                return Err("is not convex (or its edges cross)".into());
            }
        }
    }
    // A convex polygon turns through exactly one full circle; more means it winds
    // around its interior several times.
    let turning: f64 = (0..n)
        .map(|i| {
            let e0 = ccw[(i + 1) % n] - ccw[i];
            let e1 = ccw[(i + 2) % n] - ccw[(i + 1) % n];
            e0.perp_dot(e1).atan2(e0.dot(e1))
        })
        .sum();
    if (turning - std::f64::consts::TAU).abs() > 1e-6 {
        return Err("is not a simple convex polygon (it winds more than once)".into());
    }
    Ok(ccw)
}

/// Rotation about X, then Y, then Z by `rotation_deg` in f64 (the convention of
/// [`crate::rotation_xyz_deg`]).
pub fn rotation_xyz_deg_f64(rotation_deg: DVec3) -> DMat3 {
    let r = rotation_deg * (std::f64::consts::PI / 180.0);
    DMat3::from_rotation_z(r.z) * DMat3::from_rotation_y(r.y) * DMat3::from_rotation_x(r.x)
}

/// An oriented box: `axes` are unit and orthogonal, `half` the half extents along them.
#[derive(Clone, Copy, Debug)]
pub struct OrientedBox {
    pub center: DVec3,
    pub axes: [DVec3; 3],
    pub half: DVec3,
}

impl OrientedBox {
    /// A box of full extents `size` rotated by `rotation_deg` (X, then Y, then Z).
    pub fn new(center: DVec3, size: DVec3, rotation_deg: DVec3) -> Self {
        let rotation = rotation_xyz_deg_f64(rotation_deg);
        Self {
            center,
            axes: [rotation.x_axis, rotation.y_axis, rotation.z_axis],
            half: size * 0.5,
        }
    }

    /// The axis-aligned box `min .. max`.
    pub fn aabb(min: DVec3, max: DVec3) -> Self {
        Self {
            center: (min + max) * 0.5,
            axes: [DVec3::X, DVec3::Y, DVec3::Z],
            half: (max - min) * 0.5,
        }
    }

    /// Whether the two boxes share a volume (see [`Solid::overlaps`]): boxes touching
    /// at a face, edge or corner do not overlap.
    #[cfg(test)]
    pub fn overlaps(&self, other: &Self) -> bool {
        Solid::from(self).overlaps(&Solid::from(other))
    }
}

impl From<&OrientedBox> for Solid {
    fn from(b: &OrientedBox) -> Self {
        let vertices = (0..8)
            .map(|corner| {
                (0..3).fold(b.center, |v, i| {
                    let sign = if corner & (1 << i) != 0 { 1.0 } else { -1.0 };
                    v + sign * b.half[i] * b.axes[i]
                })
            })
            .collect();
        Self {
            vertices,
            normals: b.axes.to_vec(),
            edges: b.axes.to_vec(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn poly(points: &[[f64; 2]]) -> Vec<DVec2> {
        points.iter().map(|p| DVec2::from_array(*p)).collect()
    }

    #[test]
    fn square_is_accepted_and_clockwise_is_reversed() {
        let ccw = poly(&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
        assert_eq!(convex_ccw_polygon(&ccw).unwrap(), ccw);
        let cw: Vec<DVec2> = ccw.iter().rev().copied().collect();
        assert_eq!(convex_ccw_polygon(&cw).unwrap(), ccw);
    }

    #[test]
    fn collinear_points_are_allowed() {
        let p = poly(&[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]]);
        assert!(convex_ccw_polygon(&p).is_ok());
    }

    #[test]
    fn degenerate_and_non_convex_polygons_are_rejected() {
        let line = poly(&[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]);
        assert!(convex_ccw_polygon(&line).unwrap_err().contains("zero area"));
        let dart = poly(&[[0.0, 0.0], [2.0, 1.0], [0.0, 2.0], [0.5, 1.0]]);
        assert!(convex_ccw_polygon(&dart).unwrap_err().contains("convex"));
        let bowtie = poly(&[[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]);
        assert!(convex_ccw_polygon(&bowtie).is_err());
        let repeated = poly(&[[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
        assert!(convex_ccw_polygon(&repeated)
            .unwrap_err()
            .contains("coincide"));
        let twice = poly(&[
            [0.0, 0.0],
            [1.0, 0.0],
            [0.0, 1.0],
            [0.0, 0.0],
            [1.0, 0.0],
            [0.0, 1.0],
        ]);
        assert!(convex_ccw_polygon(&twice).is_err());
        let pentagram: Vec<DVec2> = (0..5)
            .map(|i| {
                let angle = (i * 2) as f64 * std::f64::consts::TAU / 5.0;
                DVec2::new(angle.cos(), angle.sin())
            })
            .collect();
        assert!(convex_ccw_polygon(&pentagram).is_err());
    }

    #[test]
    fn sat_handles_touching_separated_and_rotated_boxes() {
        let unit = |c: [f64; 3], r: [f64; 3]| {
            OrientedBox::new(DVec3::from_array(c), DVec3::ONE, DVec3::from_array(r))
        };
        let a = unit([0.0; 3], [0.0; 3]);
        assert!(a.overlaps(&unit([0.5, 0.0, 0.0], [0.0; 3])));
        assert!(!a.overlaps(&unit([1.0, 0.0, 0.0], [0.0; 3])));
        assert!(!a.overlaps(&unit([1.0, 1.0, 1.0], [0.0; 3])));
        // A 45° box reaches sqrt(0.5) along X: overlaps at 1.2, not at 1.25.
        assert!(a.overlaps(&unit([1.2, 0.0, 0.0], [0.0, 0.0, 45.0])));
        assert!(!a.overlaps(&unit([1.25, 0.0, 0.0], [0.0, 0.0, 45.0])));
        // Two boxes rotated alike and touching along their shared rotated face.
        let rotation = [10.0, 20.0, 30.0];
        let offset = rotation_xyz_deg_f64(DVec3::from_array(rotation)) * DVec3::X;
        let b = unit([0.0; 3], rotation);
        let touching = unit(offset.to_array(), rotation);
        assert!(!b.overlaps(&touching));
        let overlapping = unit((offset * 0.99).to_array(), rotation);
        assert!(b.overlaps(&overlapping));
    }

    #[test]
    fn f64_rotation_matches_the_public_convention() {
        let angles = DVec3::new(12.0, -70.0, 135.0);
        let exact = rotation_xyz_deg_f64(angles);
        let single = crate::rotation_xyz_deg(angles.as_vec3()).as_dmat3();
        assert!((exact - single)
            .abs()
            .to_cols_array()
            .iter()
            .all(|e| *e < 1e-6));
    }

    #[test]
    fn sat_needs_edge_cross_axes() {
        // Cube A has an edge along X on top, cube B one along Z below: only their
        // cross product (Y) separates them, no face axis does.
        let a = OrientedBox::new(DVec3::ZERO, DVec3::ONE, DVec3::new(45.0, 0.0, 0.0));
        let above = |dy: f64| {
            let center = DVec3::new(0.0, std::f64::consts::SQRT_2 + dy, 0.0);
            OrientedBox::new(center, DVec3::ONE, DVec3::new(0.0, 0.0, 45.0))
        };
        assert!(!a.overlaps(&above(0.01)));
        assert!(!a.overlaps(&above(0.0)));
        assert!(a.overlaps(&above(-0.01)));
    }
}
