//! The phase function and direction sampling.

use std::f64::consts::PI;

use glam::DVec3;

use super::rng::Rng;

/// The Henyey–Greenstein phase function, normalized over the sphere; `cos_theta` is the
/// cosine between the travel directions before and after scattering, |g| < 1 (so the
/// base 1 + g² − 2g·cosθ ≥ (1 − |g|)² > 0).
pub(crate) fn henyey_greenstein(cos_theta: f64, g: f64) -> f64 {
    let base = 1.0 + g * g - 2.0 * g * cos_theta;
    (1.0 - g * g) / (4.0 * PI * base * base.sqrt())
}

/// Two unit vectors completing unit `n` to a right-handed orthonormal basis (Duff et
/// al. 2017); sign(0) is taken as +1, so 1/(sign + n.z) has |sign + n.z| ≥ 1.
fn orthonormal_basis(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// The unit direction with cosine `cos_theta` to `axis` and azimuth 2π·u.
pub(crate) fn direction_around(axis: DVec3, cos_theta: f64, u: f64) -> DVec3 {
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = 2.0 * PI * u;
    let (t, b) = orthonormal_basis(axis);
    (sin_theta * phi.cos() * t + sin_theta * phi.sin() * b + cos_theta * axis).normalize()
}

/// Samples a new travel direction from the HG lobe around travel direction `d`.
/// Inverts the CDF P(μ) = (1−g²)/(2g)·[(1+g²−2gμ)^{−1/2} − 1/(1+g)] = u (its base
/// 1 − g + 2gu is in [1 − |g|, 1 + |g|], > 0); |g| < 1e-4 uses the isotropic limit.
pub(crate) fn sample_hg(d: DVec3, g: f64, rng: &mut Rng) -> DVec3 {
    let (u1, u2) = (rng.uniform(), rng.uniform());
    let cos_theta = if g.abs() < 1e-4 {
        1.0 - 2.0 * u1
    } else {
        let q = (1.0 - g * g) / (1.0 - g + 2.0 * g * u1);
        ((1.0 + g * g - q * q) / (2.0 * g)).clamp(-1.0, 1.0)
    };
    direction_around(d, cos_theta, u2)
}

/// Samples a cosine-distributed direction around unit `n` (pdf cosθ/π).
pub(crate) fn sample_cosine(n: DVec3, rng: &mut Rng) -> DVec3 {
    let (u1, u2) = (rng.uniform(), rng.uniform());
    direction_around(n, (1.0 - u1).sqrt(), u2)
}

/// Uniform on the unit sphere (pdf 1/(4π)).
pub(crate) fn sample_sphere(rng: &mut Rng) -> DVec3 {
    let (u1, u2) = (rng.uniform(), rng.uniform());
    direction_around(DVec3::Z, 1.0 - 2.0 * u1, u2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phase_sampling_matches_the_hg_moments() {
        // HG's Legendre moments are g^l: E[μ] = g and E[μ²] = (1 + 2g²)/3; the cosine
        // lobe has E[cosθ] = 2/3.
        let n = 100_000;
        let axis = DVec3::new(0.3, -0.8, 0.52).normalize();
        let mut rng = Rng::new(1, 2);
        for g in [-0.7, 0.0, 0.3, 0.9] {
            let (mut m1, mut m2) = (0.0, 0.0);
            for _ in 0..n {
                let w = sample_hg(axis, g, &mut rng);
                assert!((w.length() - 1.0).abs() < 1e-12);
                let mu = w.dot(axis);
                m1 += mu;
                m2 += mu * mu;
            }
            let n = f64::from(n);
            assert!(
                (m1 / n - g).abs() < 5.0 / n.sqrt(),
                "g = {g}: E[μ] = {}",
                m1 / n
            );
            let expected = (1.0 + 2.0 * g * g) / 3.0;
            assert!((m2 / n - expected).abs() < 5.0 / n.sqrt(), "g = {g}");
        }
        let mean_cos: f64 = (0..n)
            .map(|_| sample_cosine(-axis, &mut rng).dot(-axis))
            .sum::<f64>()
            / f64::from(n);
        assert!((mean_cos - 2.0 / 3.0).abs() < 5.0 * 0.24 / f64::from(n).sqrt());
    }
}
