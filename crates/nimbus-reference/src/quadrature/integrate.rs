//! Global adaptive Gauss–Kronrod (G7, K15) quadrature of RGB integrands.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use glam::DVec3;

/// Equal pieces each in-medium interval starts as, before adaptive refinement.
pub const INITIAL_SUBINTERVALS: usize = 64;
/// Deepest bisection of one initial piece (a piece of length ℓ/2^40 is not split).
pub const MAX_DEPTH: u32 = 40;
/// Most bisections spent on one integral.
pub const MAX_BISECTIONS: usize = 20_000;

/// [t0, t1] split into [`INITIAL_SUBINTERVALS`] equal pieces and at each cut inside it.
pub(super) fn split_interval(t0: f64, t1: f64, cuts: &[f64]) -> Vec<(f64, f64)> {
    let n = INITIAL_SUBINTERVALS;
    let mut points: Vec<f64> = (0..=n)
        .map(|i| t0 + (t1 - t0) * i as f64 / n as f64)
        .chain(cuts.iter().copied().filter(|&t| t > t0 && t < t1))
        .collect();
    points[n] = t1;
    points.sort_by(f64::total_cmp);
    points
        .windows(2)
        .filter(|w| w[1] > w[0])
        .map(|w| (w[0], w[1]))
        .collect()
}

/// Gauss–Kronrod nodes on [−1, 1] (non-negative half, descending) and weights, from
/// QUADPACK's `qk15`. Odd indices are the 7-point Gauss nodes.
#[allow(clippy::excessive_precision)]
const XGK: [f64; 8] = [
    0.991_455_371_120_812_639_206_854_697_526_329,
    0.949_107_912_342_758_524_526_189_684_047_851,
    0.864_864_423_359_769_072_789_712_788_640_926,
    0.741_531_185_599_394_439_863_864_773_280_788,
    0.586_087_235_467_691_130_294_144_845_693_013,
    0.405_845_151_377_397_166_906_606_412_076_961,
    0.207_784_955_007_898_467_600_689_403_773_245,
    0.0,
];
#[allow(clippy::excessive_precision)]
const WGK: [f64; 8] = [
    0.022_935_322_010_529_224_963_732_008_058_970,
    0.063_092_092_629_978_553_290_700_663_189_204,
    0.104_790_010_322_250_183_839_876_322_541_518,
    0.140_653_259_715_525_918_745_189_590_510_238,
    0.169_004_726_639_267_902_826_583_426_598_550,
    0.190_350_578_064_785_409_913_256_402_421_014,
    0.204_432_940_075_298_892_414_161_999_234_649,
    0.209_482_141_084_727_828_012_999_174_891_714,
];
/// Weights of the 7-point Gauss rule at `XGK[1]`, `XGK[3]`, `XGK[5]`, `XGK[7]`.
#[allow(clippy::excessive_precision)]
const WG: [f64; 4] = [
    0.129_484_966_168_869_693_270_611_432_679_082,
    0.279_705_391_489_276_667_901_467_771_423_780,
    0.381_830_050_505_118_944_950_369_775_488_975,
    0.417_959_183_673_469_387_755_102_040_816_327,
];

/// K15 on [a, b] and the error estimate max_c |K15 − G7|.
fn gauss_kronrod_15(f: &impl Fn(f64) -> DVec3, a: f64, b: f64) -> (DVec3, f64) {
    let (mid, half) = (0.5 * (a + b), 0.5 * (b - a));
    let f_mid = f(mid);
    let mut kronrod = WGK[7] * f_mid;
    let mut gauss = WG[3] * f_mid;
    for k in 0..7 {
        let dx = half * XGK[k];
        let pair = f(mid - dx) + f(mid + dx);
        kronrod += WGK[k] * pair;
        if k % 2 == 1 {
            gauss += WG[k / 2] * pair;
        }
    }
    let error = ((kronrod - gauss) * half).abs().max_element();
    (kronrod * half, error)
}

struct Piece {
    a: f64,
    b: f64,
    tag: usize,
    depth: u32,
    value: DVec3,
    error: f64,
}

impl PartialEq for Piece {
    fn eq(&self, other: &Self) -> bool {
        self.error.total_cmp(&other.error) == Ordering::Equal
    }
}
impl Eq for Piece {}
impl PartialOrd for Piece {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Piece {
    fn cmp(&self, other: &Self) -> Ordering {
        self.error.total_cmp(&other.error)
    }
}

/// Integrates f over the union of `pieces`, see [`integrate_adaptive_tagged`].
pub(super) fn integrate_adaptive(
    pieces: &[(f64, f64)],
    f: impl Fn(f64) -> DVec3,
    rel_tol: f64,
    abs_tol: f64,
) -> DVec3 {
    let tags = vec![0; pieces.len()];
    integrate_adaptive_tagged(pieces, &tags, |t, _| f(t), rel_tol, abs_tol)
}

/// Global adaptive Gauss–Kronrod quadrature of f(t, tag) over pieces, each with a tag
/// passed to f. Bisects the piece with the largest error estimate until the summed
/// estimate ≤ max(abs_tol, rel_tol · max_c |I_c|), every remaining piece is at
/// [`MAX_DEPTH`], or [`MAX_BISECTIONS`] are spent.
pub(super) fn integrate_adaptive_tagged(
    pieces: &[(f64, f64)],
    tags: &[usize],
    f: impl Fn(f64, usize) -> DVec3,
    rel_tol: f64,
    abs_tol: f64,
) -> DVec3 {
    let estimate = |a: f64, b: f64, tag: usize, depth: u32| {
        let (value, error) = gauss_kronrod_15(&|t| f(t, tag), a, b);
        Piece {
            a,
            b,
            tag,
            depth,
            value,
            error,
        }
    };
    let mut heap: BinaryHeap<Piece> = pieces
        .iter()
        .zip(tags)
        .map(|(&(a, b), &tag)| estimate(a, b, tag, 0))
        .collect();
    let mut finished: Vec<Piece> = Vec::new();
    let total = |heap: &BinaryHeap<Piece>, finished: &[Piece]| {
        heap.iter()
            .chain(finished)
            .fold((DVec3::ZERO, 0.0), |(value, error), p| {
                (value + p.value, error + p.error)
            })
    };

    // Track the totals incrementally and refresh them exactly now and then.
    let (mut value, mut error) = total(&heap, &finished);
    for bisection in 0..MAX_BISECTIONS {
        if error <= abs_tol.max(rel_tol * value.abs().max_element()) {
            break;
        }
        let Some(worst) = heap.pop() else {
            break;
        };
        let mid = 0.5 * (worst.a + worst.b);
        if worst.depth >= MAX_DEPTH || !(mid > worst.a && mid < worst.b) {
            finished.push(worst);
            continue;
        }
        let left = estimate(worst.a, mid, worst.tag, worst.depth + 1);
        let right = estimate(mid, worst.b, worst.tag, worst.depth + 1);
        value += left.value + right.value - worst.value;
        error += left.error + right.error - worst.error;
        heap.push(left);
        heap.push(right);
        if bisection % 256 == 255 {
            (value, error) = total(&heap, &finished);
        }
    }
    total(&heap, &finished).0
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;
    use crate::common::sampling::henyey_greenstein;
    use crate::common::testing::assert_close;

    #[test]
    fn gauss_kronrod_constants_integrate_polynomials_exactly() {
        // K15 is exact to degree 22 and G7 to degree 13; x^k on [0, 1] is 1/(k+1).
        for k in 0..=13 {
            let f = |t: f64| DVec3::splat(t.powi(k));
            let (value, error) = gauss_kronrod_15(&f, 0.0, 1.0);
            assert_close(value.x, 1.0 / f64::from(k + 1), 1e-14);
            assert!(error < 1e-14, "k = {k}: G7 error estimate {error:e}");
        }
        let (value, _) = gauss_kronrod_15(&|t: f64| DVec3::splat(t.powi(22)), 0.0, 1.0);
        assert_close(value.x, 1.0 / 23.0, 1e-14);
    }

    #[test]
    fn adaptive_quadrature_finds_a_step() {
        // The step sits away from every initial cut, so only adaptivity finds it.
        let step = 0.123_456_789;
        let f = |t: f64| DVec3::new(if t < step { 1.0 } else { 0.0 }, t.exp(), 0.0);
        let pieces = split_interval(0.0, 1.0, &[]);
        let value = integrate_adaptive(&pieces, f, 1e-12, 0.0);
        assert_close(value.x, step, 1e-11);
        assert_close(value.y, std::f64::consts::E - 1.0, 1e-12);
    }

    #[test]
    fn henyey_greenstein_integrates_to_one_over_the_sphere() {
        // ∫ p dω = 2π ∫_{-1}^{1} p(μ) dμ.
        for g in [-0.9, -0.3, 0.0, 0.5, 0.95] {
            let pieces = split_interval(-1.0, 1.0, &[]);
            let f = |mu: f64| DVec3::splat(2.0 * PI * henyey_greenstein(mu, g));
            let total = integrate_adaptive(&pieces, f, 1e-13, 0.0).x;
            assert_close(total, 1.0, 1e-11);
        }
        assert_close(henyey_greenstein(0.3, 0.0), 1.0 / (4.0 * PI), 1e-15);
    }
}
