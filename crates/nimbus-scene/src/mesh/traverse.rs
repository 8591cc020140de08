//! Rays against triangles: the watertight ray–triangle test (Woop, Benthin and Wald
//! 2013, as in pbrt-v4), a conservative ray–box test, BVH traversal and the
//! brute-force references.

use glam::Vec3;

use super::bvh::{Bvh, BVH_STACK_SIZE};
use super::{max_axis, TriangleMesh};

/// A ray `origin + t · dir` for t > 0. `dir` need not be normalized (t is in units of
/// its length); a zero or non-finite `dir` hits nothing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
}

/// A ray–triangle hit: distance `t` along the ray, the triangle's index in the
/// [`TriangleMesh`] the BVH was built from, and barycentrics: the point is
/// `(1 − u − v) · p0 + u · p1 + v · p2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub triangle: u32,
    pub u: f32,
    pub v: f32,
}

/// pbrt's γ(n) = nε / (1 − nε) for f32, with ε the unit roundoff 2^-24.
fn gamma(n: f32) -> f32 {
    let eps = f32::EPSILON * 0.5;
    n * eps / (1.0 - n * eps)
}

/// The watertight ray–triangle test. Returns (t, u, v) when the ray hits the triangle
/// `p` at 0 < t < `t_max` (with t conservatively > 0: pbrt's error bound), else
/// `None`.
///
/// Epsilon policy: none. Vertices are translated to the ray origin and sheared so the
/// ray is +z (f32, as a GPU would); the three edge functions are then evaluated in
/// f64, where the products of f32 values are exact, so an edge shared by two
/// triangles gets exactly opposite values in both and a ray through the edge or a
/// vertex hits at least one of them (no cracks), and a ray exactly on an edge
/// counts for both. Degenerate triangles (zero area) are never hit. Hits on either
/// side count (no back-face culling).
pub fn intersect_triangle(ray: &Ray, p: [Vec3; 3], t_max: f32) -> Option<(f32, f32, f32)> {
    TriangleRay::new(ray)?.intersect(p, t_max)
}

/// A ray prepared for the watertight test: the axis permutation and the shear,
/// computed once per ray.
pub(crate) struct TriangleRay {
    origin: Vec3,
    /// Axes that become x, y, z (z: the largest |dir| component).
    k: [usize; 3],
    /// Shear: x += sx·z, y += sy·z, z *= sz.
    sx: f32,
    sy: f32,
    sz: f32,
}

impl TriangleRay {
    /// `None` for a zero or non-finite direction or a non-finite origin.
    pub fn new(ray: &Ray) -> Option<Self> {
        let d = ray.dir;
        if !d.is_finite() || d == Vec3::ZERO || !ray.origin.is_finite() {
            return None;
        }
        // Permute so z is the largest |dir| axis, then shear the ray onto +z.
        let kz = max_axis(d.abs());
        let kx = (kz + 1) % 3;
        let ky = (kx + 1) % 3;
        let d = d.to_array();
        let (dx, dy, dz) = (d[kx], d[ky], d[kz]);
        Some(Self {
            origin: ray.origin,
            k: [kx, ky, kz],
            sx: -dx / dz,
            sy: -dy / dz,
            sz: 1.0 / dz,
        })
    }

    /// See [`intersect_triangle`].
    pub fn intersect(&self, p: [Vec3; 3], t_max: f32) -> Option<(f32, f32, f32)> {
        // Translate to the ray origin, permute, shear x and y (f32, as a GPU would).
        let [kx, ky, kz] = self.k;
        let sheared = |q: Vec3| {
            let q = (q - self.origin).to_array();
            let z = q[kz];
            (q[kx] + self.sx * z, q[ky] + self.sy * z, z)
        };
        let (x0, y0, z0) = sheared(p[0]);
        let (x1, y1, z1) = sheared(p[1]);
        let (x2, y2, z2) = sheared(p[2]);
        // Edge functions in f64 (exact products, one rounding each).
        let edge = |ax: f32, ay: f32, bx: f32, by: f32| {
            f64::from(ax) * f64::from(by) - f64::from(ay) * f64::from(bx)
        };
        let e0 = edge(x1, y1, x2, y2);
        let e1 = edge(x2, y2, x0, y0);
        let e2 = edge(x0, y0, x1, y1);
        if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
            return None;
        }
        let det = e0 + e1 + e2;
        if det == 0.0 {
            return None;
        }
        // Scaled distance, compared with the range before the division.
        let sz = f64::from(self.sz);
        let (z0, z1, z2) = (f64::from(z0) * sz, f64::from(z1) * sz, f64::from(z2) * sz);
        let t_scaled = e0 * z0 + e1 * z1 + e2 * z2;
        let t_max = f64::from(t_max);
        if det < 0.0 && (t_scaled >= 0.0 || t_scaled < t_max * det) {
            return None;
        }
        if det > 0.0 && (t_scaled <= 0.0 || t_scaled > t_max * det) {
            return None;
        }
        let inv_det = 1.0 / det;
        let t = t_scaled * inv_det;
        // t conservatively > 0 (pbrt-v4 sec. 6.8.4 bounds, with the f32 shear's error).
        let max_zt = z0.abs().max(z1.abs()).max(z2.abs());
        let max_xt = f64::from(x0.abs().max(x1.abs()).max(x2.abs()));
        let max_yt = f64::from(y0.abs().max(y1.abs()).max(y2.abs()));
        let g = |n: f32| f64::from(gamma(n));
        let delta_z = g(3.0) * max_zt;
        let delta_x = g(5.0) * (max_xt + max_zt);
        let delta_y = g(5.0) * (max_yt + max_zt);
        let delta_e = 2.0 * (g(2.0) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
        let max_e = e0.abs().max(e1.abs()).max(e2.abs());
        let delta_t =
            3.0 * (g(3.0) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv_det.abs();
        if t <= delta_t {
            return None;
        }
        let t = t as f32;
        if !(t > 0.0 && t < t_max as f32) {
            return None;
        }
        Some((t, (e1 * inv_det) as f32, (e2 * inv_det) as f32))
    }
}

/// A ray prepared for box tests.
pub(crate) struct BoxRay {
    origin: Vec3,
    inv_dir: Vec3,
    dir_zero: [bool; 3],
}

/// 1 + 2γ(3): widens a box interval so rounding never misses a box a ray enters
/// (Ize 2013, pbrt-v4 sec. 6.8.2).
fn widen() -> f32 {
    1.0 + 2.0 * gamma(3.0)
}

impl BoxRay {
    pub fn new(ray: &Ray) -> Self {
        Self {
            origin: ray.origin,
            inv_dir: ray.dir.recip(),
            dir_zero: [ray.dir.x == 0.0, ray.dir.y == 0.0, ray.dir.z == 0.0],
        }
    }

    /// The entry distance (>= 0) when the ray overlaps the box `[lo, hi]` within
    /// `[0, t_max]`, conservatively (never misses a box that a hit inside lies in).
    pub fn enter(&self, lo: [f32; 3], hi: [f32; 3], t_max: f32) -> Option<f32> {
        let mut t0 = 0.0f32;
        let mut t1 = t_max;
        for axis in 0..3 {
            let o = self.origin[axis];
            if self.dir_zero[axis] {
                // Parallel to the slabs: inside them or never.
                if o < lo[axis] || o > hi[axis] {
                    return None;
                }
                continue;
            }
            let inv = self.inv_dir[axis];
            let a = (lo[axis] - o) * inv;
            let b = (hi[axis] - o) * inv;
            let (near, far) = if a <= b { (a, b) } else { (b, a) };
            t0 = t0.max(near);
            t1 = t1.min(far * widen());
        }
        (t0 <= t1 * widen()).then_some(t0)
    }
}

impl Bvh {
    /// The closest hit at 0 < t < `t_max` (use `f32::INFINITY` for no limit), or
    /// `None`. Between triangles at exactly the same t (a ray through a shared edge)
    /// the one visited first wins, which may differ from brute force's choice; t is
    /// bit-identical to brute force's either way.
    pub fn closest_hit(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        let tri_ray = TriangleRay::new(ray)?;
        let mut best: Option<Hit> = None;
        let mut t_best = t_max;
        self.traverse(ray, t_max, |triangle, tri| {
            if let Some((t, u, v)) = tri_ray.intersect(tri, t_best) {
                t_best = t;
                best = Some(Hit { t, triangle, u, v });
            }
            (false, t_best)
        });
        best
    }

    /// Whether anything is hit at 0 < t < `t_max` (a shadow ray).
    pub fn any_hit(&self, ray: &Ray, t_max: f32) -> bool {
        let Some(tri_ray) = TriangleRay::new(ray) else {
            return false;
        };
        let mut hit = false;
        self.traverse(ray, t_max, |_, tri| {
            hit = tri_ray.intersect(tri, t_max).is_some();
            (hit, t_max)
        });
        hit
    }

    /// Visits the leaves the ray may hit, nearer child first, with a fixed stack of
    /// [`BVH_STACK_SIZE`] entries (the GPU's discipline: descend into the nearer child,
    /// push the farther). `visit(mesh triangle index, corners)` returns (stop, new
    /// t_max).
    fn traverse(
        &self,
        ray: &Ray,
        t_max: f32,
        mut visit: impl FnMut(u32, [Vec3; 3]) -> (bool, f32),
    ) {
        if !ray.dir.is_finite() || ray.dir == Vec3::ZERO || !ray.origin.is_finite() {
            return;
        }
        let nodes = self.nodes();
        let Some(root) = nodes.first() else {
            return;
        };
        let box_ray = BoxRay::new(ray);
        let mut t_max = t_max;
        if box_ray.enter(root.min, root.max, t_max).is_none() {
            return;
        }
        let mut stack = [(0u32, 0.0f32); BVH_STACK_SIZE];
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let Some(n) = nodes.get(node) else {
                return;
            };
            if n.count > 0 {
                let first = n.left_or_first as usize;
                for slot in first..first + n.count as usize {
                    let (Some(&tri), Some(&id)) = (
                        self.leaf_triangles().get(slot),
                        self.triangle_ids().get(slot),
                    ) else {
                        return;
                    };
                    let (stop, t) = visit(id, tri);
                    if stop {
                        return;
                    }
                    t_max = t;
                }
            } else {
                let left = n.left_or_first as usize;
                let (Some(a), Some(b)) = (nodes.get(left), nodes.get(left + 1)) else {
                    return;
                };
                let ta = box_ray.enter(a.min, a.max, t_max);
                let tb = box_ray.enter(b.min, b.max, t_max);
                match (ta, tb) {
                    (Some(ta), Some(tb)) => {
                        let (near, far, t_far) = if ta <= tb {
                            (left, left + 1, tb)
                        } else {
                            (left + 1, left, ta)
                        };
                        // Cannot overflow: the build bounds the depth (see `Bvh`).
                        debug_assert!(sp < BVH_STACK_SIZE, "BVH deeper than its bound");
                        if let Some(entry) = stack.get_mut(sp) {
                            *entry = (far as u32, t_far);
                            sp += 1;
                        }
                        node = near;
                        continue;
                    }
                    (Some(_), None) => {
                        node = left;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = left + 1;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop the next subtree still in range.
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                let (next, t_enter) = stack[sp];
                if t_enter <= t_max * widen() {
                    node = next as usize;
                    break;
                }
            }
        }
    }
}

impl TriangleMesh {
    /// The closest hit over all triangles, one by one: the reference for
    /// [`Bvh::closest_hit`] (the same test, so the same t for the same triangle; among
    /// equal t the lowest triangle index wins). Triangles with out-of-range indices
    /// are skipped.
    pub fn closest_hit_brute_force(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        let tri_ray = TriangleRay::new(ray)?;
        let mut best: Option<Hit> = None;
        let mut t_best = t_max;
        for i in 0..self.indices.len() {
            let Some(tri) = self.triangle(i) else {
                continue;
            };
            if let Some((t, u, v)) = tri_ray.intersect(tri, t_best) {
                t_best = t;
                best = Some(Hit {
                    t,
                    triangle: i as u32,
                    u,
                    v,
                });
            }
        }
        best
    }

    /// Whether any triangle is hit at 0 < t < `t_max`, one by one.
    pub fn any_hit_brute_force(&self, ray: &Ray, t_max: f32) -> bool {
        let Some(tri_ray) = TriangleRay::new(ray) else {
            return false;
        };
        (0..self.indices.len()).any(|i| {
            self.triangle(i)
                .is_some_and(|tri| tri_ray.intersect(tri, t_max).is_some())
        })
    }
}
