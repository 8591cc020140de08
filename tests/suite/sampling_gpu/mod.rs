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

// ---------------------------------------------------------------------------------------
// Tests.

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

// ---------------------------------------------------------------------------------------
// The sampling families: sample_X, X_pdf and invert_X together.

const MODE_SAMPLE: u32 = 3;
const MODE_ROUND_TRIP: u32 = 4;
const MODE_PDF: u32 = 5;

const FAMILY_HG: u32 = 0;
const FAMILY_COSINE: u32 = 1;
const FAMILY_SPHERE: u32 = 2;
const FAMILY_CONE: u32 = 3;
const FAMILY_EXPONENTIAL: u32 = 4;
const FAMILY_TRUNCATED_EXPONENTIAL: u32 = 5;

/// Samples per family configuration in the round-trip test.
const ROUND_TRIP_SAMPLES: usize = 20_000;
/// Quadrature nodes of a distance family's pdf.
const DISTANCE_NODES: usize = 20_000;
/// A distance family's pdf is integrated over [0, DISTANCE_SPAN / rate]: e^-40 of the
/// mass lies beyond.
const DISTANCE_SPAN: f64 = 40.0;
/// f32's machine epsilon: the spacing of floats just above 1.
const EPS32: f64 = f32::EPSILON as f64;

/// One sampling family at one parameter, with its f64 references.
struct Family {
    name: String,
    id: u32,
    /// g (HG), 1 − cos θ_max (cone), the rate (exponential), the optical depth x
    /// (truncated exponential); unused otherwise.
    param: f32,
    /// Directions (the variable is cos θ about the axis) or a distance.
    direction: bool,
    /// The variable's domain.
    domain: (f64, f64),
}

impl Family {
    fn p(&self) -> f64 {
        f64::from(self.param)
    }

    /// The reference pdf in f64 (solid angle for directions) at cos θ or the distance.
    fn pdf(&self, x: f64) -> f64 {
        let p = self.p();
        match self.id {
            FAMILY_HG => hg_phase(p, x),
            FAMILY_COSINE => x.max(0.0) / std::f64::consts::PI,
            FAMILY_SPHERE => 0.25 / std::f64::consts::PI,
            FAMILY_CONE => 0.5 / (std::f64::consts::PI * p),
            FAMILY_EXPONENTIAL => p * (-p * x).exp(),
            _ if p == 0.0 => 1.0,
            _ => p * (-p * x).exp() / -(-p).exp_m1(),
        }
    }

    /// The reference u.x of a sample with polar angle θ about the axis (directions) or
    /// at distance t, formed without cancellation: for directions the probability of a
    /// cos θ' < cos θ (sample_* sends u.x = 0 to the axis), for distances the CDF.
    fn u_x(&self, theta: f64, t: f64) -> f64 {
        let p = self.p();
        // 1 − cos θ = 2 sin²(θ/2).
        let one_minus_cos = 2.0 * (0.5 * theta).sin().powi(2);
        match self.id {
            FAMILY_HG => hg_cdf(p, theta).1,
            FAMILY_COSINE => theta.sin().powi(2),
            FAMILY_SPHERE => 0.5 * one_minus_cos,
            FAMILY_CONE => one_minus_cos / p,
            FAMILY_EXPONENTIAL => -(-p * t).exp_m1(),
            _ if p == 0.0 => t,
            _ => (-p * t).exp_m1() / (-p).exp_m1(),
        }
    }

    /// |du.x / d(variable)|: the reference pdf times the azimuth's 2π for directions.
    fn du_dx(&self, x: f64) -> f64 {
        let measure = if self.direction {
            2.0 * std::f64::consts::PI
        } else {
            1.0
        };
        measure * self.pdf(x)
    }

    /// Quadrature nodes over the domain, finer where the pdf varies fastest.
    fn nodes(&self) -> Vec<f64> {
        let (lo, hi) = self.domain;
        let mut nodes: Vec<f64> = if self.direction {
            // Geometric in the distance from both ends, as for hg_phase's integral.
            const NODES_PER_END: usize = 18_000;
            const DECADES: f64 = 9.3;
            let width = hi - lo;
            let mut v = vec![lo, 0.5 * (lo + hi), hi];
            for k in 0..=NODES_PER_END {
                let distance = width * 10f64.powf(-DECADES * k as f64 / NODES_PER_END as f64);
                v.push(hi - distance);
                v.push(lo + distance);
            }
            v
        } else {
            (0..=DISTANCE_NODES)
                .map(|k| lo + (hi - lo) * k as f64 / DISTANCE_NODES as f64)
                .collect()
        };
        // The GPU evaluates at f32 nodes; keep each node's f64 value equal to its f32.
        for x in &mut nodes {
            *x = f64::from(x.clamp(lo, hi) as f32);
        }
        nodes.retain(|x| (lo..=hi).contains(x));
        nodes.sort_by(f64::total_cmp);
        nodes.dedup();
        nodes
    }
}

/// Every family at the parameters tested.
fn families() -> Vec<Family> {
    let mut out = Vec::new();
    let full = (-1.0, 1.0);
    for &g in &G_VALUES {
        out.push(Family {
            name: format!("hg(g = {g})"),
            id: FAMILY_HG,
            param: g,
            direction: true,
            domain: full,
        });
    }
    out.push(Family {
        name: "cosine hemisphere".into(),
        id: FAMILY_COSINE,
        param: 0.0,
        direction: true,
        domain: (0.0, 1.0),
    });
    out.push(Family {
        name: "uniform sphere".into(),
        id: FAMILY_SPHERE,
        param: 0.0,
        direction: true,
        domain: full,
    });
    // The whole sphere, a hemisphere, and narrower cones (1 − cos θ_max, powers of two so
    // that cos θ_max is an f32 and the quadrature spans the cone exactly).
    for omc in [2.0f32, 1.0, 0.125, 1.0 / 1024.0] {
        out.push(Family {
            name: format!("uniform cone(1 - cos θmax = {omc})"),
            id: FAMILY_CONE,
            param: omc,
            direction: true,
            domain: (1.0 - f64::from(omc), 1.0),
        });
    }
    for rate in [1e-3f32, 1.0, 37.5, 1e4] {
        out.push(Family {
            name: format!("exponential(rate {rate})"),
            id: FAMILY_EXPONENTIAL,
            param: rate,
            direction: false,
            domain: (0.0, DISTANCE_SPAN / f64::from(rate)),
        });
    }
    // From the flat limit through the series branches to a steep density.
    for x in [0.0f32, 1e-7, 1e-3, 0.3, 1.0, 7.0, 50.0, 1e4] {
        out.push(Family {
            name: format!("truncated exponential(x = {x})"),
            id: FAMILY_TRUNCATED_EXPONENTIAL,
            param: x,
            direction: false,
            domain: (
                0.0,
                if x > 0.0 {
                    (DISTANCE_SPAN / f64::from(x)).min(1.0)
                } else {
                    1.0
                },
            ),
        });
    }
    out
}

/// |a − b| on the circle of circumference 1 (azimuth fractions).
fn circular_distance(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(1.0);
    d.min(1.0 - d)
}

/// Allowed |Δu.x| of a round trip: an absolute floor, plus the f32 rounding of the
/// sample's variable carried through the CDF (its derivative du.x/dx times a few
/// float spacings at x: the samplers round cos θ or t in f32 before normalising).
const ROUND_TRIP_FLOOR: f64 = 1e-6;
/// How many float spacings of the variable the samplers may lose.
const ROUND_TRIP_ULPS: f64 = 4.0;
/// Allowed relative error of the GPU pdf against the f64 formula at the same value.
const PDF_REL_TOL: f64 = 1e-5;
/// Allowed |∫ pdf − 1| and |running ∫ pdf − reference CDF| of the GPU pdf.
const PDF_INTEGRAL_TOL: f64 = 1e-5;

#[test]
fn every_family_round_trips_through_its_inverse() {
    let gpu = Gpu::new();
    let mut rng = Pcg32::new(0x5a3d_0003);
    let axes = axes(&mut rng);
    println!(
        "round trips: {ROUND_TRIP_SAMPLES} samples each; |Δu| <= {ROUND_TRIP_FLOOR:e} + \
         {ROUND_TRIP_ULPS} ulp of the variable x {{du/dx}}"
    );
    for family in families() {
        let family_axes: Vec<(&str, [f32; 3])> = match family.id {
            FAMILY_SPHERE => vec![("+Y", [0.0, 1.0, 0.0])],
            _ if family.direction => axes.clone(),
            _ => vec![("-", [0.0, 0.0, 1.0])],
        };
        let (mut worst_x, mut worst_y, mut worst_ref, mut worst_pdf) =
            (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        for &(axis_name, axis) in &family_axes {
            let u = rng.uniforms(ROUND_TRIP_SAMPLES);
            let samples = gpu.run_family(MODE_SAMPLE, family.id, axis, family.param, &u);
            let trips = gpu.run_family(MODE_ROUND_TRIP, family.id, axis, family.param, &u);
            let frame = Frame::new(axis);
            let what = format!("{} about {axis_name}", family.name);
            for ((ui, s), trip) in u.iter().zip(&samples).zip(&trips) {
                let s64 = to_f64([s[0], s[1], s[2]]);
                // The sample's variable: cos θ about the axis, or the distance.
                let (theta, x) = if family.direction {
                    let (theta, _) = frame.angles(s64);
                    (theta, theta.cos())
                } else {
                    (0.0, s64[0])
                };
                let du_dx = family.du_dx(x);
                let spacing = EPS32 * x.abs().max(if family.direction { 1.0 } else { 0.0 });
                let tol_x = ROUND_TRIP_FLOOR + ROUND_TRIP_ULPS * spacing * du_dx;
                let (u0, u1) = (f64::from(ui[0]), f64::from(ui[1]));
                let (back_x, back_y, pdf) =
                    (f64::from(trip[0]), f64::from(trip[1]), f64::from(trip[2]));
                assert!(
                    s.iter().all(|c| c.is_finite()) && pdf.is_finite() && pdf > 0.0,
                    "{what}: u {ui:?} gives sample {s:?} with pdf {pdf}"
                );
                // invert(sample(u)) = u.
                let dx = (back_x - u0).abs();
                assert!(
                    dx <= tol_x,
                    "{what}: u.x {u0} comes back as {back_x} (|Δ| {dx:e} > {tol_x:e}); \
                     sample {s:?}"
                );
                worst_x = worst_x.max(dx / tol_x);
                // The inverse agrees with the f64 CDF at the sample.
                let reference = family.u_x(theta, x);
                let dref = (back_x - reference).abs();
                assert!(
                    dref <= tol_x,
                    "{what}: invert gives u.x {back_x} at {s:?}, the f64 CDF {reference} \
                     (|Δ| {dref:e} > {tol_x:e})"
                );
                worst_ref = worst_ref.max(dref / tol_x);
                // The azimuth comes back too: a direction's rounding of a few spacings moves
                // it by that over sin θ (radians), so the tolerance grows towards the axis.
                if family.direction {
                    let sin_theta = theta.sin().max(1e-30);
                    let tol_y = ROUND_TRIP_FLOOR
                        + ROUND_TRIP_ULPS * EPS32 / (2.0 * std::f64::consts::PI * sin_theta);
                    let dy = circular_distance(back_y, u1);
                    assert!(
                        dy <= tol_y,
                        "{what}: u.y {u1} comes back as {back_y} (|Δ| {dy:e} > {tol_y:e}); \
                         sample {s:?}"
                    );
                    worst_y = worst_y.max(dy / tol_y);
                }
                // The pdf at the sample is the f64 formula's at its variable (the GPU's own
                // cos θ may differ by a few spacings: allowed through the pdf's slope).
                let reference_pdf = family.pdf(x);
                let h = 4.0 * spacing.max(EPS32 * 0.5);
                let slope = ((family.pdf(x + h) - family.pdf(x - h)) / (2.0 * h)).abs();
                let tol_pdf = PDF_REL_TOL * reference_pdf + 4.0 * spacing.max(EPS32) * slope;
                let dpdf = (pdf - reference_pdf).abs();
                assert!(
                    dpdf <= tol_pdf,
                    "{what}: pdf {pdf} at sample {s:?}, f64 formula {reference_pdf} \
                     (|Δ| {dpdf:e} > {tol_pdf:e})"
                );
                worst_pdf = worst_pdf.max(dpdf / tol_pdf);
            }
        }
        println!(
            "  {:<40} worst |Δu.x| {worst_x:.2} of tol, |Δu.y| {worst_y:.2}, invert vs f64 \
             CDF {worst_ref:.2}, pdf {worst_pdf:.2}",
            family.name
        );
    }
    gpu.finish();
}

#[test]
fn every_family_pdf_integrates_to_one_and_matches_its_cdf() {
    let gpu = Gpu::new();
    println!(
        "pdfs: GPU vs f64 within {PDF_REL_TOL:e} relative; |∫ − 1| and the running \
         integral against the f64 CDF within {PDF_INTEGRAL_TOL:e}"
    );
    for family in families() {
        let nodes = family.nodes();
        let inputs: Vec<[f32; 2]> = nodes.iter().map(|&x| [x as f32, 0.0]).collect();
        let outputs = gpu.run_family(MODE_PDF, family.id, [0.0, 0.0, 1.0], family.param, &inputs);
        let gpu_pdf: Vec<f64> = outputs.iter().map(|o| f64::from(o[3])).collect();
        // The GPU pdf is the f64 formula's, pointwise.
        let mut max_rel = 0.0f64;
        for (&x, &p) in nodes.iter().zip(&gpu_pdf) {
            let reference = family.pdf(x);
            let rel = (p - reference).abs() / reference.max(1e-300);
            assert!(
                p.is_finite() && (rel <= PDF_REL_TOL || (p - reference).abs() < 1e-30),
                "{}: pdf {p} at {x}, f64 formula {reference} (relative {rel:e})",
                family.name
            );
            max_rel = max_rel.max(rel);
        }
        // Integrate by trapezoids, from where u.x = 0 (cos θ = 1, or distance 0), and
        // compare the running integral with the f64 CDF at every node.
        let measure = if family.direction {
            2.0 * std::f64::consts::PI
        } else {
            1.0
        };
        let order: Vec<usize> = if family.direction {
            (0..nodes.len()).rev().collect()
        } else {
            (0..nodes.len()).collect()
        };
        let (mut running, mut worst_cdf) = (0.0f64, 0.0f64);
        let (mut reference_running, mut worst_quadrature) = (0.0f64, 0.0f64);
        for pair in order.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            let h = (nodes[b] - nodes[a]).abs();
            running += measure * 0.5 * h * (gpu_pdf[a] + gpu_pdf[b]);
            reference_running += measure * 0.5 * h * (family.pdf(nodes[a]) + family.pdf(nodes[b]));
            let x = nodes[b];
            let cdf = family.u_x(x.clamp(-1.0, 1.0).acos(), x);
            worst_cdf = worst_cdf.max((running - cdf).abs());
            worst_quadrature = worst_quadrature.max((reference_running - cdf).abs());
        }
        // The distance families' tails beyond the nodes hold e^-40 of the mass.
        println!(
            "  {:<40} ∫ pdf − 1 = {:+.2e}; running ∫ vs CDF {worst_cdf:.2e} (f64 formula: \
             {worst_quadrature:.2e}); max relative pdf error {max_rel:.2e} over {} nodes",
            family.name,
            running - 1.0,
            nodes.len()
        );
        assert!(
            worst_quadrature < 0.1 * PDF_INTEGRAL_TOL,
            "{}: quadrature error {worst_quadrature:e} of the f64 formula: refine the nodes",
            family.name
        );
        assert!(
            (running - 1.0).abs() < PDF_INTEGRAL_TOL,
            "{}: the GPU pdf integrates to {running}, not 1",
            family.name
        );
        assert!(
            worst_cdf < PDF_INTEGRAL_TOL,
            "{}: the running integral of the GPU pdf strays {worst_cdf:e} from the f64 CDF",
            family.name
        );
    }
    gpu.finish();
}
