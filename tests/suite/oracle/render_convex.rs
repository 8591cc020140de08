//! Convex media in the crepuscular pass (the paper's Fig. 11: a dodecahedral medium) on
//! lavapipe with validation: one MCWVDS sample per pixel-centre ray is the f64
//! quadrature where nothing occludes, every estimator converges to the quadrature with
//! an occluder and on the box's hard cases (camera on a face, an edge or a vertex, light
//! parallel to a face, a thin sliver, 64 planes), and multiple scattering matches the
//! CPU Monte Carlo oracle.

use crate::common::gpu::{assert_means_agree, context, render_checked, scene, se_of_mean};
use crate::common::scenes::probe_header;
use nimbus::output::ImageRgb;
use nimbus_reference::quadrature::{self, ReferenceOptions};
use nimbus_scene::BoxEstimator;

/// `[[medium]]` planes of a regular dodecahedron of inradius `r` about `center`, turned
/// by `turn` radians about Y (so no face is axis-aligned), as TOML.
pub fn dodecahedron_planes(center: [f64; 3], r: f64, turn: f64) -> String {
    let phi = (1.0 + 5f64.sqrt()) / 2.0;
    let mut planes = Vec::new();
    for a in [-1.0, 1.0] {
        for b in [-phi, phi] {
            for n in [[0.0, a, b], [a, b, 0.0], [b, 0.0, a]] {
                let len: f64 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
                let len = len.sqrt();
                let (c, s) = (turn.cos(), turn.sin());
                let n = [
                    (c * n[0] + s * n[2]) / len,
                    n[1] / len,
                    (-s * n[0] + c * n[2]) / len,
                ];
                let d = r + n[0] * center[0] + n[1] * center[1] + n[2] * center[2];
                planes.push(format!("[{}, {}, {}, {d}]", n[0], n[1], n[2]));
            }
        }
    }
    format!("planes = [{}]", planes.join(", "))
}

/// A dodecahedral medium (inradius 0.9 at the origin) under one light, seen from
/// (0.4, 0.7, 3.2) through pixel centres; `extra` is appended.
fn dodecahedron_scene(width: u32, height: u32, extra: &str) -> String {
    format!(
        r#"
[render]
width = {width}
height = {height}
pixel_jitter = false
[camera]
position = [0.4, 0.7, 3.2]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 50
[[light]]
type = "directional"
direction = [0.3, -1.0, -0.4]
irradiance = [2.0, 1.5, 1.0]
[[medium]]
type = "convex"
{}
sigma_t = 1.7
albedo = 0.8
g = 0.4
{extra}
"#,
        dodecahedron_planes([0.0, 0.0, 0.0], 0.9, 0.3)
    )
}

/// Relative difference of two image means, largest channel.
fn mean_rel_diff(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3)
        .map(|c| (a[c] - b[c]).abs() / b[c].abs().max(1e-30))
        .fold(0.0, f64::max)
}

/// With nothing in the way, one MCWVDS sample per pixel-centre ray is the analytic
/// integral over the dodecahedron's trapezoid pieces: every pixel matches the f64
/// quadrature to 1e-4, the tolerance of boxes, with and without a gobo.
#[test]
fn unoccluded_dodecahedron_pixels_are_exact_with_one_mcwvds_sample() {
    let ctx = context();
    for gobo in ["", "gobo = [[-0.6, -0.5], [0.7, -0.4], [0.4, 0.7], [-0.5, 0.5]]\ngobo_origin = [0.1, 2.0, 0.0]"] {
        let text = dodecahedron_scene(20, 16, "[integrator]\nbox_estimator = \"mcwvds\"\nbox_samples = 1")
            .replace("irradiance = [2.0, 1.5, 1.0]", &format!("irradiance = [2.0, 1.5, 1.0]\n{gobo}"));
        let scene = scene(&text, "dodecahedron.toml");
        let gpu = render_checked(&ctx, &scene, Some(1));
        let reference = quadrature::render(
            &scene,
            &ReferenceOptions {
                rel_tol: 1e-9,
                footprint_samples: 1,
            },
        )
        .expect("reference");
        let (mut lit, mut worst) = (0, 0.0f64);
        for (g, r) in gpu.image.data.iter().zip(&reference) {
            for c in 0..3 {
                let (g, r) = (f64::from(g[c]), r[c]);
                if r > 1e-6 {
                    lit += 1;
                    worst = worst.max((g - r).abs() / r);
                }
                assert!(
                    (g - r).abs() <= 1e-4 * r + 1e-9,
                    "gobo {gobo:?}: gpu {g} vs reference {r}"
                );
            }
        }
        println!("gobo {:?}: {lit} lit channels, worst relative error {worst:.2e}", !gobo.is_empty());
        assert!(lit > 100, "the dodecahedron covers the image: {lit}");
    }
}

/// A sphere up the beam shadows part of the dodecahedron: every estimator's image mean
/// is within five standard errors (+0.5 % for the quadrature's footprint) of the f64
/// quadrature, and MCWVDS's per-pixel error is consistent with its standard error.
#[test]
fn every_estimator_converges_to_the_quadrature_on_an_occluded_dodecahedron() {
    let ctx = context();
    let mut scene = scene(
        &dodecahedron_scene(
            12,
            10,
            "[[shape]]\ntype = \"sphere\"\ncenter = [-0.55, 2.2, 0.9]\nradius = 0.45",
        ),
        "dodecahedron.toml",
    );
    scene.render.frames = 32;
    scene.render.spp = 2;
    scene.render.seed = 11;
    let reference = quadrature::render(
        &scene,
        &ReferenceOptions {
            rel_tol: 1e-6,
            footprint_samples: 1,
        },
    )
    .expect("reference");
    let reference = ImageRgb::from_rgb_f64(12, 10, &reference).expect("finite reference");
    let r_mean = reference.mean();
    for estimator in BoxEstimator::EXACT {
        scene.integrator.box_estimator = estimator;
        let gpu = render_checked(&ctx, &scene, Some(8));
        let (g_mean, se) = (gpu.image.mean(), se_of_mean(&gpu.std_error));
        let e = estimator.name();
        println!("{e}: gpu {g_mean:?} ± {se:.2e}, reference {r_mean:?}");
        for c in 0..3 {
            assert!(
                (g_mean[c] - r_mean[c]).abs() <= 5.0 * se + 0.005 * r_mean[c],
                "{e} channel {c}: {} vs {}",
                g_mean[c],
                r_mean[c]
            );
        }
        if estimator == BoxEstimator::Mcwvds {
            let mut beyond = 0;
            for ((a, b), s) in gpu
                .image
                .data
                .iter()
                .zip(&reference.data)
                .zip(&gpu.std_error.data)
            {
                for c in 0..3 {
                    if (a[c] - b[c]).abs() > 5.0 * s[c] + 1e-4 * b[c] + 1e-7 {
                        beyond += 1;
                    }
                }
            }
            assert!(beyond * 100 <= 360, "MCWVDS: {beyond} channels beyond 5 SE");
        }
    }
}

/// (name, camera, look_at, light direction, planes, sigma_t) of a hard case.
type HardCase<'a> = (&'a str, [f64; 3], [f64; 3], [f64; 3], String, f64);

/// The box's degenerate cases on convex media, for every estimator: the camera on a
/// face, an edge and a vertex of the dodecahedron, light parallel to one of its faces, a
/// sliver 2 mm thick, and a 62-gon prism (64 planes). Each image mean is within five
/// standard errors (+0.5 %) of the quadrature, and no sample is non-finite.
#[test]
fn convex_hard_cases_render_right_with_every_estimator() {
    let ctx = context();
    // A vertex, an edge midpoint and a face centre of the dodecahedron of inradius 1
    // (unturned), from its polyhedron.
    let phi = (1.0 + 5f64.sqrt()) / 2.0;
    let norm = (1.0 + phi * phi).sqrt();
    let mut unit_planes = Vec::new();
    for a in [-1.0, 1.0] {
        for b in [-phi, phi] {
            for n in [[0.0, a, b], [a, b, 0.0], [b, 0.0, a]] {
                unit_planes.push([n[0] / norm, n[1] / norm, n[2] / norm, 1.0]);
            }
        }
    }
    let poly = nimbus_scene::convex::ConvexPolyhedron::new(&unit_planes).unwrap();
    let vertex = poly.vertices[0];
    let on = |p: glam::DVec3, i: usize| {
        let q = unit_planes[i];
        (q[0] * p.x + q[1] * p.y + q[2] * p.z - q[3]).abs() < 1e-9
    };
    let neighbour = poly.vertices[1..]
        .iter()
        .copied()
        .find(|w| (0..12).filter(|&i| on(vertex, i) && on(*w, i)).count() == 2)
        .unwrap();
    let edge = (0.5 * (vertex + neighbour)).to_array();
    let face = [unit_planes[0][0], unit_planes[0][1], unit_planes[0][2]];
    let vertex = vertex.to_array();
    let prism = |sides: usize, radius: f64, height: f64| {
        let mut planes: Vec<String> = (0..sides)
            .map(|i| {
                let a = std::f64::consts::TAU * (i as f64 + 0.5) / sides as f64;
                let apothem = radius * (std::f64::consts::PI / sides as f64).cos();
                format!("[{}, 0, {}, {apothem}]", a.cos(), a.sin())
            })
            .collect();
        planes.push(format!("[0, 1, 0, {}]", 0.5 * height));
        planes.push(format!("[0, -1, 0, {}]", 0.5 * height));
        format!("planes = [{}]", planes.join(", "))
    };
    let dodeca = dodecahedron_planes([0.0; 3], 1.0, 0.0);
    let cases: Vec<HardCase> = vec![
        // (name, camera, look_at, light direction, planes, sigma_t)
        (
            "camera on a face",
            face,
            [0.0; 3],
            [0.3, -1.0, 0.2],
            dodeca.clone(),
            1.0,
        ),
        (
            "camera on an edge",
            edge,
            [0.0; 3],
            [0.3, -1.0, 0.2],
            dodeca.clone(),
            1.0,
        ),
        (
            "camera on a vertex",
            vertex,
            [0.0; 3],
            [0.3, -1.0, 0.2],
            dodeca.clone(),
            1.0,
        ),
        (
            "light parallel to a face",
            [0.2, 0.5, 3.0],
            [0.0; 3],
            [0.0, -face[2], face[1]],
            dodeca.clone(),
            1.5,
        ),
        (
            "sliver 2 mm thick",
            [0.3, 1.5, 2.5],
            [0.0; 3],
            [0.3, -1.0, 0.2],
            prism(6, 1.0, 2e-3),
            3.0,
        ),
        (
            "62-gon prism",
            [0.0, 0.4, 3.0],
            [0.0; 3],
            [0.05, -0.1, -1.0],
            prism(62, 1.0, 2.0),
            1.2,
        ),
    ];
    for (name, position, look_at, direction, planes, sigma_t) in cases {
        let header = probe_header(position, look_at, direction);
        let text = format!(
            r#"
{header}
[[medium]]
type = "convex"
{planes}
sigma_t = {sigma_t:?}
albedo = 1.0
g = 0.3
"#
        );
        let mut scene = scene(&text, &format!("{name}.toml"));
        let reference = quadrature::render(
            &scene,
            &ReferenceOptions {
                rel_tol: 1e-6,
                footprint_samples: 6,
            },
        )
        .expect("reference");
        let reference = ImageRgb::from_rgb_f64(8, 8, &reference).expect("finite reference");
        let r_mean = reference.mean()[0];
        assert!(r_mean > 0.0, "{name}: the medium must be seen");
        for estimator in BoxEstimator::EXACT {
            scene.integrator.box_estimator = estimator;
            let gpu = render_checked(&ctx, &scene, Some(16));
            let g_mean = gpu.image.mean()[0];
            let se_mean = se_of_mean(&gpu.std_error);
            let e = estimator.name();
            println!("{name} / {e}: gpu {g_mean:.6e} ± {se_mean:.2e}, reference {r_mean:.6e}");
            assert!(
                (g_mean - r_mean).abs() <= 5.0 * se_mean + 0.005 * r_mean + 1e-12,
                "{name} / {e}: image mean {g_mean} ± {se_mean} vs reference {r_mean}"
            );
        }
    }
}

/// Multiple scattering (K = 2, 4) in the dodecahedron over a Lambertian floor: MCWVDS and
/// RM path tracers agree with the CPU Monte Carlo oracle on the image mean within 4
/// combined standard errors + 1 %.
#[test]
fn convex_multiple_scattering_matches_the_cpu_monte_carlo_reference() {
    use nimbus_reference::mc::{render_mc, McOptions};
    let ctx = context();
    let mut scene = scene(
        &dodecahedron_scene(
            10,
            10,
            "[[shape]]\ntype = \"quad\"\ncorner = [-3.0, -1.0, -3.0]\nedge_u = [6.0, 0.0, 0.0]\n\
             edge_v = [0.0, 0.0, 6.0]\nalbedo = 0.6",
        )
        .replace("pixel_jitter = false\n", ""),
        "dodecahedron-ms.toml",
    );
    scene.render.frames = 32;
    scene.render.spp = 4;
    scene.render.seed = 21;
    for k in [2u32, 4] {
        scene.integrator.max_bounces = k;
        let (cpu_mean, cpu_se) = render_mc(
            &scene,
            &McOptions {
                max_bounces: k,
                paths: 1024,
                seed: 77,
            },
            4,
        )
        .expect("cpu reference");
        let cpu = ImageRgb::from_rgb_f64(10, 10, &cpu_mean).unwrap();
        let cpu_se = ImageRgb::from_rgb_f64(10, 10, &cpu_se).unwrap();
        for estimator in [BoxEstimator::Mcwvds, BoxEstimator::Rm] {
            scene.integrator.box_estimator = estimator;
            let gpu = render_checked(&ctx, &scene, Some(8));
            let what = format!("K={k} {}: gpu vs cpu", estimator.name());
            let (gpu, cpu) = ((&gpu.image, &gpu.std_error), (&cpu, &cpu_se));
            assert_means_agree(&what, gpu, cpu, 4.0, 0.01);
        }
        assert!(mean_rel_diff(cpu.mean(), [0.0; 3]) > 0.0);
    }
}
