//! Environment maps: the direction ↔ (u, v) convention, EXR loading and validation,
//! and the importance sampler checked against independent quadrature, a χ² test and a
//! Monte Carlo integral.

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use exr::prelude::{f16, Encoding, Image, SpecificChannels, Vec2, WritableImage};
use glam::{DVec3, Vec3};
use nimbus_scene::{
    direction_to_uv, environment_rotation, uv_to_direction, EnvMap, EnvRotation, EnvSampler, Light,
};

/// splitmix64, for reproducible uniforms in [0, 1).
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    fn u2(&mut self) -> [f64; 2] {
        [self.uniform(), self.uniform()]
    }

    /// A uniformly distributed unit vector (z = 1 − 2ξ, φ = 2πξ').
    fn unit_vector(&mut self) -> DVec3 {
        let z = 1.0 - 2.0 * self.uniform();
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = 2.0 * PI * self.uniform();
        DVec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

/// The direction at polar angle θ from +Y and azimuth φ = atan2(x, −z), written out
/// from docs/scene-format.md rather than through the crate.
fn dir_theta_phi(theta: f64, phi: f64) -> DVec3 {
    DVec3::new(
        theta.sin() * phi.sin(),
        theta.cos(),
        -theta.sin() * phi.cos(),
    )
}

/// 64×32 test map: a sky gradient (brighter and bluer at the zenith), a black ground
/// band in the bottom 4 rows, and one sun texel about 10⁴ times the sky.
fn sun_sky_map() -> EnvMap {
    let (w, h) = (64u32, 32u32);
    let mut texels = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let t = (y as f32 + 0.5) / h as f32;
            let sky = if y >= 28 {
                [0.0, 0.0, 0.0]
            } else {
                let azimuthal = 1.0 + 0.3 * (x as f32 / w as f32 * std::f32::consts::TAU).sin();
                [
                    (0.2 + 0.5 * t) * azimuthal,
                    (0.3 + 0.4 * t) * azimuthal,
                    (1.0 - 0.3 * t) * azimuthal,
                ]
            };
            texels.push(sky);
        }
    }
    // The sun: texel (40, 9).
    texels[(9 * w + 40) as usize] = [9000.0, 8000.0, 6500.0];
    EnvMap {
        width: w,
        height: h,
        texels,
    }
}

/// Exact solid angle of a texel in row y of an H-row map.
fn texel_solid_angle(y: u32, w: u32, h: u32) -> f64 {
    let t0 = PI * y as f64 / h as f64;
    let t1 = PI * (y + 1) as f64 / h as f64;
    2.0 * PI / w as f64 * (t0.cos() - t1.cos())
}

/// ∫ pdf dω over θ ∈ [θ0, θ1], φ ∈ [φ0, φ1] by the midpoint rule on an n×n grid in
/// (θ, φ) with the sin θ Jacobian.
fn integrate_pdf(s: &EnvSampler, theta: (f64, f64), phi: (f64, f64), n: usize) -> f64 {
    let dt = (theta.1 - theta.0) / n as f64;
    let dp = (phi.1 - phi.0) / n as f64;
    let mut sum = 0.0;
    for i in 0..n {
        let t = theta.0 + (i as f64 + 0.5) * dt;
        let mut row = 0.0;
        for j in 0..n {
            let p = phi.0 + (j as f64 + 0.5) * dp;
            row += s.pdf(dir_theta_phi(t, p));
        }
        sum += row * t.sin();
    }
    sum * dt * dp
}

fn tmp_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("nimbus-envmap-{name}"))
}

fn write_rgb_f32(path: &Path, w: usize, h: usize, f: impl Fn(usize, usize) -> [f32; 3] + Sync) {
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let p = f(x, y);
        (p[0], p[1], p[2])
    });
    Image::from_encoded_channels((w, h), Encoding::SMALL_LOSSLESS, channels)
        .write()
        .to_file(path)
        .unwrap();
}

fn err_string(r: anyhow::Result<EnvMap>) -> String {
    format!("{:#}", r.expect_err("expected an error"))
}

#[test]
fn uv_direction_round_trip_on_random_directions() {
    let mut rng = Rng(1);
    for _ in 0..100_000 {
        let d = rng.unit_vector();
        let (u, v) = direction_to_uv(d);
        assert!(
            (0.0..1.0).contains(&u) && (0.0..=1.0).contains(&v),
            "{u} {v}"
        );
        let back = uv_to_direction(u, v);
        assert!((back - d).length() < 1e-12, "{d} -> ({u}, {v}) -> {back}");
        // Non-normalized input gives the same (u, v).
        let (u2, v2) = direction_to_uv(d * 7.5);
        assert!((u2 - u).abs() < 1e-14 && (v2 - v).abs() < 1e-14);
    }
    for _ in 0..100_000 {
        let (u, v) = (rng.uniform(), rng.uniform());
        let (u2, v2) = direction_to_uv(uv_to_direction(u, v));
        let du = (u2 - u).abs();
        // Poles lose u; elsewhere it comes back (modulo the wrap at 1).
        if (PI * v).sin() > 1e-6 {
            assert!(du.min(1.0 - du) < 1e-9, "u {u} -> {u2} (v {v})");
        }
        assert!((v2 - v).abs() < 1e-9, "v {v} -> {v2}");
        // u wraps.
        let d1 = uv_to_direction(u + 1.0, v);
        let d2 = uv_to_direction(u - 3.0, v);
        assert!((d1 - uv_to_direction(u, v)).length() < 1e-12);
        assert!((d2 - uv_to_direction(u, v)).length() < 1e-12);
    }
}

#[test]
fn uv_convention_matches_scene_format() {
    // u = 0.5 + atan2(d.x, −d.z)/(2π), v = acos(d.y)/π.
    let uv = |d: DVec3| direction_to_uv(d);
    assert_eq!(uv(DVec3::Y).1, 0.0, "+Y is v = 0 (top row)");
    assert_eq!(uv(DVec3::NEG_Y).1, 1.0, "−Y is v = 1");
    // −Z: atan2(0, 1) = 0 → u = 0.5, on the horizon v = 0.5.
    assert_eq!(uv(DVec3::NEG_Z), (0.5, 0.5));
    // +X: atan2(1, 0) = π/2 → u = 0.75.
    assert_eq!(uv(DVec3::X), (0.75, 0.5));
    // −X: atan2(−1, 0) = −π/2 → u = 0.25.
    assert_eq!(uv(DVec3::NEG_X), (0.25, 0.5));
    // +Z: atan2(0, −1) = π → u = 1, which wraps to 0.
    assert_eq!(uv(DVec3::Z), (0.0, 0.5));
    // Inverses of the same points.
    assert!((uv_to_direction(0.5, 0.5) - DVec3::NEG_Z).length() < 1e-15);
    assert!((uv_to_direction(0.75, 0.5) - DVec3::X).length() < 1e-15);
    assert_eq!(uv_to_direction(0.3, 0.0), DVec3::Y);
    assert_eq!(uv_to_direction(0.3, 1.0), DVec3::NEG_Y);

    // Degenerate inputs never give NaN.
    for d in [
        DVec3::Y,
        DVec3::NEG_Y,
        DVec3::new(-0.0, 1.0, -0.0),
        DVec3::new(0.0, -1.0, 0.0),
        DVec3::ZERO,
        DVec3::splat(f64::NAN),
        DVec3::new(1e-300, 1.0, 0.0),
    ] {
        let (u, v) = uv(d);
        assert!(
            u.is_finite() && v.is_finite() && (0.0..1.0).contains(&u),
            "{d}"
        );
    }
    for (u, v) in [
        (0.0, 0.0),
        (1.0, 1.0),
        (0.5, -1.0),
        (0.5, 2.0),
        (f64::NAN, f64::NAN),
    ] {
        let d = uv_to_direction(u, v);
        assert!(d.is_finite(), "({u}, {v}) -> {d}");
    }

    // Lookup: nearest texel, row 0 at the top. Texel (x, y) holds [x, y, 0].
    let map = EnvMap {
        width: 4,
        height: 2,
        texels: (0..2)
            .flat_map(|y| (0..4).map(move |x| [x as f32, y as f32, 0.0]))
            .collect(),
    };
    let up_a_bit = |d: DVec3| (d + DVec3::Y * 0.1).normalize();
    let down_a_bit = |d: DVec3| (d - DVec3::Y * 0.1).normalize();
    assert_eq!(map.lookup(DVec3::Y), [0.0, 0.0, 0.0]); // u wraps to 0 at the pole
    assert_eq!(map.lookup(up_a_bit(DVec3::NEG_Z)), [2.0, 0.0, 0.0]); // u = 0.5
    assert_eq!(map.lookup(up_a_bit(DVec3::X)), [3.0, 0.0, 0.0]); // u = 0.75
    assert_eq!(map.lookup(down_a_bit(DVec3::NEG_X)), [1.0, 1.0, 0.0]); // u = 0.25
    assert_eq!(map.lookup(down_a_bit(DVec3::Z)), [0.0, 1.0, 0.0]); // u = 0 (wrapped)
    assert_eq!(map.lookup(DVec3::NEG_Y), [0.0, 1.0, 0.0]); // v = 1 clamps to last row
    assert_eq!(
        EnvMap::constant(Vec3::new(1.0, 2.0, 3.0)).lookup(DVec3::X),
        [1.0, 2.0, 3.0]
    );
}

#[test]
fn exr_round_trip_f32_and_half() {
    let (w, h) = (8usize, 4usize);
    // Multiples of 1/8 below 16 are exact in f16.
    let value = |x: usize, y: usize| [x as f32 / 8.0, y as f32, (x + y) as f32 * 0.125 + 1.0];
    let scale = Vec3::new(2.0, 1.0, 0.5);

    let f32_path = tmp_path("rgb32.exr");
    write_rgb_f32(&f32_path, w, h, value);
    let half_path = tmp_path("rgb16.exr");
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let p = value(x, y);
        (
            f16::from_f32(p[0]),
            f16::from_f32(p[1]),
            f16::from_f32(p[2]),
        )
    });
    Image::from_encoded_channels((w, h), Encoding::SMALL_LOSSLESS, channels)
        .write()
        .to_file(&half_path)
        .unwrap();
    // RGBA: alpha is ignored.
    let rgba_path = tmp_path("rgba32.exr");
    let channels = SpecificChannels::rgba(|Vec2(x, y): Vec2<usize>| {
        let p = value(x, y);
        (p[0], p[1], p[2], 0.25f32)
    });
    Image::from_encoded_channels((w, h), Encoding::UNCOMPRESSED, channels)
        .write()
        .to_file(&rgba_path)
        .unwrap();

    for path in [&f32_path, &half_path, &rgba_path] {
        let map = EnvMap::load_exr(path, scale).unwrap();
        assert_eq!((map.width, map.height), (w as u32, h as u32));
        for y in 0..h {
            for x in 0..w {
                let p = value(x, y);
                let want = [p[0] * 2.0, p[1], p[2] * 0.5];
                assert_eq!(map.texels[y * w + x], want, "{} ({x}, {y})", path.display());
            }
        }
    }
}

#[test]
fn bad_exr_files_name_the_file_and_pixel() {
    let missing = tmp_path("does-not-exist.exr");
    let e = err_string(EnvMap::load_exr(&missing, Vec3::ONE));
    assert!(e.contains("does-not-exist.exr"), "{e}");

    let nan = tmp_path("nan.exr");
    write_rgb_f32(&nan, 6, 3, |x, y| {
        if (x, y) == (4, 1) {
            [1.0, f32::NAN, 1.0]
        } else {
            [1.0; 3]
        }
    });
    let e = err_string(EnvMap::load_exr(&nan, Vec3::ONE));
    assert!(
        e.contains("nan.exr") && e.contains("(4, 1)") && e.contains("NaN"),
        "{e}"
    );

    let neg = tmp_path("negative.exr");
    write_rgb_f32(&neg, 6, 3, |x, y| {
        if (x, y) == (0, 2) {
            [1.0, 1.0, -0.5]
        } else {
            [1.0; 3]
        }
    });
    let e = err_string(EnvMap::load_exr(&neg, Vec3::ONE));
    assert!(
        e.contains("negative.exr") && e.contains("(0, 2)") && e.contains("-0.5"),
        "{e}"
    );

    let inf = tmp_path("inf.exr");
    write_rgb_f32(&inf, 2, 2, |x, y| {
        if (x, y) == (1, 0) {
            [f32::INFINITY, 1.0, 1.0]
        } else {
            [1.0; 3]
        }
    });
    let e = err_string(EnvMap::load_exr(&inf, Vec3::ONE));
    assert!(
        e.contains("inf.exr") && e.contains("(1, 0)") && e.contains("inf"),
        "{e}"
    );

    // Finite texels that overflow once scaled.
    let big = tmp_path("big.exr");
    write_rgb_f32(&big, 2, 2, |_, _| [3e38; 3]);
    let e = err_string(EnvMap::load_exr(&big, Vec3::splat(10.0)));
    assert!(e.contains("big.exr") && e.contains("(0, 0)"), "{e}");

    // A single luminance channel is not RGB.
    let gray = tmp_path("gray.exr");
    let channels = SpecificChannels::build()
        .with_channel("Y")
        .with_pixel_fn(|_: Vec2<usize>| (1.0f32,));
    Image::from_encoded_channels((4, 2), Encoding::UNCOMPRESSED, channels)
        .write()
        .to_file(&gray)
        .unwrap();
    let e = err_string(EnvMap::load_exr(&gray, Vec3::ONE));
    assert!(e.contains("gray.exr") && e.contains("R, G, B"), "{e}");

    // Too wide.
    let wide = tmp_path("wide.exr");
    write_rgb_f32(&wide, 16385, 1, |_, _| [0.0; 3]);
    let e = err_string(EnvMap::load_exr(&wide, Vec3::ONE));
    assert!(e.contains("wide.exr") && e.contains("16385"), "{e}");

    // Bad scale.
    let ok = tmp_path("ok.exr");
    write_rgb_f32(&ok, 2, 1, |_, _| [1.0; 3]);
    let e = err_string(EnvMap::load_exr(&ok, Vec3::new(1.0, -1.0, 1.0)));
    assert!(e.contains("ok.exr") && e.contains("scale"), "{e}");
}

#[test]
fn pdf_integrates_to_one_over_the_sphere() {
    // Midpoint rule on a (θ, φ) grid of 16×16 cells per texel, aligned with the texel
    // edges (θ = πy/H, φ = −π + 2πx/W): the pdf jumps at texel edges, and an unaligned
    // 3000×1500 grid misplaces enough of the sun texel's mass to err by 0.5%. Inside a
    // cell pdf·sin θ is constant, so the rule measures the pdf's normalization and
    // Jacobian, not quadrature error.
    let maps = [
        ("sun+sky", sun_sky_map()),
        ("constant", EnvMap::constant(Vec3::new(0.5, 1.0, 2.0))),
        (
            "black 5×3",
            EnvMap {
                width: 5,
                height: 3,
                texels: vec![[0.0; 3]; 15],
            },
        ),
    ];
    for (name, map) in maps {
        let s = EnvSampler::new(&map);
        let (nt, np) = (16 * map.height as usize, 16 * map.width as usize);
        let (dt, dp) = (PI / nt as f64, 2.0 * PI / np as f64);
        let mut total = 0.0;
        for i in 0..nt {
            let t = (i as f64 + 0.5) * dt;
            let mut row = 0.0;
            for j in 0..np {
                let p = -PI + (j as f64 + 0.5) * dp;
                row += s.pdf(dir_theta_phi(t, p));
            }
            total += row * t.sin() * dt * dp;
        }
        println!("{name}: ∫ pdf dω = {total:.9}");
        assert!((total - 1.0).abs() < 1e-3, "{name}: ∫ pdf dω = {total}");
    }
}

#[test]
fn sample_pdf_matches_pdf_and_invert_round_trips() {
    let map = sun_sky_map();
    let s = EnvSampler::new(&map);
    let mut rng = Rng(7);
    let mut worst = 0.0f64;
    for _ in 0..200_000 {
        let u = rng.u2();
        let (d, pdf) = s.sample(u);
        assert!(d.is_finite() && (d.length() - 1.0).abs() < 1e-12);
        assert!(pdf > 0.0 && pdf.is_finite(), "u {u:?}: pdf {pdf}");
        let p = s.pdf(d);
        let rel = (p - pdf).abs() / pdf;
        worst = worst.max(rel);
        assert!(rel < 1e-6, "u {u:?}: sample pdf {pdf}, pdf() {p}");
        // Never samples the black ground (rows 28..32 start at θ = 7π/8).
        assert!(d.y.acos() < 7.0 * PI / 8.0 + 1e-12, "{d}");
        let back = s.invert(d);
        assert!(
            (back[0] - u[0]).abs() < 1e-9 && (back[1] - u[1]).abs() < 1e-9,
            "u {u:?} -> {d} -> {back:?}"
        );
    }
    println!("max relative |pdf(sample) − sample pdf| = {worst:e}");
    // Black texels have pdf 0.
    assert_eq!(s.pdf(DVec3::NEG_Y), 0.0);
    assert_eq!(s.pdf(DVec3::new(0.3, -0.95, 0.1)), 0.0);
    assert_eq!(s.pdf(DVec3::Y), 0.0);
}

#[test]
fn chi_square_of_samples_against_integrated_pdf() {
    let map = sun_sky_map();
    let s = EnvSampler::new(&map);
    const N_PHI: usize = 16;
    const N_THETA: usize = 8;
    const SAMPLES: usize = 200_000;

    // Bin samples by (θ, φ) computed from the direction.
    let mut observed = [0u64; N_PHI * N_THETA];
    let mut rng = Rng(42);
    for _ in 0..SAMPLES {
        let (d, _) = s.sample(rng.u2());
        let theta = d.y.clamp(-1.0, 1.0).acos();
        let phi = d.x.atan2(-d.z);
        let it = ((theta / PI * N_THETA as f64) as usize).min(N_THETA - 1);
        let ip = (((phi + PI) / (2.0 * PI) * N_PHI as f64) as usize).min(N_PHI - 1);
        observed[it * N_PHI + ip] += 1;
    }
    // Expected counts from the pdf integrated over each bin (64×64 midpoint grid).
    let mut expected = [0.0f64; N_PHI * N_THETA];
    for it in 0..N_THETA {
        for ip in 0..N_PHI {
            let t = (
                PI * it as f64 / N_THETA as f64,
                PI * (it + 1) as f64 / N_THETA as f64,
            );
            let p = (
                -PI + 2.0 * PI * ip as f64 / N_PHI as f64,
                -PI + 2.0 * PI * (ip + 1) as f64 / N_PHI as f64,
            );
            expected[it * N_PHI + ip] = SAMPLES as f64 * integrate_pdf(&s, t, p, 64);
        }
    }
    let total: f64 = expected.iter().sum();
    assert!((total / SAMPLES as f64 - 1.0).abs() < 1e-6, "{total}");

    // Pool bins expected below 5; bins of zero probability must stay empty.
    let (mut chi2, mut bins) = (0.0, 0usize);
    let (mut pooled_obs, mut pooled_exp) = (0.0, 0.0);
    for (&o, &e) in observed.iter().zip(&expected) {
        if e == 0.0 {
            assert_eq!(o, 0, "sample in a zero-pdf bin");
        } else if e < 5.0 {
            pooled_obs += o as f64;
            pooled_exp += e;
        } else {
            chi2 += (o as f64 - e).powi(2) / e;
            bins += 1;
        }
    }
    if pooled_exp > 0.0 {
        chi2 += (pooled_obs - pooled_exp).powi(2) / pooled_exp;
        bins += 1;
    }
    let dof = bins - 1;
    // Upper 1e-3 quantile of χ²(dof) by Wilson–Hilferty (z = 3.090232; accurate to
    // ~0.1% at these dof): 112 bins → dof 111 → 162.8.
    let k = dof as f64;
    let z = 3.090_232;
    let critical = k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3);
    println!("χ² = {chi2:.2}, dof = {dof}, critical (α = 1e-3) = {critical:.2}");
    assert!(chi2 < critical, "χ² {chi2} >= {critical} (dof {dof})");
}

#[test]
fn monte_carlo_integral_matches_texel_sum() {
    let map = sun_sky_map();
    let s = EnvSampler::new(&map);
    let (w, h) = (map.width, map.height);
    // Exact ∫ L dω = Σ texel · solid angle.
    let mut exact = [0.0f64; 3];
    for y in 0..h {
        let omega = texel_solid_angle(y, w, h);
        for x in 0..w {
            let texel = map.texels[(y * w + x) as usize];
            for (e, t) in exact.iter_mut().zip(texel) {
                *e += t as f64 * omega;
            }
        }
    }
    const N: usize = 200_000;
    let mut rng = Rng(99);
    let (mut sum, mut sum2) = ([0.0f64; 3], [0.0f64; 3]);
    for _ in 0..N {
        let (d, pdf) = s.sample(rng.u2());
        if pdf == 0.0 {
            continue;
        }
        let l = map.lookup(d);
        for c in 0..3 {
            let f = l[c] as f64 / pdf;
            sum[c] += f;
            sum2[c] += f * f;
        }
    }
    for c in 0..3 {
        let mean = sum[c] / N as f64;
        let var = (sum2[c] / N as f64 - mean * mean).max(0.0);
        let se = (var / N as f64).sqrt();
        println!(
            "channel {c}: MC {mean:.6} ± {se:.6}, exact {:.6}, |Δ|/SE = {:.2}",
            exact[c],
            (mean - exact[c]).abs() / se
        );
        assert!((mean - exact[c]).abs() < 4.0 * se, "channel {c}");
    }
}

#[test]
fn sampling_is_deterministic() {
    let map = sun_sky_map();
    let (a, b) = (EnvSampler::new(&map), EnvSampler::new(&map));
    assert_eq!(a, b);
    let mut r1 = Rng(5);
    let mut r2 = Rng(5);
    for _ in 0..1000 {
        let (da, pa) = a.sample(r1.u2());
        let (db, pb) = b.sample(r2.u2());
        assert_eq!(
            da.to_array().map(f64::to_bits),
            db.to_array().map(f64::to_bits)
        );
        assert_eq!(pa.to_bits(), pb.to_bits());
    }
    assert_eq!(a.to_gpu_tables(), b.to_gpu_tables());
}

#[test]
fn black_map_falls_back_without_nan() {
    let map = EnvMap {
        width: 8,
        height: 4,
        texels: vec![[0.0; 3]; 32],
    };
    let s = EnvSampler::new(&map);
    assert!(s.is_black());
    assert_eq!(s.integral(), 0.0);
    let mut rng = Rng(3);
    for _ in 0..10_000 {
        let u = rng.u2();
        let (d, pdf) = s.sample(u);
        assert!(d.is_finite() && pdf.is_finite() && pdf > 0.0, "{u:?}");
        assert!((s.pdf(d) - pdf).abs() <= 1e-6 * pdf);
    }
    // Edge uniforms, including exactly 0 (pole: pdf 0) and 1 (clamped below 1).
    for u in [[0.0, 0.0], [1.0, 1.0], [0.0, 1.0], [1.0, 0.0], [0.5, 0.5]] {
        let (d, pdf) = s.sample(u);
        assert!(d.is_finite() && pdf.is_finite() && pdf >= 0.0, "{u:?}");
    }
    assert!(!EnvSampler::new(&EnvMap::constant(Vec3::ONE)).is_black());
}

#[test]
fn gpu_tables_layout() {
    let map = sun_sky_map();
    let s = EnvSampler::new(&map);
    let (w, h) = (map.width as usize, map.height as usize);
    let (marginal, conditional) = s.to_gpu_tables();
    assert_eq!(marginal.len(), h + 1);
    assert_eq!(conditional.len(), h * (w + 1));
    assert_eq!((marginal[0], marginal[h]), (0.0, 1.0));
    assert!(marginal.windows(2).all(|p| p[0] <= p[1]));
    for y in 0..h {
        let row = &conditional[y * (w + 1)..(y + 1) * (w + 1)];
        assert_eq!((row[0], row[w]), (0.0, 1.0), "row {y}");
        assert!(row.windows(2).all(|p| p[0] <= p[1]), "row {y}");
        assert_eq!(
            row,
            s.conditional_cdf(y as u32)
                .iter()
                .map(|&c| c as f32)
                .collect::<Vec<_>>()
        );
    }
    // The black ground rows have zero marginal probability.
    assert_eq!(marginal[28], 1.0);
    // The pdf from table differences matches the sampler (f32 precision).
    let x = 40;
    let y = 9;
    let pdf_uv = (w * h) as f64
        * (marginal[y + 1] - marginal[y]) as f64
        * (conditional[y * (w + 1) + x + 1] - conditional[y * (w + 1) + x]) as f64;
    let d = uv_to_direction((x as f64 + 0.5) / w as f64, (y as f64 + 0.5) / h as f64);
    let sin_theta = (PI * (y as f64 + 0.5) / h as f64).sin();
    let want = s.pdf(d) * 2.0 * PI * PI * sin_theta;
    assert!((pdf_uv - want).abs() < 1e-4 * want, "{pdf_uv} vs {want}");
}

/// The rotation's convention (docs/scene-format.md): positive turns +X towards −Z about
/// +Y, and u = frac(0.5 + atan2(d.x, −d.z)/(2π) + θ/360°) of world direction d; exact
/// at multiples of 90°, and the identity leaves every direction bit for bit.
#[test]
fn rotation_convention_and_exact_quarter_turns() {
    let r = |deg: f64| EnvRotation::from_degrees(deg);
    for (deg, cos, sin) in [
        (0.0, 1.0, 0.0),
        (-0.0, 1.0, 0.0),
        (90.0, 0.0, 1.0),
        (180.0, -1.0, 0.0),
        (270.0, 0.0, -1.0),
        (-90.0, 0.0, -1.0),
        (360.0, 1.0, 0.0),
        (450.0, 0.0, 1.0),
        (-720.0, 1.0, 0.0),
    ] {
        let got = r(deg);
        assert_eq!((got.cos, got.sin), (cos, sin), "{deg}");
        // No −0: 0° and 180° are (±1, +0) exactly.
        assert!(got.sin.is_sign_positive() || got.sin < 0.0, "{deg}");
    }
    assert!(r(0.0).is_identity() && r(360.0).is_identity() && !r(1e-9).is_identity());
    assert!(r(f64::NAN).is_identity());
    for deg in [1.0, 33.3, 89.999, 135.0, 200.5, 300.0, 359.9, -47.0] {
        let got = r(deg);
        let (s, c) = deg.to_radians().sin_cos();
        assert!(
            (got.cos - c).abs() < 1e-15 && (got.sin - s).abs() < 1e-15,
            "{deg}"
        );
    }
    // +X turns towards −Z: the map's +X (u = 0.75) is seen at world −Z.
    let quarter = r(90.0);
    assert_eq!(quarter.map_to_world(DVec3::X), DVec3::NEG_Z);
    assert_eq!(quarter.world_to_map(DVec3::NEG_Z), DVec3::X);
    assert_eq!(quarter.map_to_world(DVec3::Y), DVec3::Y);
    // u of world d is the unrotated u plus θ/360°, wrapped.
    let mut rng = Rng(9);
    for deg in [90.0, -30.0, 123.4, 400.0] {
        let rot = r(deg);
        for _ in 0..200 {
            let d = rng.unit_vector();
            let (u, v) = direction_to_uv(rot.world_to_map(d));
            let (u0, v0) = direction_to_uv(d);
            let want = (u0 + deg / 360.0).rem_euclid(1.0);
            let du = (u - want).abs();
            assert!(du.min(1.0 - du) < 1e-9, "{deg}: u {u} vs {want}");
            assert!((v - v0).abs() < 1e-12);
            let back = rot.map_to_world(rot.world_to_map(d));
            assert!((back - d).length() < 1e-12);
        }
    }
    // The identity is bit-exact, signed zeros too.
    let d = DVec3::new(-0.0, 1.0, -0.0);
    let same = EnvRotation::IDENTITY.world_to_map(d);
    assert!(same.x.is_sign_negative() && same.z.is_sign_negative());
}

/// A map turned by 90° looks up what the map with its columns shifted a quarter turn
/// shows unturned, and its sampler's pdf of the turned direction is the shifted map's.
#[test]
fn a_quarter_turn_is_the_map_shifted_a_quarter() {
    let map = sun_sky_map();
    let (w, h) = (map.width as usize, map.height as usize);
    // shifted(u) = map(u + 1/4): column x of the shifted map is column x + W/4.
    let shifted = EnvMap {
        width: map.width,
        height: map.height,
        texels: (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                map.texels[y * w + (x + w / 4) % w]
            })
            .collect(),
    };
    let rot = EnvRotation::from_degrees(90.0);
    let (sampler, shifted_sampler) = (EnvSampler::new(&map), EnvSampler::new(&shifted));
    let mut rng = Rng(4);
    let mut checked = 0;
    for _ in 0..20_000 {
        let d = rng.unit_vector();
        // Away from texel edges, where f64 rounding may pick either side.
        let (u, v) = direction_to_uv(d);
        let (fx, fy) = ((u * w as f64).fract(), (v * h as f64).fract());
        if fx.min(1.0 - fx) < 1e-6 || fy.min(1.0 - fy) < 1e-6 {
            continue;
        }
        checked += 1;
        assert_eq!(map.lookup(rot.world_to_map(d)), shifted.lookup(d), "{d}");
        let (p, q) = (sampler.pdf(rot.world_to_map(d)), shifted_sampler.pdf(d));
        assert!((p - q).abs() <= 1e-9 * q.max(1e-300), "{d}: pdf {p} vs {q}");
        // The wrong sign would look elsewhere: the sun texel shows that.
    }
    assert!(checked > 19_000);
    let wrong = EnvRotation::from_degrees(-90.0);
    let sun = uv_to_direction((40.5 - 16.0) / w as f64, 9.5 / h as f64);
    assert_eq!(shifted.lookup(sun), [9000.0, 8000.0, 6500.0]);
    assert_eq!(map.lookup(rot.world_to_map(sun)), [9000.0, 8000.0, 6500.0]);
    assert_ne!(
        map.lookup(wrong.world_to_map(sun)),
        [9000.0, 8000.0, 6500.0]
    );
}

/// The scene's map rotation: the environment light with a `file`; identity for a
/// constant environment or none.
#[test]
fn environment_rotation_comes_from_the_map_light() {
    let env = |file: Option<&str>, deg: f32| Light::Environment {
        radiance: Vec3::ONE,
        file: file.map(PathBuf::from),
        scale: Vec3::ONE,
        rotation_deg: deg,
    };
    assert!(environment_rotation(&[]).is_identity());
    assert!(environment_rotation(&[env(None, 90.0)]).is_identity());
    let r = environment_rotation(&[env(None, 10.0), env(Some("sky.exr"), 90.0)]);
    assert_eq!((r.cos, r.sin), (0.0, 1.0));
}

/// The camera's background is the map interpolated between texel centres: a texel's
/// centre shows that texel, halfway between two columns their mean (across the u seam
/// too), halfway between two rows their mean, and beyond the first and last rows' centres
/// the row itself; a constant map stays constant.
#[test]
fn the_bilinear_background_interpolates_between_texel_centres() {
    // 4 x 2 texels, each its own value.
    let map = EnvMap {
        width: 4,
        height: 2,
        texels: (0..8).map(|i| [i as f32, 10.0 * i as f32, 1.0]).collect(),
    };
    let at = |u: f64, v: f64| map.lookup_bilinear(uv_to_direction(u, v))[0];
    let close = |a: f32, b: f32| (a - b).abs() < 1e-4;
    // Texel centres: (x + 0.5) / 4, (y + 0.5) / 2.
    assert!(close(at(0.125, 0.25), 0.0));
    assert!(close(at(0.625, 0.75), 6.0));
    // Halfway between columns 1 and 2 of row 0, and across the seam (3 and 0).
    assert!(close(at(0.5, 0.25), 1.5));
    assert!(close(at(0.0, 0.25), 1.5));
    assert!(close(at(0.999_999, 0.25), 1.5));
    // Halfway between rows at column 1: (1 + 5) / 2.
    assert!(close(at(0.375, 0.5), 3.0));
    // Above the first row's centre and below the last row's: the row.
    assert!(close(at(0.375, 0.1), 1.0));
    assert!(close(at(0.375, 0.9), 5.0));
    let flat = EnvMap::constant(Vec3::new(1.0, 2.0, 3.0));
    assert_eq!(
        flat.lookup_bilinear(DVec3::new(0.3, -0.2, 0.9)),
        [1.0, 2.0, 3.0]
    );
}
