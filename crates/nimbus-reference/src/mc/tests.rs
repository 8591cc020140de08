//! The box Monte Carlo oracle against the quadrature reference, closed forms and
//! itself.

use std::f64::consts::PI;
use std::path::PathBuf;

use glam::{DVec3, Vec2, Vec3};
use nimbus_scene::{Gobo, GridMedium, GridSource, Light, Medium, Scene, Shape};

use super::*;
use crate::common::sampling::henyey_greenstein;
use crate::common::testing::{
    assert_within, box_medium, box_scene, constant_env, convex_medium, dodecahedron_planes, sun,
    test_scene,
};
use crate::quadrature::{self, ReferenceOptions};

const QUADRATURE: ReferenceOptions = ReferenceOptions {
    rel_tol: 1e-9,
    footprint_samples: 1,
};

/// A rotated box in front of the camera, lit obliquely (no environment: the
/// quadrature has none to light the box).
fn lit_box(shapes: Vec<Shape>, gobo: Option<Gobo>) -> Scene {
    let m = box_medium(
        Vec3::new(0.1, -0.2, 0.0),
        Vec3::new(2.0, 1.5, 1.0),
        Vec3::new(20.0, 35.0, -10.0),
        0.8,
        0.4,
    );
    let light = Light::Directional {
        direction: Vec3::new(0.3, -1.0, 0.4).normalize(),
        irradiance: Vec3::new(2.0, 1.5, 1.0),
        gobo,
    };
    box_scene(vec![m], shapes, vec![light])
}

#[test]
fn single_scattering_agrees_with_the_quadrature_reference() {
    let omega = Vec3::new(0.3, -1.0, 0.4).normalize();
    // A sphere up the beam from the box shadows part of it (and is lit itself).
    let sphere = Shape::Sphere {
        center: Vec3::new(0.3, 0.0, 0.0) - 2.5 * omega,
        radius: 0.45,
        albedo: Vec3::new(0.6, 0.4, 0.2),
        emission: Vec3::ZERO,
    };
    // A triangle gobo through the box centre (vertical-ish beam: u ≈ x).
    let gobo = Gobo {
        polygon: vec![
            Vec2::new(-0.7, -0.5),
            Vec2::new(0.6, -0.4),
            Vec2::new(0.0, 0.6),
        ],
        origin: Vec3::new(0.1, -0.2, 0.0) - 5.0 * omega,
    };
    let scenes = [
        ("box", lit_box(Vec::new(), None)),
        ("box + sphere", lit_box(vec![sphere], None)),
        ("box + gobo", lit_box(Vec::new(), Some(gobo))),
    ];
    let origin = DVec3::new(0.0, 0.2, 5.0);
    let targets = [
        DVec3::new(0.1, -0.2, 0.0),
        DVec3::new(0.5, 0.1, 0.2),
        DVec3::new(-0.4, -0.5, -0.3),
        // The sphere's upper front, lit.
        DVec3::new(0.3, 0.36, 0.0) - 2.5 * omega.as_dvec3(),
        DVec3::new(4.0, 3.0, 0.0), // a miss
    ];
    for (i, (name, s)) in scenes.iter().enumerate() {
        for (j, target) in targets.into_iter().enumerate() {
            let opts = McOptions {
                max_bounces: 1,
                paths: 200_000,
                seed: (10 * i + j) as u64,
            };
            let dir = target - origin;
            let expected = quadrature::radiance(s, origin, dir, &QUADRATURE).unwrap();
            let mc = radiance_mc(s, origin, dir, &opts).unwrap();
            assert_within(&mc, expected, 4.0, &format!("{name}, towards {target}"));
        }
    }
}

#[test]
fn without_albedo_higher_orders_add_nothing() {
    // Black medium and black shapes: every path stops at its first scattering, so
    // K = 3 draws the same numbers as K = 1 and gives the same bits (the environment
    // lights nothing black).
    let mut s = lit_box(
        vec![Shape::Quad {
            corner: Vec3::new(-3.0, -1.5, 3.0),
            edge_u: Vec3::new(6.0, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, -6.0),
            albedo: Vec3::ZERO,
            emission: Vec3::ZERO,
        }],
        None,
    );
    let Medium::Box(m) = &mut s.media[0] else {
        unreachable!()
    };
    m.albedo = Vec3::ZERO;
    s.lights.push(constant_env(Vec3::new(0.1, 0.2, 0.3)));
    let (origin, dir) = (DVec3::new(0.0, 0.2, 5.0), DVec3::new(0.02, -0.08, -1.0));
    let one = McOptions {
        max_bounces: 1,
        paths: 20_000,
        seed: 3,
    };
    let three = McOptions {
        max_bounces: 3,
        ..one
    };
    let k1 = radiance_mc(&s, origin, dir, &one).unwrap();
    let k3 = radiance_mc(&s, origin, dir, &three).unwrap();
    assert_eq!(k1, k3);
    // Only the environment through the box remains, and not every path sees it.
    assert!(k1.mean[2] > 0.0 && k1.std_error[2] > 0.0);
}

/// A dense, bright rotated box of albedo `albedo` over a bright floor, lit by a sun,
/// with `more` shapes.
fn dense_box_over_floor(albedo: Vec3, more: Vec<Shape>) -> Scene {
    let mut m = box_medium(
        Vec3::ZERO,
        Vec3::new(2.0, 1.0, 1.5),
        Vec3::new(0.0, 30.0, 10.0),
        2.5,
        0.3,
    );
    m.albedo = albedo;
    let floor = Shape::Quad {
        corner: Vec3::new(-4.0, -1.0, 4.0),
        edge_u: Vec3::new(8.0, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 0.0, -8.0),
        albedo: Vec3::splat(0.7),
        emission: Vec3::ZERO,
    };
    box_scene(
        vec![m],
        [floor].into_iter().chain(more).collect(),
        vec![sun(Vec3::new(0.4, -1.0, 0.2), Vec3::splat(3.0))],
    )
}

/// A camera ray (origin, direction) through [`dense_box_over_floor`].
const DENSE_BOX_RAY: (DVec3, DVec3) = (DVec3::new(0.0, 0.5, 5.0), DVec3::new(0.1, -0.15, -1.0));

#[test]
fn radiance_grows_with_the_scattering_order() {
    // A dense, bright box over a bright floor: common random numbers make each
    // path's K = 1 estimate a prefix of its K = 2 and K = 4 ones, so the means are
    // ordered exactly; the increments must also exceed the noise.
    let s = dense_box_over_floor(Vec3::new(0.95, 0.8, 0.6), Vec::new());
    let (origin, dir) = DENSE_BOX_RAY;
    let run = |k: u32| {
        let opts = McOptions {
            max_bounces: k,
            paths: 50_000,
            seed: 5,
        };
        radiance_mc(&s, origin, dir, &opts).unwrap()
    };
    let (k1, k2, k4) = (run(1), run(2), run(4));
    for c in 0..3 {
        assert!(k1.mean[c] <= k2.mean[c] && k2.mean[c] <= k4.mean[c]);
        assert!(
            k2.mean[c] - k1.mean[c] > 4.0 * k2.std_error[c],
            "channel {c}"
        );
        assert!(
            k4.mean[c] - k2.mean[c] > 4.0 * k4.std_error[c],
            "channel {c}"
        );
    }
}

/// ∫_a^b f by composite 5-point Gauss–Legendre on `panels` equal pieces.
fn gauss_legendre(f: impl Fn(f64) -> f64, a: f64, b: f64, panels: u32) -> f64 {
    const NODES: [f64; 5] = [
        0.0,
        -0.538_469_310_105_683_1,
        0.538_469_310_105_683_1,
        -0.906_179_845_938_664,
        0.906_179_845_938_664,
    ];
    const WEIGHTS: [f64; 5] = [
        0.568_888_888_888_888_9,
        0.478_628_670_499_366_5,
        0.478_628_670_499_366_5,
        0.236_926_885_056_189_1,
        0.236_926_885_056_189_1,
    ];
    let h = (b - a) / f64::from(panels);
    (0..panels)
        .map(|i| {
            let mid = a + (f64::from(i) + 0.5) * h;
            (0..5)
                .map(|j| WEIGHTS[j] * f(mid + 0.5 * h * NODES[j]))
                .sum::<f64>()
                * 0.5
                * h
        })
        .sum()
}

#[test]
fn double_scattering_in_a_slab_matches_a_one_dimensional_integral() {
    // A wide slab z ∈ [0, H] seen along +z from z < 0, lit by a beam travelling +z
    // (so everything is symmetric about the z axis). Order 1: the camera sees
    // backscatter, L1 = σs p(−1) E (1 − e^{−2σH})/(2σ). Order 2: with the second
    // scattering at depth z on the camera ray and the first at distance r in
    // direction u from it, μ = u·z, the first turns ω into −u (cosine −μ), the
    // second −u into −z (cosine μ); integrating r up to the slab face R(μ):
    // L2 = 2π σs² E ∫_0^H e^{−2σz} ∫_{−1}^{1} p(−μ) p(μ) (1 − e^{−σR(1+μ)})/(σ(1+μ)) dμ dz,
    // R = (H − z)/μ for μ > 0 and z/(−μ) for μ < 0.
    let (sigma, h, g) = (1.0f64, 1.0f64, 0.3f64);
    let mut m = box_medium(
        Vec3::new(0.0, 0.0, 0.5),
        Vec3::new(400.0, 400.0, 1.0),
        Vec3::ZERO,
        sigma as f32,
        g as f32,
    );
    m.albedo = Vec3::new(0.95, 0.6, 0.3);
    let albedo = m.albedo.as_dvec3();
    let s = box_scene(vec![m], Vec::new(), vec![sun(Vec3::Z, Vec3::ONE)]);

    let p = |mu: f64| henyey_greenstein(mu, g);
    let first = p(-1.0) * (1.0 - (-2.0 * sigma * h).exp()) / (2.0 * sigma);
    // The inner integrand, with (1 − e^{−a})/(1+μ) via expm1 near μ = −1; the
    // substitution μ = ±s² (dμ = 2s ds) resolves the edge near μ = 0 where R → ∞.
    let inner = |z: f64, mu: f64| {
        let r = if mu > 0.0 { (h - z) / mu } else { z / -mu };
        p(-mu) * p(mu) * -(-sigma * r * (1.0 + mu)).exp_m1() / (sigma * (1.0 + mu))
    };
    let second = 2.0
        * PI
        * gauss_legendre(
            |z| {
                let forward = gauss_legendre(|s| 2.0 * s * inner(z, s * s), 0.0, 1.0, 60);
                let back = gauss_legendre(|s| 2.0 * s * inner(z, -s * s), 0.0, 1.0, 60);
                (-2.0 * sigma * z).exp() * (forward + back)
            },
            0.0,
            h,
            60,
        );
    let expected: [f64; 3] = std::array::from_fn(|c| {
        let sigma_s = albedo[c] * sigma;
        sigma_s * first + sigma_s * sigma_s * second
    });

    let opts = McOptions {
        max_bounces: 2,
        paths: 200_000,
        seed: 9,
    };
    let mc = radiance_mc(&s, DVec3::new(0.0, 0.0, -1.0), DVec3::Z, &opts).unwrap();
    assert_within(&mc, expected, 4.0, "slab, K = 2");
    // The second order is a sizeable part of the answer, so the test can see it.
    assert!(second * albedo[0] > 0.3 * first, "{second} vs {first}");
}

#[test]
fn render_agrees_with_the_quadrature_render() {
    // A wide slab fills the whole view, so every pixel is smooth; the quadrature's
    // 6×6 midpoint footprint and the MC's jittered 2×2 strata estimate the same mean.
    let m = box_medium(
        Vec3::ZERO,
        Vec3::new(20.0, 20.0, 1.5),
        Vec3::new(5.0, -10.0, 0.0),
        1.2,
        0.5,
    );
    let s = box_scene(
        vec![m],
        Vec::new(),
        vec![sun(Vec3::new(0.2, -0.5, -1.0), Vec3::new(1.0, 2.0, 3.0))],
    );
    let opts = McOptions {
        max_bounces: 1,
        paths: 2_000,
        seed: 21,
    };
    let (mean, std_error) = render_mc(&s, &opts, 2).unwrap();
    assert_eq!((mean.len(), std_error.len()), (24, 24));
    let ref_opts = ReferenceOptions {
        rel_tol: 1e-8,
        footprint_samples: 6,
    };
    let expected = quadrature::render(&s, &ref_opts).unwrap();
    for (i, e) in expected.into_iter().enumerate() {
        let mc = McEstimate {
            mean: mean[i],
            std_error: std_error[i],
        };
        assert_within(&mc, e, 4.5, &format!("pixel {i}"));
    }
    // Same seed, same image; footprint 0 is the pixel centre.
    assert_eq!(render_mc(&s, &opts, 2).unwrap().0, mean);
    let (centre, centre_se) = render_mc(&s, &opts, 0).unwrap();
    let ref_centre = ReferenceOptions {
        rel_tol: 1e-8,
        footprint_samples: 1,
    };
    for (i, e) in quadrature::render(&s, &ref_centre)
        .unwrap()
        .into_iter()
        .enumerate()
    {
        let mc = McEstimate {
            mean: centre[i],
            std_error: centre_se[i],
        };
        assert_within(&mc, e, 4.5, &format!("pixel centre {i}"));
    }
}

#[test]
fn unsupported_scenes_and_options_are_errors() {
    let opts = McOptions {
        max_bounces: 2,
        paths: 16,
        seed: 0,
    };
    let ray = |s: &Scene, opts: &McOptions| {
        radiance_mc(s, DVec3::ZERO, DVec3::X, opts)
            .map(|_| ())
            .map_err(|e| format!("{e:#}"))
    };
    let point = Light::Point {
        position: Vec3::ZERO,
        intensity: Vec3::ONE,
    };
    let sphere = Light::Sphere {
        center: Vec3::ZERO,
        radius: 1.0,
        radiance: Vec3::ONE,
    };
    let missing_map = Light::Environment {
        radiance: Vec3::ONE,
        file: Some(PathBuf::from("no-such-sky.exr")),
        scale: Vec3::ONE,
        rotation_deg: 0.0,
    };
    for (light, words) in [
        (point, "point lights"),
        (sphere, "sphere lights"),
        (missing_map, "light 1"),
    ] {
        let message = ray(&box_scene(Vec::new(), Vec::new(), vec![light]), &opts).unwrap_err();
        assert!(message.contains(words), "{message}");
    }

    let mut s = box_scene(Vec::new(), Vec::new(), Vec::new());
    s.media.push(Medium::Grid(GridMedium {
        bounds_min: Vec3::splat(-1.0),
        bounds_max: Vec3::ONE,
        density: GridSource::ProceduralCloud {
            dims: [4, 4, 4],
            noise_seed: 1,
            kind: Default::default(),
        },
        density_scale: 1.0,
        albedo: Vec3::ONE,
        g: 0.0,
        emission: None,
        emission_scale: Vec3::ONE,
        temperature: None,
        albedo_grid: None,
        velocity: None,
        velocity_scale: 1.0,
        frames: Vec::new(),
        vdb: None,
    }));
    assert!(ray(&s, &opts).unwrap_err().contains("grid media"));

    let s = box_scene(Vec::new(), Vec::new(), Vec::new());
    assert!(ray(&s, &opts).is_ok());
    let zero_k = McOptions {
        max_bounces: 0,
        ..opts
    };
    assert!(ray(&s, &zero_k).is_err());
    let one_path = McOptions { paths: 1, ..opts };
    assert!(ray(&s, &one_path).is_err());
    assert!(radiance_mc(&s, DVec3::ZERO, DVec3::ZERO, &opts).is_err());
    // 16 paths do not fill 3×3 strata evenly.
    assert!(render_mc(&s, &opts, 3).is_err());
    assert!(render_mc(&s, &opts, 4).is_ok());
}

/// Cost of the estimator: `cargo test --release -p nimbus-reference mc:: --
/// --ignored --nocapture`.
#[test]
#[ignore]
fn time_per_million_segments() {
    let ball = Shape::Sphere {
        center: Vec3::new(1.5, 1.5, 0.0),
        radius: 0.4,
        albedo: Vec3::splat(0.5),
        emission: Vec3::ZERO,
    };
    let s = dense_box_over_floor(Vec3::splat(0.95), vec![ball]);
    let tracer = Tracer::new(&s).unwrap();
    let opts = McOptions {
        max_bounces: 8,
        paths: 400_000,
        seed: 1,
    };
    let (origin, dir) = DENSE_BOX_RAY;
    let start = std::time::Instant::now();
    let sums = tracer.radiance(origin, dir.normalize(), &opts);
    let seconds = start.elapsed().as_secs_f64();
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get());
    println!(
        "{} paths, {} segments ({:.2} per path) in {seconds:.3} s on {threads} threads: \
         {:.3} s per million segments",
        sums.moments.n,
        sums.segments,
        sums.segments as f64 / sums.moments.n as f64,
        seconds / (sums.segments as f64 * 1e-6)
    );
}

#[test]
fn a_dodecahedron_agrees_with_the_quadrature_reference() {
    // A dodecahedron lit obliquely, half shadowed by a sphere up the beam.
    let omega = Vec3::new(0.3, -1.0, 0.4).normalize();
    let planes = dodecahedron_planes(Vec3::new(0.1, -0.2, 0.0), 0.9);
    let medium = convex_medium(&planes, 1.1, 0.4);
    let sphere = Shape::Sphere {
        center: Vec3::new(0.5, -0.2, 0.0) - 2.5 * omega,
        radius: 0.5,
        albedo: Vec3::ZERO,
        emission: Vec3::ZERO,
    };
    let s = test_scene(
        vec![Medium::Convex(medium)],
        vec![sphere],
        vec![sun(omega, Vec3::new(2.0, 1.5, 1.0))],
        (6, 4),
        40.0,
    );
    let origin = DVec3::new(0.0, 0.2, 5.0);
    for (j, target) in [
        DVec3::new(0.1, -0.2, 0.0),
        DVec3::new(0.6, 0.1, 0.2),
        DVec3::new(-0.5, -0.6, -0.3),
        DVec3::new(-0.2, 0.4, 0.3),
    ]
    .into_iter()
    .enumerate()
    {
        let opts = McOptions {
            max_bounces: 1,
            paths: 200_000,
            seed: 70 + j as u64,
        };
        let dir = target - origin;
        let expected = quadrature::radiance(&s, origin, dir, &QUADRATURE).unwrap();
        assert!(
            expected[0] > 0.0,
            "towards {target}: the ray must see light"
        );
        let mc = radiance_mc(&s, origin, dir, &opts).unwrap();
        assert_within(
            &mc,
            expected,
            4.0,
            &format!("dodecahedron, towards {target}"),
        );
    }
}

#[test]
fn an_albedo_one_furnace_returns_the_sky() {
    // A white box (g = 0.5) over a white floor under a constant sky and nothing else:
    // β stays 1 and every path escapes after a few scatterings, so each one returns
    // the sky exactly (K = 200 is far beyond the scatterings a path makes here). A
    // path that did not add the sky after scattering would fall short.
    let mut m = box_medium(
        Vec3::ZERO,
        Vec3::new(2.0, 1.0, 1.5),
        Vec3::new(0.0, 30.0, 10.0),
        2.5,
        0.5,
    );
    m.albedo = Vec3::ONE;
    let floor = Shape::Quad {
        corner: Vec3::new(-4.0, -1.0, 4.0),
        edge_u: Vec3::new(8.0, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 0.0, -8.0),
        albedo: Vec3::ONE,
        emission: Vec3::ZERO,
    };
    let sky = Vec3::new(1.0, 0.5, 0.25);
    let s = box_scene(vec![m], vec![floor], vec![constant_env(sky)]);
    let (origin, dir) = DENSE_BOX_RAY;
    let opts = McOptions {
        max_bounces: 200,
        paths: 20_000,
        seed: 17,
    };
    let mc = radiance_mc(&s, origin, dir, &opts).unwrap();
    for c in 0..3 {
        crate::common::testing::assert_close(mc.mean[c], f64::from(sky[c]), 1e-12);
    }
    // At K = 1 most paths scatter more than once before they escape: much less.
    let once = radiance_mc(
        &s,
        origin,
        dir,
        &McOptions {
            max_bounces: 1,
            ..opts
        },
    )
    .unwrap();
    assert!(once.mean[0] < 0.8 * f64::from(sky[0]), "{once:?}");
}

#[test]
fn a_constant_sky_single_scattered_in_a_slab_matches_a_two_dimensional_integral() {
    // A wide slab z ∈ [0, H] under a constant sky L, seen along d = +z from below,
    // K = 1. Sky light from direction w (μ = w·z) reaches depth z through the slab
    // length R(μ) = (H − z)/μ for μ > 0 and z/(−μ) for μ < 0, travels along −w and
    // scatters into −d with the phase p(d·w) = p(μ):
    //   L = L_sky e^{−σH} + σs L_sky 2π ∫_0^H e^{−σz} ∫_{−1}^{1} p(μ) e^{−σR(μ)} dμ dz,
    // the first term the sky the camera ray sees through the slab.
    let (sigma, h, g) = (1.0f64, 1.0f64, 0.6f64);
    let mut m = box_medium(
        Vec3::new(0.0, 0.0, 0.5),
        Vec3::new(400.0, 400.0, 1.0),
        Vec3::ZERO,
        sigma as f32,
        g as f32,
    );
    m.albedo = Vec3::new(0.95, 0.6, 0.3);
    let albedo = m.albedo.as_dvec3();
    let sky = DVec3::new(1.0, 2.0, 0.5);
    let s = box_scene(vec![m], Vec::new(), vec![constant_env(sky.as_vec3())]);

    let inner = |z: f64, mu: f64| {
        let r = if mu > 0.0 { (h - z) / mu } else { z / -mu };
        henyey_greenstein(mu, g) * (-sigma * r).exp()
    };
    // μ = ±s² (dμ = 2s ds) resolves the edge near μ = 0, where R → ∞.
    let single = 2.0
        * PI
        * gauss_legendre(
            |z| {
                let up = gauss_legendre(|s| 2.0 * s * inner(z, s * s), 0.0, 1.0, 60);
                let down = gauss_legendre(|s| 2.0 * s * inner(z, -s * s), 0.0, 1.0, 60);
                (-sigma * z).exp() * (up + down)
            },
            0.0,
            h,
            60,
        );
    let expected: [f64; 3] =
        std::array::from_fn(|c| sky[c] * (-sigma * h).exp() + albedo[c] * sigma * sky[c] * single);

    let opts = McOptions {
        max_bounces: 1,
        paths: 400_000,
        seed: 23,
    };
    let mc = radiance_mc(&s, DVec3::new(0.0, 0.0, -1.0), DVec3::Z, &opts).unwrap();
    assert_within(&mc, expected, 4.0, "sky in a slab, K = 1");
    // The scattered sky is a sizeable part of the answer, so the test can see it.
    assert!(
        albedo[0] * sigma * single > 0.3 * (-sigma * h).exp(),
        "{single}"
    );
}

/// Writes an 8 × 4 equirectangular map: radiance `upper` in the top two rows (every
/// direction with y > 0), black below.
fn write_half_sky(name: &str, upper: [f32; 3]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus-reference-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    exr::prelude::write_rgb_file(&path, 8, 4, |_, y| {
        if y < 2 {
            (upper[0], upper[1], upper[2])
        } else {
            (0.0, 0.0, 0.0)
        }
    })
    .unwrap();
    path
}

#[test]
fn a_map_lights_a_floor_from_above_only() {
    // A Lambertian floor under a map that is white above the horizon and black below:
    // every reflected path of the floor's upper side escapes upwards into the white
    // half (E = π L, so L_out = albedo · L exactly), every one of its lower side into
    // the black half; a camera ray that misses the floor upwards, above the centres of
    // the white rows, sees the white half (the camera's background is the map
    // interpolated between texel centres).
    let path = write_half_sky("half-sky.exr", [1.0, 0.5, 2.0]);
    let floor = Shape::Quad {
        corner: Vec3::new(-2.0, 0.0, -2.0),
        edge_u: Vec3::new(4.0, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 0.0, 4.0),
        albedo: Vec3::new(0.6, 0.3, 0.9),
        emission: Vec3::ZERO,
    };
    let map = Light::Environment {
        radiance: Vec3::ONE,
        file: Some(path),
        scale: Vec3::splat(2.0),
        rotation_deg: 0.0,
    };
    let s = box_scene(Vec::new(), vec![floor], vec![map]);
    let opts = McOptions {
        max_bounces: 2,
        paths: 2_000,
        seed: 4,
    };
    let ray = |o: DVec3, d: DVec3| radiance_mc(&s, o, d, &opts).unwrap().mean;
    let above = ray(DVec3::new(0.3, 2.0, 1.0), DVec3::new(0.1, -1.0, -0.4));
    let below = ray(DVec3::new(0.3, -2.0, 1.0), DVec3::new(0.1, 1.0, -0.4));
    let sky = ray(DVec3::new(0.3, -2.0, 1.0), DVec3::new(0.1, 1.0, 0.6));
    let upper = [1.0, 0.5, 2.0].map(|l| 2.0 * l);
    for c in 0..3 {
        let albedo = [0.6, 0.3, 0.9][c];
        crate::common::testing::assert_close(above[c], albedo * upper[c], 1e-6);
        assert_eq!(below[c], 0.0);
        crate::common::testing::assert_close(sky[c], upper[c], 1e-12);
    }
}

/// A map turned by `rotation_deg` = 90 is the map with its columns shifted a quarter
/// turn, exactly: the analog escapes draw the same directions in both scenes and look
/// up the same texel (a wall facing +Z sees the bright patch only when it is turned
/// towards +Z, so the wrong sign, −90, is far off).
#[test]
fn a_map_turned_a_quarter_is_the_map_shifted_a_quarter() {
    use crate::common::testing::{map_env, wall_facing_z, write_turned_maps};
    let (map, shifted) = write_turned_maps("mc-turn");
    let opts = McOptions {
        max_bounces: 1,
        paths: 4_000,
        seed: 8,
    };
    let render = |light: Light| {
        let s = box_scene(Vec::new(), vec![wall_facing_z()], vec![light]);
        let wall = radiance_mc(
            &s,
            DVec3::new(0.4, 0.5, 3.0),
            DVec3::new(-0.1, 0.0, -1.0),
            &opts,
        )
        .unwrap()
        .mean;
        // A camera ray that escapes upwards past the wall into the turned patch.
        let sky = radiance_mc(
            &s,
            DVec3::new(0.0, 0.5, 3.0),
            DVec3::new(-1.0, 0.6, 0.3),
            &opts,
        )
        .unwrap()
        .mean;
        (wall, sky)
    };
    let (turned_wall, turned_sky) = render(map_env(map.clone(), 90.0));
    let (shifted_wall, shifted_sky) = render(map_env(shifted.clone(), 0.0));
    let (wrong_wall, _) = render(map_env(map, -90.0));
    // The camera's background: the shifted map interpolated between texel centres.
    let background = nimbus_scene::EnvMap::load_exr(&shifted, Vec3::ONE)
        .unwrap()
        .lookup_bilinear(DVec3::new(-1.0, 0.6, 0.3));
    for c in 0..3 {
        crate::common::testing::assert_close(turned_wall[c], shifted_wall[c], 1e-9);
        crate::common::testing::assert_close(turned_sky[c], shifted_sky[c], 1e-9);
        crate::common::testing::assert_close(turned_sky[c], f64::from(background[c]), 1e-6);
    }
    assert!(turned_sky[0] > 2.0, "the patch is seen: {turned_sky:?}");
    assert!(
        turned_wall[0] > 3.0 * wrong_wall[0],
        "{turned_wall:?} vs {wrong_wall:?}"
    );
}
