//! Scenes and checks for the oracles' unit tests.

use glam::Vec3;
use nimbus_scene::{BoxMedium, ConvexMedium, Light, Medium, Scene, Shape};

use super::estimate::McEstimate;

/// A scene for the oracles' unit tests: a camera at (0, 0, 5) looking at the origin,
/// `size` pixels, `fov_deg` horizontal field of view, default integrator settings.
pub(crate) fn test_scene(
    media: Vec<Medium>,
    shapes: Vec<Shape>,
    lights: Vec<Light>,
    size: (u32, u32),
    fov_deg: f32,
) -> Scene {
    Scene {
        source: std::path::PathBuf::from("<test>"),
        light_keyframes: Vec::new(),
        light_groups: Vec::new(),
        render: nimbus_scene::RenderSettings {
            width: size.0,
            height: size.1,
            ..nimbus_scene::RenderSettings::default()
        },
        camera: nimbus_scene::Camera {
            position: Vec3::new(0.0, 0.0, 5.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            horizontal_fov_deg: fov_deg,
            keyframes: Vec::new(),
        },
        lights,
        media,
        overlaps: Vec::new(),
        shapes,
        integrator: nimbus_scene::Integrator::default(),
    }
}

/// [`test_scene`] of 6×4 pixels, 40° wide, with homogeneous box media.
pub(crate) fn box_scene(media: Vec<BoxMedium>, shapes: Vec<Shape>, lights: Vec<Light>) -> Scene {
    test_scene(
        media.into_iter().map(Medium::Box).collect(),
        shapes,
        lights,
        (6, 4),
        40.0,
    )
}

/// A homogeneous box of albedo (0.9, 0.5, 0.25).
pub(crate) fn box_medium(
    center: Vec3,
    size: Vec3,
    rotation_deg: Vec3,
    sigma_t: f32,
    g: f32,
) -> BoxMedium {
    BoxMedium {
        center,
        size,
        rotation_deg,
        sigma_t,
        albedo: Vec3::new(0.9, 0.5, 0.25),
        g,
    }
}

/// A homogeneous convex medium of albedo (0.9, 0.5, 0.25): the half-spaces n·x <= d
/// of `planes`.
pub(crate) fn convex_medium(planes: &[[f64; 4]], sigma_t: f32, g: f32) -> ConvexMedium {
    ConvexMedium::new(planes, sigma_t, Vec3::new(0.9, 0.5, 0.25), g).unwrap()
}

/// The 12 planes of a regular dodecahedron of inradius `r` about `center`.
pub(crate) fn dodecahedron_planes(center: Vec3, r: f64) -> Vec<[f64; 4]> {
    let phi = (1.0 + 5f64.sqrt()) / 2.0;
    let mut planes = Vec::new();
    for a in [-1.0, 1.0] {
        for b in [-phi, phi] {
            for n in [[0.0, a, b], [a, b, 0.0], [b, 0.0, a]] {
                let n = glam::DVec3::from_array(n).normalize();
                planes.push([n.x, n.y, n.z, r + n.dot(center.as_dvec3())]);
            }
        }
    }
    planes
}

/// A directional light without a gobo.
pub(crate) fn sun(direction: Vec3, irradiance: Vec3) -> Light {
    Light::Directional {
        direction: direction.normalize(),
        irradiance,
        gobo: None,
    }
}

/// A constant environment light.
pub(crate) fn constant_env(radiance: Vec3) -> Light {
    Light::Environment {
        radiance,
        file: None,
        scale: Vec3::ONE,
        rotation_deg: 0.0,
    }
}

/// |mc − expected| ≤ k·SE + 1e-12·|expected| per channel (the slack covers rays
/// whose estimate is deterministic, SE = 0).
pub(crate) fn assert_within(mc: &McEstimate, expected: [f64; 3], k: f64, what: &str) {
    for (c, e) in expected.into_iter().enumerate() {
        let (m, se) = (mc.mean[c], mc.std_error[c]);
        println!(
            "{what}, channel {c}: MC {m:.6} ± {se:.6}, expected {e:.6} ({:.2} SE)",
            (m - e) / se
        );
        assert!(
            (m - e).abs() <= k * se + 1e-12 * e.abs(),
            "{what}, channel {c}: MC {m:e} ± {se:e}, expected {e:e} ({:.2} SE)",
            (m - e) / se
        );
    }
}

/// |actual − expected| ≤ rel·|expected|.
pub(crate) fn assert_close(actual: f64, expected: f64, rel: f64) {
    let err = (actual - expected).abs();
    assert!(
        err <= rel * expected.abs().max(1e-300),
        "actual {actual:e}, expected {expected:e}, relative error {:e} > {rel:e}",
        err / expected.abs()
    );
}

/// Writes an 8 × 4 equirectangular map to the temp dir, and beside it the same map with
/// its columns shifted a quarter turn (column x of the second is column x + 2 of the
/// first: shifted(u) = map(u + 1/4), what the first shows turned by `rotation_deg` =
/// 90). The map is dim (0.1) but for a bright patch (radiance 10, 5, 2) in columns 2
/// and 3 of the upper two rows: azimuths from −X to −Z above the horizon.
pub(crate) fn write_turned_maps(name: &str) -> (std::path::PathBuf, std::path::PathBuf) {
    let dir = std::env::temp_dir().join(format!("nimbus-reference-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let texel = |x: usize, y: usize| {
        if y < 2 && (2..4).contains(&x) {
            (10.0f32, 5.0f32, 2.0f32)
        } else {
            (0.1, 0.1, 0.1)
        }
    };
    let map = dir.join(format!("{name}.exr"));
    let shifted = dir.join(format!("{name}-shifted.exr"));
    exr::prelude::write_rgb_file(&map, 8, 4, texel).unwrap();
    exr::prelude::write_rgb_file(&shifted, 8, 4, |x, y| texel((x + 2) % 8, y)).unwrap();
    (map, shifted)
}

/// An environment light of the map at `file` turned by `rotation_deg`.
pub(crate) fn map_env(file: std::path::PathBuf, rotation_deg: f32) -> Light {
    Light::Environment {
        radiance: Vec3::ONE,
        file: Some(file),
        scale: Vec3::ONE,
        rotation_deg,
    }
}

/// A 4 × 3 m Lambertian wall of albedo 0.8 in the plane z = 0, facing +Z, its lower
/// edge at y = −1.
pub(crate) fn wall_facing_z() -> Shape {
    Shape::Quad {
        corner: Vec3::new(-2.0, -1.0, 0.0),
        edge_u: Vec3::new(4.0, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 3.0, 0.0),
        albedo: Vec3::splat(0.8),
        emission: Vec3::ZERO,
    }
}
