//! The sampling families (HG, cosine hemisphere, uniform sphere, uniform cone,
//! exponential, truncated exponential): `sample_X`, `X_pdf` and `invert_X` together, each
//! at several parameters (the round trip and the pdf's integral, see [`super`]).

use super::*;

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
