//! The measurements of `docs/denoise.md`: noisy and denoised error against a converged
//! reference on the benchmark scenes, and the denoiser's GPU milliseconds.
//!
//! ```sh
//! # the references (once; 256 frames x 16 spp of the baseline path tracer at 160x120):
//! nimbus render assets/scenes/bench/cloud-g0.toml --width 160 --height 120 --frames 256 \
//!     --spp 16 --seed 1000 --set integrator.volume=baseline --out /tmp/dn/ref-cloud-g0.exr
//! cargo run --release --example denoise_study -- errors assets/scenes/bench/cloud-g0.toml \
//!     /tmp/dn/ref-cloud-g0.exr [--seeds 1,2,3] [--pngs docs/denoise/cloud-g0] [--set KEY=VALUE]
//! cargo run --release --example denoise_study -- timing 640 480
//! ```
//!
//! `errors` renders, per seed, (a) one frame of 16 spp of the baseline path tracer and
//! (b) one frame of ReSTIR (the scene's spp), at the reference's size, denoises each
//! (no guides), and prints nRMSE (RMSE over the reference's mean) of both against the
//! reference. `--set` sets a denoiser parameter (`sigma_luminance=4`, `iterations=5`,
//! `variance_boost=1`, ...). `timing W H` denoises a W x H image 5 times and prints the
//! GPU ms of each stage (median).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _, Result};
use nimbus::denoise::{nrmse, DenoiseParams, Denoiser, Guides, NoisyImage};
use nimbus::output::{read_layers, Display, ImageRgb, Tonemap};
use nimbus::renderer::{render, RenderOptions};
use nimbus_gpu::{Context, ContextDesc};
use nimbus_scene::FieldOverride;

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
    println!("case | seed | noisy nRMSE | denoised nRMSE | ratio | denoise GPU ms");
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
        let mut ratios = Vec::new();
        for &seed in &seeds {
            let mut fields = vec![
                FieldOverride::new("render.width", i64::from(w)),
                FieldOverride::new("render.height", i64::from(h)),
                FieldOverride::new("render.frames", 1i64),
                FieldOverride::new("render.seed", seed as i64),
            ];
            fields.extend(overrides.iter().cloned());
            let scene = nimbus::load_scene(Some(&scene_path), &fields)?;
            let plan = nimbus::plan::build(&scene, None)?;
            let result = render(ctx, &scene, &plan, &RenderOptions::default())?;
            let mut denoiser = Denoiser::new(params)?;
            let out = denoiser.run(ctx, &NoisyImage::of(&result), &Guides::none())?;
            denoiser.destroy(ctx);
            let noisy = nrmse(&result.image, &reference.color).context("nRMSE")?;
            let denoised = nrmse(&out.color, &reference.color).context("nRMSE")?;
            ratios.push(denoised / noisy);
            println!(
                "{case} | {seed} | {noisy:.4} | {denoised:.4} | {:.3} | {:.2}",
                denoised / noisy,
                out.gpu_ms.unwrap_or(f64::NAN)
            );
            if let (Some(prefix), true) = (&pngs, seed == seeds[0]) {
                let name = prefix.file_name().unwrap_or_default().to_string_lossy();
                for (kind, image) in [("noisy", &result.image), ("denoised", &out.color)] {
                    nimbus::output::write_image_with(
                        &prefix.with_file_name(format!("{name}-{case}-{kind}.png")),
                        image,
                        &display,
                    )?;
                }
            }
        }
        let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
        let (lo, hi) = ratios
            .iter()
            .fold((f64::MAX, f64::MIN), |(l, h), &r| (l.min(r), h.max(r)));
        println!("{case}: denoised/noisy mean {mean:.3}, min {lo:.3}, max {hi:.3}");
    }
    Ok(())
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
    let with_guides = args.get(2).is_some_and(|a| a == "guides");
    let guides = if with_guides {
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
