//! The scene in f64 as the quadrature models it, and the radiance along one camera ray.

// pbrt names from the equations: T_cam, T_end, E.
#![allow(non_snake_case)]

use std::f64::consts::PI;

use anyhow::{bail, ensure};
use glam::DVec3;
use nimbus_scene::Scene;

use super::hints::{push_gobo_crossings, push_region_edge_crossings};
use super::integrate::{integrate_adaptive_tagged, split_interval};
use super::shapes::{intersect, push_shadow_crossings, SurfaceHit};
use crate::common::geometry::{homogeneous, Region};
use crate::common::lights::{suns_and_sky, Sun};
use crate::common::sampling::henyey_greenstein;
use crate::common::surface::{surface_offset, Surface};

struct PreparedMedium {
    bounds: Region,
    sigma_t: f64,
    sigma_s: DVec3,
    g: f64,
}

/// The scene in f64, checked against what the reference models.
pub(super) struct PreparedScene {
    media: Vec<PreparedMedium>,
    shapes: Vec<Surface>,
    lights: Vec<Sun>,
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
    pub(super) fn new(scene: &Scene) -> anyhow::Result<Self> {
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
            let (Some(bounds), Some((sigma_t, albedo, g))) =
                (Region::of(medium), homogeneous(medium))
            else {
                bail!("{source}: medium {i}: grid media are not supported by the reference");
            };
            media.push(PreparedMedium {
                bounds,
                sigma_t,
                sigma_s: albedo * sigma_t,
                g,
            });
        }

        let shapes: Vec<Surface> = scene.shapes.iter().map(Surface::from_shape).collect();

        let (lights, environment) = suns_and_sky(scene, "reference")?;
        // The renderer's environment lights media and surfaces; this model has it only
        // as the background, which is the whole answer only when nothing scatters.
        let scatters = media.iter().any(|m| m.sigma_s != DVec3::ZERO)
            || shapes.iter().any(|s| s.albedo != DVec3::ZERO);
        ensure!(
            environment == DVec3::ZERO || !scatters,
            "{source}: the reference has the environment only as the background that \
             escaping rays see, but here it would light scattering media or reflecting \
             shapes: use the Monte Carlo reference (nimbus_reference::mc), or black media \
             and shapes"
        );

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
            .filter_map(|s| intersect(s, o, d, t_min))
            .min_by(|a, b| a.t.total_cmp(&b.t))
    }

    /// V_ω(x) T_ω(x) E for one light: the irradiance reaching x, shadowed and
    /// attenuated.
    fn irradiance_at(&self, x: DVec3, light: &Sun) -> DVec3 {
        if let Some(gobo) = &light.gobo {
            if !gobo.lets_through(x) {
                return DVec3::ZERO;
            }
        }
        let towards_light = -light.omega;
        let s_min = surface_offset(x);
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

    /// L along o + t·d, t ≥ 0, |d| = 1, to relative accuracy `rel_tol`.
    pub(super) fn radiance(&self, o: DVec3, d: DVec3, rel_tol: f64) -> [f64; 3] {
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
                    push_region_edge_crossings(&m.bounds, o, d, light.omega, &mut cuts);
                }
                for shape in &self.shapes {
                    push_shadow_crossings(shape, o, d, light.omega, &mut cuts);
                }
                if let Some(gobo) = &light.gobo {
                    push_gobo_crossings(gobo, o, d, light.omega, &mut cuts);
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

#[cfg(test)]
mod tests {
    use glam::{Vec2, Vec3};
    use nimbus_scene::{Gobo, Light, Shape};

    use super::super::{radiance, render, ReferenceOptions};
    use super::*;
    use crate::common::testing::{assert_close, box_medium, box_scene, constant_env, sun};

    const TIGHT: ReferenceOptions = ReferenceOptions {
        rel_tol: 1e-10,
        footprint_samples: 1,
    };

    #[test]
    fn radiance_includes_albedo_phase_and_environment() {
        // Backlit slab along −z (ω = d, cosθ = −1); the environment behind it is seen
        // through it where the slab is black, and refused where it would be lit.
        let sigma_t = 0.6f32;
        let medium = box_medium(
            Vec3::ZERO,
            Vec3::new(2.0, 2.0, 3.0),
            Vec3::ZERO,
            sigma_t,
            0.5,
        );
        let environment = constant_env(Vec3::new(0.5, 1.0, 2.0));
        let lit = sun(Vec3::NEG_Z, Vec3::splat(3.0));
        let s = box_scene(vec![medium.clone()], Vec::new(), vec![lit.clone()]);
        let (origin, dir) = (DVec3::new(0.1, 0.2, 5.0), DVec3::NEG_Z);
        let actual = radiance(&s, origin, dir, &TIGHT).unwrap();

        let (sigma, len) = (f64::from(sigma_t), 3.0);
        let t_box = (1.0 - (-2.0 * sigma * len).exp()) / (2.0 * sigma);
        let phase = (1.0 - 0.25) / (4.0 * PI * 1.5f64.powi(3));
        for (c, a) in actual.into_iter().enumerate() {
            let sigma_s = f64::from(medium.albedo[c]) * sigma;
            assert_close(a, sigma_s * phase * 3.0 * t_box, 1e-9);
        }

        let mut black = medium.clone();
        black.albedo = Vec3::ZERO;
        let s = box_scene(
            vec![black],
            Vec::new(),
            vec![lit.clone(), environment.clone()],
        );
        let actual = radiance(&s, origin, dir, &TIGHT).unwrap();
        for (a, l) in actual.into_iter().zip([0.5, 1.0, 2.0]) {
            assert_close(a, l * (-sigma * len).exp(), 1e-9);
        }

        let s = box_scene(vec![medium], Vec::new(), vec![lit, environment]);
        let message = format!("{:#}", radiance(&s, origin, dir, &TIGHT).unwrap_err());
        assert!(message.contains("Monte Carlo reference"), "{message}");
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
            0.0,
        );
        let (xc, r) = (2.75, 0.375);
        let sphere = Shape::Sphere {
            center: Vec3::new(xc as f32, 3.0, 0.0),
            radius: r as f32,
            albedo: Vec3::ONE,
            emission: Vec3::ZERO,
        };
        let s = box_scene(
            vec![medium.clone()],
            vec![sphere],
            vec![sun(Vec3::NEG_Y, Vec3::splat(2.0))],
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
            0.0,
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
        let s = box_scene(vec![medium], Vec::new(), vec![light]);
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
            emission: Vec3::ZERO,
        };
        let origin = DVec3::new(0.0, 2.0, 2.0);
        let dir = DVec3::new(0.0, -2.0, -2.0);
        let s = box_scene(
            Vec::new(),
            vec![floor.clone()],
            vec![sun(direction, Vec3::splat(4.0))],
        );
        let lit = radiance(&s, origin, dir, &TIGHT).unwrap();
        for (c, albedo) in [0.5, 0.25, 1.0].into_iter().enumerate() {
            assert_close(lit[c], albedo / PI * 4.0 * f64::from(mu), 1e-6);
        }

        let blocker = Shape::Box {
            center: -direction * 2.0,
            size: Vec3::splat(0.5),
            rotation_deg: Vec3::new(10.0, 20.0, 30.0),
            albedo: Vec3::ZERO,
            emission: Vec3::ZERO,
        };
        let s = box_scene(
            Vec::new(),
            vec![floor, blocker],
            vec![sun(direction, Vec3::splat(4.0))],
        );
        assert_eq!(radiance(&s, origin, dir, &TIGHT).unwrap(), [0.0; 3]);
    }

    #[test]
    fn render_averages_footprints_in_row_major_order() {
        let medium = box_medium(
            Vec3::ZERO,
            Vec3::new(2.0, 1.0, 1.0),
            Vec3::new(0.0, 30.0, 0.0),
            1.0,
            0.0,
        );
        let s = box_scene(
            vec![medium],
            Vec::new(),
            vec![sun(Vec3::new(1.0, -1.0, -0.5), Vec3::splat(2.0))],
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
        let s = box_scene(Vec::new(), Vec::new(), vec![point]);
        let message = format!(
            "{:#}",
            radiance(&s, DVec3::ZERO, DVec3::X, &TIGHT).unwrap_err()
        );
        assert!(
            message.contains("not supported by the reference"),
            "{message}"
        );

        let mut s = box_scene(Vec::new(), Vec::new(), Vec::new());
        s.integrator.max_bounces = 3;
        assert!(render(&s, &TIGHT).is_err());

        let s = box_scene(Vec::new(), Vec::new(), Vec::new());
        let bad = ReferenceOptions {
            rel_tol: 1e-3,
            footprint_samples: 0,
        };
        assert!(render(&s, &bad).is_err());
    }
}
