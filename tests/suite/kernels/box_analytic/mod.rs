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
//! The hard cases and the limits are in [`hard`], the pdf and sampling checks in [`pdf`],
//! and the same checks on convex polyhedra in [`convex`].
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
const _: () = assert!(MAX_PIECES == nimbus::shader_data::features::MAX_CONVEX_PLANES as usize);

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
                    nimbus::shader_data::features::SC_ID_MAX_PIECES,
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
mod hard;
mod pdf;

use pdf::{check_pdf, check_samples_follow_the_pdf};

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
