//! Denoises synthetic noisy images whose clean version is known, and checks that OIDN
//! at least halves the RMS error; and that bad inputs are refused with a clear error.

use nimbus_oidn::{denoise, Denoiser};

const W: u32 = 192;
const H: u32 = 128;

/// A smooth HDR image: gradients plus a low-frequency ripple, brighter than 1 in places.
fn clean(w: u32, h: u32) -> Vec<f32> {
    let mut image = Vec::with_capacity((w * h * 3) as usize);
    for y in 0..h {
        for x in 0..w {
            let u = x as f32 / w as f32;
            let v = y as f32 / h as f32;
            let ripple = 0.25 * (6.0 * u).sin() * (4.0 * v).cos();
            image.push(0.2 + 1.2 * u + ripple);
            image.push(0.3 + 0.8 * v + 0.5 * ripple);
            image.push(0.6 + 0.2 * (u + v));
        }
    }
    image
}

/// Monte-Carlo-like noise: each pixel is the mean of `spp` samples of value * e/E[e]
/// with e exponential (a heavy right tail, like a path tracer's), from a fixed seed.
fn noisy(clean: &[f32], spp: u32, seed: u64) -> Vec<f32> {
    let mut state = seed | 1;
    let mut uniform = move || {
        // xorshift64*
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        let bits = state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 40;
        (bits as f32 + 0.5) / (1u64 << 24) as f32
    };
    clean
        .chunks(3)
        .flat_map(|rgb| {
            // One path throughput per sample, shared by the channels (luminance noise).
            let mut weight = 0.0;
            for _ in 0..spp {
                weight += -uniform().ln();
            }
            let weight = weight / spp as f32;
            rgb.iter().map(move |c| c * weight).collect::<Vec<_>>()
        })
        .collect()
}

fn rmse(a: &[f32], b: &[f32]) -> f64 {
    assert_eq!(a.len(), b.len());
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2))
        .sum();
    (sum / a.len() as f64).sqrt()
}

#[test]
fn hdr_denoise_at_least_halves_the_error() {
    let reference = clean(W, H);
    let input = noisy(&reference, 4, 0x5eed);
    let before = rmse(&input, &reference);
    let output = denoise(W, H, &input, None, None, true).unwrap();
    let after = rmse(&output, &reference);
    eprintln!(
        "hdr: rmse noisy {before:.4} -> denoised {after:.4} ({:.1}x)",
        before / after
    );
    assert!(before > 0.1, "the test image is not noisy enough: {before}");
    assert!(
        after * 2.0 <= before,
        "rmse {before} -> {after}: less than halved"
    );
    assert!(output.iter().all(|v| v.is_finite()));
}

#[test]
fn albedo_and_normal_are_used_and_still_halve_the_error() {
    let reference = clean(W, H);
    let input = noisy(&reference, 4, 0xa1bed0);
    // A constant-material scene: albedo = clean color normalised, normals facing +z.
    let albedo: Vec<f32> = reference.iter().map(|c| (c / 2.0).min(1.0)).collect();
    let normal: Vec<f32> = (0..W * H).flat_map(|_| [0.0, 0.0, 1.0]).collect();
    let denoiser = Denoiser::new().unwrap();
    let with_albedo = denoiser
        .denoise(W, H, &input, Some(&albedo), None, true)
        .unwrap();
    let with_both = denoiser
        .denoise(W, H, &input, Some(&albedo), Some(&normal), true)
        .unwrap();
    let plain = denoiser.denoise(W, H, &input, None, None, true).unwrap();
    let before = rmse(&input, &reference);
    for (name, out) in [("albedo", &with_albedo), ("albedo+normal", &with_both)] {
        let after = rmse(out, &reference);
        eprintln!("{name}: rmse noisy {before:.4} -> denoised {after:.4}");
        assert!(after * 2.0 <= before, "{name}: rmse {before} -> {after}");
        // The feature images reach the filter: the result differs from the plain one.
        assert!(
            rmse(out, &plain) > 1e-4,
            "{name}: identical to the plain result"
        );
    }
}

#[test]
fn ldr_denoise_at_least_halves_the_error() {
    let reference: Vec<f32> = clean(W, H).iter().map(|c| (c * 0.4).min(1.0)).collect();
    let input: Vec<f32> = noisy(&reference, 8, 0x1d2)
        .into_iter()
        .map(|c| c.min(1.0))
        .collect();
    let before = rmse(&input, &reference);
    let output = Denoiser::cpu()
        .unwrap()
        .denoise(W, H, &input, None, None, false)
        .unwrap();
    let after = rmse(&output, &reference);
    eprintln!("ldr: rmse noisy {before:.4} -> denoised {after:.4}");
    assert!(after * 2.0 <= before, "rmse {before} -> {after}");
}

#[test]
fn bad_inputs_are_refused_with_what_and_where() {
    let d = Denoiser::cpu().unwrap();
    let ok = vec![0.5_f32; 4 * 2 * 3];
    let err = |r: anyhow::Result<Vec<f32>>| format!("{:#}", r.unwrap_err());

    let e = err(d.denoise(4, 2, &ok[..21], None, None, true));
    assert!(e.contains("color image has 21 floats; 24 expected"), "{e}");
    let e = err(d.denoise(0, 2, &[], None, None, true));
    assert!(e.contains("0x2"), "{e}");
    let mut nan = ok.clone();
    nan[3 * 5 + 1] = f32::NAN;
    let e = err(d.denoise(4, 2, &nan, None, None, true));
    assert!(
        e.contains("color image has NaN at pixel (1, 1) channel 1"),
        "{e}"
    );
    let mut neg = ok.clone();
    neg[0] = -1.0;
    let e = err(d.denoise(4, 2, &neg, None, None, true));
    assert!(e.contains("finite values >= 0"), "{e}");
    let mut bright = ok.clone();
    bright[2] = 1.5;
    let e = err(d.denoise(4, 2, &bright, None, None, false));
    assert!(e.contains("values in [0, 1]"), "{e}");
    let e = err(d.denoise(4, 2, &ok, Some(&ok[..3]), None, true));
    assert!(e.contains("albedo image has 3 floats"), "{e}");
    let e = err(d.denoise(4, 2, &ok, None, Some(&ok), true));
    assert!(
        e.contains("normal image was given without an albedo"),
        "{e}"
    );
    // An HDR value above 1 is fine.
    assert_eq!(
        d.denoise(4, 2, &bright, None, None, true).unwrap().len(),
        24
    );
}
