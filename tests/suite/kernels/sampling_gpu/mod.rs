//! The sampling families of `shaders/include/sampling.glsl` and `phase.glsl` run on the
//! GPU through `shaders/tests/sampling.comp`, with validation layers on, against f64
//! mathematics on the CPU (pbrt-style: the mathematics before the pictures):
//!
//! - `sample_hg(d, g, u)` follows HG: for 6 values of g and 4 axes d (+Z, −Z, a direction
//!   with d.z ≈ −1 and a random one), 200 000 samples from uniform random u. μ = cos θ =
//!   dot(ω, d) is binned into 64 bins of equal probability under HG, i.e. uniform in the
//!   CDF F(μ) (derived below); Pearson χ² with 63 degrees of freedom must stay below
//!   103.44, its 0.999 quantile. The azimuth about d is binned into 32 equal bins; χ² with
//!   31 degrees of freedom below 61.10. The mean cosine must equal g within 4 standard
//!   errors.
//! - `hg_phase` integrates to 1 over the sphere: 2π × trapezoid quadrature over μ ∈ [−1, 1]
//!   of GPU values at 19 493 distinct f32 nodes graded geometrically towards both μ = ±1
//!   (down to 1 − |μ| = 1e-9, below f32 resolution there), |∫ − 1| < 1e-5 (the f32 phase function reaches 6e-7 at |g| = 0.99 since its
//!   denominator is a sum of non-negative terms). The same
//!   quadrature of the f64 formula at the same nodes shows the quadrature error (asserted
//!   < 1e-6).
//! - `sample_cosine_hemisphere(n, u)` stays in the hemisphere (dot(n, ω) >= 0), μ = dot(n, ω)
//!   follows the pdf 2μ of p(ω) = cos θ / π (64 bins uniform in its CDF μ², χ² as above),
//!   and its azimuth is uniform, for 5 normals including −Z.
//! - Every sampled direction is finite and of unit length within 1e-5.
//!
//! Every family (HG, cosine hemisphere, uniform sphere, uniform cone, exponential,
//! truncated exponential), each at several parameters, keeps `sample_X`, `X_pdf` and
//! `invert_X` consistent:
//!
//! - **Round trip**: for 20 000 random u per configuration, `invert_X(sample_X(u)) = u`
//!   within 1e-6 + 4 float spacings of the sampled variable (cos θ, or the distance)
//!   times du/dx there: the samplers round that variable in f32 (HG's cos θ formula, a
//!   normalised direction), and the CDF carries the rounding on with its slope, which is
//!   large where the density peaks (HG at |g| = 0.99) or in narrow cones. The azimuth
//!   u.y comes back within 1e-6 + 4 ε / (2π sin θ), since a direction's rounding of a few
//!   ε moves its azimuth by that over sin θ. The inverse also matches the f64 CDF of the
//!   sample within the same tolerance, and the pdf at the sample matches the f64 formula
//!   within 1e-5 relative plus the pdf's slope times 4 spacings (the GPU's own cos θ).
//!   Measured on lavapipe: at most about half of each tolerance.
//! - **The pdf integrates to 1 and is the CDF's derivative**: trapezoid quadrature of the
//!   GPU pdf over graded f32 nodes (the HG nodes for directions; 20 000 uniform nodes over
//!   40 mean free paths for distances) gives 1 within 1e-5, its running integral stays
//!   within 1e-5 of the f64 CDF at every node, and the pointwise GPU values are the f64
//!   formula's within 1e-5 relative. The same quadrature of the f64 formula bounds the
//!   quadrature error (asserted < 1e-6).
//!
//! Together: the sampler is the inverse of the CDF, and the CDF is the integral of the
//! pdf, so samples are distributed by the pdf.
//!
//! The direction tests are in [`directions`], the families' in [`families`]; this module
//! holds the GPU side and the f64 statistics they share.
//!
//! # The HG CDF
//!
//! With D(μ) = 1 + g² − 2gμ, the density of μ is f(μ) = 2π p(μ) = (1 − g²) / (2 D^{3/2}),
//! and d/dμ D^{−1/2} = g D^{−3/2}, so
//!
//! ```text
//! F(μ) = (1 − g²)/(2g) · (D(μ)^{−1/2} − 1/(1 + g)),          F(1) = 1.
//! ```
//!
//! Rationalised (using (1 + g)² − D = 2g(1 + μ) and D − (1 − g)² = 2g(1 − μ)), with s = √D:
//!
//! ```text
//! F(μ)     = (1 − g)(1 + μ) / (s (1 + g + s)),
//! 1 − F(μ) = (1 + g)(1 − μ) / (s (1 − g + s)),
//! ```
//!
//! free of cancellation and of the division by g (g = 0 gives F = (1 + μ)/2). Both 1 ± μ
//! come from θ = atan2(|ω × d|, ω · d) as 2 sin²(θ/2) and 2 cos²(θ/2), exact to f64 even
//! where f32's μ is 1 to within its rounding (g = ±0.99 puts 1/64 of its mass within
//! 1 − |μ| < 1.6e-6), and D = (1 − g)² + 2g(1 − μ) for g >= 0, (1 + g)² − 2g(1 + μ) for
//! g < 0, a sum of non-negative terms.
//!
//! All seeds are fixed, so each outcome is deterministic; at significance 1e-3 the 58
//! χ² checks all pass with probability 0.94 under the null.

use crate::common::kernel::{records, Arg, Kernel};
use crate::common::rng::Pcg32;
use bytemuck::{Pod, Zeroable};
use nimbus_gpu::BindingDesc;

mod directions;
mod families;

/// The HG asymmetries tested (as f32, which the GPU and the reference both use).
const G_VALUES: [f32; 6] = [-0.99, -0.5, 0.0, 0.3, 0.8, 0.99];
/// Samples per (g, axis) or per normal.
const SAMPLES: usize = 200_000;
/// Equiprobable bins for μ.
const COS_BINS: usize = 64;
/// Equal bins for the azimuth.
const PHI_BINS: usize = 32;
/// 0.999 quantile of χ² with 63 degrees of freedom (regularised incomplete gamma, bisected).
const CHI2_CRIT_63: f64 = 103.442;
/// 0.999 quantile of χ² with 31 degrees of freedom.
const CHI2_CRIT_31: f64 = 61.098;
/// Standard errors allowed for the mean cosine.
const Z: f64 = 4.0;
/// Allowed | |ω| − 1 |.
const UNIT_TOL: f64 = 1e-5;
/// Allowed |∫ p dω − 1| for the GPU's hg_phase.
const INTEGRAL_TOL: f64 = 1e-5;
/// Allowed quadrature error, measured on the f64 formula.
const QUADRATURE_TOL: f64 = 1e-6;

const MODE_HG: u32 = 0;
const MODE_COSINE: u32 = 1;
const MODE_PHASE: u32 = 2;
const LOCAL_SIZE: u32 = 64;

// ---------------------------------------------------------------------------------------
// GPU side.

/// The push constants of sampling.comp.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuPush {
    axis_g: [f32; 4],
    mode: u32,
    count: u32,
    family: u32,
    pad: u32,
}

const _: () = assert!(std::mem::size_of::<GpuPush>() == 32);

/// The test kernel `shaders/tests/sampling.comp`.
struct Gpu {
    kernel: Kernel,
}

impl Gpu {
    fn new() -> Self {
        let layout = [
            BindingDesc::storage_buffer(0),
            BindingDesc::storage_buffer(1),
        ];
        Self {
            kernel: Kernel::new(
                nimbus::shaders::TESTS_SAMPLING,
                &layout,
                std::mem::size_of::<GpuPush>() as u32,
                &[],
                "sampling test",
            ),
        }
    }

    /// One invocation per input; one output (xyz direction, w phase value) per input.
    fn run(&self, mode: u32, axis: [f32; 3], g: f32, inputs: &[[f32; 2]]) -> Vec<[f32; 4]> {
        self.run_family(mode, 0, axis, g, inputs)
    }

    /// As [`Gpu::run`] for a sampling family (`FAMILY_*`) with its parameter.
    fn run_family(
        &self,
        mode: u32,
        family: u32,
        axis: [f32; 3],
        param: f32,
        inputs: &[[f32; 2]],
    ) -> Vec<[f32; 4]> {
        let count = u32::try_from(inputs.len()).expect("input count fits u32");
        let push = GpuPush {
            axis_g: [axis[0], axis[1], axis[2], param],
            mode,
            count,
            family,
            pad: 0,
        };
        let out = self.kernel.run(
            &[
                Arg::Storage(0, bytemuck::cast_slice(inputs)),
                Arg::Zeroed(1, inputs.len() * 16),
            ],
            bytemuck::bytes_of(&push),
            [count.div_ceil(LOCAL_SIZE), 1, 1],
        );
        records(&out[1], inputs.len())
    }

    /// Fails on any validation error so far.
    fn finish(self) {
        self.kernel.finish();
    }
}

// ---------------------------------------------------------------------------------------
// Random numbers and vectors.

type V3 = [f64; 3];

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn length(a: V3) -> f64 {
    dot(a, a).sqrt()
}

fn scale(a: V3, s: f64) -> V3 {
    a.map(|c| c * s)
}

fn unit_f32(v: V3) -> [f32; 3] {
    scale(v, 1.0 / length(v)).map(|c| c as f32)
}

fn to_f64(v: [f32; 3]) -> V3 {
    v.map(f64::from)
}

/// The axes: ±Z (exact), one with d.z ≈ −1 (orthonormal_basis's s = −1 branch near its
/// pole) and one random.
fn axes(rng: &mut Pcg32) -> Vec<(&'static str, [f32; 3])> {
    vec![
        ("+Z", [0.0, 0.0, 1.0]),
        ("-Z", [0.0, 0.0, -1.0]),
        ("z≈-1", unit_f32([1e-3, -2e-3, -1.0])),
        ("random", rng.unit_vector_f32_renormalized()),
    ]
}

// ---------------------------------------------------------------------------------------
// Statistics.

/// Polar angle θ of `w` about unit `axis` and its azimuth φ ∈ [−π, π] in an f64 frame of
/// the CPU's own (any fixed frame: a uniform φ stays uniform under a constant shift).
struct Frame {
    axis: V3,
    t: V3,
    b: V3,
}

impl Frame {
    fn new(axis: [f32; 3]) -> Self {
        let axis = to_f64(axis);
        let axis = scale(axis, 1.0 / length(axis));
        let helper = if axis[0].abs() < 0.6 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 1.0, 0.0]
        };
        let t = cross(helper, axis);
        let t = scale(t, 1.0 / length(t));
        let b = cross(axis, t);
        Self { axis, t, b }
    }

    /// (θ, φ) of `w` (any length).
    fn angles(&self, w: V3) -> (f64, f64) {
        let theta = length(cross(w, self.axis)).atan2(dot(w, self.axis));
        let phi = dot(w, self.b).atan2(dot(w, self.t));
        (theta, phi)
    }
}

/// (F(μ), 1 − F(μ)) of HG with asymmetry g, from θ (see the module docs).
fn hg_cdf(g: f64, theta: f64) -> (f64, f64) {
    let one_minus_mu = 2.0 * (0.5 * theta).sin().powi(2);
    let one_plus_mu = 2.0 * (0.5 * theta).cos().powi(2);
    let d = if g >= 0.0 {
        (1.0 - g).powi(2) + 2.0 * g * one_minus_mu
    } else {
        (1.0 + g).powi(2) - 2.0 * g * one_plus_mu
    };
    let s = d.sqrt();
    (
        (1.0 - g) * one_plus_mu / (s * (1.0 + g + s)),
        (1.0 + g) * one_minus_mu / (s * (1.0 - g + s)),
    )
}

/// HG phase function p(μ) in f64.
fn hg_phase(g: f64, mu: f64) -> f64 {
    let d = 1.0 + g * g - 2.0 * g * mu;
    (1.0 - g * g) / (4.0 * std::f64::consts::PI * d * d.sqrt())
}

/// The bin of a sample with CDF value f (complement fc) among `bins` equiprobable bins,
/// taken from the nearer end for precision.
fn cdf_bin(f: f64, fc: f64, bins: usize) -> usize {
    let n = bins as f64;
    if f <= 0.5 {
        ((f * n) as usize).min(bins - 1)
    } else {
        bins - 1 - ((fc * n) as usize).min(bins - 1)
    }
}

fn phi_bin(phi: f64) -> usize {
    let x = (phi + std::f64::consts::PI) / (2.0 * std::f64::consts::PI);
    ((x * PHI_BINS as f64) as usize).min(PHI_BINS - 1)
}

/// Pearson χ² of counts against equal expected counts.
fn chi2_uniform(counts: &[u64]) -> f64 {
    let total: u64 = counts.iter().sum();
    let expected = total as f64 / counts.len() as f64;
    counts
        .iter()
        .map(|&c| (c as f64 - expected).powi(2) / expected)
        .sum()
}

/// Every direction finite and of unit length; returns the largest | |ω| − 1 |.
fn check_unit(outputs: &[[f32; 4]], what: &str) -> f64 {
    let mut worst = 0.0f64;
    for (i, o) in outputs.iter().enumerate() {
        let w = [o[0], o[1], o[2]];
        assert!(
            w.iter().all(|c| c.is_finite()),
            "{what}: sample {i} is not finite: {w:?}"
        );
        let error = (length(to_f64(w)) - 1.0).abs();
        assert!(
            error <= UNIT_TOL,
            "{what}: sample {i} {w:?} has length 1 {error:+e}"
        );
        worst = worst.max(error);
    }
    worst
}
