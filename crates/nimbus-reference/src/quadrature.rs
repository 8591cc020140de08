//! An independent f64 CPU reference for single scattering in homogeneous box media.
//!
//! This is the oracle the GPU passes are checked against, so it shares no algorithm with
//! them: its own f64 geometry (slab tests in each box's local frame, exact segment
//! lengths) and brute-force adaptive Gauss–Kronrod quadrature along each camera ray
//! instead of analytic integration, ray marching or sampling.
//!
//! # Model
//!
//! A camera ray is x(t) = o + t·d with |d| = 1, t ≥ 0.
//!
//! - **Media**: homogeneous boxes ([`BoxMedium`]), world = center + R·local with R =
//!   `rotation_xyz_deg(rotation_deg)` and local ∈ [−size/2, size/2]. Extinction σt is a
//!   scalar, σs = albedo·σt per RGB channel, Henyey–Greenstein phase with asymmetry g.
//!   Media do not overlap; outside them is vacuum.
//! - **Shapes** ([`Shape`]) are opaque Lambertian surfaces with `albedo` (0 is a black
//!   occluder). t_S is the distance to the first shape hit (∞ if none).
//! - **Lights**: directional lights with travel direction ω (unit), irradiance E and an
//!   optional gobo (x is lit only if its projection (u, v) = ((x − origin)·U,
//!   (x − origin)·V), (U, V) = `Gobo::basis(ω)`, lies in the convex polygon, boundary
//!   included). Constant environment lights (`radiance · scale`, no file) are seen only
//!   by rays that escape; in this single-scattering model they light neither media nor
//!   surfaces. Any other light, grid media, animated cameras and `max_bounces` ≠ 1 are
//!   errors.
//! - **Transmittance** T(a→b) = exp(−Σ_media σt·ℓ_media), ℓ the length of the segment
//!   inside each box. Light transmittance T_ω(x) is T along x − s·ω, s ∈ [0, ∞), and the
//!   visibility V_ω(x) is 0 if x − s·ω hits a shape for some s > ε, times the gobo mask.
//! - **Phase**: p(cosθ) = (1 − g²) / (4π (1 + g² − 2g·cosθ)^{3/2}) with cosθ = ω·(−d).
//!
//! The radiance along the ray is
//!
//! ```text
//! L = ∫_0^{t_S} T(o→x(t)) Σ_{media ∋ x(t)} σs Σ_lights p(ω·(−d)) E V_ω(x(t)) T_ω(x(t)) dt
//!   + [t_S < ∞] T(o→x_S) (albedo/π) Σ_lights E max(0, n·(−ω)) V_ω(x_S) T_ω(x_S)
//!   + [t_S = ∞] T(o→∞) L_env
//! ```
//!
//! with n the shape normal at x_S flipped towards the camera (n·d < 0).
//!
//! # Quadrature
//!
//! The in-scattering integral is split at every medium boundary along the ray, each
//! in-medium interval into [`INITIAL_SUBINTERVALS`] equal pieces, and additionally at
//! *hints*: where the camera ray crosses a plane or cylinder swept along ω by an edge of
//! a box, quad, gobo or sphere silhouette, which is where V_ω and T_ω may jump or kink.
//! The hints only help; correctness does not depend on them. Then a global adaptive
//! Gauss–Kronrod (G7, K15) scheme bisects the piece with the largest error estimate
//! |K15 − G7| until the summed estimate is at most `rel_tol` times the ray's radiance
//! (per channel maximum), a piece reaches depth [`MAX_DEPTH`], or [`MAX_BISECTIONS`] are
//! spent. A lit feature thinner than about 1/(15·64) of an in-medium interval that no
//! hint marks could be missed.
//!
//! A pixel is the mean of L over its footprint (box filter), computed as an N×N
//! stratified midpoint rule over the footprint (`footprint_samples` = N). That is a
//! quadrature of the footprint too: tests must use an N large enough for the edges their
//! scene puts inside pixels.

// pbrt names from the equations: T_cam, T_end, E.
#![allow(non_snake_case)]

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::f64::consts::PI;
use std::sync::atomic::{AtomicUsize, Ordering as AtomicOrdering};

use anyhow::{bail, ensure};
use glam::{DMat3, DVec2, DVec3, Vec3};
use nimbus_scene::{BoxMedium, Gobo, Light, Medium, Scene, Shape};

/// Equal pieces each in-medium interval starts as, before adaptive refinement.
pub const INITIAL_SUBINTERVALS: usize = 64;
/// Deepest bisection of one initial piece (a piece of length ℓ/2^40 is not split).
pub const MAX_DEPTH: u32 = 40;
/// Most bisections spent on one integral.
pub const MAX_BISECTIONS: usize = 20_000;

/// Accuracy settings of the reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferenceOptions {
    /// Target relative error of each ray's radiance (largest channel), > 0.
    pub rel_tol: f64,
    /// N: each pixel averages an N×N stratified midpoint grid over its footprint, ≥ 1.
    pub footprint_samples: u32,
}

impl Default for ReferenceOptions {
    fn default() -> Self {
        Self {
            rel_tol: 1e-4,
            footprint_samples: 4,
        }
    }
}

/// The radiance (W/(m²·sr), RGB) reaching `origin` along the camera ray origin + t·dir,
/// t ≥ 0. `dir` need not be normalized.
pub fn radiance(
    scene: &Scene,
    origin: DVec3,
    dir: DVec3,
    opts: &ReferenceOptions,
) -> anyhow::Result<[f64; 3]> {
    check_options(opts)?;
    let dir = normalized(dir, "ray direction")?;
    let prepared = PreparedScene::new(scene)?;
    Ok(prepared.radiance(origin, dir, opts.rel_tol))
}

/// Renders the scene's frame 0: `width * height` pixels, row-major from the top left,
/// each the footprint mean of [`radiance`]. Rows are shared among
/// `available_parallelism` threads.
pub fn render(scene: &Scene, opts: &ReferenceOptions) -> anyhow::Result<Vec<[f64; 3]>> {
    check_options(opts)?;
    let prepared = PreparedScene::new(scene)?;
    let (width, height) = (scene.render.width, scene.render.height);
    let frame = scene.camera.frame_at(0);
    let origin = frame.position.as_dvec3();
    let n = opts.footprint_samples;

    // Average L over an n×n midpoint grid inside pixel (x, y).
    let pixel = |x: u32, y: u32| -> [f64; 3] {
        let mut sum = DVec3::ZERO;
        for j in 0..n {
            for i in 0..n {
                let px = f64::from(x) + (f64::from(i) + 0.5) / f64::from(n);
                let py = f64::from(y) + (f64::from(j) + 0.5) / f64::from(n);
                let dir = frame
                    .ray_direction(px as f32, py as f32, width, height)
                    .as_dvec3()
                    .normalize();
                sum += DVec3::from_array(prepared.radiance(origin, dir, opts.rel_tol));
            }
        }
        (sum / f64::from(n * n)).to_array()
    };

    // Hand rows to worker threads from a shared counter.
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get());
    let next_row = AtomicUsize::new(0);
    let mut rows: Vec<(usize, Vec<[f64; 3]>)> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                s.spawn(|| {
                    let mut done = Vec::new();
                    loop {
                        let y = next_row.fetch_add(1, AtomicOrdering::Relaxed);
                        if y >= height as usize {
                            return done;
                        }
                        let row = (0..width).map(|x| pixel(x, y as u32)).collect();
                        done.push((y, row));
                    }
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| {
                w.join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
            })
            .collect()
    });
    rows.sort_by_key(|(y, _)| *y);
    Ok(rows.into_iter().flat_map(|(_, row)| row).collect())
}

/// ∫_0^{t_max} T_cam(t) T_ω(x(t)) [x(t) ∈ box] dt for `medium` alone in vacuum, without
/// σs, phase or irradiance (the paper's unoccluded "T_box" integral). x(t) = origin +
/// t·dir; T_cam is the transmittance from origin to x(t) and T_ω that from x(t) out of
/// the box towards where light travelling along `light_dir` comes from. The origin may
/// lie inside or outside the box and `t_max` may be infinite. Both directions are
/// normalized first, so t is a distance in metres.
pub fn unoccluded_single_scatter(
    medium: &BoxMedium,
    light_dir: DVec3,
    origin: DVec3,
    dir: DVec3,
    t_max: f64,
    rel_tol: f64,
) -> f64 {
    let bounds = OrientedBox::new(medium.center, medium.size, medium.rotation_deg);
    let sigma_t = f64::from(medium.sigma_t);
    let (omega, d) = (light_dir.normalize(), dir.normalize());
    let Some((t0, t1)) = bounds.clip(origin, d, 0.0, t_max) else {
        return 0.0;
    };

    // Split at the planes swept along ω by the box edges (where T_ω's exit face changes).
    let mut cuts = Vec::new();
    bounds.push_edge_plane_crossings(origin, d, omega, &mut cuts);
    let pieces = split_interval(t0, t1, &cuts);
    let integrand = |t: f64| {
        let x = origin + t * d;
        let T_cam = (-sigma_t * (t - t0)).exp();
        let T_light = (-sigma_t * bounds.chord_length(x, -omega, 0.0, f64::INFINITY)).exp();
        DVec3::new(T_cam * T_light, 0.0, 0.0)
    };
    integrate_adaptive(&pieces, integrand, rel_tol.max(f64::EPSILON), 0.0).x
}

/// The Henyey–Greenstein phase function, normalized over the sphere; `cos_theta` is the
/// cosine between the travel directions before and after scattering, |g| < 1 (so the
/// base 1 + g² − 2g·cosθ ≥ (1 − |g|)² > 0).
pub fn henyey_greenstein(cos_theta: f64, g: f64) -> f64 {
    let denom = 1.0 + g * g - 2.0 * g * cos_theta;
    (1.0 - g * g) / (4.0 * PI * denom * denom.sqrt())
}

/// Rotation `rotation_deg` (about X, then Y, then Z) in f64: world = Rz·Ry·Rx·local.
pub fn rotation_xyz_deg_f64(rotation_deg: Vec3) -> DMat3 {
    let r = rotation_deg.as_dvec3() * (PI / 180.0);
    DMat3::from_rotation_z(r.z) * DMat3::from_rotation_y(r.y) * DMat3::from_rotation_x(r.x)
}

fn check_options(opts: &ReferenceOptions) -> anyhow::Result<()> {
    ensure!(
        opts.rel_tol.is_finite() && opts.rel_tol > 0.0,
        "reference rel_tol must be finite and > 0, got {}",
        opts.rel_tol
    );
    ensure!(
        opts.footprint_samples >= 1,
        "reference footprint_samples must be at least 1"
    );
    Ok(())
}

fn normalized(v: DVec3, what: &str) -> anyhow::Result<DVec3> {
    let n = v.normalize_or_zero();
    ensure!(
        n != DVec3::ZERO && n.is_finite(),
        "{what} {v} cannot be normalized"
    );
    Ok(n)
}

/// A box, world = center + R·local, local ∈ [−half, half].
#[derive(Clone, Copy, Debug)]
struct OrientedBox {
    center: DVec3,
    half: DVec3,
    world_from_local: DMat3,
    local_from_world: DMat3,
}

/// Where a line o + t·d is inside a box, with the local axis of the entry and exit face.
#[derive(Clone, Copy, Debug)]
struct SlabInterval {
    t_near: f64,
    t_far: f64,
    axis_near: usize,
    axis_far: usize,
}

impl OrientedBox {
    fn new(center: Vec3, size: Vec3, rotation_deg: Vec3) -> Self {
        let world_from_local = rotation_xyz_deg_f64(rotation_deg);
        Self {
            center: center.as_dvec3(),
            half: size.as_dvec3() * 0.5,
            world_from_local,
            local_from_world: world_from_local.transpose(),
        }
    }

    /// Slab test in the box's local frame; t is shared with the world ray because R is
    /// a rotation. A direction component of exactly 0 keeps the line inside that slab
    /// only if its coordinate is.
    fn slab(&self, o: DVec3, d: DVec3) -> Option<SlabInterval> {
        let o_local = self.local_from_world * (o - self.center);
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
    fn clip(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<(f64, f64)> {
        let hit = self.slab(o, d)?;
        let (t0, t1) = (hit.t_near.max(t_min), hit.t_far.min(t_max));
        (t0 < t1).then_some((t0, t1))
    }

    /// Length of o + t·d, t ∈ [t_min, t_max], inside the box.
    fn chord_length(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> f64 {
        self.clip(o, d, t_min, t_max)
            .map_or(0.0, |(t0, t1)| t1 - t0)
    }

    /// Unit outward normal of the faces perpendicular to local `axis` (sign open).
    fn axis_world(&self, axis: usize) -> DVec3 {
        self.world_from_local.col(axis)
    }

    /// Pushes the t where o + t·d crosses each plane that contains ω and one of the
    /// box's 12 edges.
    fn push_edge_plane_crossings(&self, o: DVec3, d: DVec3, omega: DVec3, cuts: &mut Vec<f64>) {
        for axis in 0..3 {
            let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
            let edge = self.axis_world(axis);
            for (s1, s2) in [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)] {
                let point = self.center
                    + s1 * self.half[a1] * self.axis_world(a1)
                    + s2 * self.half[a2] * self.axis_world(a2);
                push_plane_crossing(o, d, point, edge.cross(omega), cuts);
            }
        }
    }
}

/// Pushes the t where o + t·d crosses the plane through `point` with normal `normal`
/// (skipped when the normal vanishes or the ray is parallel to the plane).
fn push_plane_crossing(o: DVec3, d: DVec3, point: DVec3, normal: DVec3, cuts: &mut Vec<f64>) {
    let denom = d.dot(normal);
    if normal.length_squared() > 0.0 && denom.abs() > 1e-12 * normal.length() {
        let t = (point - o).dot(normal) / denom;
        if t.is_finite() {
            cuts.push(t);
        }
    }
}

struct PreparedMedium {
    bounds: OrientedBox,
    sigma_t: f64,
    sigma_s: DVec3,
    g: f64,
}

enum ShapeGeometry {
    Quad {
        corner: DVec3,
        edge_u: DVec3,
        edge_v: DVec3,
        /// edge_u × edge_v, not normalized.
        normal: DVec3,
    },
    Box(OrientedBox),
    Sphere {
        center: DVec3,
        radius: f64,
    },
}

struct PreparedShape {
    geometry: ShapeGeometry,
    albedo: DVec3,
}

/// A ray–shape intersection: distance and a unit normal of either orientation.
struct SurfaceHit {
    t: f64,
    normal: DVec3,
    albedo: DVec3,
}

impl PreparedShape {
    /// The nearest intersection with t > t_min.
    fn intersect(&self, o: DVec3, d: DVec3, t_min: f64) -> Option<SurfaceHit> {
        let (t, normal) = match self.geometry {
            ShapeGeometry::Quad {
                corner,
                edge_u,
                edge_v,
                normal,
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
        };
        Some(SurfaceHit {
            t,
            normal,
            albedo: self.albedo,
        })
    }

    /// Pushes the t where o + t·d crosses the boundary of this shape's shadow along ω.
    fn push_shadow_crossings(&self, o: DVec3, d: DVec3, omega: DVec3, cuts: &mut Vec<f64>) {
        match self.geometry {
            ShapeGeometry::Quad {
                corner,
                edge_u,
                edge_v,
                normal,
            } => {
                // The quad's plane and the four planes swept along ω by its edges.
                push_plane_crossing(o, d, corner, normal, cuts);
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
            ShapeGeometry::Box(bounds) => bounds.push_edge_plane_crossings(o, d, omega, cuts),
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
        }
    }
}

struct PreparedGobo {
    origin: DVec3,
    u_axis: DVec3,
    v_axis: DVec3,
    /// Counter-clockwise convex polygon.
    polygon: Vec<DVec2>,
}

impl PreparedGobo {
    fn new(gobo: &Gobo, omega: Vec3) -> Self {
        let (u_axis, v_axis) = Gobo::basis(omega);
        Self {
            origin: gobo.origin.as_dvec3(),
            u_axis: u_axis.as_dvec3(),
            v_axis: v_axis.as_dvec3(),
            polygon: gobo.polygon.iter().map(|p| p.as_dvec2()).collect(),
        }
    }

    fn edges(&self) -> impl Iterator<Item = (DVec2, DVec2)> + '_ {
        let n = self.polygon.len();
        (0..n).map(move |i| (self.polygon[i], self.polygon[(i + 1) % n]))
    }

    /// Whether the beam through the polygon contains x (boundary included).
    fn passes(&self, x: DVec3) -> bool {
        let rel = x - self.origin;
        let q = DVec2::new(rel.dot(self.u_axis), rel.dot(self.v_axis));
        self.edges().all(|(a, b)| (b - a).perp_dot(q - a) >= 0.0)
    }

    fn to_world(&self, p: DVec2) -> DVec3 {
        self.origin + p.x * self.u_axis + p.y * self.v_axis
    }

    /// Pushes the t where o + t·d crosses the planes swept along ω by the edges.
    fn push_crossings(&self, o: DVec3, d: DVec3, omega: DVec3, cuts: &mut Vec<f64>) {
        for (a, b) in self.edges() {
            let edge = self.to_world(b) - self.to_world(a);
            push_plane_crossing(o, d, self.to_world(a), edge.cross(omega), cuts);
        }
    }
}

struct PreparedLight {
    /// Travel direction, unit.
    omega: DVec3,
    irradiance: DVec3,
    gobo: Option<PreparedGobo>,
}

/// The scene in f64, checked against what the reference models.
struct PreparedScene {
    media: Vec<PreparedMedium>,
    shapes: Vec<PreparedShape>,
    lights: Vec<PreparedLight>,
    environment: DVec3,
}

/// One in-medium stretch of a camera ray.
#[derive(Clone, Copy)]
struct RaySegment {
    medium: usize,
    t0: f64,
    t1: f64,
}

impl PreparedScene {
    fn new(scene: &Scene) -> anyhow::Result<Self> {
        let source = scene.source.display();
        ensure!(
            scene.integrator.max_bounces == 1,
            "{source}: the reference computes single scattering only, but \
             [integrator] max_bounces = {}",
            scene.integrator.max_bounces
        );
        ensure!(
            scene.camera.keyframes.is_empty() || scene.render.frames <= 1,
            "{source}: animated cameras are not supported by the reference (it renders \
             frame 0 only)"
        );

        let mut media = Vec::new();
        for (i, medium) in scene.media.iter().enumerate() {
            let Medium::Box(m) = medium else {
                bail!("{source}: medium {i}: grid media are not supported by the reference");
            };
            media.push(PreparedMedium {
                bounds: OrientedBox::new(m.center, m.size, m.rotation_deg),
                sigma_t: f64::from(m.sigma_t),
                sigma_s: m.albedo.as_dvec3() * f64::from(m.sigma_t),
                g: f64::from(m.g),
            });
        }

        let shapes = scene
            .shapes
            .iter()
            .map(|shape| match *shape {
                Shape::Quad {
                    corner,
                    edge_u,
                    edge_v,
                    albedo,
                } => PreparedShape {
                    geometry: ShapeGeometry::Quad {
                        corner: corner.as_dvec3(),
                        edge_u: edge_u.as_dvec3(),
                        edge_v: edge_v.as_dvec3(),
                        normal: edge_u.as_dvec3().cross(edge_v.as_dvec3()),
                    },
                    albedo: albedo.as_dvec3(),
                },
                Shape::Box {
                    center,
                    size,
                    rotation_deg,
                    albedo,
                } => PreparedShape {
                    geometry: ShapeGeometry::Box(OrientedBox::new(center, size, rotation_deg)),
                    albedo: albedo.as_dvec3(),
                },
                Shape::Sphere {
                    center,
                    radius,
                    albedo,
                } => PreparedShape {
                    geometry: ShapeGeometry::Sphere {
                        center: center.as_dvec3(),
                        radius: f64::from(radius),
                    },
                    albedo: albedo.as_dvec3(),
                },
            })
            .collect();

        let mut lights = Vec::new();
        let mut environment = DVec3::ZERO;
        for (i, light) in scene.lights.iter().enumerate() {
            match light {
                Light::Directional {
                    direction,
                    irradiance,
                    gobo,
                } => lights.push(PreparedLight {
                    omega: normalized(direction.as_dvec3(), "light direction")?,
                    irradiance: irradiance.as_dvec3(),
                    gobo: gobo.as_ref().map(|g| PreparedGobo::new(g, *direction)),
                }),
                Light::Environment {
                    radiance,
                    file: None,
                    scale,
                } => environment += radiance.as_dvec3() * scale.as_dvec3(),
                Light::Environment { file: Some(f), .. } => bail!(
                    "{source}: light {i}: environment maps ({}) are not supported by the \
                     reference (constant radiance only)",
                    f.display()
                ),
                Light::Point { .. } => {
                    bail!("{source}: light {i}: point lights are not supported by the reference")
                }
                Light::Sphere { .. } => {
                    bail!("{source}: light {i}: sphere lights are not supported by the reference")
                }
            }
        }

        Ok(Self {
            media,
            shapes,
            lights,
            environment,
        })
    }

    /// The nearest shape hit along o + t·d, t > t_min.
    fn first_hit(&self, o: DVec3, d: DVec3, t_min: f64) -> Option<SurfaceHit> {
        self.shapes
            .iter()
            .filter_map(|s| s.intersect(o, d, t_min))
            .min_by(|a, b| a.t.total_cmp(&b.t))
    }

    /// V_ω(x) T_ω(x) E for one light: the irradiance reaching x, shadowed and
    /// attenuated.
    fn irradiance_at(&self, x: DVec3, light: &PreparedLight) -> DVec3 {
        if let Some(gobo) = &light.gobo {
            if !gobo.passes(x) {
                return DVec3::ZERO;
            }
        }
        let towards_light = -light.omega;
        let s_min = 1e-9 * (1.0 + x.abs().max_element());
        if self.first_hit(x, towards_light, s_min).is_some() {
            return DVec3::ZERO;
        }
        let optical_depth: f64 = self
            .media
            .iter()
            .map(|m| m.sigma_t * m.bounds.chord_length(x, towards_light, 0.0, f64::INFINITY))
            .sum();
        light.irradiance * (-optical_depth).exp()
    }

    /// Optical depth from the camera to t along the camera ray's segments.
    fn camera_optical_depth(segments: &[RaySegment], media: &[PreparedMedium], t: f64) -> f64 {
        segments
            .iter()
            .map(|s| media[s.medium].sigma_t * (t.min(s.t1) - s.t0).max(0.0))
            .sum()
    }

    fn radiance(&self, o: DVec3, d: DVec3, rel_tol: f64) -> [f64; 3] {
        let hit = self.first_hit(o, d, 0.0);
        let t_end = hit.as_ref().map_or(f64::INFINITY, |h| h.t);

        // Find the in-medium segments of the camera ray before the first surface.
        let mut segments: Vec<RaySegment> = self
            .media
            .iter()
            .enumerate()
            .filter_map(|(medium, m)| {
                let (t0, t1) = m.bounds.clip(o, d, 0.0, t_end)?;
                Some(RaySegment { medium, t0, t1 })
            })
            .collect();
        segments.sort_by(|a, b| a.t0.total_cmp(&b.t0));
        let T_end = (-Self::camera_optical_depth(&segments, &self.media, t_end)).exp();

        // Add the lit surface or the environment behind the media.
        let end_radiance = match &hit {
            Some(hit) => {
                let x = o + hit.t * d;
                let n = if hit.normal.dot(d) < 0.0 {
                    hit.normal
                } else {
                    -hit.normal
                };
                let E: DVec3 = self
                    .lights
                    .iter()
                    .map(|l| self.irradiance_at(x, l) * n.dot(-l.omega).max(0.0))
                    .sum();
                hit.albedo / PI * E
            }
            None => self.environment,
        } * T_end;

        // Integrate in-scattering over each segment, cut where shadows and exit faces change.
        let mut pieces = Vec::new();
        let mut piece_medium = Vec::new();
        for segment in &segments {
            let mut cuts = Vec::new();
            for light in &self.lights {
                for m in &self.media {
                    m.bounds
                        .push_edge_plane_crossings(o, d, light.omega, &mut cuts);
                }
                for shape in &self.shapes {
                    shape.push_shadow_crossings(o, d, light.omega, &mut cuts);
                }
                if let Some(gobo) = &light.gobo {
                    gobo.push_crossings(o, d, light.omega, &mut cuts);
                }
            }
            for piece in split_interval(segment.t0, segment.t1, &cuts) {
                pieces.push(piece);
                piece_medium.push(segment.medium);
            }
        }
        let integrand = |t: f64, medium: usize| -> DVec3 {
            let m = &self.media[medium];
            let x = o + t * d;
            let T_cam = (-Self::camera_optical_depth(&segments, &self.media, t)).exp();
            let inscattered: DVec3 = self
                .lights
                .iter()
                .map(|l| henyey_greenstein(l.omega.dot(-d), m.g) * self.irradiance_at(x, l))
                .sum();
            T_cam * m.sigma_s * inscattered
        };
        let abs_tol = rel_tol * end_radiance.max_element();
        let inscattering =
            integrate_adaptive_tagged(&pieces, &piece_medium, integrand, rel_tol, abs_tol);
        (inscattering + end_radiance).to_array()
    }
}

/// [t0, t1] split into [`INITIAL_SUBINTERVALS`] equal pieces and at each cut inside it.
fn split_interval(t0: f64, t1: f64, cuts: &[f64]) -> Vec<(f64, f64)> {
    let n = INITIAL_SUBINTERVALS;
    let mut points: Vec<f64> = (0..=n)
        .map(|i| t0 + (t1 - t0) * i as f64 / n as f64)
        .chain(cuts.iter().copied().filter(|&t| t > t0 && t < t1))
        .collect();
    points[n] = t1;
    points.sort_by(f64::total_cmp);
    points
        .windows(2)
        .filter(|w| w[1] > w[0])
        .map(|w| (w[0], w[1]))
        .collect()
}

/// Gauss–Kronrod nodes on [−1, 1] (non-negative half, descending) and weights, from
/// QUADPACK's `qk15`. Odd indices are the 7-point Gauss nodes.
#[allow(clippy::excessive_precision)]
const XGK: [f64; 8] = [
    0.991_455_371_120_812_639_206_854_697_526_329,
    0.949_107_912_342_758_524_526_189_684_047_851,
    0.864_864_423_359_769_072_789_712_788_640_926,
    0.741_531_185_599_394_439_863_864_773_280_788,
    0.586_087_235_467_691_130_294_144_845_693_013,
    0.405_845_151_377_397_166_906_606_412_076_961,
    0.207_784_955_007_898_467_600_689_403_773_245,
    0.0,
];
#[allow(clippy::excessive_precision)]
const WGK: [f64; 8] = [
    0.022_935_322_010_529_224_963_732_008_058_970,
    0.063_092_092_629_978_553_290_700_663_189_204,
    0.104_790_010_322_250_183_839_876_322_541_518,
    0.140_653_259_715_525_918_745_189_590_510_238,
    0.169_004_726_639_267_902_826_583_426_598_550,
    0.190_350_578_064_785_409_913_256_402_421_014,
    0.204_432_940_075_298_892_414_161_999_234_649,
    0.209_482_141_084_727_828_012_999_174_891_714,
];
/// Weights of the 7-point Gauss rule at XGK[1], XGK[3], XGK[5], XGK[7].
#[allow(clippy::excessive_precision)]
const WG: [f64; 4] = [
    0.129_484_966_168_869_693_270_611_432_679_082,
    0.279_705_391_489_276_667_901_467_771_423_780,
    0.381_830_050_505_118_944_950_369_775_488_975,
    0.417_959_183_673_469_387_755_102_040_816_327,
];

/// K15 on [a, b] and the error estimate max_c |K15 − G7|.
fn gauss_kronrod_15(f: &impl Fn(f64) -> DVec3, a: f64, b: f64) -> (DVec3, f64) {
    let (mid, half) = (0.5 * (a + b), 0.5 * (b - a));
    let f_mid = f(mid);
    let mut kronrod = WGK[7] * f_mid;
    let mut gauss = WG[3] * f_mid;
    for k in 0..7 {
        let dx = half * XGK[k];
        let pair = f(mid - dx) + f(mid + dx);
        kronrod += WGK[k] * pair;
        if k % 2 == 1 {
            gauss += WG[k / 2] * pair;
        }
    }
    let error = ((kronrod - gauss) * half).abs().max_element();
    (kronrod * half, error)
}

struct Piece {
    a: f64,
    b: f64,
    tag: usize,
    depth: u32,
    value: DVec3,
    error: f64,
}

impl PartialEq for Piece {
    fn eq(&self, other: &Self) -> bool {
        self.error.total_cmp(&other.error) == Ordering::Equal
    }
}
impl Eq for Piece {}
impl PartialOrd for Piece {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Piece {
    fn cmp(&self, other: &Self) -> Ordering {
        self.error.total_cmp(&other.error)
    }
}

/// Integrates f over the union of `pieces`, see [`integrate_adaptive_tagged`].
fn integrate_adaptive(
    pieces: &[(f64, f64)],
    f: impl Fn(f64) -> DVec3,
    rel_tol: f64,
    abs_tol: f64,
) -> DVec3 {
    let tags = vec![0; pieces.len()];
    integrate_adaptive_tagged(pieces, &tags, |t, _| f(t), rel_tol, abs_tol)
}

/// Global adaptive Gauss–Kronrod quadrature of f(t, tag) over pieces, each with a tag
/// passed to f. Bisects the piece with the largest error estimate until the summed
/// estimate ≤ max(abs_tol, rel_tol · max_c |I_c|), every remaining piece is at
/// [`MAX_DEPTH`], or [`MAX_BISECTIONS`] are spent.
fn integrate_adaptive_tagged(
    pieces: &[(f64, f64)],
    tags: &[usize],
    f: impl Fn(f64, usize) -> DVec3,
    rel_tol: f64,
    abs_tol: f64,
) -> DVec3 {
    let estimate = |a: f64, b: f64, tag: usize, depth: u32| {
        let (value, error) = gauss_kronrod_15(&|t| f(t, tag), a, b);
        Piece {
            a,
            b,
            tag,
            depth,
            value,
            error,
        }
    };
    let mut heap: BinaryHeap<Piece> = pieces
        .iter()
        .zip(tags)
        .map(|(&(a, b), &tag)| estimate(a, b, tag, 0))
        .collect();
    let mut finished: Vec<Piece> = Vec::new();
    let total = |heap: &BinaryHeap<Piece>, finished: &[Piece]| {
        heap.iter()
            .chain(finished)
            .fold((DVec3::ZERO, 0.0), |(value, error), p| {
                (value + p.value, error + p.error)
            })
    };

    // Track the totals incrementally and refresh them exactly now and then.
    let (mut value, mut error) = total(&heap, &finished);
    for bisection in 0..MAX_BISECTIONS {
        if error <= abs_tol.max(rel_tol * value.abs().max_element()) {
            break;
        }
        let Some(worst) = heap.pop() else {
            break;
        };
        let mid = 0.5 * (worst.a + worst.b);
        if worst.depth >= MAX_DEPTH || !(mid > worst.a && mid < worst.b) {
            finished.push(worst);
            continue;
        }
        let left = estimate(worst.a, mid, worst.tag, worst.depth + 1);
        let right = estimate(mid, worst.b, worst.tag, worst.depth + 1);
        value += left.value + right.value - worst.value;
        error += left.error + right.error - worst.error;
        heap.push(left);
        heap.push(right);
        if bisection % 256 == 255 {
            (value, error) = total(&heap, &finished);
        }
    }
    total(&heap, &finished).0
}

#[cfg(test)]
mod tests {
    use glam::{Vec2, Vec3};

    use super::*;

    const TIGHT: ReferenceOptions = ReferenceOptions {
        rel_tol: 1e-10,
        footprint_samples: 1,
    };

    fn box_medium(center: Vec3, size: Vec3, rotation_deg: Vec3, sigma_t: f32) -> BoxMedium {
        BoxMedium {
            center,
            size,
            rotation_deg,
            sigma_t,
            albedo: Vec3::new(0.9, 0.5, 0.25),
            g: 0.0,
        }
    }

    fn scene(media: Vec<BoxMedium>, shapes: Vec<Shape>, lights: Vec<Light>) -> Scene {
        crate::common::test_scene(
            media.into_iter().map(Medium::Box).collect(),
            shapes,
            lights,
            (6, 4),
            40.0,
        )
    }

    fn sun(direction: Vec3, irradiance: f32) -> Light {
        Light::Directional {
            direction: direction.normalize(),
            irradiance: Vec3::splat(irradiance),
            gobo: None,
        }
    }

    fn assert_close(actual: f64, expected: f64, rel: f64) {
        let err = (actual - expected).abs();
        assert!(
            err <= rel * expected.abs().max(1e-300),
            "actual {actual:e}, expected {expected:e}, relative error {:e} > {rel:e}",
            err / expected.abs()
        );
    }

    #[test]
    fn gauss_kronrod_constants_integrate_polynomials_exactly() {
        // K15 is exact to degree 22 and G7 to degree 13; x^k on [0, 1] is 1/(k+1).
        for k in 0..=13 {
            let f = |t: f64| DVec3::splat(t.powi(k));
            let (value, error) = gauss_kronrod_15(&f, 0.0, 1.0);
            assert_close(value.x, 1.0 / f64::from(k + 1), 1e-14);
            assert!(error < 1e-14, "k = {k}: G7 error estimate {error:e}");
        }
        let (value, _) = gauss_kronrod_15(&|t: f64| DVec3::splat(t.powi(22)), 0.0, 1.0);
        assert_close(value.x, 1.0 / 23.0, 1e-14);
    }

    #[test]
    fn adaptive_quadrature_finds_a_step() {
        // The step sits away from every initial cut, so only adaptivity finds it.
        let step = 0.123_456_789;
        let f = |t: f64| DVec3::new(if t < step { 1.0 } else { 0.0 }, t.exp(), 0.0);
        let pieces = split_interval(0.0, 1.0, &[]);
        let value = integrate_adaptive(&pieces, f, 1e-12, 0.0);
        assert_close(value.x, step, 1e-11);
        assert_close(value.y, std::f64::consts::E - 1.0, 1e-12);
    }

    #[test]
    fn henyey_greenstein_integrates_to_one_over_the_sphere() {
        // ∫ p dω = 2π ∫_{-1}^{1} p(μ) dμ.
        for g in [-0.9, -0.3, 0.0, 0.5, 0.95] {
            let pieces = split_interval(-1.0, 1.0, &[]);
            let f = |mu: f64| DVec3::splat(2.0 * PI * henyey_greenstein(mu, g));
            let total = integrate_adaptive(&pieces, f, 1e-13, 0.0).x;
            assert_close(total, 1.0, 1e-11);
        }
        assert_close(henyey_greenstein(0.3, 0.0), 1.0 / (4.0 * PI), 1e-15);
    }

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

    #[test]
    fn light_along_the_view_direction() {
        // ω = d: T_cam = T_ω = exp(−σt (t − t0)), so the integral is (1 − e^{−2σt L})/(2σt).
        let sigma_t = 0.7;
        let medium = box_medium(Vec3::ZERO, Vec3::new(2.0, 3.0, 4.0), Vec3::ZERO, sigma_t);
        let (origin, dir) = (DVec3::new(0.2, -0.3, 5.0), DVec3::NEG_Z);
        let (s, len) = (f64::from(sigma_t), 4.0);
        let expected = (1.0 - (-2.0 * s * len).exp()) / (2.0 * s);
        let actual = unoccluded_single_scatter(&medium, dir, origin, dir, f64::INFINITY, 1e-12);
        assert_close(actual, expected, 1e-10);
    }

    #[test]
    fn light_against_the_view_direction() {
        // ω = −d: T_cam·T_ω = exp(−σt L) along the whole chord, so the integral is L e^{−σt L}.
        let sigma_t = 1.3;
        let medium = box_medium(Vec3::ZERO, Vec3::new(2.0, 3.0, 4.0), Vec3::ZERO, sigma_t);
        let (origin, dir) = (DVec3::new(-4.0, 0.5, 0.1), DVec3::X);
        let (s, len) = (f64::from(sigma_t), 2.0);
        let actual = unoccluded_single_scatter(&medium, -dir, origin, dir, f64::INFINITY, 1e-12);
        assert_close(actual, len * (-s * len).exp(), 1e-10);
    }

    #[test]
    fn camera_inside_the_box_with_light_along_the_view() {
        // The light ray first crosses the b metres behind the camera: T_ω = e^{−σt(t + b)}.
        let sigma_t = 0.4;
        let medium = box_medium(Vec3::ZERO, Vec3::splat(2.0), Vec3::ZERO, sigma_t);
        let (origin, dir) = (DVec3::new(0.3, 0.1, -0.25), DVec3::Z);
        let (s, ahead, behind) = (f64::from(sigma_t), 1.25, 0.75);
        let expected = (-s * behind).exp() * (1.0 - (-2.0 * s * ahead).exp()) / (2.0 * s);
        let actual = unoccluded_single_scatter(&medium, dir, origin, dir, f64::INFINITY, 1e-12);
        assert_close(actual, expected, 1e-10);

        // Truncating at t_max integrates only the first t_max metres.
        let t_max = 0.5;
        let expected = (-s * behind).exp() * (1.0 - (-2.0 * s * t_max).exp()) / (2.0 * s);
        let actual = unoccluded_single_scatter(&medium, dir, origin, dir, t_max, 1e-12);
        assert_close(actual, expected, 1e-10);
    }

    #[test]
    fn oblique_light_through_a_rotated_slab() {
        // A wide slab of thickness H seen straight down; light enters through the top at
        // cosine μ, so at depth z the integrand is e^{−σt z} e^{−σt z/μ}. Rotating slab,
        // camera and light together must not change the answer.
        let (sigma_t, thickness, mu) = (0.8f32, 1.5, 0.6);
        let k = f64::from(sigma_t) * (1.0 + 1.0 / mu);
        let expected = (1.0 - (-k * thickness).exp()) / k;
        let light = DVec3::new((1.0 - mu * mu).sqrt(), -mu, 0.0);
        for rotation in [Vec3::ZERO, Vec3::new(25.0, -40.0, 70.0)] {
            let r = rotation_xyz_deg_f64(rotation);
            let center = Vec3::new(1.0, -2.0, 0.5);
            let medium = box_medium(
                center,
                Vec3::new(40.0, thickness as f32, 40.0),
                rotation,
                sigma_t,
            );
            let origin = center.as_dvec3() + r * DVec3::new(0.0, 3.0, 0.0);
            let actual = unoccluded_single_scatter(
                &medium,
                r * light,
                origin,
                r * DVec3::NEG_Y,
                f64::INFINITY,
                1e-12,
            );
            assert_close(actual, expected, 1e-9);
        }
    }

    #[test]
    fn vanishing_extinction_gives_the_chord_length() {
        // Through the centre along the rotated local x axis the chord is size.x.
        let rotation = Vec3::new(12.0, 34.0, 56.0);
        let medium = box_medium(
            Vec3::new(0.5, 0.0, -1.0),
            Vec3::new(1.7, 0.4, 0.9),
            rotation,
            0.0,
        );
        let axis = rotation_xyz_deg_f64(rotation) * DVec3::X;
        let origin = medium.center.as_dvec3() - 3.0 * axis;
        let light = DVec3::new(0.3, -1.0, 0.2);
        let actual = unoccluded_single_scatter(&medium, light, origin, axis, f64::INFINITY, 1e-12);
        assert_close(actual, 1.7, 1e-6);
    }

    #[test]
    fn a_miss_gives_zero() {
        let medium = box_medium(Vec3::ZERO, Vec3::ONE, Vec3::ZERO, 1.0);
        let value = unoccluded_single_scatter(
            &medium,
            DVec3::NEG_Y,
            DVec3::new(0.0, 2.0, 0.0),
            DVec3::X,
            f64::INFINITY,
            1e-9,
        );
        assert_eq!(value, 0.0);
    }

    #[test]
    fn radiance_includes_albedo_phase_and_environment() {
        // Backlit slab along −z (ω = d, cosθ = −1) in front of a constant environment.
        let sigma_t = 0.6f32;
        let mut medium = box_medium(Vec3::ZERO, Vec3::new(2.0, 2.0, 3.0), Vec3::ZERO, sigma_t);
        medium.g = 0.5;
        let environment = Light::Environment {
            radiance: Vec3::new(0.5, 1.0, 2.0),
            file: None,
            scale: Vec3::ONE,
        };
        let s = scene(
            vec![medium.clone()],
            Vec::new(),
            vec![sun(Vec3::NEG_Z, 3.0), environment],
        );
        let (origin, dir) = (DVec3::new(0.1, 0.2, 5.0), DVec3::NEG_Z);
        let actual = radiance(&s, origin, dir, &TIGHT).unwrap();

        let (sigma, len) = (f64::from(sigma_t), 3.0);
        let t_box = (1.0 - (-2.0 * sigma * len).exp()) / (2.0 * sigma);
        let phase = (1.0 - 0.25) / (4.0 * PI * 1.5f64.powi(3));
        for c in 0..3 {
            let sigma_s = f64::from(medium.albedo[c]) * sigma;
            let background = [0.5, 1.0, 2.0][c] * (-sigma * len).exp();
            assert_close(actual[c], sigma_s * phase * 3.0 * t_box + background, 1e-9);
        }
    }

    #[test]
    fn sphere_shadow_removes_its_diameter() {
        // Light straight down onto a ray along +x at y = z = 0; a sphere above the box
        // shadows |x − xc| ≤ r, and T_ω = e^{−σt h} from the box top at height h.
        let sigma_t = 0.5f32;
        let medium = box_medium(
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(4.0, 2.0, 2.0),
            Vec3::ZERO,
            sigma_t,
        );
        let (xc, r) = (2.75, 0.375);
        let sphere = Shape::Sphere {
            center: Vec3::new(xc as f32, 3.0, 0.0),
            radius: r as f32,
            albedo: Vec3::ONE,
        };
        let s = scene(
            vec![medium.clone()],
            vec![sphere],
            vec![sun(Vec3::NEG_Y, 2.0)],
        );
        let origin = DVec3::new(-1.0, 0.0, 0.0);
        let actual = radiance(&s, origin, DVec3::X, &TIGHT).unwrap();

        // ∫ e^{−σ x} over [0, 4] without [xc − r, xc + r], times e^{−σ·1} and σs p E.
        let sigma = f64::from(sigma_t);
        let lit = |a: f64, b: f64| ((-sigma * a).exp() - (-sigma * b).exp()) / sigma;
        let path = lit(0.0, xc - r) + lit(xc + r, 4.0);
        let p = 1.0 / (4.0 * PI);
        for (actual, albedo) in actual.into_iter().zip(medium.albedo.to_array()) {
            let sigma_s = f64::from(albedo) * sigma;
            assert_close(actual, sigma_s * p * 2.0 * (-sigma).exp() * path, 1e-9);
        }
    }

    #[test]
    fn gobo_limits_the_beam() {
        // A vertical sun has gobo axes u = +x, v = −z; the square u ∈ [0.5, 1.5] lights
        // only x ∈ [0.5, 1.5] + origin.x of the ray along +x.
        let sigma_t = 0.9f32;
        let medium = box_medium(
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(4.0, 2.0, 2.0),
            Vec3::ZERO,
            sigma_t,
        );
        let gobo = Gobo {
            polygon: vec![
                Vec2::new(0.5, -1.0),
                Vec2::new(1.5, -1.0),
                Vec2::new(1.5, 1.0),
                Vec2::new(0.5, 1.0),
            ],
            origin: Vec3::new(0.25, 10.0, 0.0),
        };
        let light = Light::Directional {
            direction: Vec3::NEG_Y,
            irradiance: Vec3::splat(1.0),
            gobo: Some(gobo),
        };
        let s = scene(vec![medium], Vec::new(), vec![light]);
        let actual = radiance(&s, DVec3::new(-1.0, 0.0, 0.0), DVec3::X, &TIGHT).unwrap();

        let sigma = f64::from(sigma_t);
        let (a, b) = (0.75, 1.75);
        let path = ((-sigma * a).exp() - (-sigma * b).exp()) / sigma;
        let sigma_s = f64::from(0.9f32) * sigma;
        let expected = sigma_s / (4.0 * PI) * (-sigma).exp() * path;
        assert_close(actual[0], expected, 1e-9);
    }

    #[test]
    fn lambertian_surface_lit_and_shadowed() {
        // A floor of albedo ρ under a sun at cosine μ: L = ρ/π E μ; a box above the hit
        // point shadows it.
        let mu = 0.8f32;
        let direction = Vec3::new((1.0 - mu * mu).sqrt(), -mu, 0.0);
        let floor = Shape::Quad {
            corner: Vec3::new(-5.0, 0.0, 5.0),
            edge_u: Vec3::new(10.0, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, -10.0),
            albedo: Vec3::new(0.5, 0.25, 1.0),
        };
        let origin = DVec3::new(0.0, 2.0, 2.0);
        let dir = DVec3::new(0.0, -2.0, -2.0);
        let s = scene(Vec::new(), vec![floor.clone()], vec![sun(direction, 4.0)]);
        let lit = radiance(&s, origin, dir, &TIGHT).unwrap();
        for (c, albedo) in [0.5, 0.25, 1.0].into_iter().enumerate() {
            assert_close(lit[c], albedo / PI * 4.0 * f64::from(mu), 1e-6);
        }

        let blocker = Shape::Box {
            center: -direction * 2.0,
            size: Vec3::splat(0.5),
            rotation_deg: Vec3::new(10.0, 20.0, 30.0),
            albedo: Vec3::ZERO,
        };
        let s = scene(Vec::new(), vec![floor, blocker], vec![sun(direction, 4.0)]);
        assert_eq!(radiance(&s, origin, dir, &TIGHT).unwrap(), [0.0; 3]);
    }

    #[test]
    fn render_averages_footprints_in_row_major_order() {
        let medium = box_medium(
            Vec3::ZERO,
            Vec3::new(2.0, 1.0, 1.0),
            Vec3::new(0.0, 30.0, 0.0),
            1.0,
        );
        let s = scene(
            vec![medium],
            Vec::new(),
            vec![sun(Vec3::new(1.0, -1.0, -0.5), 2.0)],
        );
        let opts = ReferenceOptions {
            rel_tol: 1e-8,
            footprint_samples: 2,
        };
        let image = render(&s, &opts).unwrap();
        assert_eq!(image.len(), 6 * 4);

        let frame = s.camera.frame_at(0);
        for (x, y) in [(0, 0), (2, 1), (5, 3)] {
            let mut expected = [0.0; 3];
            for (dx, dy) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                let dir = frame.ray_direction(x as f32 + dx, y as f32 + dy, 6, 4);
                let l = radiance(&s, frame.position.as_dvec3(), dir.as_dvec3(), &opts).unwrap();
                for c in 0..3 {
                    expected[c] += 0.25 * l[c];
                }
            }
            let actual = image[y * 6 + x];
            for c in 0..3 {
                assert_close(actual[c], expected[c], 1e-12);
            }
        }
    }

    #[test]
    fn unsupported_scenes_are_errors() {
        let point = Light::Point {
            position: Vec3::ZERO,
            intensity: Vec3::ONE,
        };
        let s = scene(Vec::new(), Vec::new(), vec![point]);
        let message = format!(
            "{:#}",
            radiance(&s, DVec3::ZERO, DVec3::X, &TIGHT).unwrap_err()
        );
        assert!(
            message.contains("not supported by the reference"),
            "{message}"
        );

        let mut s = scene(Vec::new(), Vec::new(), Vec::new());
        s.integrator.max_bounces = 3;
        assert!(render(&s, &TIGHT).is_err());

        let s = scene(Vec::new(), Vec::new(), Vec::new());
        let bad = ReferenceOptions {
            rel_tol: 1e-3,
            footprint_samples: 0,
        };
        assert!(render(&s, &bad).is_err());
    }
}
