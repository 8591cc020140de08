//! `nimbus render --denoise` (issue 28, item 2; `docs/denoise.md`): the denoiser keeps a
//! constant image constant and a guided edge sharp, halves the error of a noisy render
//! against its converged reference, accumulates a sequence over time, stays finite on
//! degenerate inputs; the CLI writes the denoised RGBA with the noisy image as the layer
//! `noisy`. Its pipelines match their SPIR-V.

use nimbus::denoise::{
    denoise, nrmse, pipeline_contracts, DenoiseParams, Denoised, Denoiser, Guides, NoisyImage,
    VarianceSource,
};
use nimbus::output::{read_layers, ImageRgb};
use nimbus_gpu::Context;

use crate::common::cli::{nimbus, scratch, text};
use crate::common::gpu::{assert_no_validation_errors, context, render_checked, scene};
use crate::common::rng::Pcg32 as Rng;

/// An image with its alpha and standard errors, owned.
struct Image {
    color: ImageRgb,
    alpha: Vec<f32>,
    std_error: ImageRgb,
    alpha_std_error: Vec<f32>,
    estimates: u32,
}

impl Image {
    /// `w` x `h` pixels of `f(x, y)` (grey), opaque, each with standard error `se` from
    /// `estimates` estimates.
    fn grey(w: u32, h: u32, se: f32, estimates: u32, f: impl Fn(u32, u32) -> f32) -> Image {
        let n = (w * h) as usize;
        Image {
            color: ImageRgb {
                width: w,
                height: h,
                data: (0..n)
                    .map(|i| {
                        let v = f(i as u32 % w, i as u32 / w);
                        [v, v, v]
                    })
                    .collect(),
            },
            alpha: vec![1.0; n],
            std_error: ImageRgb {
                width: w,
                height: h,
                data: vec![[se; 3]; n],
            },
            alpha_std_error: vec![0.0; n],
            estimates,
        }
    }

    fn noisy(&self) -> NoisyImage<'_> {
        NoisyImage {
            color: &self.color,
            alpha: &self.alpha,
            std_error: &self.std_error,
            alpha_std_error: &self.alpha_std_error,
            estimates: self.estimates,
        }
    }
}

fn run(ctx: &Context, image: &Image, guides: &Guides) -> Denoised {
    let out = denoise(ctx, &image.noisy(), guides, DenoiseParams::default()).unwrap();
    assert_no_validation_errors(ctx);
    assert_eq!(out.color.data.len(), image.color.data.len());
    assert!(
        out.color.data.iter().flatten().all(|v| v.is_finite())
            && out.alpha.iter().all(|v| v.is_finite()),
        "the denoised image is not finite"
    );
    out
}

/// Guides of two regions split at column `split`: depth 1 and 3, normals +z and +x,
/// albedo 0.8.
fn two_region_guides(w: u32, h: u32, split: u32) -> Guides {
    let n = (w * h) as usize;
    let left = |i: usize| (i as u32 % w) < split;
    Guides {
        depth: Some((0..n).map(|i| if left(i) { 1.0 } else { 3.0 }).collect()),
        normal: Some([
            (0..n).map(|i| if left(i) { 0.0 } else { 1.0 }).collect(),
            vec![0.0; n],
            (0..n).map(|i| if left(i) { 1.0 } else { 0.0 }).collect(),
        ]),
        albedo: Some([vec![0.8; n], vec![0.8; n], vec![0.8; n]]),
        motion: None,
    }
}

#[test]
fn a_constant_image_stays_constant() {
    let ctx = context();
    let c = [0.3f32, 0.5, 0.7];
    for (se, estimates) in [(0.0, 1), (0.2, 8)] {
        let mut image = Image::grey(40, 30, se, estimates, |_, _| 0.0);
        image.color.data.iter_mut().for_each(|p| *p = c);
        for guides in [Guides::none(), two_region_guides(40, 30, 17)] {
            let out = run(&ctx, &image, &guides);
            assert_eq!(
                out.variance,
                if estimates > 1 {
                    VarianceSource::Film
                } else {
                    VarianceSource::Estimated
                }
            );
            for (p, a) in out.color.data.iter().zip(&out.alpha) {
                for k in 0..3 {
                    assert!((p[k] - c[k]).abs() <= 1e-5 * c[k], "{p:?} from {c:?}");
                }
                assert!((a - 1.0).abs() <= 1e-6, "alpha {a}");
            }
        }
    }
}

/// Two regions of close brightness (0.5 | 0.6) with noise of standard deviation 0.05:
/// with depth and normal guides the edge stays sharp (each side's columns next to it
/// keep their level) while the noise drops; without guides the luminance alone cannot
/// tell the edge from the noise, and the levels bleed into each other.
#[test]
fn a_hard_edge_stays_sharp_with_guides() {
    let ctx = context();
    let (w, h, split) = (48u32, 64u32, 24u32);
    let mut rng = Rng::new(28);
    let noise: Vec<f32> = (0..w * h)
        .map(|_| 0.05 * 3f32.sqrt() * (2.0 * rng.uniform_f32() - 1.0))
        .collect();
    let level = |x: u32| if x < split { 0.5 } else { 0.6 };
    let image = Image::grey(w, h, 0.05, 8, |x, y| level(x) + noise[(y * w + x) as usize]);
    let column_mean = |img: &ImageRgb, x: u32| {
        (0..h)
            .map(|y| img.data[(y * w + x) as usize][0])
            .sum::<f32>()
            / h as f32
    };
    let rms_error = |img: &ImageRgb| {
        let se: f32 = (0..w * h)
            .map(|i| (img.data[i as usize][0] - level(i % w)).powi(2))
            .sum();
        (se / (w * h) as f32).sqrt()
    };
    let guided = run(&ctx, &image, &two_region_guides(w, h, split));
    let bare = run(&ctx, &image, &Guides::none());
    let step = |img: &ImageRgb| column_mean(img, split) - column_mean(img, split - 1);
    assert!(
        (step(&guided.color) - 0.1).abs() < 0.02,
        "guided: the step across the edge is {} (0.1 in the image)",
        step(&guided.color)
    );
    assert!(
        step(&bare.color) < 0.07,
        "unguided: the step is {}, so the test's edge is no test of the guides",
        step(&bare.color)
    );
    let (before, after) = (rms_error(&image.color), rms_error(&guided.color));
    assert!(
        after < 0.5 * before,
        "guided: RMS error {after} after, {before} before"
    );
}

/// A small cloud (baseline path tracer): one frame of 4 spp against 64 frames of 16 spp.
const CLOUD: &str = r#"
[render]
width = 40
height = 30
frames = 1
spp = 16
seed = 11
[camera]
position = [0.0, 0.2, 2.4]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 50
[[light]]
type = "directional"
direction = [0.6, -0.5, -0.6]
irradiance = [6.0, 5.6, 5.0]
[[light]]
type = "environment"
radiance = [0.25, 0.35, 0.55]
[[medium]]
type = "grid"
bounds_min = [-1.0, -0.6, -1.0]
bounds_max = [1.0, 0.6, 1.0]
density = { procedural = "cloud", dims = [16, 10, 16], noise_seed = 7 }
density_scale = 12.0
albedo = 0.95
[integrator]
volume = "baseline"
max_bounces = 3
# The noise this test was made for (split NEE halves it, and the denoiser's gain on it).
[integrator.baseline]
nee = "one"
"#;

#[test]
fn denoising_halves_the_error_of_a_noisy_render() {
    let ctx = context();
    let noisy = render_checked(
        &ctx,
        &scene(&CLOUD.replace("spp = 16", "spp = 4"), "cloud.toml"),
        None,
    );
    let reference = render_checked(
        &ctx,
        &scene(
            &CLOUD
                .replace("frames = 1", "frames = 64")
                .replace("seed = 11", "seed = 1000"),
            "cloud-reference.toml",
        ),
        None,
    );
    let out = run(
        &ctx,
        &Image {
            color: noisy.image.clone(),
            alpha: noisy.alpha.clone(),
            std_error: noisy.std_error.clone(),
            alpha_std_error: noisy.alpha_std_error.clone(),
            estimates: noisy.estimates,
        },
        &Guides::none(),
    );
    let before = nrmse(&noisy.image, &reference.image).unwrap();
    let after = nrmse(&out.color, &reference.image).unwrap();
    eprintln!("nRMSE {after:.4} denoised, {before:.4} noisy");
    assert!(
        after <= 0.5 * before,
        "nRMSE {after:.4} denoised, {before:.4} noisy"
    );
}

/// A sequence of frames of a still image, each with fresh noise and zero motion: the
/// temporal history lowers the error frame by frame; a denoiser without motion (no
/// history) does not.
#[test]
fn a_sequence_accumulates_through_the_motion_vectors() {
    let ctx = context();
    let (w, h) = (32u32, 24u32);
    let n = (w * h) as usize;
    let truth = |x: u32, y: u32| 0.2 + 0.6 * (x as f32 / w as f32) + 0.1 * (y as f32 / h as f32);
    let mut rng = Rng::new(7);
    let still = Guides {
        motion: Some([vec![0.0; n], vec![0.0; n]]),
        ..Guides::none()
    };
    let mut temporal = Denoiser::new(DenoiseParams::default()).unwrap();
    let mut spatial = Denoiser::new(DenoiseParams::default()).unwrap();
    let error = |img: &ImageRgb| {
        let se: f32 = (0..n)
            .map(|i| (img.data[i][0] - truth(i as u32 % w, i as u32 / w)).powi(2))
            .sum();
        (se / n as f32).sqrt()
    };
    let mut errors = Vec::new();
    for frame in 0..8 {
        let noise: Vec<f32> = (0..n).map(|_| 0.3 * (rng.uniform_f32() - 0.5)).collect();
        let image = Image::grey(w, h, 0.0, 1, |x, y| {
            truth(x, y) + noise[(y * w + x) as usize]
        });
        let t = temporal.run(&ctx, &image.noisy(), &still).unwrap();
        let s = spatial.run(&ctx, &image.noisy(), &Guides::none()).unwrap();
        assert_eq!(t.temporal, frame > 0, "frame {frame}: history used");
        assert!(!s.temporal);
        errors.push((error(&t.color), error(&s.color)));
    }
    temporal.destroy(&ctx);
    spatial.destroy(&ctx);
    assert_no_validation_errors(&ctx);
    let (last_t, last_s) = errors[7];
    assert!(
        last_t < 0.6 * last_s && last_t < 0.6 * errors[0].0,
        "RMS errors per frame (temporal, spatial): {errors:?}"
    );
}

#[test]
fn degenerate_inputs_give_finite_images() {
    let ctx = context();
    let (w, h) = (20u32, 16u32);
    let n = (w * h) as usize;
    let mut rng = Rng::new(3);
    let values: Vec<f32> = (0..n).map(|_| rng.uniform_f32()).collect();
    // A black image stays black, with and without film variance.
    for estimates in [1, 4] {
        let black = Image::grey(w, h, 0.0, estimates, |_, _| 0.0);
        let out = run(&ctx, &black, &Guides::none());
        assert!(out.color.data.iter().flatten().all(|&v| v == 0.0));
    }
    // Noise that the film says has zero variance.
    let certain = Image::grey(w, h, 0.0, 8, |x, y| values[(y * w + x) as usize]);
    run(&ctx, &certain, &Guides::none());
    // Zero albedo everywhere (nothing is divided out), zero normals, no depth.
    let zero = Guides {
        depth: Some(vec![f32::INFINITY; n]),
        normal: Some([vec![0.0; n], vec![0.0; n], vec![0.0; n]]),
        albedo: Some([vec![0.0; n], vec![0.0; n], vec![0.0; n]]),
        motion: Some([vec![f32::NAN; n], vec![0.0; n]]),
    };
    let noisy = Image::grey(w, h, 0.1, 1, |x, y| values[(y * w + x) as usize]);
    run(&ctx, &noisy, &zero);
    // Non-finite pixels in the input do not spread.
    let mut bad = Image::grey(w, h, 0.1, 4, |x, y| values[(y * w + x) as usize]);
    bad.color.data[5] = [f32::NAN; 3];
    bad.color.data[50] = [f32::INFINITY; 3];
    bad.std_error.data[70] = [f32::NAN; 3];
    run(&ctx, &bad, &zero);
}

#[test]
fn the_pipelines_match_their_spirv() {
    for c in pipeline_contracts() {
        let words = nimbus::passes::spirv_words(c.spirv).unwrap();
        let layout: Vec<_> = c.bindings.iter().map(|b| (b.binding, b.ty)).collect();
        nimbus_gpu::spirv::check(&c.name, &words, &layout, &[], c.push_constant_size).unwrap();
        assert_eq!(
            nimbus_gpu::spirv::reflect(&words).push_constant_size,
            Some(c.push_constant_size),
            "{}",
            c.name
        );
    }
}

/// The CLI: the EXR's RGBA is the denoised image (the denoiser run again on its `noisy`
/// layer and its albedo layer gives it), the `noisy` layer is the render without
/// --denoise, and the guide it was steered by (the albedo) is a layer too.
#[test]
fn render_denoise_writes_the_noisy_layer() {
    let dir = scratch("denoise", "cli");
    let scene_path = dir.join("cloud.toml");
    std::fs::write(
        &scene_path,
        CLOUD
            .replace("frames = 1", "frames = 2")
            .replace("spp = 16", "spp = 4"),
    )
    .unwrap();
    let scene_arg = scene_path.to_str().unwrap();
    let plain = dir.join("plain.exr");
    let denoised = dir.join("denoised.exr");
    for (out, extra) in [(&plain, None), (&denoised, Some("--denoise"))] {
        let mut args = vec!["render", scene_arg, "--out", out.to_str().unwrap()];
        args.extend(extra);
        let o = nimbus(&args);
        assert!(o.status.success(), "{}", text(&o.stderr));
        if extra.is_some() {
            assert!(text(&o.stderr).contains("denoised"), "{}", text(&o.stderr));
        }
    }
    let plain = read_layers(&plain).unwrap();
    let layers = read_layers(&denoised).unwrap();
    let noisy = layers
        .aovs
        .iter()
        .find(|a| a.name == "noisy")
        .expect("a noisy layer");
    let channel = |name: &str| &noisy.channels.iter().find(|(c, _)| c == name).unwrap().1;
    let n = plain.color.data.len();
    for (k, name) in ["R", "G", "B"].iter().enumerate() {
        let values = channel(name);
        assert_eq!(values.len(), n);
        for (i, (v, p)) in values.iter().zip(&plain.color.data).enumerate() {
            assert_eq!(*v, p[k], "noisy.{name} at {i}");
        }
    }
    assert_eq!(channel("A"), &plain.alpha);
    assert!(layers.attributes.contains_key("denoise"));
    assert_ne!(layers.color, plain.color, "the RGBA is not denoised");

    // The filter is steered by the albedo alone (docs/denoise.md, "Guides").
    let guides = Guides {
        albedo: Guides::from_aovs(&layers.aovs).albedo,
        ..Guides::none()
    };
    assert_eq!(guides.describe(), "albedo");
    let ctx = context();
    let again = run(
        &ctx,
        &Image {
            color: plain.color.clone(),
            alpha: plain.alpha.clone(),
            std_error: plain.std_error.clone(),
            alpha_std_error: plain.alpha_std_error.clone(),
            estimates: layers.attributes["estimates"].parse().unwrap(),
        },
        &guides,
    );
    assert_eq!(again.variance, VarianceSource::Film);
    for (a, b) in again.color.data.iter().zip(&layers.color.data) {
        for k in 0..3 {
            assert!(
                (a[k] - b[k]).abs() <= 1e-6 * (1.0 + b[k].abs()),
                "{a:?} vs {b:?}"
            );
        }
    }
    for (a, b) in again.alpha.iter().zip(&layers.alpha) {
        assert!((a - b).abs() <= 1e-6, "alpha {a} vs {b}");
    }
}
