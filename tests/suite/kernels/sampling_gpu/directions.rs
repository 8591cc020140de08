//! The direction samplers against their distributions: HG samples follow the HG phase
//! function with a uniform azimuth, `hg_phase` integrates to 1 over the sphere, and
//! cosine-hemisphere samples follow cos θ / π (the first three items of [`super`]).

use super::*;

#[test]
fn hg_samples_follow_hg_phase_and_have_uniform_azimuth() {
    let gpu = Gpu::new();
    let mut rng = Pcg32::new(0x5a3b_0001);
    let axes = axes(&mut rng);
    let (mut worst_cos, mut worst_phi, mut worst_z, mut worst_unit) =
        (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    println!(
        "HG: {SAMPLES} samples each; χ² of μ over {COS_BINS} equiprobable bins (critical \
         {CHI2_CRIT_63}), of φ over {PHI_BINS} bins (critical {CHI2_CRIT_31})"
    );
    for &g in &G_VALUES {
        let g64 = f64::from(g);
        for &(name, axis) in &axes {
            let u = rng.uniforms(SAMPLES);
            let outputs = gpu.run(MODE_HG, axis, g, &u);
            let what = format!("sample_hg(g = {g}, d = {name} {axis:?})");
            worst_unit = worst_unit.max(check_unit(&outputs, &what));
            let frame = Frame::new(axis);
            let mut cos_counts = [0u64; COS_BINS];
            let mut phi_counts = [0u64; PHI_BINS];
            let (mut sum, mut sum_sq) = (0.0f64, 0.0f64);
            for o in &outputs {
                let (theta, phi) = frame.angles(to_f64([o[0], o[1], o[2]]));
                let (f, fc) = hg_cdf(g64, theta);
                cos_counts[cdf_bin(f, fc, COS_BINS)] += 1;
                phi_counts[phi_bin(phi)] += 1;
                let mu = theta.cos();
                sum += mu;
                sum_sq += mu * mu;
            }
            let n = SAMPLES as f64;
            let mean = sum / n;
            let se = ((sum_sq / n - mean * mean).max(0.0) / (n - 1.0)).sqrt();
            let z = (mean - g64).abs() / se;
            let chi2_cos = chi2_uniform(&cos_counts);
            let chi2_phi = chi2_uniform(&phi_counts);
            println!(
                "  g = {g:>5}, d = {name:<6}: χ²(μ) {chi2_cos:>6.1}, χ²(φ) {chi2_phi:>5.1}, \
                 mean μ {mean:+.5} ± {se:.5} (|z| {z:.2})"
            );
            assert!(
                chi2_cos < CHI2_CRIT_63,
                "{what}: μ does not follow HG: χ² {chi2_cos} >= {CHI2_CRIT_63} (63 dof, \
                 p < 1e-3); counts per equiprobable bin {cos_counts:?}"
            );
            assert!(
                chi2_phi < CHI2_CRIT_31,
                "{what}: azimuth not uniform: χ² {chi2_phi} >= {CHI2_CRIT_31} (31 dof, \
                 p < 1e-3); counts {phi_counts:?}"
            );
            assert!(
                z <= Z,
                "{what}: mean cosine {mean} ± {se} differs from g by {z:.2} standard errors"
            );
            worst_cos = worst_cos.max(chi2_cos);
            worst_phi = worst_phi.max(chi2_phi);
            worst_z = worst_z.max(z);
        }
    }
    println!(
        "HG: largest χ²(μ) {worst_cos:.1}, χ²(φ) {worst_phi:.1}, |z| of mean cosine \
         {worst_z:.2}, | |ω| − 1 | {worst_unit:.1e}"
    );
    gpu.finish();
}

#[test]
fn hg_phase_integrates_to_one_over_the_sphere() {
    /// Nodes per end, geometric in 1 − |μ| from 2 down to 1e-9.
    const NODES_PER_END: usize = 18_000;
    const DECADES: f64 = 9.3;
    let gpu = Gpu::new();
    let mut nodes: Vec<f32> = vec![-1.0, 0.0, 1.0];
    for k in 0..=NODES_PER_END {
        let distance = 2.0 * 10f64.powf(-DECADES * k as f64 / NODES_PER_END as f64);
        nodes.push((1.0 - distance) as f32);
        nodes.push((distance - 1.0) as f32);
    }
    nodes.sort_by(f32::total_cmp);
    nodes.dedup();
    let inputs: Vec<[f32; 2]> = nodes.iter().map(|&mu| [mu, 0.0]).collect();
    println!(
        "hg_phase: trapezoid quadrature over {} f32 nodes",
        nodes.len()
    );
    let mut worst = 0.0f64;
    for &g in &G_VALUES {
        let g64 = f64::from(g);
        let outputs = gpu.run(MODE_PHASE, [0.0, 0.0, 1.0], g, &inputs);
        let mus: Vec<f64> = nodes.iter().map(|&mu| f64::from(mu)).collect();
        let gpu_values: Vec<f64> = outputs.iter().map(|o| f64::from(o[3])).collect();
        let reference: Vec<f64> = mus.iter().map(|&mu| hg_phase(g64, mu)).collect();
        let max_rel = gpu_values
            .iter()
            .zip(&reference)
            .map(|(a, b)| (a - b).abs() / b)
            .fold(0.0f64, f64::max);
        let integrate = |p: &[f64]| {
            2.0 * std::f64::consts::PI
                * mus
                    .windows(2)
                    .zip(p.windows(2))
                    .map(|(m, v)| 0.5 * (m[1] - m[0]) * (v[0] + v[1]))
                    .sum::<f64>()
        };
        let gpu_integral = integrate(&gpu_values);
        let reference_integral = integrate(&reference);
        println!(
            "  g = {g:>5}: 2π ∫ p dμ − 1 = {:+.3e} (GPU), {:+.3e} (f64 formula, quadrature \
             error); max pointwise relative error GPU vs f64 {max_rel:.2e}",
            gpu_integral - 1.0,
            reference_integral - 1.0
        );
        assert!(
            gpu_values.iter().all(|v| v.is_finite() && *v > 0.0),
            "hg_phase(·, {g}) not finite and positive everywhere"
        );
        assert!(
            (reference_integral - 1.0).abs() < QUADRATURE_TOL,
            "quadrature error {} at g = {g}: refine the grid",
            reference_integral - 1.0
        );
        assert!(
            (gpu_integral - 1.0).abs() < INTEGRAL_TOL,
            "hg_phase(·, {g}) integrates to {gpu_integral} over the sphere, not 1 \
             (|error| >= {INTEGRAL_TOL}); the f64 formula at the same nodes gives \
             {reference_integral}"
        );
        worst = worst.max((gpu_integral - 1.0).abs());
    }
    println!("hg_phase: largest |∫ − 1| {worst:.2e}");
    gpu.finish();
}

#[test]
fn cosine_hemisphere_samples_follow_cos_over_pi() {
    let gpu = Gpu::new();
    let mut rng = Pcg32::new(0x5a3c_0002);
    let mut normals = axes(&mut rng);
    normals.push(("+X", [1.0, 0.0, 0.0]));
    let (mut worst_cos, mut worst_phi, mut worst_unit) = (0.0f64, 0.0f64, 0.0f64);
    println!(
        "cosine hemisphere: {SAMPLES} samples each; χ² of μ over {COS_BINS} equiprobable \
         bins (critical {CHI2_CRIT_63}), of φ over {PHI_BINS} bins (critical {CHI2_CRIT_31})"
    );
    for &(name, n) in &normals {
        let u = rng.uniforms(SAMPLES);
        let outputs = gpu.run(MODE_COSINE, n, 0.0, &u);
        let what = format!("sample_cosine_hemisphere(n = {name} {n:?})");
        worst_unit = worst_unit.max(check_unit(&outputs, &what));
        let frame = Frame::new(n);
        let mut cos_counts = [0u64; COS_BINS];
        let mut phi_counts = [0u64; PHI_BINS];
        let mut min_cos = f64::INFINITY;
        for (i, o) in outputs.iter().enumerate() {
            let w = to_f64([o[0], o[1], o[2]]);
            let cos = dot(w, frame.axis);
            assert!(
                cos >= 0.0,
                "{what}: sample {i} {w:?} below the hemisphere ({cos})"
            );
            min_cos = min_cos.min(cos);
            let (theta, phi) = frame.angles(w);
            // μ has pdf 2μ on [0, 1]: F = μ² = cos² θ, 1 − F = sin² θ.
            cos_counts[cdf_bin(theta.cos().powi(2), theta.sin().powi(2), COS_BINS)] += 1;
            phi_counts[phi_bin(phi)] += 1;
        }
        let chi2_cos = chi2_uniform(&cos_counts);
        let chi2_phi = chi2_uniform(&phi_counts);
        println!(
            "  n = {name:<6}: χ²(μ) {chi2_cos:>6.1}, χ²(φ) {chi2_phi:>5.1}, min dot(n, ω) \
             {min_cos:.2e}"
        );
        assert!(
            chi2_cos < CHI2_CRIT_63,
            "{what}: μ does not follow 2μ: χ² {chi2_cos} >= {CHI2_CRIT_63} (63 dof, p < \
             1e-3); counts {cos_counts:?}"
        );
        assert!(
            chi2_phi < CHI2_CRIT_31,
            "{what}: azimuth not uniform: χ² {chi2_phi} >= {CHI2_CRIT_31} (31 dof, p < 1e-3); \
             counts {phi_counts:?}"
        );
        worst_cos = worst_cos.max(chi2_cos);
        worst_phi = worst_phi.max(chi2_phi);
    }
    println!(
        "cosine hemisphere: largest χ²(μ) {worst_cos:.1}, χ²(φ) {worst_phi:.1}, | |ω| − 1 | \
         {worst_unit:.1e}"
    );
    gpu.finish();
}
