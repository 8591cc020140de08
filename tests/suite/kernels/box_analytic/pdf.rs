//! Whole-volume distance sampling: the pdf integrates to 1 and equals the integrand
//! over T_box, and the GPU's samples follow it (Pearson chi-square against bin masses
//! from the f64 reference). `check_pdf` and `check_samples_follow_the_pdf` serve boxes
//! and convex polyhedra ([`super::convex`]) alike.

use super::*;

/// Quantile of the truncated exponential density ∝ exp(−x v) on [0, 1] at probability m.
fn truncated_exp_quantile(x: f64, m: f64) -> f64 {
    if x < 1e-12 {
        return m;
    }
    let a = m * -(-x).exp_m1();
    (-(-a).ln_1p() / x).clamp(0.0, 1.0)
}

/// Simpson panel ends over one piece in fractions v of its length: 64 equal-mass panels of
/// the piece's own density, the last one split geometrically (mass halved 40 times) so
/// that no panel's density varies by more than a factor of about 2 (Simpson is then
/// accurate to ~1e-4 of each panel's mass) and the final, possibly long, panel holds a
/// negligible mass.
fn panel_ends(x: f64, rising: bool) -> Vec<f64> {
    const M: usize = 64;
    let mut masses: Vec<f64> = (0..M).map(|i| i as f64 / M as f64).collect();
    masses.extend((1..=40).map(|j| 1.0 - 0.5f64.powi(j) / M as f64));
    let mut v: Vec<f64> = masses
        .iter()
        .map(|&m| truncated_exp_quantile(x, m))
        .collect();
    v.push(1.0);
    if rising {
        v = v.iter().rev().map(|&e| 1.0 - e).collect();
    }
    v.dedup();
    v
}

#[test]
fn wvds_pdf_integrates_to_one_and_equals_integrand_over_t_box() {
    let gpu = Gpu::new();
    let mut rng = Pcg32::new(0x9df_0001);
    let mut cases = Vec::new();
    while cases.len() < 300 {
        let case = random_case(&mut rng, cases.len());
        if !case.is_empty() {
            cases.push(case);
        }
    }
    check_pdf(&gpu, &cases);
    gpu.finish();
}

/// ∫ pdf = 1 over every case (Simpson on each piece's equal-mass panels) and, at the
/// panel midpoints, pdf = integrand / T_box by the f64 side.
pub(super) fn check_pdf(gpu: &Gpu, cases: &[Case]) {
    let first = gpu.run_configs(cases, 0.5);
    // Keep configurations whose T_box is a normal float (the pdf divides by it).
    let kept: Vec<usize> = (0..cases.len())
        .filter(|&i| first[i].0.total > 1e-30)
        .collect();

    // Evaluate the GPU pdf at the Simpson nodes of every piece. The nodes are rounded to
    // f32 first and the rule uses the rounded positions, so that rounding does not bias
    // the sum; piece k ends where piece k + 1 starts.
    let round = |t: f64| f64::from(t as f32);
    let mut queries = Vec::new();
    let mut panels: Vec<(usize, [f64; 3])> = Vec::new(); // (case, nodes a, mid, b)
    for &i in &kept {
        let (result, pieces) = first[i];
        let count = result.count as usize;
        for k in 0..count {
            let t0 = f64::from(pieces.t_start[k]);
            let t1 = if k + 1 < count {
                f64::from(pieces.t_start[k + 1])
            } else {
                t0 + f64::from(pieces.len[k])
            };
            let slope = f64::from(pieces.slope[k]);
            let ends = panel_ends(slope.abs() * (t1 - t0), slope < 0.0);
            for pair in ends.windows(2) {
                let (a, b) = (t0 + pair[0] * (t1 - t0), t0 + pair[1] * (t1 - t0));
                let nodes = [round(a), round(0.5 * (a + b)), round(b)];
                for t in nodes {
                    queries.push(GpuQuery {
                        config: i as u32,
                        flags: 0,
                        u: 0.5,
                        t_eval: t as f32,
                    });
                }
                panels.push((i, nodes));
            }
        }
    }
    let (results, _) = gpu.run(cases, &queries);
    assert!(
        results.iter().all(|r| r.non_finite == 0),
        "non-finite values"
    );

    // Integrate per configuration: Simpson's rule for unequal spacing (the integral of the
    // parabola through the three nodes), the trapezoid rule where rounding merged nodes.
    let mut integral = vec![0.0f64; cases.len()];
    for (p, &(i, [a, m, b])) in panels.iter().enumerate() {
        let f = |j: usize| f64::from(results[3 * p + j].pdf_eval);
        let (h1, h2) = (m - a, b - m);
        integral[i] += if h1 > 0.0 && h2 > 0.0 {
            (h1 + h2) / 6.0
                * ((2.0 - h2 / h1) * f(0)
                    + (h1 + h2).powi(2) / (h1 * h2) * f(1)
                    + (2.0 - h1 / h2) * f(2))
        } else {
            0.5 * (b - a) * (f(0) + f(2))
        };
    }
    let mut worst = (0.0f64, 0usize);
    for &i in &kept {
        let deviation = (integral[i] - 1.0).abs();
        if deviation > worst.0 {
            worst = (deviation, i);
        }
        assert!(
            deviation < 1e-3,
            "{}: ∫ pdf = {} ({} pieces {:?}): {:?}",
            cases[i].name,
            integral[i],
            first[i].0.count,
            first[i].1,
            cases[i]
        );
    }
    println!(
        "{} configurations: max |∫pdf − 1| = {:.3e} ({}), {} pdf evaluations",
        kept.len(),
        worst.0,
        cases[worst.1].name,
        queries.len()
    );

    // At the panel midpoints the pdf is the integrand over T_box (Eq. 11), by an f64 slab
    // test and the reference's T_box; checked where the pdf is not negligible.
    let references = par_map(&kept, |&i| cases[i].reference());
    let reference_of = |i: usize| references[kept.binary_search(&i).expect("kept")];
    let mut worst_point = (0.0f64, 0usize, 0.0f64);
    for (p, &(i, [_, t, _])) in panels.iter().enumerate() {
        let case = &cases[i];
        let expected = case.integrand(t) / reference_of(i);
        let span = f64::from(case.t_b) - f64::from(case.t_a);
        if expected * span < 1e-6 {
            continue;
        }
        let gpu_pdf = f64::from(results[3 * p + 1].pdf_eval);
        let error = (gpu_pdf / expected - 1.0).abs();
        let tolerance = T_BOX_REL_TOL + 2.0 * case.kappa();
        if error / tolerance > worst_point.0 {
            worst_point = (error / tolerance, i, error);
        }
        assert!(
            error <= tolerance,
            "{}: pdf({t}) gpu {gpu_pdf:e} vs integrand / T_box {expected:e}: {case:?}",
            case.name
        );
    }
    println!(
        "pdf vs integrand / T_box: worst error {:.3e} ({:.3} of its tolerance, {})",
        worst_point.2, worst_point.0, cases[worst_point.1].name
    );
}

// ---------------------------------------------------------------------------------------
// Chi-square.

/// ln Γ(x), x > 0 (Lanczos, g = 7, 9 terms; ~1e-15 relative).
fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// The regularized upper incomplete gamma function Q(s, x) (series below s + 1, Lentz's
/// continued fraction above, as in Numerical Recipes' gammq).
fn gamma_q(s: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let log_prefactor = -x + s * x.ln() - ln_gamma(s);
    if x < s + 1.0 {
        let (mut term, mut sum, mut n) = (1.0 / s, 1.0 / s, s);
        for _ in 0..10_000 {
            n += 1.0;
            term *= x / n;
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        1.0 - sum * log_prefactor.exp()
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - s;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -f64::from(i) * (f64::from(i) - s);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let delta = d * c;
            h *= delta;
            if (delta - 1.0).abs() < 1e-16 {
                break;
            }
        }
        log_prefactor.exp() * h
    }
}

/// P(χ²_dof > x).
fn chi_square_sf(x: f64, dof: usize) -> f64 {
    gamma_q(dof as f64 / 2.0, x / 2.0)
}

/// The x with P(χ²_dof > x) = alpha, by bisection.
fn chi_square_critical(alpha: f64, dof: usize) -> f64 {
    let (mut lo, mut hi) = (0.0, 10.0 * dof as f64 + 100.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if chi_square_sf(mid, dof) > alpha {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[test]
fn chi_square_critical_value_for_63_dof_is_103_4() {
    let critical = chi_square_critical(1e-3, 63);
    println!("χ²(63) critical value at 1e-3: {critical:.3}");
    // Tables give 103.442.
    assert!((critical - 103.442).abs() < 0.01, "{critical}");
    // And the survival function at a few known points: P(χ²_1 > 3.841) = 0.05,
    // P(χ²_10 > 18.307) = 0.05.
    assert!((chi_square_sf(3.841_459, 1) - 0.05).abs() < 1e-5);
    assert!((chi_square_sf(18.307_04, 10) - 0.05).abs() < 1e-5);
}

#[test]
fn wvds_samples_follow_the_pdf_chi_square_for_1_2_and_3_pieces() {
    let h = DVec3::new(1.0, 0.5, 2.0);
    let v = DVec3::new;
    // (case, expected pieces). Found by a search for pieces of comparable length and
    // mass; σt chosen so that σt·c·L is O(1) per piece.
    let setups = [
        (
            Case::new(
                "1 piece, c = 2.09",
                v(-0.8, 0.0, -1.0),
                v(1.0, 0.1, 0.6),
                v(1.0, 0.05, 0.8),
                h,
                1.0,
            ),
            1,
        ),
        (
            Case::new(
                "2 pieces, clamped start and end",
                v(0.2, 0.1, -1.5),
                v(0.3, 0.2, 1.0),
                v(0.1, -0.2, 1.0),
                h,
                1.5,
            )
            .clamp_start(0.05)
            .clamp_end(0.95),
            2,
        ),
        (
            Case::new(
                "2 pieces, c < 0 in the second",
                v(0.5, -0.2, 0.0),
                v(-0.2, -1.0, 0.1),
                v(1.0, 0.12, 0.0),
                h,
                10.0,
            ),
            2,
        ),
        (
            Case::new(
                "3 pieces",
                v(0.72, -0.22, 0.37),
                v(-0.41, -0.59, -0.70),
                v(0.57, -0.28, 0.77),
                h,
                6.0,
            ),
            3,
        ),
        (
            Case::new(
                "3 pieces, c < 0 in the third",
                v(0.94, 0.33, 1.95),
                v(0.80, 0.50, -0.32),
                v(-0.12, -0.93, -0.34),
                h,
                40.0,
            ),
            3,
        ),
    ];
    let gpu = Gpu::new();
    check_samples_follow_the_pdf(&gpu, &setups);
    gpu.finish();
}

/// Pearson χ² of `SAMPLES` GPU samples of each (case, expected pieces) in 64 bins against
/// bin masses from the reference, at significance 1e-3, and the pdf a sample carries
/// equals wvds_pdf there.
pub(super) fn check_samples_follow_the_pdf(gpu: &Gpu, setups: &[(Case, u32)]) {
    const SAMPLES: usize = 200_000;
    const BINS: usize = 64;
    const ALPHA: f64 = 1e-3;
    let cases: Vec<Case> = setups.iter().map(|s| s.0.clone()).collect();
    let first = gpu.run_configs(&cases, 0.5);
    let mut rng = Pcg32::new(0xc415_5eed);
    for (index, ((case, expected_pieces), (result, pieces))) in
        setups.iter().zip(&first).enumerate()
    {
        assert_eq!(
            result.count, *expected_pieces,
            "{}: pieces {pieces:?}",
            case.name
        );
        let queries: Vec<GpuQuery> = (0..SAMPLES)
            .map(|_| GpuQuery {
                config: index as u32,
                flags: 0,
                u: rng.uniform_f32(),
                t_eval: case.t_a,
            })
            .collect();
        let (samples, _) = gpu.run(&cases, &queries);
        let (t_a, t_b) = (f64::from(case.t_a), f64::from(case.t_b));
        let width = (t_b - t_a) / BINS as f64;

        // Histogram the samples; every one lies in [t_a, t_b] with a positive pdf.
        let mut observed = [0.0f64; BINS];
        for s in &samples {
            assert_eq!(s.non_finite, 0);
            let t = f64::from(s.t_sample);
            assert!(
                s.pdf_sample > 0.0 && t >= t_a - 1e-6 && t <= t_b + 1e-6,
                "{}: sample {s:?}",
                case.name
            );
            let bin = (((t - t_a) / width).floor().max(0.0) as usize).min(BINS - 1);
            observed[bin] += 1.0;
        }

        // Expected counts from bin integrals of the reference.
        let edges: Vec<f64> = (0..=BINS).map(|i| t_a + width * i as f64).collect();
        let masses = par_map(&edges.windows(2).collect::<Vec<_>>(), |e| {
            case.reference_between(e[0], e[1])
        });
        let total: f64 = masses.iter().sum();
        let expected: Vec<f64> = masses.iter().map(|m| m / total * SAMPLES as f64).collect();

        // Merge neighbouring bins until each expects at least 5 samples.
        let (mut groups, mut acc) = (Vec::<(f64, f64)>::new(), (0.0, 0.0));
        for (o, e) in observed.iter().zip(&expected) {
            acc = (acc.0 + o, acc.1 + e);
            if acc.1 >= 5.0 {
                groups.push(acc);
                acc = (0.0, 0.0);
            }
        }
        if acc.1 > 0.0 || acc.0 > 0.0 {
            match groups.last_mut() {
                Some(last) => *last = (last.0 + acc.0, last.1 + acc.1),
                None => groups.push(acc),
            }
        }
        let chi2: f64 = groups.iter().map(|(o, e)| (o - e).powi(2) / e).sum();
        let dof = groups.len() - 1;
        let p_value = chi_square_sf(chi2, dof);
        let critical = chi_square_critical(ALPHA, dof);
        println!(
            "{:<36} pieces {} slopes {:?}: χ² = {chi2:.2} with {dof} dof (critical {critical:.2}), p = {p_value:.3}",
            case.name,
            result.count,
            &pieces.slope[..result.count as usize]
        );
        assert!(
            p_value > ALPHA,
            "{}: samples do not follow the pdf: χ² = {chi2} with {dof} dof, p = {p_value}",
            case.name
        );

        // The pdf returned with a sample is wvds_pdf at that sample.
        let checks: Vec<GpuQuery> = samples
            .iter()
            .take(20_000)
            .map(|s| GpuQuery {
                config: index as u32,
                flags: 0,
                u: 0.5,
                t_eval: s.t_sample,
            })
            .collect();
        let (evaluated, _) = gpu.run(&cases, &checks);
        for (s, e) in samples.iter().zip(&evaluated) {
            assert_eq!(e.non_finite, 0, "{}: {e:?}", case.name);
            let error = (f64::from(e.pdf_eval) / f64::from(s.pdf_sample) - 1.0).abs();
            assert!(
                error < 1e-3,
                "{}: pdf at sample {} is {} but sample_wvds said {}",
                case.name,
                s.t_sample,
                e.pdf_eval,
                s.pdf_sample
            );
        }
    }
}
