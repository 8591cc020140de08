//! The grid Monte Carlo oracle against the box oracle, closed forms, a furnace and
//! quadrature of its own transmittance.

use std::f64::consts::PI;
use std::path::PathBuf;

use glam::{DVec3, Vec3};
use nimbus_scene::{
    BoxMedium, Gobo, GridMedium, GridSource, Light, Medium, Scene, Shape, VoxelGrid,
};

use super::media::{GridF64, LoadedGrid, MediumKind};
use super::*;
use crate::common::estimate::McEstimate;
use crate::common::testing::{assert_within, constant_env, sun, test_scene};
use crate::mc::{radiance_mc, McOptions};

fn scene(media: Vec<Medium>, shapes: Vec<Shape>, lights: Vec<Light>) -> Scene {
    test_scene(media, shapes, lights, (4, 3), 30.0)
}

fn grid_medium(lo: Vec3, hi: Vec3, density_scale: f32, albedo: Vec3, g: f32) -> GridMedium {
    GridMedium {
        bounds_min: lo,
        bounds_max: hi,
        density: GridSource::ProceduralCloud {
            dims: [16, 16, 16],
            noise_seed: 7,
            kind: Default::default(),
        },
        density_scale,
        albedo,
        g,
        emission: None,
        emission_scale: Vec3::ONE,
        temperature: None,
        albedo_grid: None,
        velocity: None,
        velocity_scale: 1.0,
        frames: Vec::new(),
        vdb: None,
    }
}

fn constant_grid(dims: [u32; 3], value: f32) -> VoxelGrid {
    let n = dims.iter().map(|&d| d as usize).product();
    VoxelGrid {
        dims,
        channels: 1,
        data: vec![value; n],
    }
}

/// A tracer for `s` whose grid media all use the given grids (in order).
fn tracer(s: &Scene, mut grids: Vec<LoadedGrid>) -> Tracer {
    grids.reverse();
    let loaded = s
        .media
        .iter()
        .map(|m| match m {
            Medium::Box(_) | Medium::Convex(_) => None,
            Medium::Grid(_) => grids.pop(),
        })
        .collect();
    Tracer::with_grids(s, loaded, Vec::new()).unwrap()
}

fn run(t: &Tracer, o: DVec3, d: DVec3, k: u32, paths: u32, seed: u64) -> McEstimate {
    let opts = GridOptions {
        max_bounces: k,
        paths,
        seed,
    };
    t.radiance(o, d.normalize(), &opts).estimate()
}

/// ∫ σt along o + t·d, t ∈ [a, b], by composite Simpson on `n` (even) pieces.
fn optical_depth(grid: &GridF64, o: DVec3, d: DVec3, a: f64, b: f64, n: u32) -> f64 {
    let h = (b - a) / f64::from(n);
    let f = |i: u32| grid.sigma_t(o + (a + f64::from(i) * h) * d);
    let mut sum = f(0) + f(n);
    for i in 1..n {
        sum += if i % 2 == 1 { 4.0 } else { 2.0 } * f(i);
    }
    sum * h / 3.0
}

#[test]
fn constant_grid_matches_the_box_reference() {
    // The same homogeneous medium as a box (`mc`, analog tracking, exact
    // shadow transmittance) and as a constant grid (delta + ratio tracking), over a
    // floor, lit by a sun, then by the sun through a gobo whose prism (u ≈ (−0.8, 0, 0.6))
    // cuts the medium and the floor about in half.
    let open = sun(Vec3::new(0.3, -1.0, 0.4), Vec3::new(2.0, 1.5, 1.0));
    let mut masked = open.clone();
    if let Light::Directional { gobo, .. } = &mut masked {
        *gobo = Some(Gobo {
            polygon: [[-0.2, -4.0], [4.0, -4.0], [4.0, 4.0], [-0.2, 4.0]]
                .map(glam::Vec2::from)
                .to_vec(),
            origin: Vec3::ZERO,
        });
    }
    for light in [open, masked] {
        constant_grid_matches_the_box_reference_lit_by(light);
    }
}

fn constant_grid_matches_the_box_reference_lit_by(light: Light) {
    let (center, size) = (Vec3::new(0.1, -0.1, 0.0), Vec3::new(2.0, 1.5, 1.0));
    let (albedo, g, sigma) = (Vec3::new(0.9, 0.5, 0.25), 0.4, 1.5);
    let boxed = Medium::Box(BoxMedium {
        center,
        size,
        rotation_deg: Vec3::ZERO,
        sigma_t: sigma,
        albedo,
        g,
    });
    let gridded = Medium::Grid(grid_medium(
        center - 0.5 * size,
        center + 0.5 * size,
        sigma,
        albedo,
        g,
    ));
    let floor = Shape::Quad {
        corner: Vec3::new(-4.0, -1.0, 4.0),
        edge_u: Vec3::new(8.0, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 0.0, -8.0),
        albedo: Vec3::splat(0.7),
        emission: Vec3::ZERO,
    };
    let box_scene = scene(vec![boxed], vec![floor.clone()], vec![light.clone()]);
    let grid_scene = scene(vec![gridded], vec![floor], vec![light]);
    let t = tracer(
        &grid_scene,
        vec![(constant_grid([5, 4, 3], 1.0), None, None, None)],
    );
    let origin = DVec3::new(0.0, 0.3, 5.0);
    for (j, target) in [DVec3::new(0.1, -0.1, 0.0), DVec3::new(0.8, -0.9, 0.6)]
        .into_iter()
        .enumerate()
    {
        for k in [1, 3] {
            let seed = 10 * j as u64 + u64::from(k);
            let paths = 100_000;
            let mc = run(&t, origin, target - origin, k, paths, seed);
            let opts = McOptions {
                max_bounces: k,
                paths,
                seed: seed + 100,
            };
            let r = radiance_mc(&box_scene, origin, target - origin, &opts).unwrap();
            for c in 0..3 {
                let se = (mc.std_error[c].powi(2) + r.std_error[c].powi(2)).sqrt();
                // Without noise (a point the gobo hides from single scattering) the two
                // must agree exactly.
                let z = if se > 0.0 {
                    (mc.mean[c] - r.mean[c]) / se
                } else {
                    assert_eq!(mc.mean[c], r.mean[c], "target {j}, K = {k}, channel {c}");
                    0.0
                };
                println!(
                    "target {j}, K = {k}, channel {c}: grid {:.6} ± {:.6}, box {:.6} ± {:.6} ({z:.2} SE)",
                    mc.mean[c], mc.std_error[c], r.mean[c], r.std_error[c]
                );
                assert!(
                    z.abs() <= 4.0,
                    "target {j}, K = {k}, channel {c}: {z:.2} SE"
                );
            }
        }
    }
}

#[test]
fn white_furnace_in_a_cloud() {
    // Albedo 1 in a constant environment of radiance 1, lit only through NEE: the
    // sum over orders is 1 everywhere. K = 64 leaves out paths with more than 64
    // collisions: at this optical thickness (max σt = 10 over 2 m) no path of 400k reached
    // 64 collisions (K = 64 and K = 256 gave identical bits).
    let cloud = grid_medium(Vec3::splat(-1.0), Vec3::ONE, 10.0, Vec3::ONE, 0.5);
    let s = scene(
        vec![Medium::Grid(cloud)],
        Vec::new(),
        vec![constant_env(Vec3::ONE)],
    );
    let t = Tracer::new(&s).unwrap();
    let rays = [
        (
            "outside",
            DVec3::new(0.0, 0.2, 5.0),
            DVec3::new(0.0, -0.04, -1.0),
        ),
        (
            "inside",
            DVec3::new(0.0, 0.2, 0.9),
            DVec3::new(0.0, -0.04, -1.0),
        ),
    ];
    for (i, (name, o, d)) in rays.into_iter().enumerate() {
        let mc = run(&t, o, d, 64, 20_000, 40 + i as u64);
        assert_within(&mc, [1.0; 3], 4.0, &format!("furnace, camera {name}"));
        // Not trivially 1: single scattering plus the env seen through the cloud
        // is well below 1.
        let k1 = run(&t, o, d, 1, 20_000, 40 + i as u64);
        println!("furnace, camera {name}: K = 1 gives {:.4}", k1.mean[0]);
        assert!(k1.mean[0] < 0.8, "{name}: {:?}", k1.mean);
    }
}

#[test]
fn heterogeneous_tracking_matches_quadrature_transmittance() {
    // An absorbing cloud (albedo 0): a camera ray through it sees the constant
    // environment times exp(−∫σt) (delta tracking), and a floor outside it lit by
    // a point light through it is albedo/π · I cosθ/r² · exp(−∫σt) (ratio tracking).
    let (lo, hi) = (Vec3::new(-1.0, -0.5, -1.0), Vec3::new(1.0, 1.5, 1.0));
    let cloud = grid_medium(lo, hi, 3.0, Vec3::ZERO, 0.0);
    let floor = Shape::Quad {
        corner: Vec3::new(-4.0, -1.0, 4.0),
        edge_u: Vec3::new(8.0, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 0.0, -8.0),
        albedo: Vec3::splat(0.6),
        emission: Vec3::ZERO,
    };
    let light_pos = DVec3::new(0.2, 3.0, -0.1);
    let point = Light::Point {
        position: light_pos.as_vec3(),
        intensity: Vec3::new(3.0, 2.0, 1.0),
    };
    let s = scene(
        vec![Medium::Grid(cloud)],
        vec![floor],
        vec![point, constant_env(Vec3::new(1.0, 0.5, 0.25))],
    );
    let t = Tracer::new(&s).unwrap();
    let MediumKind::Grid(grid) = &t.media[0].kind else {
        unreachable!()
    };

    // Camera ray through the cloud to the sky (misses the floor).
    let (o, d) = (
        DVec3::new(-3.0, 0.3, 4.0),
        DVec3::new(3.1, 0.35, -4.0).normalize(),
    );
    let (a, b) = grid.bounds.clip(o, d, 0.0, f64::INFINITY).unwrap();
    let tau = optical_depth(grid, o, d, a, b, 20_000);
    assert!(tau > 0.5, "{tau}");
    // The floor is lit too (env NEE): keep the ray above it (it escapes upwards).
    assert!(d.y > 0.0);
    let mc = run(&t, o, d, 1, 100_000, 50);
    let e = (-tau).exp();
    assert_within(
        &mc,
        [e, 0.5 * e, 0.25 * e],
        4.0,
        "camera ray through the cloud",
    );

    // A floor point whose shadow ray to the light crosses the cloud, seen from a
    // camera that does not; env NEE lights the floor too, so remove the env.
    let s2 = scene(s.media.clone(), s.shapes.clone(), vec![s.lights[0].clone()]);
    let t2 = Tracer::new(&s2).unwrap();
    let p = DVec3::new(0.0, -1.0, 0.1);
    let cam = DVec3::new(0.0, -0.6, 5.0);
    assert!(grid
        .bounds
        .clip(cam, (p - cam).normalize(), 0.0, (p - cam).length())
        .is_none());
    let to_light = light_pos - p;
    let (r, l) = (to_light.length(), to_light.normalize());
    let (a, b) = grid.bounds.clip(p, l, 0.0, r).unwrap();
    let tau = optical_depth(grid, p, l, a, b, 20_000);
    assert!(tau > 0.5, "{tau}");
    let geometric = 0.6 / PI * l.y / (r * r) * (-tau).exp();
    let mc = run(&t2, cam, p - cam, 1, 100_000, 51);
    assert_within(
        &mc,
        [3.0 * geometric, 2.0 * geometric, geometric],
        4.0,
        "point light through the cloud",
    );
}

#[test]
fn point_and_sphere_lights_match_closed_forms() {
    // A thin absorbing layer (σt = 0.2, albedo 0) around camera and lights; a
    // Lambertian floor below it at y = −1, the layer's bottom at y = −0.9.
    let layer = grid_medium(
        Vec3::new(-5.0, -0.9, -5.0),
        Vec3::new(5.0, 3.0, 8.0),
        0.2,
        Vec3::ZERO,
        0.0,
    );
    let floor = Shape::Quad {
        corner: Vec3::new(-4.0, -1.0, 4.0),
        edge_u: Vec3::new(8.0, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 0.0, -8.0),
        albedo: Vec3::splat(0.6),
        emission: Vec3::ZERO,
    };
    let (cam, p) = (DVec3::new(0.0, 0.5, 3.0), DVec3::new(0.1, -1.0, -0.2));
    // The length of a segment from y0 to y1 above y = −0.9, per unit length.
    let inside = |y0: f64, y1: f64| (y1.max(-0.9) - y0.max(-0.9)).abs() / (y1 - y0).abs();
    let t_cam = (-0.2 * (cam - p).length() * inside(-1.0, 0.5)).exp();

    let light_pos = DVec3::new(0.3, 1.0, 0.2);
    let point = Light::Point {
        position: light_pos.as_vec3(),
        intensity: Vec3::new(2.0, 1.0, 0.5),
    };
    let s = scene(
        vec![Medium::Grid(layer.clone())],
        vec![floor.clone()],
        vec![point],
    );
    let t = tracer(&s, vec![(constant_grid([4, 4, 4], 1.0), None, None, None)]);
    let to = light_pos - p;
    let (r, l) = (to.length(), to.normalize());
    let t_shadow = (-0.2 * r * inside(-1.0, 1.0)).exp();
    let e = 0.6 / PI * l.y / (r * r) * t_shadow * t_cam;
    let mc = run(&t, cam, p - cam, 1, 100_000, 60);
    assert_within(&mc, [2.0 * e, e, 0.5 * e], 4.0, "point light");

    // Sphere light in vacuum: radiance of the floor = albedo · L · (R/d)² · cosθ
    // (a sphere wholly above the horizon), and the camera sees L directly.
    let (center, radius) = (DVec3::new(0.3, 0.6, 0.2), 0.4);
    let sphere = Light::Sphere {
        center: center.as_vec3(),
        radius: radius as f32,
        radiance: Vec3::new(5.0, 3.0, 1.0),
    };
    let s = scene(Vec::new(), vec![floor.clone()], vec![sphere.clone()]);
    let t = tracer(&s, Vec::new());
    let to = center - p;
    let (dist, axis) = (to.length(), to.normalize());
    let e = 0.6 * (radius / dist).powi(2) * axis.y;
    let mc = run(&t, cam, p - cam, 1, 100_000, 61);
    assert_within(&mc, [5.0 * e, 3.0 * e, e], 4.0, "sphere light on the floor");
    // Seen directly through the absorbing layer (deterministic: SE 0 but exact).
    let s = scene(vec![Medium::Grid(layer)], vec![floor], vec![sphere]);
    let t = tracer(&s, vec![(constant_grid([4, 4, 4], 1.0), None, None, None)]);
    let near = center.z + radius; // the sphere's front at x = 0.3, y = 0.6
    let o = DVec3::new(0.3, 0.6, 7.0);
    let tr = (-0.2 * (o.z - near)).exp();
    let mc = run(&t, o, DVec3::NEG_Z, 1, 100_000, 62);
    assert_within(
        &mc,
        [5.0 * tr, 3.0 * tr, tr],
        4.0,
        "sphere light seen directly",
    );
}

#[test]
fn emission_only_is_le_times_one_minus_transmittance() {
    let mut m = grid_medium(Vec3::splat(-1.0), Vec3::ONE, 1.2, Vec3::ZERO, 0.0);
    m.emission = Some(GridSource::ProceduralCloud {
        dims: [2, 2, 2],
        noise_seed: 0,
        kind: Default::default(),
    });
    m.emission_scale = Vec3::new(0.5, 1.0, 2.0);
    let le = m.emission_scale.as_dvec3();
    let (o, d) = (DVec3::new(0.2, -0.1, 5.0), DVec3::NEG_Z);
    let one_minus_t = 1.0 - (-1.2f64 * 2.0).exp();
    for albedo in [0.0f32, 0.3] {
        m.albedo = Vec3::splat(albedo);
        let s = scene(vec![Medium::Grid(m.clone())], Vec::new(), Vec::new());
        let t = tracer(
            &s,
            vec![(
                constant_grid([3, 3, 3], 1.0),
                Some(constant_grid([2, 2, 2], 1.0)),
                None,
                None,
            )],
        );
        // K = 1: emission at the first collision only, (1 − albedo)·Le·(1 − T).
        let mc = run(&t, o, d, 1, 100_000, 70);
        let expected = (le * (1.0 - f64::from(albedo)) * one_minus_t).to_array();
        assert_within(&mc, expected, 4.0, &format!("emission, albedo {albedo}"));
    }
}

#[test]
fn results_are_deterministic_and_options_checked() {
    let mut cloud = grid_medium(Vec3::splat(-1.0), Vec3::ONE, 3.0, Vec3::splat(0.8), 0.3);
    cloud.emission = Some(GridSource::ProceduralCloud {
        dims: [8, 8, 8],
        noise_seed: 3,
        kind: Default::default(),
    });
    let s = scene(
        vec![Medium::Grid(cloud)],
        vec![Shape::Sphere {
            center: Vec3::new(0.0, -2.0, 0.0),
            radius: 0.8,
            albedo: Vec3::splat(0.5),
            emission: Vec3::ZERO,
        }],
        vec![
            sun(Vec3::new(0.2, -1.0, 0.1), Vec3::ONE),
            Light::Point {
                position: Vec3::new(1.5, 1.5, 1.0),
                intensity: Vec3::ONE,
            },
            Light::Sphere {
                center: Vec3::new(-1.5, 1.5, 0.0),
                radius: 0.3,
                radiance: Vec3::ONE,
            },
            constant_env(Vec3::splat(0.2)),
        ],
    );
    let opts = GridOptions {
        max_bounces: 4,
        paths: 64,
        seed: 5,
    };
    let (mean, se) = render_grid_mc(&s, &opts, 2).unwrap();
    assert_eq!((mean.len(), se.len()), (12, 12));
    assert_eq!(render_grid_mc(&s, &opts, 2).unwrap(), (mean.clone(), se));
    assert!(mean.iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
    let (o, d) = (DVec3::new(0.0, 0.0, 5.0), DVec3::new(0.05, 0.02, -1.0));
    let a = radiance_grid_mc(&s, o, d, &opts).unwrap();
    assert_eq!(a, radiance_grid_mc(&s, o, d, &opts).unwrap());
    let other = GridOptions { seed: 6, ..opts };
    assert_ne!(a, radiance_grid_mc(&s, o, d, &other).unwrap());

    let bad_k = GridOptions {
        max_bounces: 0,
        ..opts
    };
    assert!(radiance_grid_mc(&s, o, d, &bad_k).is_err());
    let one_path = GridOptions { paths: 1, ..opts };
    assert!(radiance_grid_mc(&s, o, d, &one_path).is_err());
    assert!(radiance_grid_mc(&s, o, DVec3::ZERO, &opts).is_err());
    assert!(render_grid_mc(&s, &opts, 3).is_err());
    let mut missing = s.clone();
    missing.lights.push(Light::Environment {
        radiance: Vec3::ONE,
        file: Some(PathBuf::from("/nonexistent/sky.exr")),
        scale: Vec3::ONE,
        rotation_deg: 0.0,
    });
    assert!(radiance_grid_mc(&missing, o, d, &opts).is_err());
}

/// A floor of albedo ρ seen straight down at the origin, under an emitting shape and no
/// medium: the radiance it reflects is ρ·E/π, with E its irradiance.
fn floor_under(emitter: Shape, albedo: f32) -> Scene {
    let floor = Shape::Quad {
        corner: Vec3::new(-20.0, 0.0, 20.0),
        edge_u: Vec3::new(40.0, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 0.0, -40.0),
        albedo: Vec3::splat(albedo),
        emission: Vec3::ZERO,
    };
    scene(Vec::new(), vec![floor, emitter], Vec::new())
}

/// E at a point below the corner of a parallel a × b rectangle of radiance L at height
/// h: π·L·F, with F = 1/(2π)·[A/√(1+A²)·atan(B/√(1+A²)) + B/√(1+B²)·atan(A/√(1+B²))],
/// A = a/h, B = b/h (the view factor of a differential area to a parallel rectangle).
fn rectangle_corner_irradiance(l: f64, a: f64, b: f64, h: f64) -> f64 {
    let (a, b) = (a / h, b / h);
    let (ra, rb) = ((1.0 + a * a).sqrt(), (1.0 + b * b).sqrt());
    let f = (a / ra * (b / ra).atan() + b / rb * (a / rb).atan()) / (2.0 * PI);
    PI * l * f
}

#[test]
fn irradiance_under_an_emitting_quad_matches_the_rectangle_view_factor() {
    // A 2 × 3 m quad at height 1.5 facing down (edge_u × edge_v = −y), centred over the
    // origin; the camera looks at the origin from beside it. E = 4 corner rectangles.
    let (l, rho) = (Vec3::new(2.0, 1.0, 0.5), 0.8);
    let down = Shape::Quad {
        corner: Vec3::new(-1.0, 1.5, -1.5),
        edge_u: Vec3::new(2.0, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 0.0, 3.0),
        albedo: Vec3::ZERO,
        emission: l,
    };
    assert!(down_normal(&down).y < 0.0);
    let s = floor_under(down.clone(), rho);
    let t = tracer(&s, Vec::new());
    let (o, d) = (DVec3::new(3.0, 1.0, 0.0), DVec3::new(-3.0, -1.0, 0.0));
    let mc = run(&t, o, d, 1, 40_000, 3);
    let e1 = 4.0 * rectangle_corner_irradiance(1.0, 1.0, 1.5, 1.5);
    let expected = [0, 1, 2].map(|c| f64::from(rho) / PI * f64::from(l[c]) * e1);
    assert_within(&mc, expected, 4.0, "quad facing down");

    // Flipped (facing up) it lights nothing below it.
    let Shape::Quad {
        corner,
        edge_u,
        edge_v,
        ..
    } = down
    else {
        unreachable!()
    };
    let up = Shape::Quad {
        corner,
        edge_u: edge_v,
        edge_v: edge_u,
        albedo: Vec3::ZERO,
        emission: l,
    };
    let t = tracer(&floor_under(up, rho), Vec::new());
    let mc = run(&t, o, d, 1, 2_000, 4);
    assert_eq!(mc.mean, [0.0; 3], "a quad facing up lights the floor");
}

fn down_normal(shape: &Shape) -> Vec3 {
    match shape {
        Shape::Quad { edge_u, edge_v, .. } => edge_u.cross(*edge_v),
        _ => Vec3::ZERO,
    }
}

#[test]
fn irradiance_from_an_emitting_sphere_is_pi_l_sin2_theta() {
    // A sphere of radius 0.4 with its centre 1.2 above the origin: E = π·L·(r/d)².
    let (l, rho, r, h) = (Vec3::new(3.0, 2.0, 1.0), 0.6, 0.4, 1.2);
    let sphere = Shape::Sphere {
        center: Vec3::new(0.0, h, 0.0),
        radius: r,
        albedo: Vec3::ZERO,
        emission: l,
    };
    let t = tracer(&floor_under(sphere, rho), Vec::new());
    let (o, d) = (DVec3::new(3.0, 0.5, 0.0), DVec3::new(-3.0, -0.5, 0.0));
    let mc = run(&t, o, d, 1, 40_000, 5);
    let sin2 = f64::from(r * r) / f64::from(h * h);
    let expected = [0, 1, 2].map(|c| f64::from(rho) / PI * PI * f64::from(l[c]) * sin2);
    assert_within(&mc, expected, 4.0, "emitting sphere");
}

#[test]
fn camera_rays_see_emitting_shapes_on_their_emitting_side_only() {
    // A black quad facing +z seen from +z (its emission) and from −z (dark); a box and a
    // sphere seen from outside (their emission); K = 1, nothing else lights them.
    let le = Vec3::new(1.5, 0.5, 0.25);
    let quad = Shape::Quad {
        corner: Vec3::new(-1.0, -1.0, 0.0),
        edge_u: Vec3::new(2.0, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 2.0, 0.0),
        albedo: Vec3::ZERO,
        emission: le,
    };
    let t = tracer(&scene(Vec::new(), vec![quad], Vec::new()), Vec::new());
    let front = run(
        &t,
        DVec3::new(0.1, 0.2, 3.0),
        DVec3::new(0.0, 0.0, -1.0),
        1,
        4,
        1,
    );
    let back = run(
        &t,
        DVec3::new(0.1, 0.2, -3.0),
        DVec3::new(0.0, 0.0, 1.0),
        1,
        4,
        1,
    );
    assert_eq!(front.mean, le.as_dvec3().to_array());
    assert_eq!(back.mean, [0.0; 3]);
    for shape in [
        Shape::Box {
            center: Vec3::ZERO,
            size: Vec3::new(1.0, 2.0, 0.5),
            rotation_deg: Vec3::new(10.0, 20.0, 30.0),
            albedo: Vec3::ZERO,
            emission: le,
        },
        Shape::Sphere {
            center: Vec3::ZERO,
            radius: 0.7,
            albedo: Vec3::ZERO,
            emission: le,
        },
    ] {
        let t = tracer(&scene(Vec::new(), vec![shape], Vec::new()), Vec::new());
        let outside = run(
            &t,
            DVec3::new(0.05, 0.1, 4.0),
            DVec3::new(0.0, 0.0, -1.0),
            1,
            4,
            2,
        );
        assert_eq!(outside.mean, le.as_dvec3().to_array());
        let inside = run(
            &t,
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 1.0),
            1,
            4,
            2,
        );
        assert_eq!(inside.mean, [0.0; 3]);
    }
}

#[test]
fn an_emitting_box_lights_the_floor_like_its_six_faces_as_quads() {
    // The same emitter as a box and as its six faces given as outward quads: the floor's
    // radiance agrees within noise (both go through the area-light sampler).
    let (center, size, rotation) = (
        Vec3::new(0.2, 1.4, -0.1),
        Vec3::new(0.8, 0.5, 0.6),
        Vec3::new(25.0, -15.0, 40.0),
    );
    let le = Vec3::new(2.0, 1.0, 1.5);
    let boxed = Shape::Box {
        center,
        size,
        rotation_deg: rotation,
        albedo: Vec3::ZERO,
        emission: le,
    };
    let r = nimbus_scene::rotation_xyz_deg(rotation);
    let half = size * 0.5;
    let axes = [r.x_axis * half.x, r.y_axis * half.y, r.z_axis * half.z];
    let mut faces = Vec::new();
    for a in 0..3 {
        let (b, c) = (axes[(a + 1) % 3], axes[(a + 2) % 3]);
        for sign in [1.0f32, -1.0] {
            let (u, v) = if sign > 0.0 { (b, c) } else { (c, b) };
            faces.push(Shape::Quad {
                corner: center + sign * axes[a] - u - v,
                edge_u: 2.0 * u,
                edge_v: 2.0 * v,
                albedo: Vec3::ZERO,
                emission: le,
            });
        }
    }
    let floor = |extra: Vec<Shape>| {
        let mut shapes = vec![Shape::Quad {
            corner: Vec3::new(-20.0, 0.0, 20.0),
            edge_u: Vec3::new(40.0, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, -40.0),
            albedo: Vec3::splat(0.7),
            emission: Vec3::ZERO,
        }];
        shapes.extend(extra);
        scene(Vec::new(), shapes, Vec::new())
    };
    let (o, d) = (DVec3::new(3.0, 1.0, 0.5), DVec3::new(-3.0, -1.0, -0.3));
    let a = run(&tracer(&floor(vec![boxed]), Vec::new()), o, d, 1, 40_000, 7);
    let b = run(&tracer(&floor(faces), Vec::new()), o, d, 1, 40_000, 8);
    for c in 0..3 {
        let se = (a.std_error[c].powi(2) + b.std_error[c].powi(2)).sqrt();
        assert!(
            (a.mean[c] - b.mean[c]).abs() <= 4.0 * se,
            "channel {c}: box {} vs faces {} (SE {se})",
            a.mean[c],
            b.mean[c]
        );
        assert!(a.mean[c] > 0.0);
    }
}

/// The grid oracle samples a turned map by its turned importance sampler: a wall facing
/// +Z under the map turned by 90° agrees with the wall under the map shifted a quarter
/// turn (sampled by the shifted map's own tables), and not with the wrong sign.
#[test]
fn a_map_turned_a_quarter_is_sampled_as_the_map_shifted_a_quarter() {
    use crate::common::testing::{map_env, wall_facing_z, write_turned_maps};
    let (map, shifted) = write_turned_maps("grid-turn");
    let run_map = |light: Light, seed: u64| {
        let s = scene(Vec::new(), vec![wall_facing_z()], vec![light]);
        let t = Tracer::new(&s).unwrap();
        run(
            &t,
            DVec3::new(0.4, 0.5, 3.0),
            DVec3::new(-0.1, 0.0, -1.0),
            1,
            20_000,
            seed,
        )
    };
    let turned = run_map(map_env(map.clone(), 90.0), 5);
    let reference = run_map(map_env(shifted, 0.0), 6);
    let wrong = run_map(map_env(map, -90.0), 7);
    for c in 0..3 {
        let se = turned.std_error[c].hypot(reference.std_error[c]);
        assert!(
            (turned.mean[c] - reference.mean[c]).abs() <= 4.0 * se,
            "channel {c}: turned {turned:?} vs shifted {reference:?}"
        );
    }
    assert!(
        turned.mean[0] > 3.0 * wrong.mean[0],
        "{turned:?} vs {wrong:?}"
    );
}
