//! Splitting a polygon into a triangle fan, refusing polygons a fan would not cover
//! correctly (concave, non-planar, self-intersecting).

use glam::{DVec3, Vec3};

/// How far (as a fraction of the face's size, its bounding-box diagonal) a vertex of a face with more than 3
/// vertices may lie from the face's mean plane before the face is refused as
/// non-planar. Generous on purpose: quads from subdivision or sculpting are rarely
/// exactly planar, and fanning a slightly bent quad is what every renderer does.
pub const MAX_FACE_NONPLANARITY: f64 = 0.05;

/// Appends the fan (v0, vi, vi+1) of the face with vertex indices `corners` (all in
/// range of `positions`) to `out`, or says why the face cannot be fanned.
///
/// A face whose area is zero (all corners on a line, or repeated) is fanned anyway:
/// its triangles are degenerate and the loader drops and counts them.
pub(crate) fn fan(
    positions: &[Vec3],
    corners: &[u32],
    out: &mut Vec<[u32; 3]>,
) -> Result<(), String> {
    if corners.len() < 3 {
        return Err(format!(
            "a face needs at least 3 vertices, got {}",
            corners.len()
        ));
    }
    if corners.len() > 3 {
        check_fan(positions, corners)?;
    }
    let first = corners[0];
    for pair in corners[1..].windows(2) {
        out.push([first, pair[0], pair[1]]);
    }
    Ok(())
}

/// The checks on a face with more than 3 vertices, in f64.
fn check_fan(positions: &[Vec3], corners: &[u32]) -> Result<(), String> {
    let p: Vec<DVec3> = corners
        .iter()
        .map(|&i| {
            positions
                .get(i as usize)
                .map_or(DVec3::ZERO, |p| p.as_dvec3())
        })
        .collect();
    let n = p.len();
    let centroid = p.iter().sum::<DVec3>() / n as f64;
    // Newell's normal: twice the vector area, well defined for non-planar faces.
    let normal: DVec3 = (0..n)
        .map(|i| (p[i] - centroid).cross(p[(i + 1) % n] - centroid))
        .sum();
    // The bounding-box diagonal: within a factor sqrt(3) of the diameter, in O(n).
    let lo = p.iter().fold(DVec3::INFINITY, |m, q| m.min(*q));
    let hi = p.iter().fold(DVec3::NEG_INFINITY, |m, q| m.max(*q));
    let diameter = (hi - lo).length();
    let negligible = 1e-12 * diameter * diameter;
    if normal.length() <= negligible {
        // Zero net area: fine when every fan triangle is degenerate (all corners on a
        // line: dropped later), a bow tie whose lobes cancel otherwise.
        let flat = (1..n - 1).all(|i| (p[i] - p[0]).cross(p[i + 1] - p[0]).length() <= negligible);
        if flat {
            return Ok(());
        }
        return Err(
            "face outline crosses itself (its signed area is zero, its triangles' is not); triangulate it in the modelling tool"
                .to_string(),
        );
    }
    let axis = normal.normalize();

    // Non-planar: a vertex far from the plane through the centroid.
    for (k, q) in p.iter().enumerate() {
        let distance = (*q - centroid).dot(axis).abs();
        if distance > MAX_FACE_NONPLANARITY * diameter {
            return Err(format!(
                "face is not planar: its vertex {} (of {n}) lies {:.3} × the face's size off the face's plane (limit {MAX_FACE_NONPLANARITY}); triangulate it in the modelling tool",
                k + 1,
                distance / diameter
            ));
        }
    }

    // Concave: a corner turning against the normal. Self-intersecting: the turns add
    // up to more than one revolution.
    let mut turning = 0.0;
    for k in 0..n {
        let a = p[k] - p[(k + n - 1) % n];
        let b = p[(k + 1) % n] - p[k];
        let scale = a.length() * b.length();
        if scale == 0.0 {
            continue; // a repeated vertex: no turn
        }
        let sin = a.cross(b).dot(axis);
        let cos = a.dot(b);
        if sin < -1e-9 * scale {
            return Err(format!(
                "face is concave at its vertex {} (of {n}), so it cannot be split into a triangle fan; triangulate it in the modelling tool",
                k + 1
            ));
        }
        turning += sin.atan2(cos);
    }
    if turning > 3.0 * std::f64::consts::PI {
        return Err(format!(
            "face outline crosses itself (it turns {:.0}° in all, not 360°); triangulate it in the modelling tool",
            turning.to_degrees()
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fan_of(points: &[[f32; 3]]) -> Result<Vec<[u32; 3]>, String> {
        let positions: Vec<Vec3> = points.iter().map(|&p| Vec3::from(p)).collect();
        let corners: Vec<u32> = (0..points.len() as u32).collect();
        let mut out = Vec::new();
        fan(&positions, &corners, &mut out).map(|()| out)
    }

    #[test]
    fn convex_quad_and_pentagon_fan() {
        let quad = fan_of(&[[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]]);
        assert_eq!(quad, Ok(vec![[0, 1, 2], [0, 2, 3]]));
        let pentagon: Vec<[f32; 3]> = (0..5)
            .map(|k| {
                let a = k as f32 * std::f32::consts::TAU / 5.0;
                [a.cos(), 0.0, -a.sin()]
            })
            .collect();
        assert_eq!(fan_of(&pentagon).map(|t| t.len()), Ok(3));
    }

    #[test]
    fn clockwise_convex_quad_is_fine() {
        // The Newell normal follows the winding, so clockwise is convex too.
        assert!(fan_of(&[[0., 0., 0.], [0., 1., 0.], [1., 1., 0.], [1., 0., 0.]]).is_ok());
    }

    #[test]
    fn concave_quad_is_refused() {
        // An arrowhead: vertex 4 points inwards.
        let e = fan_of(&[[0., 0., 0.], [2., 0., 0.], [2., 2., 0.], [1., 0.5, 0.]]);
        let e = e.err().unwrap_or_default();
        assert!(e.contains("concave at its vertex 4"), "{e}");
    }

    #[test]
    fn non_planar_quad_is_refused_slightly_bent_is_not() {
        let e = fan_of(&[[0., 0., 0.], [1., 0., 0.], [1., 1., 0.5], [0., 1., 0.]]);
        assert!(e.err().unwrap_or_default().contains("not planar"));
        assert!(fan_of(&[[0., 0., 0.], [1., 0., 0.], [1., 1., 0.02], [0., 1., 0.]]).is_ok());
    }

    #[test]
    fn pentagram_is_refused() {
        let star: Vec<[f32; 3]> = (0..5)
            .map(|k| {
                let a = (2 * k) as f32 * std::f32::consts::TAU / 5.0;
                [a.cos(), a.sin(), 0.0]
            })
            .collect();
        let e = fan_of(&star).err().unwrap_or_default();
        assert!(e.contains("crosses itself"), "{e}");
    }

    #[test]
    fn bow_tie_is_refused() {
        let e = fan_of(&[[0., 0., 0.], [1., 1., 0.], [1., 0., 0.], [0., 1., 0.]]);
        assert!(e.err().unwrap_or_default().contains("crosses itself"));
    }

    #[test]
    fn collinear_corner_and_zero_area_faces_are_fanned() {
        // A square with an extra vertex in the middle of one edge.
        let t = fan_of(&[
            [0., 0., 0.],
            [1., 0., 0.],
            [2., 0., 0.],
            [2., 2., 0.],
            [0., 2., 0.],
        ]);
        assert_eq!(t.map(|t| t.len()), Ok(3));
        let line = fan_of(&[[0., 0., 0.], [1., 0., 0.], [2., 0., 0.], [3., 0., 0.]]);
        assert_eq!(line.map(|t| t.len()), Ok(2));
    }

    #[test]
    fn short_face_is_refused() {
        assert!(fan_of(&[[0., 0., 0.], [1., 0., 0.]]).is_err());
    }
}
