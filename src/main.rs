//! `nimbus`: the command-line renderer and GPU profiler.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context as _, Result};
use clap::{Args, Parser, Subcommand};
use nimbus::{load_scene, output, plan, profile, renderer, study};
use nimbus_gpu::{enumerate_devices, Context, ContextDesc};
use nimbus_scene::FieldOverride;

#[derive(Parser)]
#[command(
    name = "nimbus",
    version,
    about = "Raw-Vulkan compute renderer for participating media"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to an image (.exr linear radiance, .png tonemapped).
    Render(RenderArgs),
    /// Render warm-up + N frames and report per-pass GPU milliseconds.
    Profile(ProfileArgs),
    /// List the Vulkan devices (pick one with NIMBUS_DEVICE=<substring of its name>).
    Devices,
    /// Measure error against a converged reference versus GPU milliseconds over a
    /// grid of settings; writes study.csv, study.md and study.png.
    Study(StudyArgs),
}

/// Overrides of scene fields. Each is applied to the scene's tables before validation,
/// so it is checked exactly like the same value written in the file.
#[derive(Args, Clone, Debug, Default)]
struct Overrides {
    /// Samples per pixel per frame ([render] spp).
    #[arg(long)]
    spp: Option<u32>,
    /// Image width in pixels ([render] width).
    #[arg(long)]
    width: Option<u32>,
    /// Image height in pixels ([render] height).
    #[arg(long)]
    height: Option<u32>,
    /// Random seed ([render] seed): same seed, scene and device, same image.
    #[arg(long)]
    seed: Option<u64>,
    /// Samples along each camera ray for the box estimators, N_sample of the paper
    /// ([integrator] box_samples).
    #[arg(long)]
    box_samples: Option<u32>,
    /// Set any scene field: TABLE.FIELD=VALUE (repeatable), e.g. render.width=640,
    /// light.2.irradiance=[1,2,3], integrator.volume=baseline. [[arrays]] are indexed
    /// from 1.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
}

impl Overrides {
    /// The field overrides, flags first, then every --set in order (a later one wins).
    fn fields(&self, frames: Option<u32>) -> Result<Vec<FieldOverride>> {
        let mut out = Vec::new();
        let mut int = |key: &str, value: Option<u64>| -> Result<()> {
            if let Some(v) = value {
                let v = i64::try_from(v)
                    .map_err(|_| anyhow::anyhow!("{key} = {v} does not fit a TOML integer"))?;
                out.push(FieldOverride::new(key, v));
            }
            Ok(())
        };
        int("render.spp", self.spp.map(u64::from))?;
        int("render.width", self.width.map(u64::from))?;
        int("render.height", self.height.map(u64::from))?;
        int("render.seed", self.seed)?;
        int("render.frames", frames.map(u64::from))?;
        int("integrator.box_samples", self.box_samples.map(u64::from))?;
        for text in &self.set {
            out.push(FieldOverride::parse(text)?);
        }
        Ok(out)
    }
}

#[derive(Args)]
struct RenderArgs {
    /// Scene file (TOML); without one, the embedded default scene (a room with a window).
    scene: Option<PathBuf>,
    /// Output image: .exr (linear float RGB) or .png (tonemapped sRGB).
    #[arg(long, short)]
    out: Option<PathBuf>,
    /// Print the render plan (passes and shader features, and why) and exit.
    #[arg(long)]
    explain: bool,
    /// Frames to render, the output is their mean ([render] frames).
    #[arg(long)]
    frames: Option<u32>,
    /// Exposure multiplier applied before tonemapping a .png (finite, > 0).
    #[arg(long, default_value_t = 1.0, value_parser = parse_exposure)]
    exposure: f32,
    /// Also write every frame's own image into this directory (frame_0000.exr, ...;
    /// .png with --sequence-format png).
    #[arg(long)]
    sequence: Option<PathBuf>,
    /// Image format of --sequence frames: exr or png.
    #[arg(long, default_value = "exr", value_parser = ["exr", "png"])]
    sequence_format: String,
    /// Frames rendered before the measured ones and not counted (fills ReSTIR's
    /// temporal history).
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=1_000_000))]
    warmup: u32,
    #[command(flatten)]
    overrides: Overrides,
}

#[derive(Args)]
struct ProfileArgs {
    /// Scene file (TOML); without one, the embedded default scene.
    scene: Option<PathBuf>,
    /// Measured frames.
    #[arg(long, default_value_t = 32, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    frames: u32,
    /// Frames rendered before measuring.
    #[arg(long, default_value_t = 4)]
    warmup: u32,
    /// Write the per-pass statistics as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write a Chrome trace (open in Perfetto or chrome://tracing).
    #[arg(long)]
    trace: Option<PathBuf>,
    #[command(flatten)]
    overrides: Overrides,
}

#[derive(Args)]
struct StudyArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// KEY=V1,V2,... (repeatable; the configurations are the cartesian product). Keys:
    /// box_estimator, spp, box_samples, frames, seed, max_bounces, volume, and the
    /// [integrator.restir] knobs candidates, temporal, temporal_limit, spatial_neighbors,
    /// spatial_radius_px, spatial_rounds, reuse, mip_candidates, mip_indirect, mip_reuse,
    /// final_transmittance. Each max_bounces gets its own reference; configurations that
    /// render the same image are measured and listed once.
    #[arg(long, value_name = "KEY=V1,V2,...")]
    vary: Vec<String>,
    /// Frames per configuration (unless frames is varied).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    frames: u32,
    /// Frames of the reference render.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    reference_frames: u32,
    /// Samples per pixel per frame of the reference render.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=65536))]
    reference_spp: u32,
    /// Box estimator of the reference (default: the scene's own).
    #[arg(long, value_name = "NAME")]
    reference_estimator: Option<String>,
    /// Samples along each camera ray of the reference.
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=65536))]
    reference_box_samples: u32,
    /// KEY=VALUE of the series the others are compared with at equal GPU time
    /// (default box_estimator=rm when box_estimator is varied).
    #[arg(long, value_name = "KEY=VALUE")]
    baseline: Option<String>,
    /// Reference cache (default $XDG_CACHE_HOME/nimbus/references or
    /// ~/.cache/nimbus/references).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Output directory (default study-<scene stem>).
    #[arg(long)]
    out_dir: Option<PathBuf>,
    /// Image width for the reference and every configuration (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16384))]
    width: Option<u32>,
    /// Image height for the reference and every configuration (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16384))]
    height: Option<u32>,
    /// Frames rendered before each configuration's measured frames, not measured. Each
    /// configuration warms up for at least 1 frame (shader compilation) and, for
    /// Volumetric ReSTIR with temporal reuse, at least 4·temporal_limit frames; this
    /// raises both.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(0..=100_000))]
    warmup: u32,
    /// Renders of every configuration, each with its own seed derived from the scene's;
    /// rows report the mean error over the seeds and its spread (min and max RMSE).
    /// --vary seed needs --seeds 1.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=i64::from(study::MAX_SEEDS)))]
    seeds: u32,
    /// Report the mean of each measured frame's own error, at the GPU time of one frame
    /// (steady-state single-frame error, as the Volumetric ReSTIR paper measures), instead
    /// of the error of the mean over the frames.
    #[arg(long)]
    per_frame: bool,
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(args) => render(args),
        Command::Profile(args) => profile_cmd(args),
        Command::Devices => devices(),
        Command::Study(args) => study_cmd(args),
    }
}

fn study_cmd(args: StudyArgs) -> Result<()> {
    let study = study::Study::new(&study::StudyOptions {
        scene: args.scene,
        vary: args.vary,
        frames: args.frames,
        reference_frames: args.reference_frames,
        reference_spp: args.reference_spp,
        reference_estimator: args.reference_estimator,
        reference_box_samples: args.reference_box_samples,
        baseline: args.baseline,
        cache_dir: args.cache_dir,
        out_dir: args.out_dir,
        width: args.width,
        height: args.height,
        warmup: args.warmup,
        seeds: args.seeds,
        per_frame: args.per_frame,
    })?;
    let ctx = Context::new(&ContextDesc::from_env())?;
    eprintln!("device: {}", ctx.info().name);
    study.run(&ctx)?;
    report_validation(&ctx)
}

/// `--exposure`: a finite multiplier > 0 (0, negative, NaN or infinite exposure would
/// write an all-black or all-white image).
fn parse_exposure(text: &str) -> std::result::Result<f32, String> {
    match text.trim().parse::<f32>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        Ok(x) => Err(format!("{x} is not a finite number > 0")),
        Err(e) => Err(format!("{text:?} is not a number: {e}")),
    }
}

fn render(args: RenderArgs) -> Result<()> {
    let scene = load_scene(args.scene.as_deref(), &args.overrides.fields(args.frames)?)?;
    let plan = plan::build(&scene, None)?;
    if args.explain {
        print!("{}", plan.explain(&scene));
        let f = nimbus::budget::Footprint::of(&scene, &plan)?;
        let mib = |b: u64| b as f64 / f64::from(1u32 << 20);
        println!(
            "  memory: {:.1} MiB of GPU buffers and images, about {:.1} MiB of host memory at the peak for the scene's data",
            mib(f.device_bytes()),
            mib(f.host_peak)
        );
        return Ok(());
    }
    let Some(out) = args.out else {
        bail!("--out FILE is required to render (or pass --explain to print the plan)");
    };
    output::check_writable(&out).context("--out")?;
    if let Some(dir) = &args.sequence {
        std::fs::create_dir_all(dir).with_context(|| {
            format!("--sequence {}: cannot create the directory", dir.display())
        })?;
    }
    let ctx = Context::new(&ContextDesc::from_env())?;
    eprintln!("device: {}", ctx.info().name);
    let result = renderer::render(
        &ctx,
        &scene,
        &plan,
        &renderer::RenderOptions {
            progress: true,
            warmup_frames: args.warmup,
            sequence: args.sequence.clone(),
            sequence_ext: args.sequence_format.clone(),
            sequence_exposure: args.exposure,
            keep_frames: false,
        },
    )?;
    output::write_image(&out, &result.image, args.exposure)?;
    let gpu_ms: f64 = result
        .frame_timings
        .iter()
        .filter_map(|f| f.first())
        .map(|s| s.duration_ms())
        .sum();
    let mib = |b: u64| b as f64 / f64::from(1u32 << 20);
    let host = nimbus::budget::peak_host_bytes().map_or_else(String::new, |b| {
        format!(", peak host memory {:.0} MiB", mib(b))
    });
    eprintln!(
        "wrote {} ({}x{}, {} frame(s) x {} spp) in {:.2} s, GPU {:.1} ms, GPU memory {:.1} MiB{host}",
        out.display(),
        scene.render.width,
        scene.render.height,
        result.frames,
        scene.render.spp,
        result.wall_time.as_secs_f64(),
        gpu_ms,
        mib(result.device_bytes)
    );
    if result.non_finite_samples > 0 {
        eprintln!(
            "warning: {} sample(s) were not finite and were dropped",
            result.non_finite_samples
        );
    }
    for note in &result.notes {
        eprintln!("note: {note}");
    }
    if result.step_cap_hits > 0 {
        eprintln!(
            "warning: {} walk(s) through the grid stopped at the step limit; their samples are biased",
            result.step_cap_hits
        );
    }
    report_validation(&ctx)
}

fn profile_cmd(args: ProfileArgs) -> Result<()> {
    let scene = load_scene(
        args.scene.as_deref(),
        &args.overrides.fields(Some(args.frames))?,
    )?;
    let plan = plan::build(&scene, None)?;
    let ctx = Context::new(&ContextDesc::from_env())?;
    let result = renderer::render(
        &ctx,
        &scene,
        &plan,
        &renderer::RenderOptions {
            progress: true,
            warmup_frames: args.warmup,
            ..Default::default()
        },
    )?;
    if result.frame_timings.is_empty() {
        bail!(
            "device '{}' reported no timestamps; nothing to profile",
            ctx.info().name
        );
    }
    let report = profile::Report::new(&ctx, &scene, &result);
    print!("{}", report.table());
    if let Some(path) = &args.json {
        std::fs::write(path, report.json()?)
            .with_context(|| format!("writing {}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    if let Some(path) = &args.trace {
        let mut file = std::io::BufWriter::new(
            std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
        );
        nimbus_gpu::write_chrome_trace(&result.frame_timings, &mut file)
            .with_context(|| format!("writing {}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    report_validation(&ctx)
}

fn devices() -> Result<()> {
    let devices = enumerate_devices()?;
    if devices.is_empty() {
        bail!("no Vulkan devices found (install mesa-vulkan-drivers for lavapipe)");
    }
    let chosen = nimbus_gpu::context::select_device(&devices, None).ok();
    for d in &devices {
        let mark = if Some(d.index) == chosen { "*" } else { " " };
        println!(
            "{mark} {}: {} ({}, Vulkan {}, driver {} {}, timestamps: {} valid bits, {} ns/tick)",
            d.index,
            d.name,
            d.device_type_name(),
            d.api_version_string,
            d.driver_name,
            d.driver_info,
            d.timestamp_valid_bits,
            d.timestamp_period_ns
        );
    }
    println!("(* = picked by default; NIMBUS_DEVICE=<substring of a name> picks another)");
    Ok(())
}

/// Validation errors seen during a run fail it (they are on with NIMBUS_VALIDATION=1).
fn report_validation(ctx: &Context) -> Result<()> {
    let errors = ctx.validation_errors();
    if errors.is_empty() {
        Ok(())
    } else {
        bail!(
            "{} Vulkan validation error(s):\n{}",
            errors.len(),
            errors.join("\n")
        )
    }
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory as _;

    use super::*;

    /// `nimbus study --help` names every key `--vary` accepts.
    #[test]
    fn study_help_lists_every_vary_key() {
        let cli = Cli::command();
        let study = cli
            .find_subcommand("study")
            .expect("the study subcommand");
        let vary = study
            .get_arguments()
            .find(|a| a.get_id() == "vary")
            .expect("--vary");
        let help = vary.get_help().expect("--vary has help").to_string();
        let keys = study::vary_keys();
        assert_eq!(keys.len(), 18);
        for key in keys {
            let listed = help
                .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .any(|word| word == key);
            assert!(listed, "--vary help does not list {key}: {help}");
        }
    }
}
