//! An independent f64 CPU reference for single scattering in homogeneous box media.
//!
//! This is the oracle the GPU passes are checked against, so it shares no algorithm with
//! them: its own f64 geometry (slab tests in each box's local frame, exact segment
//! lengths, its own ray–shape intersections in `shapes`) and brute-force adaptive
//! Gauss–Kronrod quadrature along each camera ray instead of analytic integration, ray
//! marching or sampling.
//!
//! # Model
//!
//! A camera ray is x(t) = o + t·d with |d| = 1, t ≥ 0.
//!
//! - **Media**: homogeneous boxes ([`BoxMedium`]), world = center + R·local with R =
//!   `rotation_xyz_deg(rotation_deg)` and local ∈ [−size/2, size/2], and homogeneous
//!   convex polyhedra ([`ConvexMedium`], the intersection of the half-spaces n·x <= d of
//!   its f32 planes, clipped plane by plane). Extinction σt is a scalar, σs = albedo·σt
//!   per RGB channel, Henyey–Greenstein phase with asymmetry g.
//!   Media do not overlap; outside them is vacuum.
//! - **Shapes** ([`Shape`](nimbus_scene::Shape)) are opaque Lambertian surfaces with
//!   `albedo` (0 is a black occluder). t_S is the distance to the first shape hit (∞ if
//!   none).
//! - **Lights**: directional lights with travel direction ω (unit), irradiance E and an
//!   optional gobo (x is lit only if its projection (u, v) = ((x − origin)·U,
//!   (x − origin)·V), (U, V) = `Gobo::basis(ω)`, lies in the convex polygon, boundary
//!   included). Constant environment lights (`radiance · scale`, no file) are seen only
//!   by rays that escape; this model has no environment lighting, so a scene whose
//!   environment would light a scattering medium or a reflecting shape (as the renderer
//!   does) is an error: [`crate::mc`] is the oracle for those. Any other light, grid
//!   media, animated cameras and `max_bounces` ≠ 1 are errors.
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
//! a box, convex polyhedron, quad, gobo or sphere silhouette, which is where V_ω and T_ω
//! may jump or kink.
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

// pbrt names from the equations: T_cam, T_light.
#![allow(non_snake_case)]

mod hints;
mod integrate;
mod scene;
mod shapes;

use anyhow::ensure;
use glam::DVec3;
use nimbus_scene::{BoxMedium, ConvexMedium, Scene};

use crate::common::geometry::{normalized, ConvexF64, OrientedBox, Region};
use crate::common::parallel::in_parallel;
use hints::push_region_edge_crossings;
use integrate::{integrate_adaptive, split_interval};
pub use integrate::{INITIAL_SUBINTERVALS, MAX_BISECTIONS, MAX_DEPTH};
use scene::PreparedScene;

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

    let rows = in_parallel(height as usize, |y| {
        (0..width).map(|x| pixel(x, y as u32)).collect::<Vec<_>>()
    });
    Ok(rows.into_iter().flatten().collect())
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
    let bounds = OrientedBox::from_scene(medium.center, medium.size, medium.rotation_deg);
    unoccluded_in_region(
        &Region::Box(bounds),
        medium.sigma_t,
        light_dir,
        origin,
        dir,
        t_max,
        rel_tol,
    )
}

/// [`unoccluded_single_scatter`] for a convex medium.
pub fn unoccluded_single_scatter_convex(
    medium: &ConvexMedium,
    light_dir: DVec3,
    origin: DVec3,
    dir: DVec3,
    t_max: f64,
    rel_tol: f64,
) -> f64 {
    let region = Region::Convex(ConvexF64::from_scene(medium));
    unoccluded_in_region(
        &region,
        medium.sigma_t,
        light_dir,
        origin,
        dir,
        t_max,
        rel_tol,
    )
}

/// ∫ T_cam T_ω over the part of the ray inside `region` (see [`unoccluded_single_scatter`]).
fn unoccluded_in_region(
    region: &Region,
    sigma_t: f32,
    light_dir: DVec3,
    origin: DVec3,
    dir: DVec3,
    t_max: f64,
    rel_tol: f64,
) -> f64 {
    let sigma_t = f64::from(sigma_t);
    let (omega, d) = (light_dir.normalize(), dir.normalize());
    let Some((t0, t1)) = region.clip(origin, d, 0.0, t_max) else {
        return 0.0;
    };

    // Split at the planes swept along ω by the edges (where T_ω's exit face changes).
    let mut cuts = Vec::new();
    push_region_edge_crossings(region, origin, d, omega, &mut cuts);
    let pieces = split_interval(t0, t1, &cuts);
    let integrand = |t: f64| {
        let x = origin + t * d;
        let T_cam = (-sigma_t * (t - t0)).exp();
        let T_light = (-sigma_t * region.chord_length(x, -omega, 0.0, f64::INFINITY)).exp();
        DVec3::new(T_cam * T_light, 0.0, 0.0)
    };
    integrate_adaptive(&pieces, integrand, rel_tol.max(f64::EPSILON), 0.0).x
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

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::common::geometry::rotation_xyz_deg_f64;
    use crate::common::testing::{assert_close, box_medium};

    #[test]
    fn light_along_the_view_direction() {
        // ω = d: T_cam = T_ω = exp(−σt (t − t0)), so the integral is (1 − e^{−2σt L})/(2σt).
        let sigma_t = 0.7;
        let medium = box_medium(
            Vec3::ZERO,
            Vec3::new(2.0, 3.0, 4.0),
            Vec3::ZERO,
            sigma_t,
            0.0,
        );
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
        let medium = box_medium(
            Vec3::ZERO,
            Vec3::new(2.0, 3.0, 4.0),
            Vec3::ZERO,
            sigma_t,
            0.0,
        );
        let (origin, dir) = (DVec3::new(-4.0, 0.5, 0.1), DVec3::X);
        let (s, len) = (f64::from(sigma_t), 2.0);
        let actual = unoccluded_single_scatter(&medium, -dir, origin, dir, f64::INFINITY, 1e-12);
        assert_close(actual, len * (-s * len).exp(), 1e-10);
    }

    #[test]
    fn camera_inside_the_box_with_light_along_the_view() {
        // The light ray first crosses the b metres behind the camera: T_ω = e^{−σt(t + b)}.
        let sigma_t = 0.4;
        let medium = box_medium(Vec3::ZERO, Vec3::splat(2.0), Vec3::ZERO, sigma_t, 0.0);
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
                0.0,
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
            0.0,
        );
        let axis = rotation_xyz_deg_f64(rotation) * DVec3::X;
        let origin = medium.center.as_dvec3() - 3.0 * axis;
        let light = DVec3::new(0.3, -1.0, 0.2);
        let actual = unoccluded_single_scatter(&medium, light, origin, axis, f64::INFINITY, 1e-12);
        assert_close(actual, 1.7, 1e-6);
    }

    #[test]
    fn a_convex_box_integrates_like_the_box() {
        // The six planes of an axis-aligned box, with one redundant plane.
        let medium = box_medium(
            Vec3::new(0.3, 0.0, -0.2),
            Vec3::new(2.0, 1.0, 1.5),
            Vec3::ZERO,
            1.3,
            0.0,
        );
        let (c, h) = (medium.center.as_dvec3(), medium.size.as_dvec3() * 0.5);
        let mut planes = Vec::new();
        for axis in 0..3 {
            for sign in [-1.0, 1.0] {
                let mut n = DVec3::ZERO;
                n[axis] = sign;
                planes.push([n.x, n.y, n.z, h[axis] + n.dot(c)]);
            }
        }
        planes.push([1.0, 1.0, 1.0, 10.0]);
        let convex = crate::common::testing::convex_medium(&planes, 1.3, 0.0);
        let light = DVec3::new(0.3, -1.0, 0.45);
        for (origin, dir) in [
            (DVec3::new(0.2, 0.9, 4.0), DVec3::new(0.0, -0.2, -1.0)),
            (DVec3::new(0.5, 0.1, 0.0), DVec3::new(-1.0, 0.3, 0.2)),
        ] {
            let expected =
                unoccluded_single_scatter(&medium, light, origin, dir, f64::INFINITY, 1e-11);
            let actual =
                unoccluded_single_scatter_convex(&convex, light, origin, dir, f64::INFINITY, 1e-11);
            assert!(expected > 0.0);
            // The planes' offsets h + n·c are rounded to f32 (the box's centre and size
            // are f32 separately): the faces differ by ~1e-8 m.
            assert_close(actual, expected, 1e-7);
        }
    }

    #[test]
    fn a_miss_gives_zero() {
        let medium = box_medium(Vec3::ZERO, Vec3::ONE, Vec3::ZERO, 1.0, 0.0);
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
}
