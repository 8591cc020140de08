//! The analytic core of the box-medium paper (`shaders/include/box_analytic.glsl`,
//! Velinov & Mitchell Sec. 4–5) run on the GPU through `shaders/tests/box_analytic.comp`,
//! with validation layers on, against independent f64 computations:
//!
//! - T_box (the unoccluded transmittance integral) against
//!   [`nimbus_reference::quadrature::unoccluded_single_scatter`] (adaptive
//!   Gauss–Kronrod) on 10 000 random configurations and on the hard cases one by one;
//! - no NaN or infinity anywhere in the shader, also at the scene format's limits;
//! - the whole-volume distance sampling pdf integrates to 1 and equals the integrand
//!   over T_box;
//! - samples follow the pdf (Pearson chi-square against bin masses from the reference).
//!
//! # Tolerance
//!
//! The GPU works in f32. Its inputs are f32 too, and the reference evaluates the exact
//! answer for exactly those inputs, but rounding a position to f32 (2^-24 of the scene's
//! scale S = |o|∞ + t_b + |h|∞) moves the light-exit distance d_m by that much divided
//! by |ω_k| (k the exit face's axis), and the optical depth by σt times that; and the
//! caller's f32 interval ends t_a, t_b (rounded box entry and exit) move a short segment's
//! ends by 2^-24 of their size. No f32 algorithm can do better than this conditioning,
//! which is large only for optically thick boxes seen from afar (σt·S ≫ 1e3) and for
//! chords much shorter than their distance from the camera. So a configuration passes when
//!
//! ```text
//! |T_gpu − T_ref| / max(T_ref, 1e-12) <= 1e-4 + κ,
//! κ = 8 · 2^-24 · σt · S · (1 + 1/|ω_k|) + 2 · 2^-24 · (|t_a| + |t_b|) / (t_b − t_a),
//! ```
//!
//! with the largest 1/|ω_k| over the exit faces along the segment. The random test prints
//! how many configurations κ loosens beyond 1e-4, the largest error there as a fraction
//! of κ, and the largest error everywhere else.

use std::f64::consts::FRAC_1_SQRT_2;

use crate::common::kernel::{records, Arg, Kernel};
use crate::common::rng::Pcg32;
use bytemuck::{Pod, Zeroable};
use glam::{DVec3, Vec3};
use nimbus_gpu::BindingDesc;
use nimbus_reference::quadrature::{unoccluded_single_scatter, unoccluded_single_scatter_convex};
use nimbus_scene::BoxMedium;

/// Relative accuracy asked of the f64 reference (its error estimate is pessimistic, so
/// the true error is far smaller still).
const REFERENCE_REL_TOL: f64 = 1e-7;
/// The relative tolerance on T_box, before the conditioning allowance κ.
const T_BOX_REL_TOL: f64 = 1e-4;
/// Below this T_box (metres), errors are measured in absolute terms.
const T_BOX_ABS_FLOOR: f64 = 1e-12;
/// f32 unit roundoff.
const EPS32: f64 = 1.0 / 16_777_216.0;

// ---------------------------------------------------------------------------------------
// GPU side: records mirrored from shaders/tests/box_analytic.comp.

/// A configuration in the box's local frame (`Config` in the shader).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuConfig {
    origin_sigma_t: [f32; 4],
    dir_t_enter: [f32; 4],
    omega_t_a: [f32; 4],
    half_size_t_b: [f32; 4],
    /// First plane and plane count of a convex polyhedron (count 0: the box).
    planes: [u32; 4],
}

/// One invocation's work (`Query` in the shader).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuQuery {
    config: u32,
    /// Bit 0: write the configuration's pieces.
    flags: u32,
    u: f32,
    t_eval: f32,
}

/// One invocation's answers (`Result` in the shader).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct GpuResult {
    total: f32,
    count: u32,
    t_sample: f32,
    pdf_sample: f32,
    pdf_eval: f32,
    non_finite: u32,
    pad: [u32; 2],
}

/// The most pieces a configuration's record holds (`MAX_CONVEX_PLANES`).
const MAX_PIECES: usize = 64;

/// A configuration's pieces (`PiecesOut` in the shader).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuPieces {
    t_start: [f32; MAX_PIECES],
    len: [f32; MAX_PIECES],
    tau0: [f32; MAX_PIECES],
    slope: [f32; MAX_PIECES],
    integral: [f32; MAX_PIECES],
}

const _: () = assert!(std::mem::size_of::<GpuConfig>() == 80);
const _: () = assert!(std::mem::size_of::<GpuQuery>() == 16);
const _: () = assert!(std::mem::size_of::<GpuResult>() == 32);
const _: () = assert!(std::mem::size_of::<GpuPieces>() == 5 * 4 * MAX_PIECES);
const _: () = assert!(MAX_PIECES == nimbus::gpu::features::MAX_CONVEX_PLANES as usize);

const LOCAL_SIZE: u32 = 64;
const FLAG_WRITE_PIECES: u32 = 1;

/// The test kernel `shaders/tests/box_analytic.comp`.
struct Gpu {
    kernel: Kernel,
}

/// The GPU configurations of `cases` and the planes they index.
fn gpu_configs(cases: &[Case]) -> (Vec<GpuConfig>, Vec<[f32; 4]>) {
    let mut planes = vec![[0.0f32; 4]];
    let configs = cases
        .iter()
        .map(|case| {
            let mut config = case.gpu();
            if !case.planes.is_empty() {
                config.planes = [planes.len() as u32, case.planes.len() as u32, 0, 0];
                planes.extend(&case.planes);
            }
            config
        })
        .collect();
    (configs, planes)
}

impl Gpu {
    /// The kernel with piece tables of 3 entries, as the renderer has for boxes.
    fn new() -> Self {
        Self::with_max_pieces(3)
    }

    /// The kernel with piece tables of `max_pieces` entries (SC_MAX_PIECES).
    fn with_max_pieces(max_pieces: u32) -> Self {
        let layout = [0, 1, 2, 3, 4].map(BindingDesc::storage_buffer);
        Self {
            kernel: Kernel::new(
                nimbus::shaders::TESTS_BOX_ANALYTIC,
                &layout,
                16,
                &[(
                    nimbus::gpu::features::SC_ID_MAX_PIECES,
                    nimbus_gpu::SpecValue::U32(max_pieces),
                )],
                "box analytic test",
            ),
        }
    }

    /// Runs every query on the configurations of `cases`; returns one result per query
    /// and one pieces record per config (zero unless some query of that config set
    /// `FLAG_WRITE_PIECES`).
    fn run(&self, cases: &[Case], queries: &[GpuQuery]) -> (Vec<GpuResult>, Vec<GpuPieces>) {
        let (configs, planes) = gpu_configs(cases);
        let count = u32::try_from(queries.len()).expect("query count fits u32");
        let out = self.kernel.run(
            &[
                Arg::Storage(0, bytemuck::cast_slice(&configs)),
                Arg::Storage(1, bytemuck::cast_slice(queries)),
                Arg::Zeroed(2, queries.len() * std::mem::size_of::<GpuResult>()),
                Arg::Zeroed(3, configs.len() * std::mem::size_of::<GpuPieces>()),
                Arg::Storage(4, bytemuck::cast_slice(&planes)),
            ],
            bytemuck::cast_slice(&[count, 0, 0, 0]),
            [count.div_ceil(LOCAL_SIZE), 1, 1],
        );
        (
            records(&out[2], queries.len()),
            records(&out[3], configs.len()),
        )
    }

    /// One query per configuration, with its pieces: (result, pieces) for each.
    fn run_configs(&self, cases: &[Case], u: f32) -> Vec<(GpuResult, GpuPieces)> {
        let queries: Vec<GpuQuery> = (0..cases.len())
            .map(|i| GpuQuery {
                config: i as u32,
                flags: FLAG_WRITE_PIECES,
                u,
                t_eval: cases[i].t_a,
            })
            .collect();
        let (results, pieces) = self.run(cases, &queries);
        results.into_iter().zip(pieces).collect()
    }

    /// Fails on any validation error so far.
    fn finish(self) {
        self.kernel.finish();
    }
}

mod convex;

// ---------------------------------------------------------------------------------------
// Configurations and the f64 side.

/// A camera segment through a box or a convex polyhedron, in its local frame, exactly as
/// the GPU sees it (f32); the f64 side widens these values, so both evaluate the same
/// problem.
#[derive(Clone, Debug)]
struct Case {
    name: String,
    o: Vec3,
    d: Vec3,
    omega: Vec3,
    /// The box's half extents (a convex polyhedron: of its bounding box).
    h: Vec3,
    sigma_t: f32,
    t_enter: f32,
    t_a: f32,
    t_b: f32,
    /// A convex polyhedron's planes (unit n, d): n·x <= d inside; empty for the box.
    planes: Vec<[f32; 4]>,
    /// The polyhedron of exactly those f32 planes, for the reference (None for the box).
    convex: Option<std::sync::Arc<nimbus_scene::ConvexMedium>>,
}

/// Where o + t·d is inside the closed box |x| <= h: (t_in, t_out), t_in > t_out for a miss
/// (f64, d need not be unit; a zero component keeps the line in its slab only if o is).
fn slab_span(o: DVec3, d: DVec3, h: DVec3) -> (f64, f64) {
    let (mut t_in, mut t_out) = (f64::NEG_INFINITY, f64::INFINITY);
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a].abs() > h[a] {
                return (1e30, -1e30);
            }
            continue;
        }
        let (t0, t1) = ((-h[a] - o[a]) / d[a], (h[a] - o[a]) / d[a]);
        t_in = t_in.max(t0.min(t1));
        t_out = t_out.min(t0.max(t1));
    }
    (t_in, t_out)
}

/// Distance from x (inside the box) to the boundary towards the light, along −ω: the
/// chord of the ray x − s·ω, s >= 0, by the slab test.
fn light_distance_f64(x: DVec3, omega: DVec3, h: DVec3) -> f64 {
    let (t_in, t_out) = slab_span(x, -omega, h);
    (t_out - t_in.max(0.0)).max(0.0)
}

impl Case {
    /// The segment of o + t·d (d, ω normalized here) inside the box, from the camera or
    /// the box entry to the box exit, like a caller without gobo or surface.
    fn new(name: &str, o: DVec3, d: DVec3, omega: DVec3, h: DVec3, sigma_t: f64) -> Self {
        let (o, h) = (o.as_vec3(), h.as_vec3());
        let (d, omega) = (d.normalize().as_vec3(), omega.normalize().as_vec3());
        let (t_in, t_out) = slab_span(o.as_dvec3(), d.as_dvec3().normalize(), h.as_dvec3());
        let t_enter = t_in.max(0.0) as f32;
        Self {
            name: name.to_owned(),
            o,
            d,
            omega,
            h,
            sigma_t: sigma_t as f32,
            t_enter,
            t_a: t_enter,
            t_b: t_out as f32,
            planes: Vec::new(),
            convex: None,
        }
    }

    /// The segment of o + t·d (d, ω normalized here) inside the convex polyhedron of
    /// `planes` ([nx, ny, nz, d]: normalized here and rounded to f32, as the loader does).
    fn convex(
        name: &str,
        o: DVec3,
        d: DVec3,
        omega: DVec3,
        planes: &[[f64; 4]],
        sigma_t: f64,
    ) -> Self {
        let polyhedron = nimbus_scene::convex::ConvexPolyhedron::new(planes)
            .unwrap_or_else(|e| panic!("{name}: {e}: {planes:?}"));
        let planes: Vec<[f32; 4]> = polyhedron
            .planes
            .iter()
            .map(|(n, d)| [n.x as f32, n.y as f32, n.z as f32, *d as f32])
            .collect();
        let (lo, hi) = polyhedron.bounds();
        let h = hi.abs().max(lo.abs()).as_vec3();
        // The reference clips by exactly the f32 planes the GPU has.
        let widened: Vec<[f64; 4]> = planes.iter().map(|p| p.map(f64::from)).collect();
        let convex = nimbus_scene::ConvexMedium {
            planes: planes.clone(),
            polyhedron: nimbus_scene::convex::ConvexPolyhedron::new(&widened).expect("polyhedron"),
            sigma_t: sigma_t as f32,
            albedo: Vec3::ONE,
            g: 0.0,
        };
        let mut case = Self {
            name: name.to_owned(),
            o: o.as_vec3(),
            d: d.normalize().as_vec3(),
            omega: omega.normalize().as_vec3(),
            h,
            sigma_t: sigma_t as f32,
            t_enter: 0.0,
            t_a: 0.0,
            t_b: 0.0,
            planes,
            convex: Some(std::sync::Arc::new(convex)),
        };
        let (t_in, t_out) = case.span64(case.o.as_dvec3(), case.d64());
        case.t_enter = t_in.max(0.0) as f32;
        case.t_a = case.t_enter;
        case.t_b = t_out as f32;
        case
    }

    /// The region's planes in f64: the convex planes widened, or the box's six faces.
    fn planes64(&self) -> Vec<(DVec3, f64)> {
        if self.planes.is_empty() {
            let h = self.h.as_dvec3();
            let mut faces = Vec::new();
            for a in 0..3 {
                for sign in [-1.0, 1.0] {
                    let mut n = DVec3::ZERO;
                    n[a] = sign;
                    faces.push((n, h[a]));
                }
            }
            return faces;
        }
        self.planes
            .iter()
            .map(|p| {
                (
                    DVec3::new(p[0].into(), p[1].into(), p[2].into()),
                    p[3].into(),
                )
            })
            .collect()
    }

    /// Where o + t·d is inside the region (f64): (t_in, t_out), t_in > t_out for a miss.
    fn span64(&self, o: DVec3, d: DVec3) -> (f64, f64) {
        if self.planes.is_empty() {
            return slab_span(o, d, self.h.as_dvec3());
        }
        let (mut t_in, mut t_out) = (f64::NEG_INFINITY, f64::INFINITY);
        for (n, offset) in self.planes64() {
            let (num, denom) = (offset - n.dot(o), n.dot(d));
            if denom == 0.0 {
                if num < 0.0 {
                    return (1e30, -1e30);
                }
                continue;
            }
            if denom > 0.0 {
                t_out = t_out.min(num / denom);
            } else {
                t_in = t_in.max(num / denom);
            }
        }
        (t_in, t_out)
    }

    /// The light-exit lines s(t) = α + β t (t along the case's ray, from o) of the faces
    /// the light enters by, with their 1/w (w = −n·ω).
    fn exit_lines(&self) -> Vec<(f64, f64, f64)> {
        let (o, d) = (self.o.as_dvec3(), self.d64());
        let omega = self.omega.as_dvec3().normalize();
        self.planes64()
            .into_iter()
            .filter_map(|(n, offset)| {
                let w = -n.dot(omega);
                (w > 0.0).then(|| ((offset - n.dot(o)) / w, -n.dot(d) / w, 1.0 / w))
            })
            .collect()
    }

    /// Distance from x (inside the region) to the boundary towards the light along −ω:
    /// the chord of x − s·ω (box), or the nearest light-facing plane (polyhedron; x may
    /// lie just outside a plane the light runs parallel to after rounding).
    fn light_distance(&self, x: DVec3) -> f64 {
        let omega = self.omega.as_dvec3().normalize();
        if self.planes.is_empty() {
            return light_distance_f64(x, omega, self.h.as_dvec3());
        }
        self.planes64()
            .into_iter()
            .filter_map(|(n, offset)| {
                let w = -n.dot(omega);
                (w > 0.0).then(|| (offset - n.dot(x)) / w)
            })
            .fold(f64::INFINITY, f64::min)
            .max(0.0)
    }

    /// Moves the start to a fraction of the segment (a gobo clamp): t_a > t_enter.
    fn clamp_start(mut self, fraction: f64) -> Self {
        let (a, b) = (f64::from(self.t_a), f64::from(self.t_b));
        self.t_a = (a + fraction * (b - a)) as f32;
        self
    }

    /// Moves the end to a fraction of the segment (a surface in front of the exit).
    fn clamp_end(mut self, fraction: f64) -> Self {
        let (a, b) = (f64::from(self.t_a), f64::from(self.t_b));
        self.t_b = (a + fraction * (b - a)) as f32;
        self
    }

    fn gpu(&self) -> GpuConfig {
        GpuConfig {
            origin_sigma_t: [self.o.x, self.o.y, self.o.z, self.sigma_t],
            dir_t_enter: [self.d.x, self.d.y, self.d.z, self.t_enter],
            omega_t_a: [self.omega.x, self.omega.y, self.omega.z, self.t_a],
            half_size_t_b: [self.h.x, self.h.y, self.h.z, self.t_b],
            planes: [0; 4],
        }
    }

    fn is_empty(&self) -> bool {
        self.t_b.partial_cmp(&self.t_a) != Some(std::cmp::Ordering::Greater)
    }

    /// The reference's integral over o + t·d, t ∈ [0, t_max], in the case's region.
    fn unoccluded(&self, o: DVec3, t_max: f64) -> f64 {
        let (d, omega) = (self.d64(), self.omega.as_dvec3());
        let Some(convex) = &self.convex else {
            let medium = BoxMedium {
                center: Vec3::ZERO,
                size: 2.0 * self.h,
                rotation_deg: Vec3::ZERO,
                sigma_t: self.sigma_t,
                albedo: Vec3::ONE,
                g: 0.0,
            };
            return unoccluded_single_scatter(&medium, omega, o, d, t_max, REFERENCE_REL_TOL);
        };
        unoccluded_single_scatter_convex(convex, omega, o, d, t_max, REFERENCE_REL_TOL)
    }

    /// The unit camera direction in f64 (the reference normalizes it the same way).
    fn d64(&self) -> DVec3 {
        self.d.as_dvec3().normalize()
    }

    /// ∫ over [t_lo, t_hi] ⊂ [t_a, t_b] of exp(−σt (t − t_enter)) T_light(t) dt by the
    /// reference: started at o + t_lo·d so that its camera transmittance starts there,
    /// then scaled by the transmittance from t_enter to t_lo.
    fn reference_between(&self, t_lo: f64, t_hi: f64) -> f64 {
        if t_hi.partial_cmp(&t_lo) != Some(std::cmp::Ordering::Greater) {
            return 0.0;
        }
        let (o, d) = (self.o.as_dvec3(), self.d64());
        let sigma_t = f64::from(self.sigma_t);
        let t_enter = f64::from(self.t_enter);
        if t_lo == t_enter {
            return self.unoccluded(o, t_hi);
        }
        let start = o + t_lo * d;
        (-sigma_t * (t_lo - t_enter)).exp() * self.unoccluded(start, t_hi - t_lo)
    }

    /// T_box over [t_a, t_b] by the reference, which is called on sub-intervals so that its
    /// adaptive quadrature sees every thin boundary layer (its 64 initial pieces and
    /// 15-point rules miss a peak narrower than about 1/1000 of the interval, e.g. the
    /// 1/(σt c) layer at the entry of an optically thick box):
    ///
    /// - split at the t where two slabs' light-exit distances cross (where the integrand
    ///   may kink: the peaks of exp(−τ) are at these points and at t_a, t_b);
    /// - grade each part geometrically towards both ends, to widths below 1/(σt·slope);
    /// - skip a sub-interval whose rigorous upper bound (camera depth at its start, the
    ///   smaller light distance at its ends, since d_m is concave) is below 1e-9 of a
    ///   rigorous lower bound of the total (width × the smaller endpoint integrand, the
    ///   integrand being exponential between crossings).
    fn reference(&self) -> f64 {
        if self.is_empty() {
            return 0.0;
        }
        let (t_a, t_b) = (f64::from(self.t_a), f64::from(self.t_b));
        let (o, d) = (self.o.as_dvec3(), self.d64());
        let sigma_t = f64::from(self.sigma_t);

        // Split where the light-exit distances of two faces cross.
        let mut splits = vec![t_a, t_b];
        let mut max_rate: f64 = 1.0;
        let lines = self.exit_lines();
        for (i, &(alpha_a, beta_a, inv_w)) in lines.iter().enumerate() {
            max_rate = max_rate.max(1.0 + inv_w);
            for &(alpha_b, beta_b, _) in &lines[i + 1..] {
                let t = (alpha_b - alpha_a) / (beta_a - beta_b);
                if t.is_finite() && t > t_a && t < t_b {
                    splits.push(t);
                }
            }
        }
        splits.sort_by(f64::total_cmp);

        // Grade every part towards both ends.
        let mut parts = Vec::new();
        for w in splits.windows(2) {
            let (lo, hi) = (w[0], w[1]);
            let len = hi - lo;
            // Two faces may cross at the same t (a vertex): nothing between them.
            if len.is_nan() || len <= 0.0 {
                continue;
            }
            let levels = ((sigma_t * max_rate * len).log2().ceil() as i32 - 4).clamp(0, 60);
            if levels == 0 {
                parts.push((lo, hi));
                continue;
            }
            let mut fractions: Vec<f64> = (1..=levels).map(|k| 0.5f64.powi(k + 1)).collect();
            fractions.reverse();
            let mut points = vec![0.0];
            points.extend(fractions.iter().copied());
            points.push(0.5);
            points.extend(fractions.iter().rev().map(|f| 1.0 - f));
            points.push(1.0);
            parts.extend(
                points
                    .windows(2)
                    .map(|p| (lo + p[0] * len, lo + p[1] * len)),
            );
        }

        // Skip what cannot matter, integrate the rest.
        let light = |t: f64| self.light_distance(o + t * d);
        let t_enter = f64::from(self.t_enter);
        let lower = parts
            .iter()
            .map(|&(lo, hi)| (hi - lo) * self.integrand(lo).min(self.integrand(hi)))
            .fold(0.0, f64::max);
        parts
            .iter()
            .filter(|&&(lo, hi)| {
                let upper =
                    (hi - lo) * (-sigma_t * ((lo - t_enter) + light(lo).min(light(hi)))).exp();
                upper >= 1e-9 * lower.max(1e-21)
            })
            .map(|&(lo, hi)| self.reference_between(lo, hi))
            .sum()
    }

    /// The integrand exp(−σt ((t − t_enter) + d_m(t))) in f64, for t in [t_a, t_b]; in a
    /// box x(t) is clamped into it, so that an end point rounded just outside a face the
    /// light runs parallel to is not taken for unlit.
    fn integrand(&self, t: f64) -> f64 {
        let h = self.h.as_dvec3();
        let mut x = self.o.as_dvec3() + t * self.d64();
        if self.planes.is_empty() {
            x = x.clamp(-h, h);
        }
        let d_m = self.light_distance(x);
        (-f64::from(self.sigma_t) * ((t - f64::from(self.t_enter)) + d_m)).exp()
    }

    /// The conditioning allowance κ of the module docs.
    fn kappa(&self) -> f64 {
        if self.is_empty() {
            return 0.0;
        }
        let (o, h) = (self.o.as_dvec3(), self.h.as_dvec3());
        let (t_a, t_b) = (f64::from(self.t_a), f64::from(self.t_b));
        let scale = o.abs().max_element() + t_b.abs() + h.max_element();
        // Find the exit faces along the segment: the argmin of the light distances.
        let lines = self.exit_lines();
        let mut inv_omega_max: f64 = 0.0;
        for i in 0..=64 {
            let t = t_a + (t_b - t_a) * f64::from(i) / 64.0;
            let mut best = (f64::INFINITY, 0.0);
            for &(alpha, beta, inv_w) in &lines {
                let s = alpha + beta * t;
                if s < best.0 {
                    best = (s, inv_w);
                }
            }
            inv_omega_max = inv_omega_max.max(best.1);
        }
        // Rounding t_a and t_b to f32 moves the interval's ends by 2^-24 of their size.
        let ends = 2.0 * EPS32 * (t_a.abs() + t_b.abs()) / (t_b - t_a);
        8.0 * EPS32 * f64::from(self.sigma_t) * scale * (1.0 + inv_omega_max) + ends
    }
}

/// |gpu − reference| relative to the reference, absolute below [`T_BOX_ABS_FLOOR`].
fn t_box_error(gpu: f64, reference: f64) -> f64 {
    (gpu - reference).abs() / reference.max(T_BOX_ABS_FLOOR)
}

/// A random configuration: box half extents log-uniform over 1e-3..1e4 m with aspect
/// ratios up to 100, σt log-uniform over 1e-6..1e3 /m,
/// random ω, camera inside or outside (up to 5 box sizes away) or missing, and sometimes
/// a clamped start (gobo) or end (surface).
fn random_case(rng: &mut Pcg32, index: usize) -> Case {
    let scale = rng.log_uniform(-3.0, 4.0);
    let h = DVec3::new(
        scale * rng.log_uniform(-2.0, 0.0),
        scale * rng.log_uniform(-2.0, 0.0),
        scale * rng.log_uniform(-2.0, 0.0),
    );
    let sigma_t = rng.log_uniform(-6.0, 3.0);
    let omega = rng.direction();
    let inside = |rng: &mut Pcg32| {
        DVec3::new(
            h.x * rng.range(-1.0, 1.0),
            h.y * rng.range(-1.0, 1.0),
            h.z * rng.range(-1.0, 1.0),
        )
    };
    let roll = rng.uniform();
    let (kind, o, d) = if roll < 0.45 {
        ("inside", inside(rng), rng.direction())
    } else if roll < 0.92 {
        // Aim from outside at a point inside.
        let target = inside(rng);
        let o = target + h.length() * rng.log_uniform(-3.0, 0.7) * rng.direction();
        ("outside", o, target - o)
    } else {
        let o = h * 3.0 * rng.direction();
        ("random", o, rng.direction())
    };
    let mut case = Case::new(&format!("random {index} ({kind})"), o, d, omega, h, sigma_t);
    if !case.is_empty() {
        if rng.uniform() < 0.25 {
            let f = rng.uniform();
            case = case.clamp_start(f);
        }
        if rng.uniform() < 0.3 {
            let f = rng.uniform();
            case = case.clamp_end(f);
        }
    }
    case
}

/// Maps `f` over `items` on all cores.
fn par_map<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let chunk = items.len().div_ceil(threads).max(1);
    std::thread::scope(|s| {
        let workers: Vec<_> = items
            .chunks(chunk)
            .map(|c| s.spawn(|| c.iter().map(&f).collect::<Vec<R>>()))
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().expect("worker thread"))
            .collect()
    })
}

/// How one configuration's T_box compared with the reference.
struct Compared {
    index: usize,
    error: f64,
    tolerance: f64,
    kappa: f64,
}

/// Compares GPU T_box with the reference for each case and fails on the first that
/// exceeds its tolerance, on any non-finite value, and on a piece count out of range
/// (0 exactly for an empty segment).
fn check_t_box(cases: &[Case], results: &[(GpuResult, GpuPieces)]) -> Vec<Compared> {
    let references = par_map(cases, Case::reference);
    let mut errors = Vec::with_capacity(cases.len());
    for (i, (case, ((result, _), &reference))) in cases
        .iter()
        .zip(results.iter().zip(&references))
        .enumerate()
    {
        assert_eq!(
            result.non_finite, 0,
            "{}: {} non-finite values in the shader: {case:?}",
            case.name, result.non_finite
        );
        let kappa = case.kappa();
        let tolerance = T_BOX_REL_TOL + kappa;
        let error = t_box_error(f64::from(result.total), reference);
        assert!(
            error <= tolerance,
            "{}: T_box gpu {} vs reference {reference:e}: error {error:e} > tolerance {tolerance:e} \
             (κ {kappa:e}); {} pieces; {case:?}",
            case.name,
            result.total,
            result.count
        );
        if case.is_empty() {
            assert_eq!(result.count, 0, "{}: empty segment has pieces", case.name);
            assert_eq!(result.total, 0.0, "{}: empty segment has T_box", case.name);
        } else {
            // A box has at most 3 pieces, a polyhedron one per light-facing plane.
            let most = if case.planes.is_empty() {
                3
            } else {
                case.exit_lines().len().max(1)
            };
            assert!(
                (1..=most as u32).contains(&result.count),
                "{}: count {} of at most {most}",
                case.name,
                result.count
            );
        }
        errors.push(Compared {
            index: i,
            error,
            tolerance,
            kappa,
        });
    }
    errors
}

// ---------------------------------------------------------------------------------------
// Tests.

#[test]
fn t_box_matches_the_f64_reference_on_10000_random_configurations() {
    let gpu = Gpu::new();
    let mut rng = Pcg32::new(0x5eed_b0c5);
    let cases: Vec<Case> = (0..10_000).map(|i| random_case(&mut rng, i)).collect();
    let results = gpu.run_configs(&cases, 0.5);
    let check = check_t_box(&cases, &results);

    let nonempty = cases.iter().filter(|c| !c.is_empty()).count();
    let worst = check
        .iter()
        .max_by(|a, b| a.error.total_cmp(&b.error))
        .expect("cases");
    let worst_ratio = check
        .iter()
        .max_by(|a, b| (a.error / a.tolerance).total_cmp(&(b.error / b.tolerance)))
        .expect("cases");
    let well_conditioned: Vec<_> = check.iter().filter(|e| e.kappa < 1e-5).collect();
    let worst_well = well_conditioned
        .iter()
        .max_by(|a, b| a.error.total_cmp(&b.error))
        .expect("well-conditioned cases");
    let loosened = check.iter().filter(|e| e.kappa > T_BOX_REL_TOL).count();
    let pieces_hist = (0..=3)
        .map(|n| results.iter().filter(|r| r.0.count == n).count())
        .collect::<Vec<_>>();
    println!(
        "{} configurations ({nonempty} non-empty; pieces 0/1/2/3: {pieces_hist:?})",
        cases.len()
    );
    println!(
        "max relative error {:.3e} (tolerance there {:.3e}): {:?}",
        worst.error, worst.tolerance, cases[worst.index]
    );
    println!(
        "max error / tolerance {:.3}: {:?}",
        worst_ratio.error / worst_ratio.tolerance,
        cases[worst_ratio.index]
    );
    println!(
        "{} configurations with κ < 1e-5: max relative error {:.3e}: {:?}",
        well_conditioned.len(),
        worst_well.error,
        cases[worst_well.index]
    );
    let max_below = check
        .iter()
        .filter(|e| e.kappa <= T_BOX_REL_TOL)
        .map(|e| e.error)
        .fold(0.0, f64::max);
    let max_over_kappa = check
        .iter()
        .filter(|e| e.kappa > T_BOX_REL_TOL)
        .map(|e| e.error / e.kappa)
        .fold(0.0, f64::max);
    let beyond = check.iter().filter(|e| e.error > T_BOX_REL_TOL).count();
    println!(
        "{loosened} configurations with κ > 1e-4 (f32-limited: optically thick and seen from \
         far); there the error is at most {max_over_kappa:.3} κ. {beyond} configurations \
         exceed 1e-4; where κ <= 1e-4 the max relative error is {max_below:.3e}"
    );
    gpu.finish();
}

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
fn check_pdf(gpu: &Gpu, cases: &[Case]) {
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
fn check_samples_follow_the_pdf(gpu: &Gpu, setups: &[(Case, u32)]) {
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
