//! Emitting shapes (area lights) of the grid oracle: one next-event sample per vertex
//! for all of them together.
//!
//! Its own sampling, not the renderer's: the emitting surfaces are cut into pieces (a
//! quad is one parallelogram, a box its six faces, a mesh its triangles, a sphere
//! itself), a piece is chosen in proportion to its power π·area·luminance(Le) (a
//! sphere's whole area) by bisection in their CDF, and a point uniformly in area on it:
//! (a, b) uniform in the unit square on a parallelogram, folded into the triangle
//! (a + b > 1 → 1 − a, 1 − b) on a triangle, a uniform direction from the centre on a
//! sphere (the far half then contributes nothing). The weight is
//! Le·max(0, cos_l)/d² / (P(piece)·1/area).

use std::f64::consts::PI;

use glam::DVec3;
use nimbus_scene::{Scene, Shape};

use crate::common::geometry::rotation_xyz_deg_f64;
use crate::common::rng::Rng;
use crate::common::sampling::sample_sphere;

/// One emitting piece of a shape, with its unit emitting normal where it is constant.
enum Piece {
    /// corner + a·u + b·v, a, b ∈ [0, 1], emitting towards `normal`.
    Parallelogram {
        corner: DVec3,
        u: DVec3,
        v: DVec3,
        normal: DVec3,
    },
    /// A mesh triangle, emitting towards (p1 − p0) × (p2 − p0).
    Triangle { p: [DVec3; 3], normal: DVec3 },
    /// A sphere, emitting outwards.
    Sphere { center: DVec3, radius: f64 },
}

/// The scene's emitting shapes as one light.
pub(super) struct AreaLights {
    pieces: Vec<(Piece, f64, DVec3)>,
    /// Inclusive power CDF over `pieces`, normalised.
    cdf: Vec<f64>,
}

/// A point on an emitting surface sampled from x.
pub(super) struct AreaSample {
    pub(super) l: DVec3,
    pub(super) distance: f64,
    pub(super) weight: DVec3,
}

fn luminance(c: DVec3) -> f64 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

impl AreaLights {
    /// The emitting shapes of `scene`, or None if none emits.
    pub(super) fn new(scene: &Scene) -> Option<AreaLights> {
        let mut pieces = Vec::new();
        for shape in &scene.shapes {
            let le = shape.emission().as_dvec3();
            if luminance(le) <= 0.0 {
                continue;
            }
            let mut add = |piece: Piece| {
                let area = match &piece {
                    Piece::Parallelogram { u, v, .. } => u.cross(*v).length(),
                    Piece::Triangle { p, .. } => 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length(),
                    Piece::Sphere { radius, .. } => 4.0 * PI * radius * radius,
                };
                if area > 0.0 {
                    pieces.push((piece, area, le));
                }
            };
            match shape {
                Shape::Quad {
                    corner,
                    edge_u,
                    edge_v,
                    ..
                } => {
                    let (u, v) = (edge_u.as_dvec3(), edge_v.as_dvec3());
                    add(Piece::Parallelogram {
                        corner: corner.as_dvec3(),
                        u,
                        v,
                        normal: u.cross(v).normalize(),
                    });
                }
                Shape::Box {
                    center,
                    size,
                    rotation_deg,
                    ..
                } => {
                    let r = rotation_xyz_deg_f64(*rotation_deg);
                    let half = 0.5 * size.as_dvec3();
                    for axis in 0..3 {
                        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
                        let (u, v) = (2.0 * half[b] * r.col(b), 2.0 * half[c] * r.col(c));
                        for sign in [-1.0, 1.0] {
                            let out = sign * r.col(axis);
                            let face = center.as_dvec3() + half[axis] * out;
                            add(Piece::Parallelogram {
                                corner: face - 0.5 * u - 0.5 * v,
                                u,
                                v,
                                normal: out,
                            });
                        }
                    }
                }
                Shape::Sphere { center, radius, .. } => add(Piece::Sphere {
                    center: center.as_dvec3(),
                    radius: f64::from(*radius),
                }),
                Shape::Mesh { mesh, .. } => {
                    for i in 0..mesh.triangle_count() {
                        let Some(p) = mesh.mesh.triangle(i) else {
                            continue;
                        };
                        let p = p.map(|q| q.as_dvec3());
                        let n = (p[1] - p[0]).cross(p[2] - p[0]);
                        if n.length() > 0.0 {
                            add(Piece::Triangle {
                                p,
                                normal: n.normalize(),
                            });
                        }
                    }
                }
            }
        }
        let total: f64 = pieces
            .iter()
            .map(|(_, area, le)| PI * area * luminance(*le))
            .sum();
        if pieces.is_empty() || total <= 0.0 {
            return None;
        }
        let mut sum = 0.0;
        let cdf = pieces
            .iter()
            .map(|(_, area, le)| {
                sum += PI * area * luminance(*le);
                sum / total
            })
            .collect();
        Some(AreaLights { pieces, cdf })
    }

    /// One sample from x: direction, distance and weight Le·cos_l/d² / pdf; None when
    /// the point faces away from x.
    pub(super) fn sample(&self, x: DVec3, rng: &mut Rng) -> Option<AreaSample> {
        let u = rng.uniform();
        let i = self
            .cdf
            .partition_point(|c| *c <= u)
            .min(self.cdf.len() - 1);
        let p_piece = self.cdf[i] - if i == 0 { 0.0 } else { self.cdf[i - 1] };
        if p_piece <= 0.0 {
            return None;
        }
        let (piece, area, le) = &self.pieces[i];
        let (a, b) = (rng.uniform(), rng.uniform());
        let (point, normal) = match piece {
            Piece::Parallelogram {
                corner,
                u,
                v,
                normal,
            } => (*corner + a * *u + b * *v, *normal),
            Piece::Triangle { p, normal } => {
                let (a, b) = if a + b > 1.0 {
                    (1.0 - a, 1.0 - b)
                } else {
                    (a, b)
                };
                (p[0] + a * (p[1] - p[0]) + b * (p[2] - p[0]), *normal)
            }
            Piece::Sphere { center, radius } => {
                let n = sample_sphere(rng);
                (*center + *radius * n, n)
            }
        };
        let to = point - x;
        let d2 = to.length_squared();
        if d2 <= 0.0 {
            return None;
        }
        let distance = d2.sqrt();
        let l = to / distance;
        let cos_l = -normal.dot(l);
        if cos_l <= 0.0 {
            return None;
        }
        Some(AreaSample {
            l,
            distance,
            weight: *le * (cos_l / d2 * area / p_piece),
        })
    }
}
