//! The measurements of `docs/denoise.md`: noisy and denoised error against a converged
//! reference on the benchmark scenes, and the denoiser's GPU milliseconds.
//!
//! ```sh
//! # the references (once; 256 frames x 16 spp of the baseline path tracer at 160x120):
//! nimbus render assets/scenes/bench/cloud-g0.toml --width 160 --height 120 --frames 256 \
//!     --spp 16 --seed 1000 --set integrator.volume=baseline --out /tmp/dn/ref-cloud-g0.exr
//! cargo run --release --example denoise_study -- errors assets/scenes/bench/cloud-g0.toml \
//!     /tmp/dn/ref-cloud-g0.exr [--seeds 1,2,3] [--pngs docs/denoise/cloud-g0] [--set KEY=VALUE]
//! cargo run --release --example denoise_study -- timing 640 480 [guides]
//! cargo run --release --features oidn --example denoise_study -- timing 1920 1080 oidn
//! ```
//!
//! `errors` renders, per seed, (a) one frame of 16 spp of the baseline path tracer and
//! (b) one frame of ReSTIR (the scene's spp), at the reference's size, with the depth,
//! normal and albedo AOVs, denoises each with the GPU filter without guides, with the
//! albedo guide, and with albedo, normal and depth (what `nimbus render --denoise`
//! passes), and, built with `--features oidn`, with Open Image Denoise (albedo and
//! normal, as `--denoise=oidn`), and prints nRMSE (RMSE over the reference's mean) of
//! each against the reference. `--set` sets a denoiser parameter (`sigma_luminance=4`,
//! `iterations=5`, `variance_boost=1`, ...). `timing W H [guides|oidn]` denoises a W x H
//! image 5 times and prints the GPU ms of each stage (median), or with `oidn` Open Image
//! Denoise's wall-clock ms with albedo and normal guides.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _, Result};
use nimbus::denoise::{nrmse, DenoiseParams, Denoiser, Guides, NoisyImage};
use nimbus::output::{read_layers, Display, ImageRgb, Tonemap};
use nimbus::renderer::{render, RenderOptions};
use nimbus_gpu::{Context, ContextDesc};
use nimbus_scene::{Aov, FieldOverride};

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let ctx = Context::new(&ContextDesc::from_env())?;
    eprintln!("device: {}", ctx.info().name);
    match args.first().map(String::as_str) {
        Some("errors") => errors(&ctx, &args[1..]),
        Some("timing") => timing(&ctx, &args[1..]),
        _ => bail!("usage: denoise_study errors SCENE REFERENCE.exr [...] | timing W H"),
    }
}

fn set_param(p: &mut DenoiseParams, kv: &str) -> Result<()> {
    let (k, v) = kv.split_once('=').context("--set KEY=VALUE")?;
    let f: f32 = v.parse().context("a number")?;
    match k {
        "iterations" => p.iterations = f as u32,
        "sigma_luminance" => p.sigma_luminance = f,
        "sigma_depth" => p.sigma_depth = f,
        "depth_relative" => p.depth_relative = f,
        "sigma_normal" => p.sigma_normal = f,
        "variance_boost" => p.variance_boost = f,
        "albedo_epsilon" => p.albedo_epsilon = f,
        _ => bail!("unknown parameter {k}"),
    }
    Ok(())
}

fn errors(ctx: &Context, args: &[String]) -> Result<()> {
    let scene_path = PathBuf::from(args.first().context("SCENE")?);
    let reference = read_layers(Path::new(args.get(1).context("REFERENCE")?))?;
    let mut seeds = vec![1u64, 2, 3];
    let mut pngs: Option<PathBuf> = None;
    let mut params = DenoiseParams::default();
    let mut rest = args[2..].iter();
    while let Some(a) = rest.next() {
        match a.as_str() {
            "--seeds" => {
                seeds = rest
                    .next()
                    .context("--seeds")?
                    .split(',')
                    .map(|s| s.parse().context("seed"))
                    .collect::<Result<_>>()?
            }
            "--pngs" => pngs = Some(PathBuf::from(rest.next().context("--pngs")?)),
            "--set" => set_param(&mut params, rest.next().context("--set")?)?,
            other => bail!("unknown argument {other}"),
        }
    }
    let (w, h) = (reference.color.width, reference.color.height);
    let display = Display {
        exposure: 1.0,
        tonemap: Tonemap::default(),
    };
    if let Some(prefix) = &pngs {
        nimbus::output::write_image_with(
            &prefix.with_file_name(format!(
                "{}-reference.png",
                prefix.file_name().unwrap_or_default().to_string_lossy()
            )),
            &reference.color,
            &display,
        )?;
    }
    println!("case | seed | guides | noisy nRMSE | denoised nRMSE | ratio | ms");
    #[cfg(feature = "oidn")]
    let oidn = nimbus_oidn::Denoiser::new()?;
    for (case, overrides) in [
        (
            "baseline-16spp",
            vec![
                FieldOverride::new("integrator.volume", "baseline"),
                FieldOverride::new("render.spp", 16i64),
            ],
        ),
        ("restir-1frame", vec![]),
    ] {
        // Per guide set (in the order of GUIDE_SETS, then OIDN): each seed's ratio.
        let mut ratios: Vec<(String, Vec<f64>)> = Vec::new();
        for &seed in &seeds {
            let mut fields = vec![
                FieldOverride::new("render.width", i64::from(w)),
                FieldOverride::new("render.height", i64::from(h)),
                FieldOverride::new("render.frames", 1i64),
                FieldOverride::new("render.seed", seed as i64),
            ];
            fields.extend(overrides.iter().cloned());
            let mut scene = nimbus::load_scene(Some(&scene_path), &fields)?;
            // The guides `nimbus render --denoise` asks for (no motion: one frame).
            scene.render.aovs = vec![Aov::Depth, Aov::Normal, Aov::Albedo];
            let plan = nimbus::plan::build(&scene, None)?;
            let result = render(ctx, &scene, &plan, &RenderOptions::default())?;
            let all = Guides::from_aovs(&result.aovs);
            if all.depth.is_none() || all.normal.is_none() || all.albedo.is_none() {
                bail!("the render has no depth, normal and albedo AOVs");
            }
            let noisy = nrmse(&result.image, &reference.color).context("nRMSE")?;
            let mut outputs: Vec<(String, ImageRgb, f64)> = Vec::new();
            for (label, pick) in GUIDE_SETS {
                let guides = pick(&all);
                let mut denoiser = Denoiser::new(params)?;
                let out = denoiser.run(ctx, &NoisyImage::of(&result), &guides)?;
                denoiser.destroy(ctx);
                outputs.push((
                    format!("svgf {label}"),
                    out.color,
                    out.gpu_ms.unwrap_or(f64::NAN),
                ));
            }
            #[cfg(feature = "oidn")]
            outputs.push(oidn_run(&oidn, &result.image, &all)?);
            for (i, (label, image, ms)) in outputs.iter().enumerate() {
                let denoised = nrmse(image, &reference.color).context("nRMSE")?;
                println!(
                    "{case} | {seed} | {label} | {noisy:.4} | {denoised:.4} | {:.3} | {ms:.1}",
                    denoised / noisy
                );
                if ratios.len() <= i {
                    ratios.push((label.clone(), Vec::new()));
                }
                ratios[i].1.push(denoised / noisy);
            }
            if let (Some(prefix), true) = (&pngs, seed == seeds[0]) {
                let name = prefix.file_name().unwrap_or_default().to_string_lossy();
                // "denoised" is what `nimbus render --denoise` gives: the albedo guide.
                let mut images = vec![("noisy", &result.image)];
                for (label, image, _) in &outputs {
                    match label.as_str() {
                        "svgf albedo" => images.push(("denoised", image)),
                        "oidn albedo+normal" => images.push(("oidn", image)),
                        _ => {}
                    }
                }
                for (kind, image) in images {
                    nimbus::output::write_image_with(
                        &prefix.with_file_name(format!("{name}-{case}-{kind}.png")),
                        image,
                        &display,
                    )?;
                }
            }
        }
        for (label, r) in &ratios {
            let mean = r.iter().sum::<f64>() / r.len() as f64;
            let (lo, hi) = r
                .iter()
                .fold((f64::MAX, f64::MIN), |(l, h), &x| (l.min(x), h.max(x)));
            println!("{case} {label}: denoised/noisy mean {mean:.3}, min {lo:.3}, max {hi:.3}");
        }
    }
    Ok(())
}

/// A guide set: its name and which of the render's guides it keeps.
type GuideSet = (&'static str, fn(&Guides) -> Guides);

/// The guide sets `errors` compares for the GPU filter.
const GUIDE_SETS: [GuideSet; 5] = [
    ("none", |_| Guides::none()),
    ("albedo", |g| Guides {
        albedo: g.albedo.clone(),
        ..Guides::none()
    }),
    ("albedo+depth", |g| Guides {
        albedo: g.albedo.clone(),
        depth: g.depth.clone(),
        ..Guides::none()
    }),
    ("albedo+normal", |g| Guides {
        albedo: g.albedo.clone(),
        normal: g.normal.clone(),
        ..Guides::none()
    }),
    ("albedo+normal+depth", |g| Guides {
        albedo: g.albedo.clone(),
        normal: g.normal.clone(),
        depth: g.depth.clone(),
        motion: None,
    }),
];

/// Open Image Denoise on `image` with the albedo and normal guides (as `--denoise=oidn`
/// passes them): the label, the image and the wall-clock ms.
#[cfg(feature = "oidn")]
fn oidn_run(
    d: &nimbus_oidn::Denoiser,
    image: &ImageRgb,
    guides: &Guides,
) -> Result<(String, ImageRgb, f64)> {
    let interleave = |planes: &[Vec<f32>; 3]| -> Vec<f32> {
        (0..planes[0].len())
            .flat_map(|i| [planes[0][i], planes[1][i], planes[2][i]])
            .collect()
    };
    let color: Vec<f32> = image.data.iter().flat_map(|p| *p).collect();
    let albedo = guides.albedo.as_ref().map(interleave);
    let normal = albedo.as_ref().and(guides.normal.as_ref()).map(interleave);
    let start = std::time::Instant::now();
    let out = d.denoise(
        image.width,
        image.height,
        &color,
        albedo.as_deref(),
        normal.as_deref(),
        true,
    )?;
    let ms = start.elapsed().as_secs_f64() * 1e3;
    let mut result = ImageRgb::new(image.width, image.height);
    for (p, c) in result.data.iter_mut().zip(out.chunks_exact(3)) {
        *p = [c[0], c[1], c[2]];
    }
    Ok(("oidn albedo+normal".to_string(), result, ms))
}

fn timing(ctx: &Context, args: &[String]) -> Result<()> {
    let w: u32 = args.first().context("W")?.parse()?;
    let h: u32 = args.get(1).context("H")?.parse()?;
    let n = w as usize * h as usize;
    // A noisy gradient: the filter's cost does not depend on the content.
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut noise = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let color = ImageRgb {
        width: w,
        height: h,
        data: (0..n)
            .map(|i| {
                let v = (i % w as usize) as f32 / w as f32 + noise();
                [v, v, v]
            })
            .collect(),
    };
    let zero = ImageRgb::new(w, h);
    let alpha = vec![1.0; n];
    let image = NoisyImage {
        color: &color,
        alpha: &alpha,
        std_error: &zero,
        alpha_std_error: &vec![0.0; n],
        estimates: 1,
    };
    let mode = args.get(2).map(String::as_str);
    let guides = if matches!(mode, Some("guides" | "oidn")) {
        Guides {
            depth: Some(
                (0..n)
                    .map(|i| 1.0 + (i / w as usize) as f32 * 0.01)
                    .collect(),
            ),
            normal: Some([vec![0.0; n], vec![0.0; n], vec![1.0; n]]),
            albedo: Some([vec![0.8; n], vec![0.8; n], vec![0.8; n]]),
            motion: None,
        }
    } else {
        Guides::none()
    };
    if mode == Some("oidn") {
        return oidn_timing(&color, &guides);
    }
    let mut denoiser = Denoiser::new(DenoiseParams::default())?;
    let mut runs = Vec::new();
    for _ in 0..5 {
        runs.push(denoiser.run(ctx, &image, &guides)?.timings);
    }
    denoiser.destroy(ctx);
    let stats = nimbus_gpu::summarize(&runs);
    println!("{w}x{h}, guides: {}", guides.describe());
    for s in stats {
        println!(
            "{}: median {:.3} ms (min {:.3}, max {:.3})",
            s.label, s.median_ms, s.min_ms, s.max_ms
        );
    }
    Ok(())
}

/// `timing W H oidn`: Open Image Denoise's wall-clock ms (the CPU's, or its CUDA device's
/// where there is one) on the image with albedo and normal guides, 5 runs.
#[cfg(feature = "oidn")]
fn oidn_timing(color: &ImageRgb, guides: &Guides) -> Result<()> {
    let d = nimbus_oidn::Denoiser::new()?;
    let mut ms = Vec::new();
    for _ in 0..5 {
        ms.push(oidn_run(&d, color, guides)?.2);
    }
    let first = ms[0];
    ms.sort_by(f64::total_cmp);
    println!(
        "{}x{}, oidn albedo+normal: wall median {:.1} ms (min {:.1}, max {:.1}, first {first:.1})",
        color.width, color.height, ms[2], ms[0], ms[4]
    );
    Ok(())
}

#[cfg(not(feature = "oidn"))]
fn oidn_timing(_: &ImageRgb, _: &Guides) -> Result<()> {
    bail!("timing ... oidn: build the example with --features oidn")
}
