//! The analytic core on convex polyhedra (the paper's Sec. 7, Fig. 11): T_box, the pdf
//! and the samples of whole-volume distance sampling against the same f64 reference and
//! under the same tolerance as boxes ([`super`]), on random polyhedra of 4 to 64 planes
//! and on the box's hard cases transposed: the camera on a face, an edge or a vertex of
//! a dodecahedron, light parallel to a face or to the view, thin slivers, many pieces.

use super::*;

/// The 12 planes [n, d] of a regular dodecahedron of inradius `r` about the origin.
fn dodecahedron(r: f64) -> Vec<[f64; 4]> {
    let phi = (1.0 + 5f64.sqrt()) / 2.0;
    let mut planes = Vec::new();
    for a in [-1.0, 1.0] {
        for b in [-phi, phi] {
            for n in [[0.0, a, b], [a, b, 0.0], [b, 0.0, a]] {
                let n = DVec3::from_array(n).normalize();
                planes.push([n.x, n.y, n.z, r]);
            }
        }
    }
    planes
}

/// A right prism over a regular `sides`-gon of circumradius `radius` in the xz plane,
/// `height` tall along y: `sides` + 2 planes.
fn prism(sides: usize, radius: f64, height: f64) -> Vec<[f64; 4]> {
    let mut planes: Vec<[f64; 4]> = (0..sides)
        .map(|i| {
            let angle = std::f64::consts::TAU * (i as f64 + 0.5) / sides as f64;
            let apothem = radius * (std::f64::consts::PI / sides as f64).cos();
            [angle.cos(), 0.0, angle.sin(), apothem]
        })
        .collect();
    planes.push([0.0, 1.0, 0.0, 0.5 * height]);
    planes.push([0.0, -1.0, 0.0, 0.5 * height]);
    planes
}

/// A random polyhedron of 4 to 64 planes about the origin: a random tetrahedron around
/// the ellipsoid of semi-axes `a` (so it is bounded), cut by planes tangent to the
/// ellipsoid in random directions (so the ellipsoid stays inside).
fn random_polyhedron(rng: &mut Pcg32, a: DVec3) -> Vec<[f64; 4]> {
    let count = 4 + (rng.next_u32() % 61) as usize;
    let support = |n: DVec3| (n * a).length();
    let rotate = {
        // A random orthonormal frame (directions may repeat: draw until independent).
        let x = rng.direction();
        let mut z = x.cross(rng.direction());
        while z.length() < 0.1 {
            z = x.cross(rng.direction());
        }
        let z = z.normalize();
        let y = z.cross(x);
        move |p: DVec3| p.x * x + p.y * y + p.z * z
    };
    let mut planes: Vec<[f64; 4]> = [
        [1.0, 1.0, 1.0],
        [1.0, -1.0, -1.0],
        [-1.0, 1.0, -1.0],
        [-1.0, -1.0, 1.0],
    ]
    .iter()
    .map(|n| {
        let n = rotate(DVec3::from_array(*n).normalize());
        [n.x, n.y, n.z, 1.5 * support(n)]
    })
    .collect();
    while planes.len() < count {
        let n = rng.direction();
        planes.push([n.x, n.y, n.z, support(n)]);
    }
    planes
}

/// A random configuration on a random polyhedron: sizes log-uniform over 1e-3..1e4 m with
/// aspect ratios up to 100, σt over 1e-6..1e3 /m, the camera inside, outside aiming at
/// it, or anywhere, sometimes clamped at the start (gobo) or end (surface).
fn random_convex_case(rng: &mut Pcg32, index: usize) -> Case {
    let scale = rng.log_uniform(-3.0, 4.0);
    let a = DVec3::new(
        scale * rng.log_uniform(-2.0, 0.0),
        scale * rng.log_uniform(-2.0, 0.0),
        scale * rng.log_uniform(-2.0, 0.0),
    );
    let planes = random_polyhedron(rng, a);
    let sigma_t = rng.log_uniform(-6.0, 3.0);
    let omega = rng.direction();
    // A point inside the ellipsoid, hence inside the polyhedron.
    let inside = |rng: &mut Pcg32| rng.direction() * a * rng.uniform().cbrt() * 0.99;
    let roll = rng.uniform();
    let (kind, o, d) = if roll < 0.45 {
        ("inside", inside(rng), rng.direction())
    } else if roll < 0.92 {
        let target = inside(rng);
        let o = target + a.length() * rng.log_uniform(-3.0, 0.7) * rng.direction();
        ("outside", o, target - o)
    } else {
        ("random", 3.0 * a * rng.direction(), rng.direction())
    };
    let name = format!("convex {index} ({kind}, {} planes)", planes.len());
    let mut case = Case::convex(&name, o, d, omega, &planes, sigma_t);
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

/// The box's hard cases on a dodecahedron of inradius 1, a thin sliver and a 62-gon
/// prism.
fn convex_hard_cases() -> Vec<Case> {
    let dodeca = dodecahedron(1.0);
    let poly = nimbus_scene::convex::ConvexPolyhedron::new(&dodeca).expect("dodecahedron");
    let v = DVec3::new;
    let w = v(0.3, -0.5, 0.8);
    let vertex = poly.vertices[0];
    let face_n = DVec3::new(dodeca[0][0], dodeca[0][1], dodeca[0][2]);
    let face_center = face_n;
    // An edge: two vertices that share two faces.
    let on = |p: DVec3, i: usize| {
        let n = DVec3::new(dodeca[i][0], dodeca[i][1], dodeca[i][2]);
        (n.dot(p) - dodeca[i][3]).abs() < 1e-9
    };
    let edge = poly
        .vertices
        .iter()
        .enumerate()
        .flat_map(|(i, a)| poly.vertices[i + 1..].iter().map(move |b| (*a, *b)))
        .find(|(a, b)| (0..12).filter(|&i| on(*a, i) && on(*b, i)).count() == 2)
        .expect("an edge");
    let edge_mid = 0.5 * (edge.0 + edge.1);
    let edge_dir = (edge.1 - edge.0).normalize();
    // A light direction parallel to the face: perpendicular to its normal.
    let along_face = face_n.cross(v(0.2, 1.0, 0.3)).normalize();
    let c = |name: &str, o: DVec3, d: DVec3, omega: DVec3, sigma_t: f64| {
        Case::convex(name, o, d, omega, &dodeca, sigma_t)
    };
    let mut cases = vec![
        c(
            "dodecahedron parallel inside (Eq. 8)",
            v(0.2, -0.1, 0.3),
            w,
            w,
            0.7,
        ),
        c(
            "dodecahedron antiparallel inside (Eq. 7)",
            v(0.2, -0.1, 0.3),
            -w,
            w,
            0.7,
        ),
        c(
            "dodecahedron parallel outside (Eq. 8)",
            v(0.2, -0.1, 0.3) - 5.0 * w,
            w,
            w,
            0.7,
        ),
        c(
            "dodecahedron antiparallel outside (Eq. 7)",
            v(0.2, -0.1, 0.3) + 5.0 * w,
            -w,
            w,
            0.7,
        ),
        c("on a vertex, inward", vertex, -vertex, w, 0.9),
        c("on a vertex, outward", vertex, vertex, w, 0.9),
        c(
            "on a vertex, along an edge",
            vertex,
            poly.vertices
                .iter()
                .map(|p| *p - vertex)
                .filter(|e| e.length() > 1e-6)
                .min_by(|a, b| a.length().total_cmp(&b.length()))
                .expect("neighbour"),
            w,
            0.9,
        ),
        c("on an edge, inward", edge_mid, -edge_mid, w, 0.9),
        c("on an edge, outward", edge_mid, edge_mid, w, 0.9),
        c(
            "on an edge, along it",
            edge.0,
            edge_dir,
            v(-0.6, 0.3, 0.5),
            0.9,
        ),
        c(
            "on a face, inward",
            face_center,
            -face_n + v(0.1, 0.2, 0.0),
            w,
            0.9,
        ),
        c("on a face, outward", face_center, face_n, w, 0.9),
        c("on a face, in its plane", face_center, along_face, w, 0.9),
        c(
            "light parallel to a face, camera inside",
            v(0.1, 0.2, -0.3),
            v(0.4, -0.2, 0.9),
            along_face,
            1.3,
        ),
        c(
            "light parallel to a face, from outside",
            v(0.1, 0.2, -0.3) - 4.0 * face_n,
            face_n,
            along_face,
            1.3,
        ),
        c(
            "dodecahedron sigma_t 1e3 from outside",
            v(0.2, 3.0, 0.3),
            v(-0.1, -3.0, -0.1),
            w,
            1e3,
        ),
        c(
            "dodecahedron sigma_t 1e-6",
            v(-3.0, 0.1, -2.5),
            v(1.0, 0.05, 0.6),
            w,
            1e-6,
        ),
        c(
            "dodecahedron miss",
            v(3.0, 3.0, 3.0),
            v(1.0, 0.0, 0.0),
            w,
            0.9,
        ),
    ];
    // A sliver 1e-3 thick: crossed obliquely, and lit almost along it.
    let sliver = prism(6, 1.0, 1e-3);
    cases.push(Case::convex(
        "sliver crossed",
        v(-0.3, 0.2, 0.1),
        v(0.5, -1.0, 0.2),
        w,
        &sliver,
        2.0,
    ));
    cases.push(Case::convex(
        "sliver, inside along it",
        v(-0.5, 0.0, 0.1),
        v(1.0, 1e-4, 0.2),
        v(0.3, -0.01, 0.8),
        &sliver,
        2.0,
    ));
    cases.push(Case::convex(
        "sliver, grazing light",
        v(-0.3, 0.2, 0.1),
        v(0.5, -1.0, 0.2),
        v(1.0, -1e-3, 0.1),
        &sliver,
        2.0,
    ));
    // A 62-gon prism (64 planes) lit across its axis, seen through its middle: as many
    // pieces as light-facing sides the segment sees.
    let many = prism(62, 1.0, 4.0);
    cases.push(Case::convex(
        "64 planes, many pieces",
        v(-3.0, 0.1, 0.05),
        v(1.0, 0.02, 0.01),
        v(0.05, -0.1, -1.0),
        &many,
        1.5,
    ));
    cases.push(Case::convex(
        "64 planes, camera inside",
        v(0.3, -0.4, 0.2),
        v(-0.6, 0.1, 0.7),
        v(0.2, 0.9, -0.4),
        &many,
        3.0,
    ));
    cases
}

#[test]
fn convex_t_box_matches_the_f64_reference_on_random_polyhedra_and_hard_cases() {
    let gpu = Gpu::with_max_pieces(nimbus::shader_data::features::MAX_CONVEX_PLANES);
    let mut rng = Pcg32::new(0xc0_4e3);
    let mut cases: Vec<Case> = (0..1500).map(|i| random_convex_case(&mut rng, i)).collect();
    let hard = convex_hard_cases();
    cases.extend(hard.iter().cloned());
    let results = gpu.run_configs(&cases, 0.5);
    let check = check_t_box(&cases, &results);

    let well: Vec<_> = check.iter().filter(|e| e.kappa < 1e-5).collect();
    let worst_well = well.iter().map(|e| e.error).fold(0.0, f64::max);
    let most_pieces = results.iter().map(|r| r.0.count).max().unwrap_or(0);
    println!(
        "{} convex configurations ({} with κ < 1e-5: max relative error {worst_well:.3e}); \
         up to {most_pieces} pieces",
        cases.len(),
        well.len()
    );
    let first_hard = cases.len() - hard.len();
    for (i, case) in cases.iter().enumerate().skip(first_hard) {
        println!(
            "{:<44} T_box {:<13e} pieces {:>2} error {:.2e} (tol {:.2e})",
            case.name, results[i].0.total, results[i].0.count, check[i].error, check[i].tolerance
        );
    }
    let named = |name: &str| {
        let i = cases.iter().position(|c| c.name == name).expect(name);
        results[i]
    };
    assert_eq!(named("dodecahedron miss").0.count, 0);
    // Leaving from a vertex, edge or face sees at most the sliver that rounding the point
    // to f32 leaves inside (the box's corners are exact, a dodecahedron's are not).
    for name in [
        "on a vertex, outward",
        "on an edge, outward",
        "on a face, outward",
    ] {
        assert!(named(name).0.total < 1e-6, "{name}: {:?}", named(name).0);
    }
    // The parallel cases are one piece with c = 2 (Eq. 8) or 0 (Eq. 7).
    for (name, c) in [
        ("dodecahedron parallel inside (Eq. 8)", 2.0),
        ("dodecahedron antiparallel inside (Eq. 7)", 0.0),
    ] {
        let (r, p) = named(name);
        assert_eq!(r.count, 1, "{name}");
        assert!(
            (f64::from(p.slope[0]) / 0.7 - c).abs() < 1e-5,
            "{name}: {}",
            p.slope[0]
        );
    }
    assert!(
        named("64 planes, many pieces").0.count >= 8,
        "a 62-gon seen through its middle"
    );
    gpu.finish();
}

#[test]
fn convex_wvds_pdf_integrates_to_one_and_samples_follow_it() {
    let gpu = Gpu::with_max_pieces(nimbus::shader_data::features::MAX_CONVEX_PLANES);
    let mut rng = Pcg32::new(0x9df_c0e4);
    let mut cases = Vec::new();
    while cases.len() < 120 {
        let case = random_convex_case(&mut rng, cases.len());
        if !case.is_empty() {
            cases.push(case);
        }
    }
    check_pdf(&gpu, &cases);

    // Samples follow the pdf on a dodecahedron seen from an edge (5 pieces) and through
    // the 62-gon prism (31 pieces).
    let hard = convex_hard_cases();
    let pick = |name: &str| hard.iter().find(|c| c.name == name).expect(name).clone();
    let setups = [pick("on an edge, inward"), pick("64 planes, many pieces")];
    let counts = gpu.run_configs(&setups, 0.5);
    println!("pieces: {} and {}", counts[0].0.count, counts[1].0.count);
    assert!(counts[0].0.count >= 4 && counts[1].0.count >= 8);
    let setups = [
        (setups[0].clone(), counts[0].0.count),
        (setups[1].clone(), counts[1].0.count),
    ];
    check_samples_follow_the_pdf(&gpu, &setups);
    gpu.finish();
}
