//! The box's hard cases one by one (parallel and antiparallel light, the camera on a
//! face, an edge or a corner, grazing and missing rays, extreme σt and sizes) against
//! the f64 reference and the closed forms of Eq. 7 and 8, and configurations at and
//! beyond the scene format's limits, where the shader must count no non-finite value.

use super::*;

/// The hard cases, each an explicit configuration (box half extents (1, 0.5, 2) unless
/// stated).
fn hard_cases() -> Vec<Case> {
    let h = DVec3::new(1.0, 0.5, 2.0);
    let v = DVec3::new;
    let w = v(0.3, -0.5, 0.8); // a generic light direction
    let mut cases = vec![
        // Light parallel and antiparallel to the view (Eq. 8 and 7), camera inside/outside.
        Case::new("parallel inside (Eq. 8)", v(0.2, -0.1, 0.3), w, w, h, 0.7),
        Case::new(
            "antiparallel inside (Eq. 7)",
            v(0.2, -0.1, 0.3),
            -w,
            w,
            h,
            0.7,
        ),
        Case::new(
            "parallel outside (Eq. 8)",
            v(0.2, -0.1, 0.3) - 5.0 * w,
            w,
            w,
            h,
            0.7,
        ),
        Case::new(
            "antiparallel outside (Eq. 7)",
            v(0.2, -0.1, 0.3) + 5.0 * w,
            -w,
            w,
            h,
            0.7,
        ),
        Case::new(
            "parallel along z",
            v(0.3, 0.2, -1.0),
            v(0., 0., 1.),
            v(0., 0., 1.),
            h,
            1.3,
        ),
        Case::new(
            "antiparallel along x",
            v(0.3, 0.2, -1.0),
            v(-1., 0., 0.),
            v(1., 0., 0.),
            h,
            1.3,
        ),
        Case::new("parallel thick", v(0.2, -0.1, 0.3), w, w, h, 1e3),
        Case::new("antiparallel thin", v(0.2, -0.1, 0.3), -w, w, h, 1e-6),
        // Camera exactly on a face (+y), inward, outward and within the face plane.
        Case::new(
            "on face, inward",
            v(0.3, 0.5, -0.7),
            v(0.2, -1.0, 0.3),
            w,
            h,
            0.9,
        ),
        Case::new(
            "on face, outward",
            v(0.3, 0.5, -0.7),
            v(0.2, 1.0, 0.3),
            w,
            h,
            0.9,
        ),
        Case::new(
            "on face, in plane, lit face",
            v(0.3, 0.5, -0.7),
            v(1.0, 0.0, 1.0),
            w,
            h,
            0.9,
        ),
        Case::new(
            "on face, in plane, far face lit",
            v(0.3, 0.5, -0.7),
            v(1.0, 0.0, 1.0),
            v(0.3, 0.5, 0.8),
            h,
            0.9,
        ),
        Case::new(
            "on face, in plane, light along face",
            v(0.3, 0.5, -0.7),
            v(1.0, 0.0, 1.0),
            v(0.6, 0.0, 0.8),
            h,
            0.9,
        ),
        // Camera exactly on an edge (x = 1, y = 0.5), inward, outward, along the edge.
        Case::new(
            "on edge, inward",
            v(1.0, 0.5, 0.2),
            v(-1.0, -1.0, 0.3),
            w,
            h,
            0.9,
        ),
        Case::new(
            "on edge, outward",
            v(1.0, 0.5, 0.2),
            v(1.0, 0.2, 0.0),
            w,
            h,
            0.9,
        ),
        Case::new(
            "on edge, along it",
            v(1.0, 0.5, 0.2),
            v(0.0, 0.0, 1.0),
            v(-0.6, 0.3, 0.5),
            h,
            0.9,
        ),
        // Camera exactly on a corner, inward, outward, along an edge.
        Case::new(
            "on corner, inward",
            v(1.0, -0.5, 2.0),
            v(-1.0, 1.0, -1.0),
            w,
            h,
            0.9,
        ),
        Case::new(
            "on corner, outward",
            v(1.0, -0.5, 2.0),
            v(1.0, -1.0, 1.0),
            w,
            h,
            0.9,
        ),
        Case::new(
            "on corner, along an edge",
            v(1.0, -0.5, 2.0),
            v(-1.0, 0.0, 0.0),
            w,
            h,
            0.9,
        ),
        // Rays grazing an edge from outside: touching it, just inside it, along it.
        Case::new(
            "grazing edge, touching",
            v(2.0, -0.5, 0.3),
            v(-FRAC_1_SQRT_2, FRAC_1_SQRT_2, 0.0),
            w,
            h,
            0.9,
        ),
        Case::new(
            "grazing edge, 1e-4 inside",
            v(2.0, -0.5 - 1e-4, 0.3),
            v(-1.0, 1.0, 0.0),
            w,
            h,
            0.9,
        ),
        Case::new(
            "grazing edge, along it",
            v(1.0, 0.5, -5.0),
            v(0.0, 0.0, 1.0),
            v(-0.6, 0.3, 0.5),
            h,
            0.9,
        ),
        // Rays that miss.
        Case::new("miss", v(3.0, 3.0, 3.0), v(1.0, 0.0, 0.0), w, h, 0.9),
        Case::new(
            "miss, beside a slab",
            v(0.0, 3.0, -5.0),
            v(0.0, 0.0, 1.0),
            w,
            h,
            0.9,
        ),
        Case::new(
            "miss, pointing away",
            v(0.0, 0.0, -5.0),
            v(0.0, 0.0, -1.0),
            w,
            h,
            0.9,
        ),
        // Extinction and size extremes.
        Case::new(
            "sigma_t 1e-6",
            v(-3.0, 0.1, -2.5),
            v(1.0, 0.05, 0.6),
            w,
            h,
            1e-6,
        ),
        Case::new(
            "sigma_t 1e3, 1e-3 from the lit face",
            v(0.2, 0.499, 0.3),
            v(0.6, 0.3, 0.7),
            w,
            h,
            1e3,
        ),
        Case::new(
            "sigma_t 1e3, entering through the lit face",
            v(0.2, 3.0, 0.3),
            v(-0.1, -3.0, -0.1),
            w,
            h,
            1e3,
        ),
        Case::new(
            "box 1e-3 m",
            v(-3e-3, 1e-4, -2.5e-3),
            v(1.0, 0.05, 0.6),
            w,
            1e-3 * h,
            50.0,
        ),
        Case::new(
            "box 1e4 m",
            v(-3e4, 1e3, -2.5e4),
            v(1.0, 0.05, 0.6),
            w,
            1e4 * h,
            1e-4,
        ),
        Case::new(
            "box 1e4 m, camera inside",
            v(0.3e4, 0.1e4, 0.5e4),
            v(-1.0, 0.3, 0.2),
            w,
            1e4 * h,
            1e-3,
        ),
        // Axis-aligned light and view.
        Case::new(
            "omega along -y",
            v(0.1, 0.2, 0.3),
            v(0.6, -0.3, 0.7),
            v(0.0, -1.0, 0.0),
            h,
            0.8,
        ),
        Case::new(
            "omega in the xz plane",
            v(0.1, 0.2, 0.3),
            v(0.6, -0.3, 0.7),
            v(0.6, 0.0, -0.8),
            h,
            0.8,
        ),
        Case::new("d along +x", v(-0.5, 0.2, 0.3), v(1.0, 0.0, 0.0), w, h, 0.8),
        Case::new(
            "d along -z from outside",
            v(0.1, 0.2, 4.0),
            v(0.0, 0.0, -1.0),
            w,
            h,
            0.8,
        ),
        Case::new(
            "d and omega along axes",
            v(-0.5, 0.2, 0.3),
            v(1.0, 0.0, 0.0),
            v(0.0, 0.0, 1.0),
            h,
            0.8,
        ),
        // Negative slope c (optical depth falling along the ray), mild and extreme.
        Case::new(
            "c < 0",
            v(0.5, -0.2, 0.0),
            v(-0.2, -1.0, 0.1),
            v(1.0, 0.12, 0.0),
            h,
            3.0,
        ),
        Case::new(
            "c << 0, thick",
            v(0.5, -0.49, 0.0),
            v(-0.2, -1.0, 0.1),
            v(1.0, 0.12, 0.0),
            h,
            1e3,
        ),
        // Grazing light (|omega_y| = 1e-4): slopes of 1e4.
        Case::new(
            "grazing light",
            v(0.2, -0.49, 0.1),
            v(0.3, -0.4, 0.5),
            v(1.0, 1e-4, 0.2),
            h,
            2.0,
        ),
        // Three pieces.
        Case::new(
            "three pieces",
            v(0.72, -0.22, 0.37),
            v(-0.41, -0.59, -0.70),
            v(0.57, -0.28, 0.77),
            h,
            6.0,
        ),
    ];
    // Clamped start (gobo) and end (surface).
    cases.push(
        Case::new(
            "clamped start",
            v(-3.0, 0.1, -2.5),
            v(1.0, 0.05, 0.6),
            w,
            h,
            0.8,
        )
        .clamp_start(0.3),
    );
    cases.push(
        Case::new(
            "clamped both",
            v(0.2, -0.1, 0.3),
            v(0.6, -0.3, 0.7),
            w,
            h,
            0.8,
        )
        .clamp_start(0.2)
        .clamp_end(0.5),
    );
    cases.push(
        Case::new(
            "clamped start, antiparallel",
            v(0.2, -0.1, 0.3) + 5.0 * w,
            -w,
            w,
            h,
            0.7,
        )
        .clamp_start(0.4),
    );
    cases
}

/// Closed forms of Eq. 7 and 8 (with the 1/(σt c) of Eq. 6) for a parallel case.
fn parallel_closed_form(case: &Case) -> f64 {
    let (t_a, t_b) = (f64::from(case.t_a), f64::from(case.t_b));
    let sigma_t = f64::from(case.sigma_t);
    let d = case.d64();
    let omega = case.omega.as_dvec3().normalize();
    let start = case.o.as_dvec3() + t_a * d;
    let d_l = case.light_distance(start);
    let length = t_b - t_a;
    let camera = (-sigma_t * (t_a - f64::from(case.t_enter))).exp();
    if d.dot(omega) > 0.0 {
        // Eq. 8: c = 2.
        camera * (-sigma_t * d_l).exp() * -(-2.0 * sigma_t * length).exp_m1() / (2.0 * sigma_t)
    } else {
        // Eq. 7: c = 0.
        camera * (-sigma_t * d_l).exp() * length
    }
}

#[test]
fn hard_cases_are_finite_and_match_the_reference_and_closed_forms() {
    let gpu = Gpu::new();
    let cases = hard_cases();
    let results = gpu.run_configs(&cases, 0.37);
    let check = check_t_box(&cases, &results);
    for ((case, (result, pieces)), e) in cases.iter().zip(&results).zip(&check) {
        println!(
            "{:<40} T_box {:<13e} pieces {} error {:.2e} (tol {:.2e}) slopes {:?}",
            case.name,
            result.total,
            result.count,
            e.error,
            e.tolerance,
            &pieces.slope[..result.count as usize]
        );
    }
    // The parallel cases are one piece each and agree with Eq. 7 / 8.
    for (case, (result, pieces)) in cases.iter().zip(&results) {
        if !case.name.contains("parallel") {
            continue;
        }
        assert_eq!(result.count, 1, "{}: pieces", case.name);
        let closed = parallel_closed_form(case);
        let error = t_box_error(f64::from(result.total), closed);
        let tolerance = T_BOX_REL_TOL + case.kappa();
        assert!(
            error <= tolerance,
            "{}: gpu {} vs closed form {closed:e}: error {error:e}",
            case.name,
            result.total
        );
        let c = f64::from(pieces.slope[0]) / f64::from(case.sigma_t);
        let expected_c = if case.name.contains("antiparallel") {
            0.0
        } else {
            2.0
        };
        assert!((c - expected_c).abs() < 1e-6, "{}: c = {c}", case.name);
    }
    // The geometry says how many pieces some cases have.
    let expect_count = |name: &str, count: u32| {
        let i = cases.iter().position(|c| c.name == name).expect(name);
        assert_eq!(results[i].0.count, count, "{name}: pieces");
    };
    for name in [
        "on face, outward",
        "on edge, outward",
        "on corner, outward",
        "grazing edge, touching",
        "miss",
        "miss, beside a slab",
        "miss, pointing away",
    ] {
        expect_count(name, 0);
    }
    expect_count("three pieces", 3);
    let neg = cases
        .iter()
        .position(|c| c.name == "c << 0, thick")
        .expect("case");
    assert!(
        results[neg].1.slope[..results[neg].0.count as usize]
            .iter()
            .any(|&s| s < -1e3),
        "the c < 0 case has no strongly negative slope: {:?}",
        results[neg].1
    );
    gpu.finish();
}

/// Configurations at and beyond the scene format's limits: sizes to 1e7 m, σt to 1e9 /m,
/// light components down to 1e-19, cameras 1e7 m away.
fn extreme_case(rng: &mut Pcg32, index: usize) -> Case {
    let scale = rng.log_uniform(-4.0, 7.0);
    let h = DVec3::new(
        scale * rng.log_uniform(-3.0, 0.0),
        scale * rng.log_uniform(-3.0, 0.0),
        scale * rng.log_uniform(-3.0, 0.0),
    );
    let sigma_t = rng.log_uniform(-8.0, 9.0);
    let mut omega = rng.direction();
    if rng.uniform() < 0.3 {
        let a = (rng.next_u32() % 3) as usize;
        omega[a] = omega[a].signum() * rng.log_uniform(-19.0, -5.0);
    }
    let target = DVec3::new(
        h.x * rng.range(-1.0, 1.0),
        h.y * rng.range(-1.0, 1.0),
        h.z * rng.range(-1.0, 1.0),
    );
    let o = if rng.uniform() < 0.5 {
        target
    } else {
        target + rng.log_uniform(-3.0, 7.0) * rng.direction()
    };
    let mut d = if rng.uniform() < 0.5 {
        target - o
    } else {
        rng.direction()
    };
    if d.length() == 0.0 {
        d = rng.direction();
    }
    let mut case = Case::new(&format!("extreme {index}"), o, d, omega, h, sigma_t);
    if !case.is_empty() && rng.uniform() < 0.3 {
        let f = rng.uniform();
        case = case.clamp_start(f);
    }
    case
}

#[test]
fn shader_counts_no_non_finite_values_even_at_extreme_inputs() {
    let gpu = Gpu::new();
    let mut rng = Pcg32::new(0xe7_7e3e);
    let cases: Vec<Case> = (0..20_000).map(|i| extreme_case(&mut rng, i)).collect();
    let queries: Vec<GpuQuery> = (0..cases.len())
        .map(|i| GpuQuery {
            config: i as u32,
            flags: 0,
            u: rng.uniform_f32(),
            t_eval: cases[i].t_a + (cases[i].t_b - cases[i].t_a) * rng.uniform_f32(),
        })
        .collect();
    let (results, _) = gpu.run(&cases, &queries);
    for (case, r) in cases.iter().zip(&results) {
        assert_eq!(
            r.non_finite, 0,
            "{}: non-finite values: {case:?} -> {r:?}",
            case.name
        );
        let span = f64::from(case.t_b) - f64::from(case.t_a);
        // The integrand is at most 1, so 0 <= T_box <= t_b - t_a.
        assert!(
            r.total >= 0.0 && f64::from(r.total) <= span.max(0.0) * (1.0 + 1e-5),
            "{}: T_box {} outside [0, {span}]: {case:?}",
            case.name,
            r.total
        );
        assert!(
            r.pdf_sample >= 0.0 && r.pdf_eval >= 0.0,
            "{}: {r:?}",
            case.name
        );
        if r.pdf_sample > 0.0 {
            let slack = 1e-6 * f64::from(case.t_b.abs().max(case.t_a.abs()));
            let t = f64::from(r.t_sample);
            assert!(
                t >= f64::from(case.t_a) - slack && t <= f64::from(case.t_b) + slack,
                "{}: sample {t} outside [{}, {}]",
                case.name,
                case.t_a,
                case.t_b
            );
        }
    }
    let sampled = results.iter().filter(|r| r.pdf_sample > 0.0).count();
    println!(
        "{} extreme configurations, no non-finite values; {sampled} with T_box > 0",
        cases.len()
    );
    gpu.finish();
}
