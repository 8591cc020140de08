//! Convex polyhedra given as intersections of half-spaces (`[[medium]] type =
//! "convex"`), computed in f64: validation (bounded, non-empty interior), vertices,
//! faces, edge directions and width, and the separating-axis test between convex
//! solids that keeps media from overlapping.
//!
//! A polyhedron is `{x : n_i·x <= d_i}` for unit normals n_i. Its vertices are found by
//! intersecting every triple of planes, together with the six faces of a cube of
//! half-size L far beyond the input ([`ConvexPolyhedron::new`]), and keeping the points
//! inside every half-space: a vertex on the cube means the half-spaces leave the region
//! open (or larger than L). The polyhedron is the convex hull of its vertices.

use glam::DVec3;

/// Fewest planes of a convex medium (a tetrahedron).
pub const MIN_CONVEX_PLANES: usize = 4;
/// Most planes of a convex medium (the crepuscular pass walks them per light ray).
pub const MAX_CONVEX_PLANES: usize = 64;

/// A bounded convex polyhedron with a non-empty interior.
#[derive(Clone, Debug, PartialEq)]
pub struct ConvexPolyhedron {
    /// (n, d) with |n| = 1: the half-space n·x <= d, in input order.
    pub planes: Vec<(DVec3, f64)>,
    /// Distinct vertices.
    pub vertices: Vec<DVec3>,
    /// Indices into `planes` of the planes that carry a face (three or more vertices).
    pub faces: Vec<usize>,
    /// Unit directions of the edges (one per pair of faces sharing two vertices).
    pub edges: Vec<DVec3>,
}

impl ConvexPolyhedron {
    /// The polyhedron `planes` = [nx, ny, nz, d] (n·x <= d; n need not be unit and is
    /// normalized here with d scaled alike), or why it is not one: a zero normal, an
    /// unbounded or empty region, or one without interior. Plane indices in messages
    /// count from 0.
    pub fn new(planes: &[[f64; 4]]) -> Result<Self, String> {
        let mut unit = Vec::with_capacity(planes.len());
        for (i, p) in planes.iter().enumerate() {
            let n = DVec3::new(p[0], p[1], p[2]);
            let length = n.length();
            if length.is_nan() || length <= 0.0 || !length.is_finite() {
                return Err(format!(
                    "plane {i}: the normal [{}, {}, {}] has no direction",
                    p[0], p[1], p[2]
                ));
            }
            unit.push((n / length, p[3] / length));
        }
        let scale = unit.iter().map(|(_, d)| d.abs()).fold(0.0, f64::max);
        // Cut the region with a cube far beyond every plane; touching it means open.
        let far = 1e3 * scale.max(1.0) + 1e8;
        let mut all = unit.clone();
        for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
            all.push((axis, far));
            all.push((-axis, far));
        }
        let tolerance = |v: DVec3| 1e-12 * (scale + v.abs().max_element()).max(1e-30);

        // Intersect every triple of planes and keep the points inside all half-spaces.
        let mut vertices: Vec<DVec3> = Vec::new();
        let count = all.len();
        for i in 0..count {
            for j in i + 1..count {
                let nij = all[i].0.cross(all[j].0);
                for k in j + 1..count {
                    let det = nij.dot(all[k].0);
                    if det.abs() < 1e-12 {
                        continue;
                    }
                    let (ni, di) = all[i];
                    let (nj, dj) = all[j];
                    let (nk, dk) = all[k];
                    let v = (di * nj.cross(nk) + dj * nk.cross(ni) + dk * nij) / det;
                    if !v.is_finite() {
                        continue;
                    }
                    let tol = tolerance(v);
                    if all.iter().all(|(n, d)| n.dot(v) <= d + tol)
                        && !vertices.iter().any(|w| (*w - v).abs().max_element() <= tol)
                    {
                        vertices.push(v);
                    }
                }
            }
        }
        if vertices
            .iter()
            .any(|v| v.abs().max_element() >= far - tolerance(*v))
        {
            return Err(
                "the half-spaces do not enclose a bounded region (it reaches infinity)".into(),
            );
        }
        if vertices.len() < 4 {
            return Err("the half-spaces have no common interior (the region is empty)".into());
        }

        // A region without interior has its vertex centroid on some plane.
        let centroid = vertices.iter().sum::<DVec3>() / vertices.len() as f64;
        let extent = vertices
            .iter()
            .map(|v| (*v - centroid).abs().max_element())
            .fold(0.0, f64::max);
        let inside = unit
            .iter()
            .map(|(n, d)| d - n.dot(centroid))
            .fold(f64::INFINITY, f64::min);
        if inside.is_nan() || inside <= 1e-12 * (extent + centroid.abs().max_element()) {
            return Err("the half-spaces have no common interior (the region is flat)".into());
        }

        // Faces carry three or more vertices; edges join two faces at two vertices.
        let on = |plane: usize, v: DVec3| {
            let (n, d) = unit[plane];
            (n.dot(v) - d).abs() <= tolerance(v) * 10.0
        };
        let faces: Vec<usize> = (0..unit.len())
            .filter(|&i| vertices.iter().filter(|v| on(i, **v)).count() >= 3)
            .collect();
        let mut edges = Vec::new();
        for (a, &i) in faces.iter().enumerate() {
            for &j in &faces[a + 1..] {
                let shared = vertices.iter().filter(|v| on(i, **v) && on(j, **v)).count();
                let direction = unit[i].0.cross(unit[j].0);
                if shared >= 2 && direction.length() > 1e-9 {
                    edges.push(direction.normalize());
                }
            }
        }
        Ok(Self {
            planes: unit,
            vertices,
            faces,
            edges,
        })
    }

    /// The smallest distance from a face's plane to the farthest vertex: the
    /// polyhedron's width across its faces (the thickness of a sliver).
    pub fn width(&self) -> f64 {
        self.faces
            .iter()
            .map(|&i| {
                let (n, d) = self.planes[i];
                self.vertices
                    .iter()
                    .map(|v| d - n.dot(*v))
                    .fold(0.0, f64::max)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// The mean of the vertices, a point inside.
    pub fn centroid(&self) -> DVec3 {
        self.vertices.iter().sum::<DVec3>() / self.vertices.len() as f64
    }

    /// The axis-aligned bounding box of the vertices (min, max).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.vertices.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), v| (lo.min(*v), hi.max(*v)),
        )
    }
}

/// A convex solid as the separating-axis test needs it: vertices, face normals and
/// edge directions.
#[derive(Clone, Debug)]
pub struct Solid {
    pub vertices: Vec<DVec3>,
    pub normals: Vec<DVec3>,
    pub edges: Vec<DVec3>,
}

impl From<&ConvexPolyhedron> for Solid {
    fn from(p: &ConvexPolyhedron) -> Self {
        Self {
            vertices: p.vertices.clone(),
            normals: p.faces.iter().map(|&i| p.planes[i].0).collect(),
            edges: p.edges.clone(),
        }
    }
}

impl Solid {
    /// Whether the two solids share a volume: they overlap by more than 1e-6 times the
    /// scene scale (the largest vertex coordinate) along every face normal of either
    /// and every cross product of their edge directions. Solids touching at a face,
    /// edge or corner do not overlap.
    pub fn overlaps(&self, other: &Self) -> bool {
        let scale = self
            .vertices
            .iter()
            .chain(&other.vertices)
            .map(|v| v.abs().max_element())
            .fold(0.0, f64::max);
        let tolerance = 1e-6 * scale;
        let mut axes: Vec<DVec3> = self.normals.iter().chain(&other.normals).copied().collect();
        for a in &self.edges {
            for b in &other.edges {
                axes.push(a.cross(*b));
            }
        }
        let project = |vertices: &[DVec3], axis: DVec3| {
            vertices
                .iter()
                .map(|v| v.dot(axis))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                    (lo.min(x), hi.max(x))
                })
        };
        for axis in axes {
            // Cross products of (nearly) parallel edges give no new axis.
            let length = axis.length();
            if length < 1e-6 {
                continue;
            }
            let axis = axis / length;
            let (a_lo, a_hi) = project(&self.vertices, axis);
            let (b_lo, b_hi) = project(&other.vertices, axis);
            if a_hi.min(b_hi) - a_lo.max(b_lo) <= tolerance {
                return false;
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(h: f64) -> Vec<[f64; 4]> {
        vec![
            [1.0, 0.0, 0.0, h],
            [-1.0, 0.0, 0.0, h],
            [0.0, 1.0, 0.0, h],
            [0.0, -1.0, 0.0, h],
            [0.0, 0.0, 1.0, h],
            [0.0, 0.0, -1.0, h],
        ]
    }

    #[test]
    fn a_cube_has_eight_vertices_six_faces_and_three_edge_directions() {
        let p = ConvexPolyhedron::new(&cube(0.5)).unwrap();
        assert_eq!(p.vertices.len(), 8);
        assert_eq!(p.faces.len(), 6);
        assert_eq!(p.edges.len(), 12);
        assert!((p.width() - 1.0).abs() < 1e-12);
        assert!(p.centroid().length() < 1e-12);
    }

    #[test]
    fn normals_are_normalized_with_their_offsets() {
        let mut planes = cube(0.5);
        planes[0] = [4.0, 0.0, 0.0, 2.0];
        let p = ConvexPolyhedron::new(&planes).unwrap();
        assert_eq!(p.planes[0], (DVec3::X, 0.5));
    }

    #[test]
    fn open_empty_and_flat_regions_are_refused() {
        let mut open = cube(1.0);
        open.pop();
        assert!(ConvexPolyhedron::new(&open)
            .unwrap_err()
            .contains("bounded"));
        let mut empty = cube(1.0);
        empty[1] = [-1.0, 0.0, 0.0, -2.0];
        assert!(ConvexPolyhedron::new(&empty).unwrap_err().contains("empty"));
        let mut flat = cube(1.0);
        flat[0] = [1.0, 0.0, 0.0, 0.0];
        flat[1] = [-1.0, 0.0, 0.0, 0.0];
        assert!(ConvexPolyhedron::new(&flat)
            .unwrap_err()
            .contains("interior"));
        let mut zero = cube(1.0);
        zero[2] = [0.0, 0.0, 0.0, 1.0];
        assert!(ConvexPolyhedron::new(&zero)
            .unwrap_err()
            .contains("plane 2"));
    }

    #[test]
    fn a_redundant_plane_is_no_face() {
        let mut planes = cube(1.0);
        planes.push([1.0, 1.0, 1.0, 10.0]);
        let p = ConvexPolyhedron::new(&planes).unwrap();
        assert_eq!(p.faces.len(), 6);
        assert_eq!(p.vertices.len(), 8);
    }

    #[test]
    fn solids_touching_at_a_face_do_not_overlap() {
        let a = ConvexPolyhedron::new(&cube(0.5)).unwrap();
        let shifted = |dx: f64| {
            let planes: Vec<[f64; 4]> = cube(0.5)
                .into_iter()
                .map(|[x, y, z, d]| [x, y, z, d + x * dx])
                .collect();
            Solid::from(&ConvexPolyhedron::new(&planes).unwrap())
        };
        let a = Solid::from(&a);
        assert!(!a.overlaps(&shifted(1.0)));
        assert!(a.overlaps(&shifted(0.9)));
        assert!(!a.overlaps(&shifted(1.5)));
    }

    #[test]
    fn an_octahedron_face_separates_it_from_a_cube_corner() {
        // The octahedron |x| + |y| + |z| <= 1 moved along (1, 1, 1) by t: its face
        // x + y + z >= 3t - 1 meets the cube's corner (x + y + z = 1.5) at t = 5/6.
        let octahedron: Vec<[f64; 4]> = (0..8)
            .map(|i| {
                let s = |b: i32| if i & b != 0 { -1.0 } else { 1.0 };
                [s(1), s(2), s(4), 1.0]
            })
            .collect();
        let p = ConvexPolyhedron::new(&octahedron).unwrap();
        assert_eq!(p.vertices.len(), 6);
        assert_eq!(p.faces.len(), 8);
        assert!((p.width() - 2.0 / 3f64.sqrt()).abs() < 1e-12);
        let moved = |t: f64| {
            let planes: Vec<[f64; 4]> = octahedron
                .iter()
                .map(|[x, y, z, d]| [*x, *y, *z, d + t * (x + y + z)])
                .collect();
            Solid::from(&ConvexPolyhedron::new(&planes).unwrap())
        };
        let cube = Solid::from(&ConvexPolyhedron::new(&cube(0.5)).unwrap());
        assert!(cube.overlaps(&moved(5.0 / 6.0 - 0.01)));
        assert!(!cube.overlaps(&moved(5.0 / 6.0)));
        assert!(!cube.overlaps(&moved(5.0 / 6.0 + 0.01)));
    }
}
