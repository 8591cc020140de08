//! The direction samplers of `shaders/include/sampling.glsl` and the phase function of
//! `shaders/include/phase.glsl` run on the GPU through `shaders/tests/sampling.comp`, with
//! validation layers on, against f64 mathematics on the CPU (pbrt-style: the mathematics
//! before the pictures):
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

mod common;

use bytemuck::{Pod, Zeroable};
use common::rng::Pcg32;
use nimbus_gpu::{
    vk, BindingDesc, Buffer, BufferDesc, ComputePipeline, ComputePipelineDesc, Context,
    DescriptorWrite,
};

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
    pad: [u32; 2],
}

const _: () = assert!(std::mem::size_of::<GpuPush>() == 32);

/// A validated context and the test pipeline.
struct Gpu {
    ctx: Context,
    /// Always `Some` until dropped.
    pipeline: Option<ComputePipeline>,
}

impl Gpu {
    fn new() -> Self {
        let ctx = common::gpu::context();
        let spirv = common::gpu::spirv(nimbus::shaders::TESTS_SAMPLING);
        let bindings = [
            BindingDesc::storage_buffer(0),
            BindingDesc::storage_buffer(1),
        ];
        let pipeline = ctx
            .create_compute_pipeline(
                &ComputePipelineDesc {
                    spirv: &spirv,
                    entry: "main",
                    bindings: &bindings,
                    push_constant_size: std::mem::size_of::<GpuPush>() as u32,
                    specialization: &[],
                },
                "sampling test",
            )
            .expect("pipeline");
        Self {
            ctx,
            pipeline: Some(pipeline),
        }
    }

    fn storage(&self, bytes: usize, name: &str) -> Buffer {
        self.ctx
            .create_buffer(
                &BufferDesc::gpu_only(bytes.max(16) as u64, vk::BufferUsageFlags::STORAGE_BUFFER),
                name,
            )
            .expect("buffer")
    }

    /// One invocation per input; one output (xyz direction, w phase value) per input.
    fn run(&self, mode: u32, axis: [f32; 3], g: f32, inputs: &[[f32; 2]]) -> Vec<[f32; 4]> {
        let ctx = &self.ctx;
        let count = u32::try_from(inputs.len()).expect("input count fits u32");
        let groups = count.div_ceil(LOCAL_SIZE);
        assert!(groups <= ctx.info().max_compute_work_group_count[0]);
        let input_buf = self.storage(std::mem::size_of_val(inputs), "sampling inputs");
        let output_buf = self.storage(inputs.len() * 16, "sampling outputs");
        ctx.upload_buffer(&input_buf, 0, bytemuck::cast_slice(inputs))
            .expect("upload inputs");
        let set = ctx
            .create_descriptor_set(
                self.pipeline(),
                &[
                    DescriptorWrite::StorageBuffer {
                        binding: 0,
                        buffer: &input_buf,
                    },
                    DescriptorWrite::StorageBuffer {
                        binding: 1,
                        buffer: &output_buf,
                    },
                ],
                "sampling set",
            )
            .expect("descriptor set");
        let push = GpuPush {
            axis_g: [axis[0], axis[1], axis[2], g],
            mode,
            count,
            pad: [0; 2],
        };
        if groups > 0 {
            ctx.submit_one_shot("sampling dispatch", |cmd| {
                self.pipeline()
                    .dispatch(ctx, cmd, &set, bytemuck::bytes_of(&push), [groups, 1, 1])
            })
            .expect("dispatch");
        }
        let outputs: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(
            &ctx.readback_buffer(&output_buf).expect("readback outputs")[..inputs.len() * 16],
        );
        ctx.destroy_descriptor_set(set);
        ctx.destroy_buffer(input_buf);
        ctx.destroy_buffer(output_buf);
        outputs
    }

    fn pipeline(&self) -> &ComputePipeline {
        self.pipeline.as_ref().expect("pipeline lives until drop")
    }

    /// Fails on any validation error so far.
    fn finish(self) {
        common::gpu::assert_no_validation_errors(&self.ctx);
    }
}

impl Drop for Gpu {
    fn drop(&mut self) {
        if let Some(pipeline) = self.pipeline.take() {
            self.ctx.destroy_compute_pipeline(pipeline);
        }
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
