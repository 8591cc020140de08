//! The unbiased estimators on the GPU: ratio tracking and residual ratio tracking against
//! the reference transmittance, and decomposition tracking's collisions against T.

use super::*;

/// 50 rays with interesting transmittance: outside starts through the box, inside starts,
/// axis-aligned and truncated ones, plus two with T = 1 (a miss, a zero-length interval).
fn estimator_rays(m: &Medium, count: usize, rng: &mut Pcg32) -> Vec<Ray> {
    let candidates = random_rays(m, 40 * count, rng);
    let mut rays: Vec<Ray> = Vec::new();
    for ray in candidates {
        let t = (-m.optical_depth(&ray)).exp();
        let wanted_kind = rays.iter().filter(|r| r.kind == ray.kind).count() < count.div_ceil(3);
        let informative = (0.02..0.98).contains(&t)
            || (matches!(ray.kind, "miss" | "zero-length")
                && !rays.iter().any(|r| r.kind == ray.kind));
        if informative && wanted_kind && rays.len() < count {
            rays.push(ray);
        }
    }
    rays
}

#[test]
fn ratio_and_residual_ratio_tracking_are_unbiased() {
    const SAMPLES_PER_INVOCATION: u32 = 64;
    const INVOCATIONS: usize = 128; // 8192 estimates per ray and estimator
    let gpu = Gpu::new();
    let mut rng = Pcg32::new(0x6a1d_0004);
    let all = media();
    let mut checked = 0;
    for (medium, count) in all.iter().zip([15, 10, 15, 10]) {
        let rays = estimator_rays(medium, count, &mut rng);
        let handle = gpu.upload(medium);
        let mut queries = Vec::new();
        for (r, ray) in rays.iter().enumerate() {
            for i in 0..INVOCATIONS {
                queries.push(ray.query(
                    MODE_ESTIMATORS,
                    SAMPLES_PER_INVOCATION,
                    (r * INVOCATIONS + i) as u32 ^ 0x5eed,
                ));
            }
        }
        let results = gpu.run(&handle, &queries);
        let n = (INVOCATIONS as u32 * SAMPLES_PER_INVOCATION) as f64;
        let (mut var_ratio_sum, mut var_residual_sum, mut worst_z) = (0.0, 0.0, 0.0f64);
        for (ray, chunk) in rays.iter().zip(results.chunks(INVOCATIONS)) {
            let reference = (-medium.optical_depth(ray)).exp();
            let sums = chunk.iter().fold([0f64; 4], |mut acc, r| {
                for (a, v) in acc.iter_mut().zip(r.r0) {
                    *a += f64::from(v);
                }
                acc
            });
            for (estimator, (sum, sum_sq)) in [
                ("ratio tracking", (sums[0], sums[1])),
                ("residual ratio tracking", (sums[2], sums[3])),
            ] {
                let mean = sum / n;
                let variance = (sum_sq / n - mean * mean).max(0.0) * n / (n - 1.0);
                let se = (variance / n).sqrt();
                let z = (mean - reference).abs() / se.max(1e-12);
                worst_z = worst_z.max(z);
                assert!(
                    (mean - reference).abs() <= Z * se + 2e-6,
                    "{}: {estimator} on {} ray {ray:?}: mean {mean} ± {se} vs T {reference}",
                    medium.name,
                    ray.kind
                );
                if estimator == "ratio tracking" {
                    var_ratio_sum += variance;
                } else {
                    var_residual_sum += variance;
                }
            }
            checked += 1;
        }
        println!(
            "{:<36} {} rays × {n} estimates: mean variance ratio tracking {:.3e}, residual ratio \
             tracking {:.3e}; largest |mean − T| / SE {worst_z:.2}",
            medium.name,
            rays.len(),
            var_ratio_sum / rays.len() as f64,
            var_residual_sum / rays.len() as f64
        );
        // Where super-voxel minima are 0 (sparse media), residual ratio tracking is ratio
        // tracking with local majorants: fewer steps, not lower variance (a larger
        // majorant lowers ratio tracking's variance). Its control component pays off
        // where the minima are positive: there it must have the lower variance.
        if medium.name.starts_with("dense") {
            assert!(
                var_residual_sum < 0.5 * var_ratio_sum,
                "{}: residual ratio tracking variance {var_residual_sum} not below half of \
                 ratio tracking's {var_ratio_sum}",
                medium.name
            );
        }
    }
    assert_eq!(checked, 50, "expected 50 rays");
    gpu.finish();
}

#[test]
fn decomposition_tracking_collisions_follow_transmittance() {
    const SAMPLES: usize = 20_000;
    let gpu = Gpu::new();
    let mut rng = Pcg32::new(0x6a1d_0005);
    let all = media();
    let mut worst_z = 0.0f64;
    for medium in [&all[0], &all[2]] {
        let rays = estimator_rays(medium, 12, &mut rng);
        let rays: Vec<Ray> = rays
            .into_iter()
            .filter(|r| r.kind != "miss")
            .take(3)
            .collect();
        let handle = gpu.upload(medium);
        let queries: Vec<GpuQuery> = rays
            .iter()
            .enumerate()
            .flat_map(|(r, ray)| {
                (0..SAMPLES).map(move |i| ray.query(MODE_COLLISION, 0, (r * SAMPLES + i) as u32))
            })
            .collect();
        let results = gpu.run(&handle, &queries);
        for (ray, chunk) in rays.iter().zip(results.chunks(SAMPLES)) {
            let (t_in, t_out) = medium.span(ray.o.map(f64::from), ray.d.map(f64::from));
            let (ta, tb) = (f64::from(ray.t0).max(t_in), f64::from(ray.t1).min(t_out));
            let distances: Vec<f64> = chunk.iter().map(|r| f64::from(r.r0[0])).collect();
            // Collisions lie in the clipped interval; FAR means the ray passed.
            for &t in &distances {
                assert!(
                    t == f64::from(FAR) || (t >= ta - 1e-5 && t < tb + 1e-5),
                    "{}: collision at {t} outside [{ta}, {tb})",
                    medium.name
                );
            }
            let mut checks = Vec::new();
            for k in 1..=4 {
                let s = ta + (tb - ta) * f64::from(k) / 5.0;
                let partial = Ray {
                    t1: s as f32,
                    ..*ray
                };
                let s = f64::from(partial.t1);
                let fraction = distances.iter().filter(|&&t| t > s).count() as f64 / SAMPLES as f64;
                checks.push((
                    format!("beyond {s:.3}"),
                    fraction,
                    (-medium.optical_depth(&partial)).exp(),
                ));
            }
            let passed =
                distances.iter().filter(|&&t| t == f64::from(FAR)).count() as f64 / SAMPLES as f64;
            checks.push(("passing".into(), passed, (-medium.optical_depth(ray)).exp()));
            for (what, fraction, expected) in &checks {
                let se = (expected * (1.0 - expected) / SAMPLES as f64).sqrt();
                let z = (fraction - expected).abs() / se.max(1e-12);
                worst_z = worst_z.max(z);
                assert!(
                    (fraction - expected).abs() <= Z * se + 1e-9,
                    "{}: {} ray {ray:?}: fraction {what} {fraction} vs T {expected} (SE {se})",
                    medium.name,
                    ray.kind
                );
            }
            println!(
                "{:<36} {} ray: {}",
                medium.name,
                ray.kind,
                checks
                    .iter()
                    .map(|(w, f, e)| format!("{w}: {f:.4} vs T {e:.4}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
    }
    println!("decomposition tracking: largest |fraction − T| / SE {worst_z:.2}");
    gpu.finish();
}
