//! Environment-map importance sampling on the GPU (`shaders/include/envmap.glsl`, driven
//! through `shaders/tests/envmap_sampling.comp` with validation layers on) against the CPU
//! reference in `nimbus_scene::envmap`, on a synthetic 64×32 map (a sky gradient varying
//! along both axes, one bright sun texel, black ground rows 26..32) uploaded with the f32
//! tables of [`EnvSampler::to_gpu_tables`]:
//!
//! 1. `env_sample(u)` against `EnvSampler::sample(u)` for the same f32 u: direction within
//!    1e-3 rad, pdf within relative 1e-3. The pdf is only compared away from texel edges
//!    (1e-3 texel): at an edge the f32 and f64 tables may legitimately pick neighbouring
//!    texels, whose pdfs differ while the direction is continuous.
//! 2. `env_pdf(d)` against `EnvSampler::pdf(d)` at random directions, poles, the zero
//!    vector: relative 1e-3, or both 0 (away from texel edges by 1e-4 texel).
//! 3. `env_lookup(d)` equals `EnvMap::lookup(d)` exactly (same edge exclusion).
//! 4. `env_direction_to_uv` / `env_uv_to_direction` against the CPU mapping, and finite,
//!    CPU-equal results at the poles, for zero, tiny and huge vectors, and out-of-range uv.
//! 5. A GPU histogram of 200 000 samples over 16×8 (u, v) bins against the CPU pdf
//!    integrated over each bin: Pearson χ² below the 1e-3 critical value (cells with
//!    expected count < 5 pooled); bins of zero probability (the black ground) stay empty.
//!
//! The map's texel probabilities are all >= ~1e-3 relative to their CDF's range, so f32
//! rounding of the tables (~6e-8 absolute) changes no pdf by more than ~1e-4 relative.

use std::f64::consts::PI;

use crate::common::kernel::{records, Arg, Kernel};
use crate::common::rng::Pcg32;
use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use nimbus_gpu::BindingDesc;
use nimbus_scene::{direction_to_uv, uv_to_direction, EnvMap, EnvSampler};

const W: u32 = 64;
const H: u32 = 32;
/// First black (ground) row.
const GROUND_ROW: u32 = 26;
/// The sun texel.
const SUN: (u32, u32) = (40, 8);

const MODE_SAMPLE: u32 = 0;
const MODE_PDF: u32 = 1;
const MODE_LOOKUP: u32 = 2;
const MODE_UV: u32 = 3;
const MODE_HISTOGRAM: u32 = 4;
const LOCAL_SIZE: u32 = 64;
const HIST_W: u32 = 16;
const HIST_H: u32 = 8;

/// The push constants of envmap_sampling.comp.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuPush {
    size: [u32; 4],
}

/// `Query` of envmap_sampling.comp.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuQuery {
    a: [f32; 4],
    b: [u32; 4],
}

/// `Result` of envmap_sampling.comp.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct GpuResult {
    r0: [f32; 4],
    r1: [f32; 4],
    non_finite: u32,
    pad: [u32; 3],
}

const _: () = assert!(std::mem::size_of::<GpuPush>() == 16);
const _: () = assert!(std::mem::size_of::<GpuQuery>() == 32);
const _: () = assert!(std::mem::size_of::<GpuResult>() == 48);

fn query(mode: u32, a: [f32; 4]) -> GpuQuery {
    GpuQuery {
        a,
        b: [mode, 0, 0, 0],
    }
}

/// The synthetic map: a sky whose radiance varies with row and column, a sun texel
/// ~300× brighter than the sky, and black ground rows.
fn test_map() -> EnvMap {
    let mut texels = Vec::with_capacity((W * H) as usize);
    for y in 0..H {
        for x in 0..W {
            let t = if y >= GROUND_ROW {
                [0.0, 0.0, 0.0]
            } else if (x, y) == SUN {
                [200.0, 180.0, 150.0]
            } else {
                let h = 1.0 - y as f32 / GROUND_ROW as f32;
                let s = 1.0 + 0.5 * (2.0 * std::f32::consts::PI * x as f32 / W as f32).sin();
                [(0.2 + 0.3 * h) * s, (0.3 + 0.4 * h) * s, 0.6 + 0.4 * h]
            };
            texels.push(t);
        }
    }
    EnvMap {
        width: W,
        height: H,
        texels,
    }
}

/// The test kernel `shaders/tests/envmap_sampling.comp` and the map it samples.
struct Gpu {
    kernel: Kernel,
    /// Texels (rgb, w unused) and the marginal then conditional CDF tables.
    texels: Vec<[f32; 4]>,
    cdf: Vec<f32>,
}

impl Gpu {
    fn new(map: &EnvMap, sampler: &EnvSampler) -> Self {
        let layout = [0, 1, 2, 3, 4].map(BindingDesc::storage_buffer);
        let kernel = Kernel::new(
            nimbus::shaders::TESTS_ENVMAP_SAMPLING,
            &layout,
            std::mem::size_of::<GpuPush>() as u32,
            &[],
            "envmap test",
        );
        let texels: Vec<[f32; 4]> = map.texels.iter().map(|t| [t[0], t[1], t[2], 0.0]).collect();
        let (marginal, conditional) = sampler.to_gpu_tables();
        assert_eq!(marginal.len(), (H + 1) as usize);
        assert_eq!(conditional.len(), (H * (W + 1)) as usize);
        let cdf: Vec<f32> = marginal.into_iter().chain(conditional).collect();
        Self {
            kernel,
            texels,
            cdf,
        }
    }

    /// Runs every query; one result per query, and the histogram (HIST_W·HIST_H bins plus
    /// the discarded-sample count).
    fn run(&self, queries: &[GpuQuery]) -> (Vec<GpuResult>, Vec<u32>) {
        let count = u32::try_from(queries.len()).expect("query count fits u32");
        let bins = (HIST_W * HIST_H + 1) as usize;
        let push = GpuPush {
            size: [W, H, count, 0],
        };
        let out = self.kernel.run(
            &[
                Arg::Storage(0, bytemuck::cast_slice(&self.texels)),
                Arg::Storage(1, bytemuck::cast_slice(&self.cdf)),
                Arg::Storage(2, bytemuck::cast_slice(queries)),
                Arg::Zeroed(3, queries.len() * std::mem::size_of::<GpuResult>()),
                Arg::Zeroed(4, bins * 4),
            ],
            bytemuck::bytes_of(&push),
            [count.div_ceil(LOCAL_SIZE), 1, 1],
        );
        let results: Vec<GpuResult> = records(&out[3], queries.len());
        let histogram: Vec<u32> = records(&out[4], bins);
        let non_finite: u32 = results.iter().map(|r| r.non_finite).sum();
        assert_eq!(non_finite, 0, "non-finite values in the envmap shader");
        (results, histogram)
    }

    /// Fails on any validation error so far.
    fn finish(self) {
        self.kernel.finish();
    }
}

fn dvec(v: [f32; 3]) -> DVec3 {
    DVec3::new(v[0].into(), v[1].into(), v[2].into())
}

fn angle(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// Distance, in texels, of direction d's (u, v) from the nearest texel edge (CPU mapping).
fn edge_distance(d: DVec3) -> f64 {
    let (u, v) = direction_to_uv(d);
    let fx = u * f64::from(W);
    let fy = v * f64::from(H);
    (fx - fx.round()).abs().min((fy - fy.round()).abs())
}

fn relative_error(got: f64, want: f64) -> f64 {
    (got - want).abs() / want.abs().max(1e-300)
}

/// Directions for the pdf and lookup checks: random, poles (both signed zeros), near
/// poles, the sun's centre, the seam, axis directions, a zero, a tiny and a huge vector.
fn test_directions(rng: &mut Pcg32) -> Vec<[f32; 3]> {
    let mut dirs: Vec<[f32; 3]> = (0..4096).map(|_| rng.unit_vector_f32()).collect();
    let sun = uv_to_direction(
        (f64::from(SUN.0) + 0.5) / f64::from(W),
        (f64::from(SUN.1) + 0.5) / f64::from(H),
    );
    dirs.extend([
        [0.0, 1.0, 0.0],
        [0.0, 1.0, -0.0],
        [-0.0, -1.0, 0.0],
        [0.0, -1.0, -0.0],
        [1e-4, 1.0, 0.0],
        [0.0, -1.0, 1e-4],
        [sun.x as f32, sun.y as f32, sun.z as f32],
        [0.0, 0.3, 1.0],
        [-1e-7, 0.3, 1.0],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, -1.0],
        [0.0, 0.0, 0.0],
        [1e-30, 2e-30, -1e-30],
        [3e38, -3e38, 3e38],
    ]);
    dirs
}

/// (1) GPU `env_sample` against `EnvSampler::sample` for the same u.
#[test]
fn sample_matches_cpu() {
    let map = test_map();
    let sampler = EnvSampler::new(&map);
    let gpu = Gpu::new(&map, &sampler);
    let mut rng = Pcg32::new(0xe17_0001);
    let mut us: Vec<[f32; 2]> = (0..8192)
        .map(|_| [rng.uniform_f32(), rng.uniform_f32()])
        .collect();
    let below_one = f32::from_bits(0x3f7f_ffff);
    us.extend([
        [0.0, 0.0],
        [below_one, below_one],
        [0.5, 0.5],
        [0.0, below_one],
    ]);
    // Exact table entries: the row/column boundaries.
    let (marginal, _) = sampler.to_gpu_tables();
    for (i, &m) in marginal.iter().enumerate() {
        us.push([(i as f32 + 0.5) / (H + 1) as f32, m]);
    }
    let queries: Vec<GpuQuery> = us
        .iter()
        .map(|u| query(MODE_SAMPLE, [u[0], u[1], 0.0, 0.0]))
        .collect();
    let (results, _) = gpu.run(&queries);
    let (mut worst_angle, mut worst_pdf, mut edge_skips, mut compared) = (0.0f64, 0.0f64, 0, 0);
    let mut row_ties = 0;
    for (u, r) in us.iter().zip(&results) {
        let got_dir = dvec([r.r0[0], r.r0[1], r.r0[2]]);
        let got_pdf = f64::from(r.r0[3]);
        // The row choice is discontinuous in the column: a u.y within f32 rounding of a
        // marginal entry m[k] may pick row k − 1 (dv ≈ 1) on the CPU and row k (dv = 0)
        // on the GPU, with the column then taken from another row. There the GPU must
        // match the CPU at u.y = m[k] exactly (row k) if it does not match at u.y.
        let mut candidates = vec![f64::from(u[1])];
        if let Some(&m) = sampler
            .marginal_cdf()
            .iter()
            .find(|&&m| (m - f64::from(u[1])).abs() < 1e-6)
        {
            candidates.push(m);
        }
        let (a, dir, pdf) = candidates
            .iter()
            .map(|&u1| {
                let (dir, pdf) = sampler.sample([f64::from(u[0]), u1]);
                (angle(got_dir, dir), dir, pdf)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .expect("one candidate");
        if candidates.len() > 1 {
            row_ties += 1;
        }
        worst_angle = worst_angle.max(a);
        assert!(
            a < 1e-3,
            "u {u:?}: GPU direction {got_dir} vs CPU {dir} ({a} rad apart)"
        );
        assert!(
            (got_dir.length() - 1.0).abs() < 1e-5,
            "u {u:?}: GPU direction {got_dir} not unit"
        );
        if pdf == 0.0 {
            assert_eq!(got_pdf, 0.0, "u {u:?}: CPU pdf 0 (pole), GPU {got_pdf}");
            continue;
        }
        if edge_distance(dir) < 1e-3 {
            edge_skips += 1;
            continue;
        }
        compared += 1;
        let e = relative_error(got_pdf, pdf);
        worst_pdf = worst_pdf.max(e);
        assert!(
            e < 1e-3,
            "u {u:?}: GPU pdf {got_pdf} vs CPU {pdf} (dir {dir})"
        );
        // The radiance returned is the sampled texel's, i.e. the lookup of dir.
        let want = map.lookup(dir);
        assert_eq!(
            [r.r1[0], r.r1[1], r.r1[2]],
            want,
            "u {u:?}: GPU radiance vs CPU lookup"
        );
    }
    println!(
        "env_sample: {} samples, max angle {worst_angle:.2e} rad; pdf + radiance compared on \
         {compared} (skipped {edge_skips} within 1e-3 texel of an edge), max relative pdf \
         error {worst_pdf:.2e}; {row_ties} u.y on a marginal entry (either row accepted)",
        us.len()
    );
    gpu.finish();
}

/// (2) and (3): `env_pdf` and `env_lookup` against the CPU at the same directions.
#[test]
fn pdf_and_lookup_match_cpu() {
    let map = test_map();
    let sampler = EnvSampler::new(&map);
    let gpu = Gpu::new(&map, &sampler);
    let mut rng = Pcg32::new(0xe17_0002);
    let dirs = test_directions(&mut rng);
    let queries: Vec<GpuQuery> = dirs
        .iter()
        .flat_map(|d| [MODE_PDF, MODE_LOOKUP].map(|m| query(m, [d[0], d[1], d[2], 0.0])))
        .collect();
    let (results, _) = gpu.run(&queries);
    let (mut worst, mut zeros, mut skips) = (0.0f64, 0, 0);
    for (d, r) in dirs.iter().zip(results.chunks(2)) {
        let dd = dvec(*d);
        let want_pdf = sampler.pdf(dd);
        let got_pdf = f64::from(r[0].r0[0]);
        let want_l = map.lookup(dd);
        let got_l = [r[1].r0[0], r[1].r0[1], r[1].r0[2]];
        let on_edge = dd.length() > 0.0 && edge_distance(dd) < 1e-4;
        if on_edge && (want_pdf == 0.0) == (got_pdf == 0.0) {
            skips += 1;
            continue;
        }
        if want_pdf == 0.0 || got_pdf == 0.0 {
            assert!(
                want_pdf == 0.0 && got_pdf == 0.0,
                "d {d:?}: GPU pdf {got_pdf} vs CPU {want_pdf}"
            );
            zeros += 1;
        } else {
            let e = relative_error(got_pdf, want_pdf);
            worst = worst.max(e);
            assert!(e < 1e-3, "d {d:?}: GPU pdf {got_pdf} vs CPU {want_pdf}");
        }
        assert_eq!(got_l, want_l, "d {d:?}: GPU lookup vs CPU");
    }
    println!(
        "env_pdf / env_lookup: {} directions, max relative pdf error {worst:.2e}, {zeros} \
         both zero, lookups equal; {skips} within 1e-4 texel of an edge skipped",
        dirs.len()
    );
    gpu.finish();
}

/// (4) The mapping both ways against the CPU, and finite at poles and degenerate inputs.
#[test]
fn uv_mapping_matches_cpu_and_is_finite() {
    let map = test_map();
    let sampler = EnvSampler::new(&map);
    let gpu = Gpu::new(&map, &sampler);
    let mut rng = Pcg32::new(0xe17_0003);
    // (direction, uv) pairs: the uv is the CPU's uv of the direction (a round trip),
    // plus degenerate directions and out-of-range uv.
    let mut dirs = test_directions(&mut rng);
    let mut uvs: Vec<[f32; 2]> = dirs
        .iter()
        .map(|&d| {
            let (u, v) = direction_to_uv(dvec(d));
            [u as f32, v as f32]
        })
        .collect();
    for (d, uv) in [
        ([0.0, 1e-38, 0.0], [0.3, 0.0]),
        ([0.0, -1e-38, -0.0], [0.3, 1.0]),
        ([1e-38, 0.0, 0.0], [0.3, -0.5]),
        ([f32::MAX, 0.0, -f32::MAX], [0.3, 1.5]),
        ([0.0, f32::MAX, 0.0], [-0.25, 0.5]),
        ([-0.0, -0.0, -0.0], [1.75, 0.5]),
        ([0.0, 0.0, 1.0], [1.0, 0.25]),
    ] {
        dirs.push(d);
        uvs.push(uv);
    }
    let queries: Vec<GpuQuery> = dirs
        .iter()
        .zip(&uvs)
        .map(|(d, uv)| GpuQuery {
            a: [d[0], d[1], d[2], 0.0],
            b: [MODE_UV, uv[0].to_bits(), uv[1].to_bits(), 0],
        })
        .collect();
    let (results, _) = gpu.run(&queries);
    let (mut worst_uv, mut worst_dir) = (0.0f64, 0.0f64);
    for ((d, uv), r) in dirs.iter().zip(&uvs).zip(&results) {
        let (want_u, want_v) = direction_to_uv(dvec(*d));
        let (got_u, got_v) = (f64::from(r.r0[0]), f64::from(r.r0[1]));
        assert!(
            (0.0..1.0).contains(&got_u),
            "d {d:?}: u {got_u} outside [0, 1)"
        );
        assert!(
            (0.0..=1.0).contains(&got_v),
            "d {d:?}: v {got_v} outside [0, 1]"
        );
        // u is periodic: compare on the circle.
        let du = (got_u - want_u).abs();
        let du = du.min(1.0 - du);
        let e = du.max((got_v - want_v).abs());
        let pole = d[0] == 0.0 && d[2] == 0.0;
        if pole || dvec(*d).length() == 0.0 {
            // Exactly the CPU's answer, signed zeros included.
            assert_eq!((got_u, got_v), (want_u, want_v), "d {d:?}: pole/zero uv");
        } else {
            worst_uv = worst_uv.max(e);
            assert!(
                e < 2e-6,
                "d {d:?}: GPU uv ({got_u}, {got_v}) vs CPU ({want_u}, {want_v})"
            );
        }
        let want_dir = uv_to_direction(f64::from(uv[0]), f64::from(uv[1]));
        let got_dir = dvec([r.r1[0], r.r1[1], r.r1[2]]);
        let a = angle(got_dir, want_dir);
        worst_dir = worst_dir.max(a);
        assert!(
            a < 1e-5 && (got_dir.length() - 1.0).abs() < 1e-5,
            "uv {uv:?}: GPU direction {got_dir} vs CPU {want_dir}"
        );
        if uv[1] <= 0.0 || uv[1] >= 1.0 {
            assert_eq!(got_dir, want_dir, "uv {uv:?}: pole must be exact");
        }
    }
    println!(
        "uv mapping: {} cases, max |Δuv| {worst_uv:.2e} (u on the circle), max round-trip \
         angle {worst_dir:.2e} rad; poles and degenerate inputs finite and equal to the CPU",
        dirs.len()
    );
    gpu.finish();
}

/// (5) χ² of a 200 000-sample GPU histogram against the CPU pdf integrated over bins.
#[test]
fn histogram_matches_cpu_pdf() {
    const INVOCATIONS: u32 = 1000;
    const PER_INVOCATION: u32 = 200;
    let map = test_map();
    let sampler = EnvSampler::new(&map);
    let gpu = Gpu::new(&map, &sampler);
    let queries: Vec<GpuQuery> = (0..INVOCATIONS)
        .map(|_| GpuQuery {
            a: [0.0; 4],
            b: [MODE_HISTOGRAM, PER_INVOCATION, 0xe17_0005, 0],
        })
        .collect();
    let (_, histogram) = gpu.run(&queries);
    let bins = (HIST_W * HIST_H) as usize;
    let discarded = histogram[bins];
    let total: u64 = histogram.iter().map(|&c| u64::from(c)).sum();
    assert_eq!(total, u64::from(INVOCATIONS * PER_INVOCATION));
    // pdf 0 only at an exact pole: u.y = 0 and u.x in a zero-width prefix, ~2^-24 per sample.
    assert!(discarded <= 2, "{discarded} samples with pdf 0");
    let n = (total - u64::from(discarded)) as f64;

    // P(bin) = ∫ pdf dω over the bin; pdf · 2π² sin θ is constant in a texel, so the
    // texel-centre midpoint rule in (u, v) is exact.
    let mut prob = vec![0.0f64; bins];
    for y in 0..H {
        for x in 0..W {
            let (u, v) = (
                (f64::from(x) + 0.5) / f64::from(W),
                (f64::from(y) + 0.5) / f64::from(H),
            );
            let d = uv_to_direction(u, v);
            let sin_theta = (PI * v).sin();
            let p = sampler.pdf(d) * 2.0 * PI * PI * sin_theta / f64::from(W * H);
            let bin = (y / (H / HIST_H) * HIST_W + x / (W / HIST_W)) as usize;
            prob[bin] += p;
        }
    }
    let sum: f64 = prob.iter().sum();
    assert!((sum - 1.0).abs() < 1e-9, "bin probabilities sum to {sum}");

    // Zero-probability bins must be empty; pool cells with expected count < 5.
    let (mut chi2, mut cells, mut empty_bins) = (0.0, 0usize, 0);
    let (mut pooled_expected, mut pooled_observed) = (0.0f64, 0.0f64);
    for (b, &p) in prob.iter().enumerate() {
        let observed = f64::from(histogram[b]);
        if p == 0.0 {
            assert_eq!(
                histogram[b], 0,
                "bin {b} has probability 0 but {observed} samples"
            );
            empty_bins += 1;
            continue;
        }
        let expected = p * n;
        if expected < 5.0 {
            pooled_expected += expected;
            pooled_observed += observed;
            continue;
        }
        chi2 += (observed - expected).powi(2) / expected;
        cells += 1;
    }
    if pooled_expected > 0.0 {
        chi2 += (pooled_observed - pooled_expected).powi(2) / pooled_expected;
        cells += 1;
    }
    let dof = (cells - 1) as f64;
    // Wilson–Hilferty approximation of the χ² quantile at 1 − 1e-3 (z = 3.090232); within
    // ~0.1 % of the exact value for dof >= 30.
    let z = 3.090_232;
    let k = 2.0 / (9.0 * dof);
    let critical = dof * (1.0 - k + z * k.sqrt()).powi(3);
    println!(
        "histogram: {n} samples ({discarded} discarded), {cells} cells ({dof} dof, pooled \
         expected {pooled_expected:.2}), {empty_bins} zero-probability bins empty; \
         χ² = {chi2:.1}, critical value at p = 1e-3: {critical:.1}"
    );
    assert!(chi2 < critical, "χ² {chi2} >= {critical} ({dof} dof)");
    gpu.finish();
}
