//! `nimbus`: the command-line renderer and GPU profiler.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, ensure, Context as _, Result};
use clap::{Args, Parser, Subcommand};
use nimbus::{load_scene, output, plan, profile, renderer};

mod render_cmd;

use nimbus_gpu::{enumerate_devices, Context, ContextDesc};
use nimbus_scene::FieldOverride;
use render_cmd::render;

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
    /// Render a scene to an image (.exr: linear premultiplied RGBA, a stderr layer and
    /// the render's metadata; .png: tonemapped sRGB).
    Render(RenderArgs),
    /// Combine partial renders of one scene and settings with different seeds into one
    /// image, weighted by their sample counts.
    Merge(MergeArgs),
    /// Render warm-up + N frames and report per-pass GPU milliseconds.
    Profile(ProfileArgs),
    /// List the Vulkan devices (pick one with NIMBUS_DEVICE=<substring of its name>).
    Devices,
    /// Measure error against a converged reference versus GPU milliseconds over a
    /// grid of settings; writes study.csv, study.md and study.png.
    ///
    /// Runs the `nimbus-study` binary, built beside this one (`nimbus study --help`
    /// lists its options).
    #[command(disable_help_flag = true)]
    Study(ForwardArgs),
    /// The cost of a sample: render the benchmark cases with work counters and
    /// timestamps, and compare them with a stored baseline (docs/performance.md).
    Bench(BenchArgs),
    /// Write the benchmark scenes' HDR daylight sky (an equirectangular .exr with a small,
    /// very bright sun), e.g. `nimbus make-sky target/bench/sky-sun.exr` for
    /// assets/scenes/bench/sky-sun.toml.
    MakeSky(MakeSkyArgs),
}

/// The arguments of a subcommand another binary implements, passed on as they are.
#[derive(Args)]
struct ForwardArgs {
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, num_args = 0..)]
    args: Vec<std::ffi::OsString>,
}

#[derive(Args)]
struct MakeSkyArgs {
    /// The map to write (.exr).
    out: PathBuf,
    /// Width in texels.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(8..=8192))]
    width: u32,
    /// Height in texels.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(4..=4096))]
    height: u32,
    /// The sun's elevation above the horizon, degrees.
    #[arg(long, default_value_t = 25.0, allow_negative_numbers = true, value_parser = parse_angle)]
    sun_elevation_deg: f64,
    /// The sun's azimuth, degrees.
    #[arg(long, default_value_t = 40.0, allow_negative_numbers = true, value_parser = parse_angle)]
    sun_azimuth_deg: f64,
    /// The sun's angular diameter, degrees, in [0.06, 28].
    #[arg(long, default_value_t = 1.5, value_parser = parse_sun_diameter)]
    sun_diameter_deg: f64,
    /// The irradiance of the sun's disc at normal incidence, W/m², in [0, 1e6]: 0 leaves
    /// the disc out (the sky and its glow around the sun stay), for a scene that gives
    /// the sun as a `directional` light instead.
    #[arg(long, default_value_t = 20.0, value_parser = parse_sun_irradiance)]
    sun_irradiance: f64,
}

/// The sun disc's irradiance in W/m², within [0, 1e6].
fn parse_sun_irradiance(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if (0.0..=1e6).contains(&v) => Ok(v),
        _ => Err(format!(
            "{text:?} is not an irradiance in W/m² within [0, 1e6]"
        )),
    }
}

/// A finite angle in degrees, within [-360, 360].
fn parse_angle(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v.abs() <= 360.0 => Ok(v),
        _ => Err(format!(
            "{text:?} is not an angle in degrees within [-360, 360]"
        )),
    }
}

/// The sun's diameter in degrees, within [0.06, 28].
fn parse_sun_diameter(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if (0.06..=28.0).contains(&v) => Ok(v),
        _ => Err(format!(
            "{text:?} is not a diameter in degrees within [0.06, 28]"
        )),
    }
}

/// `nimbus make-sky`: the daylight sky of `nimbus_scene::daylight_sky`, the sun alone
/// giving `--sun-irradiance` (20 W/m² by default) at normal incidence.
fn make_sky_cmd(args: MakeSkyArgs) -> Result<()> {
    // An environment light's `file` must end in .exr, so a sky written under any other
    // name could not be used (issue 24: `make-sky abc` wrote an EXR named abc).
    let exr = args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    ensure!(
        exr && !args.out.is_dir(),
        "OUT {}: name the sky's file .exr (it is an OpenEXR map, and an environment light's \
         `file` must end in .exr)",
        args.out.display()
    );
    let (w, h) = (args.width as usize, args.height as usize);
    let sun = nimbus_scene::sun_direction(
        args.sun_elevation_deg.to_radians() as f32,
        args.sun_azimuth_deg.to_radians() as f32,
    );
    let texels = nimbus_scene::daylight_sky(
        w,
        h,
        sun,
        args.sun_diameter_deg.to_radians(),
        args.sun_irradiance,
    );
    let out = &args.out;
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    nimbus::output::write_atomically(out, |tmp| {
        use exr::prelude::{Encoding, Image, SpecificChannels, Vec2, WritableImage};
        // Lossless ZIP: the sky is smooth along its rows, so a committed map stays small.
        let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
            let [r, g, b] = texels[y * w + x];
            (r, g, b)
        });
        Image::from_encoded_channels((w, h), Encoding::SMALL_LOSSLESS, channels)
            .write()
            .to_file(tmp)
            .with_context(|| format!("writing {}", out.display()))
    })?;
    let sun = if args.sun_irradiance > 0.0 {
        format!("sun {:.2} deg across", args.sun_diameter_deg)
    } else {
        "no sun disc".to_string()
    };
    println!("wrote {} ({w}x{h}, {sun})", out.display());
    Ok(())
}

#[derive(Args)]
struct BenchArgs {
    /// The stored baseline to compare with.
    #[arg(long, default_value = "assets/bench/baseline.json")]
    baseline: PathBuf,
    /// Write this run as the new baseline (after a change of work that is meant).
    #[arg(long)]
    update: bool,
    /// Only the cases whose name contains this.
    #[arg(long)]
    case: Option<String>,
    /// Also write this run's report as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// Overrides of scene fields. Each is applied to the scene's tables before validation,
/// so it is checked exactly like the same value written in the file.
#[derive(Args, Clone, Debug, Default)]
struct Overrides {
    /// Samples per pixel per frame ([render] spp).
    #[arg(long, value_name = "N")]
    spp: Option<u32>,
    /// Image width in pixels ([render] width).
    #[arg(long, value_name = "PIXELS")]
    width: Option<u32>,
    /// Image height in pixels ([render] height).
    #[arg(long, value_name = "PIXELS")]
    height: Option<u32>,
    /// Random seed ([render] seed): same seed, scene and device, same image. Parts of
    /// a render meant for `nimbus merge` need different seeds.
    #[arg(long, value_name = "S")]
    seed: Option<u64>,
    /// Samples along each camera ray for the box estimators, N_sample of the paper
    /// ([integrator] box_samples).
    #[arg(long, value_name = "N")]
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
        // A refused value names its flag (issue 24: `--width 0` was reported as coming
        // from `--set render.width=0`).
        let mut int = |flag: &str, key: &str, value: Option<u64>| -> Result<()> {
            if let Some(v) = value {
                let v = i64::try_from(v).map_err(|_| {
                    anyhow::anyhow!("{flag} {v}: does not fit a TOML integer (at most 2^63 - 1)")
                })?;
                out.push(FieldOverride::from_flag(flag, key, v));
            }
            Ok(())
        };
        int("--spp", "render.spp", self.spp.map(u64::from))?;
        int("--width", "render.width", self.width.map(u64::from))?;
        int("--height", "render.height", self.height.map(u64::from))?;
        int("--seed", "render.seed", self.seed)?;
        int("--frames", "render.frames", frames.map(u64::from))?;
        int(
            "--box-samples",
            "integrator.box_samples",
            self.box_samples.map(u64::from),
        )?;
        for text in &self.set {
            out.push(FieldOverride::parse(text)?);
        }
        Ok(out)
    }
}

#[derive(Args)]
struct RenderArgs {
    /// Scene file (TOML, see docs/scene-format.md); without one, the embedded default
    /// scene (a room with a window).
    scene: Option<PathBuf>,
    /// Output image: .exr (linear radiance, premultiplied RGBA, a `stderr` layer with
    /// each pixel's standard error, the render's metadata in the header) or .png
    /// (tonemapped 8-bit sRGB, see --exposure and --tonemap). Written atomically; an
    /// interrupted render (Ctrl-C, SIGTERM) still writes the frames it has.
    #[arg(long, short, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Print the render plan (passes and shader features, and why) and exit.
    #[arg(long)]
    explain: bool,
    /// [render] frames. A static scene accumulates them (the image is their mean); in an
    /// animated scene they are the animation's frames 0..N-1 (without --frame or
    /// --frame-range the image is the mean of the whole animation).
    #[arg(long, value_name = "N")]
    frames: Option<u32>,
    /// Render frame N of an animated scene into --out: --passes dispatches of that frame
    /// accumulated, after --warmup frames of history.
    #[arg(long, value_name = "N", conflicts_with = "frame_range")]
    frame: Option<u32>,
    /// Render frames A to B of an animated scene (both included), each into its own
    /// image frame_NNNN.<ext> in --sequence DIR (each --passes dispatches, history
    /// carried from frame to frame).
    #[arg(long, value_name = "A..B", value_parser = parse_frame_range, requires = "sequence", conflicts_with = "out")]
    frame_range: Option<(u32, u32)>,
    /// With --frame / --frame-range: dispatches of each frame accumulated into its image
    /// (each spp samples per pixel; the stderr layer comes from their spread, so it
    /// needs 2 or more). Default 1.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    passes: Option<u32>,
    /// With --frame-range: skip the leading frames whose images already exist in
    /// --sequence DIR (an interrupted frame is written as frame_NNNN.partial.<ext> and
    /// rendered again).
    #[arg(long, requires = "frame_range")]
    resume: bool,
    /// Render until the image's relative standard error (RMS of the per-pixel standard
    /// errors over the image's mean, estimated from the per-pixel sums; for ReSTIR from
    /// batch means of its correlated frames) is at most E, e.g. 0.03. Checked once at
    /// least 8 independent estimates exist. With --frame/--frame-range, per frame.
    #[arg(long, value_name = "E", value_parser = parse_target_error)]
    target_error: Option<f64>,
    /// Stop an image before a frame would end past this many seconds of rendering
    /// (set-up and warm-up not counted; with --frame-range, per frame). At least one
    /// frame is rendered. The warm-up frames stop at this limit too, on their own clock.
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds)]
    time_limit: Option<f64>,
    /// Exposure multiplier applied before tonemapping a .png (finite, > 0).
    #[arg(long, default_value_t = 1.0, value_parser = parse_exposure)]
    exposure: f32,
    /// Leave out the environment where camera rays see it directly (it still lights the
    /// scene): the image is then the foreground alone, premultiplied by its alpha, ready
    /// to composite over a plate ([render] transparent_background = true). A .png is
    /// then RGBA with straight alpha.
    #[arg(long)]
    transparent: bool,
    /// Output layers (AOVs) written into the .exr beside the beauty, comma separated
    /// (overrides [render] aovs): depth (Z), normal (N), albedo, emission, direct,
    /// indirect, lightgroups (lightgroup.<name> per [[light]] group), motion, or all.
    #[arg(long, value_name = "LIST")]
    aovs: Option<String>,
    /// Tone curve of a .png: aces (Narkowicz's ACES fit), filmic (Hable's curve) or
    /// clamp (none: values above 1 clip).
    #[arg(long, default_value = "aces", value_parser = ["aces", "filmic", "clamp"])]
    tonemap: String,
    /// Also write every frame's own image into this directory (frame_0000.exr, ...);
    /// with --frame-range, where each frame's image goes.
    #[arg(long, value_name = "DIR")]
    sequence: Option<PathBuf>,
    /// Image format of --sequence frames: exr or png.
    #[arg(long, default_value = "exr", value_parser = ["exr", "png"])]
    sequence_format: String,
    /// Frames rendered before the measured ones and not counted (fills ReSTIR's
    /// temporal history). Default 0; with --frame/--frame-range, the frames just before
    /// the first one (ReSTIR with temporal reuse: up to 4·(temporal_limit + 1)).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=1_000_000))]
    warmup: Option<u32>,
    /// Denoise the image (docs/denoise.md): the main RGBA is denoised, the noisy image
    /// stays in the .exr as the layer `noisy`, and the denoiser's guides (depth, normal,
    /// albedo; motion with --frame-range) are rendered as AOVs and written as layers.
    /// `--denoise` (or `--denoise=svgf`): an SVGF-style a-trous filter on the GPU, with
    /// temporal accumulation through the motion vectors across a --frame-range.
    /// `--denoise=oidn`: Intel Open Image Denoise on the CPU (or CUDA), for final frames;
    /// needs a nimbus built with `--features oidn` (tools/install-oidn.sh, docs/oidn.md).
    #[arg(long, num_args = 0..=1, require_equals = true, default_missing_value = "svgf", value_name = "DENOISER", value_parser = nimbus::denoise::Engine::parse)]
    denoise: Option<nimbus::denoise::Engine>,
    #[command(flatten)]
    overrides: Overrides,
}

#[derive(Args)]
struct MergeArgs {
    /// The merged image (.exr).
    #[arg(long, short, value_name = "FILE")]
    out: PathBuf,
    /// Two or more .exr images from `nimbus render` of the same scene and settings with
    /// different --seed values (the scene hash and settings in their headers must
    /// agree). Their mean is weighted by their samples per pixel; the stderr layer is
    /// combined exactly (independent parts: s² = Σ (wᵢ/W)² sᵢ²).
    #[arg(required = true, value_name = "IN")]
    inputs: Vec<PathBuf>,
}

#[derive(Args)]
struct ProfileArgs {
    /// Scene file (TOML); without one, the embedded default scene.
    scene: Option<PathBuf>,
    /// Measured frames (of an animation: its scene frames W..W+N-1 after a warm-up of W).
    #[arg(long, default_value_t = 32, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    frames: u32,
    /// Frames rendered before measuring (of an animation: its scene frames 0..W-1, so
    /// that the measured frames continue the motion).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(0..=100_000))]
    warmup: u32,
    /// Write the per-pass statistics as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write a Chrome trace (open in Perfetto or chrome://tracing).
    #[arg(long)]
    trace: Option<PathBuf>,
    /// Also count each pass's work on the GPU (tracking steps, density and majorant
    /// fetches, tentative collisions, shadow rays and their steps, BVH nodes, dispatches
    /// per frame): deterministic for a scene, seed and device. The counting pipelines are
    /// specialized apart, so the timings of this run include the counting.
    #[arg(long)]
    counters: bool,
    /// A cost diagnostic: every 8x8 workgroup of the path tracers (baseline,
    /// crepuscular) traces the camera samples of its first pixel in all its invocations,
    /// so the lanes of a SIMD row or warp never wait for a slower lane. The ratio of the
    /// two profiles is what divergence costs on this device (the most a wavefront or
    /// path-regenerating integrator could win); the work per lane is statistically the
    /// scene's, the image is not.
    #[arg(long)]
    coherent_lanes: bool,
    /// Milliseconds of arithmetic load on the device right before the first measured
    /// frame, so that a GPU that lowered its clocks while the scene loaded is timed at
    /// its working clocks (an idle H200 runs a light frame up to 4x slower); 0 for none.
    /// Never on a CPU device (lavapipe).
    #[arg(long, value_name = "MS", default_value_t = renderer::settle::DEFAULT_SETTLE.as_millis() as u64, value_parser = clap::value_parser!(u64).range(0..=60_000))]
    settle_ms: u64,
    /// Time the frames of the still that `nimbus render` makes of a static scene (the
    /// mean of its frames), not real-time frames: ReSTIR's `temporal = "auto"` then
    /// leaves temporal reuse out, as the render does. An animated scene's frames are
    /// images either way.
    #[arg(long)]
    still: bool,
    #[command(flatten)]
    overrides: Overrides,
}

/// The exit status of a render that was interrupted (SIGINT or SIGTERM) and wrote the
/// frames it had: 128 + SIGINT, as shells report Ctrl-C.
const EXIT_INTERRUPTED: u8 = 130;

fn main() -> ExitCode {
    // SAFETY: called first in main, before any thread exists; SIG_DFL is a valid
    // disposition for SIGPIPE. Rust's runtime ignores SIGPIPE, which turns a closed
    // reader of our standard output (`nimbus render --explain | head`) into a panic in
    // print!; with the default disposition the process ends quietly, like other tools.
    #[cfg(unix)]
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    match run(Cli::parse()) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<ExitCode> {
    let ok = |()| ExitCode::SUCCESS;
    match cli.command {
        Command::Render(args) => render(args),
        Command::Merge(args) => merge_cmd(args).map(ok),
        Command::Profile(args) => profile_cmd(args).map(ok),
        Command::Devices => devices().map(ok),
        Command::Study(args) => forward_to_study(args),
        Command::Bench(args) => bench_cmd(args),
        Command::MakeSky(args) => make_sky_cmd(args).map(ok),
    }
}

fn merge_cmd(args: MergeArgs) -> Result<()> {
    output::check_writable(&args.out).context("--out")?;
    anyhow::ensure!(
        args.out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("exr")),
        "--out {}: a merge writes an .exr (its stderr layer and metadata need one)",
        args.out.display()
    );
    let info = nimbus::merge::merge_files(&args.out, &args.inputs)?;
    eprintln!(
        "merged {} renders (seeds {}) into {}: {} samples per pixel, relative error {}",
        args.inputs.len(),
        info.seeds
            .iter()
            .map(u64::to_string)
            .collect::<Vec<_>>()
            .join(", "),
        args.out.display(),
        info.samples,
        info.rel_error
            .map_or_else(|| "unknown".to_string(), |e| format!("{e:.4}"))
    );
    Ok(())
}

/// `--frame-range A..B`: frames A to B, both included, A ≤ B.
fn parse_frame_range(text: &str) -> std::result::Result<(u32, u32), String> {
    let (a, b) = text
        .split_once("..")
        .ok_or_else(|| format!("{text:?} is not a range A..B (e.g. 0..99)"))?;
    let number = |s: &str| {
        s.trim()
            .trim_start_matches('=')
            .parse::<u32>()
            .map_err(|e| format!("{s:?} in {text:?} is not a frame number: {e}"))
    };
    let (a, b) = (number(a)?, number(b)?);
    if a > b {
        return Err(format!(
            "{text:?}: the first frame {a} comes after the last {b}"
        ));
    }
    Ok((a, b))
}

/// `--target-error`: a relative error in (0, 1).
fn parse_target_error(text: &str) -> std::result::Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(x) if x > 0.0 && x < 1.0 => Ok(x),
        Ok(x) => Err(format!(
            "{x} is not a relative error in (0, 1), e.g. 0.03 for 3 %"
        )),
        Err(e) => Err(format!("{text:?} is not a number: {e}")),
    }
}

/// `--time-limit`: finite seconds > 0.
fn parse_seconds(text: &str) -> std::result::Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 && x < 1.0e9 => Ok(x),
        Ok(x) if x >= 1.0e9 => Err(format!(
            "{x} seconds is more than 31 years: give a limit below 1e9 s, or none"
        )),
        Ok(x) => Err(format!("{x} is not a number of seconds > 0")),
        Err(e) => Err(format!("{text:?} is not a number of seconds: {e}")),
    }
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

fn profile_cmd(args: ProfileArgs) -> Result<()> {
    // Outputs are checked before anything renders (issue 24: a bad --json failed after
    // the render, without naming the flag).
    if let Some(path) = &args.json {
        check_file_writable("--json", path)?;
    }
    if let Some(path) = &args.trace {
        check_file_writable("--trace", path)?;
    }
    let scene = load_scene(
        args.scene.as_deref(),
        &args.overrides.fields(Some(args.frames))?,
    )?;
    let product = if args.still {
        plan::Product::Still
    } else {
        plan::Product::Frames
    };
    let plan = plan::build_for(&scene, None, product)?;
    let ctx = Context::new(&ContextDesc::from_env())?;
    let result = renderer::render(
        &ctx,
        &scene,
        &plan,
        &renderer::RenderOptions {
            progress: true,
            warmup_frames: args.warmup,
            // An animation's warm-up renders its first frames, and the measured frames
            // follow them.
            first_frame: args.warmup,
            counters: args.counters,
            skip_alpha: true,
            coherent_lanes: args.coherent_lanes,
            settle: std::time::Duration::from_millis(args.settle_ms),
            ..Default::default()
        },
    )?;
    if result.frame_timings.is_empty() {
        bail!(
            "device '{}' reported no timestamps; nothing to profile",
            ctx.info().name
        );
    }
    let report = profile::Report {
        coherent_lanes: args.coherent_lanes,
        settled: renderer::settle::applies(&ctx)
            .then(|| std::time::Duration::from_millis(args.settle_ms)),
        ..profile::Report::new(&ctx, &scene, &result)
    };
    print!("{}", report.table());
    if let Some(work) = &result.work {
        print!("{}", work.table());
    }
    // A timing of a wrong image is no timing: say so as `render` does.
    result.warnings().iter().for_each(|w| eprintln!("{w}"));
    if let Some(w) = report.timing_warning() {
        eprintln!("{w}");
    }
    if let Some(path) = &args.json {
        std::fs::write(path, report.json()?)
            .with_context(|| format!("--json: writing {}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    if let Some(path) = &args.trace {
        let mut file = std::io::BufWriter::new(
            std::fs::File::create(path)
                .with_context(|| format!("--trace: creating {}", path.display()))?,
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
/// `nimbus bench`: exit 1 when a work counter moved past the margin.
fn bench_cmd(args: BenchArgs) -> Result<ExitCode> {
    // Every argument is checked before the device is touched (issue 24: `--case abc`
    // failed after creating the device without naming the flag, a bad `--json` after
    // every case had rendered, and `--baseline` read a device file until memory ran out).
    if let Some(case) = &args.case {
        let names: Vec<&str> = nimbus::bench::CASES.iter().map(|c| c.name).collect();
        ensure!(
            !case.trim().is_empty() && names.iter().any(|n| n.contains(case.as_str())),
            "--case {case:?}: no bench case matches (cases: {})",
            names.join(", ")
        );
    }
    if let Some(path) = &args.json {
        check_file_writable("--json", path)?;
    }
    let base = if args.update {
        check_file_writable("--baseline", &args.baseline)?;
        None
    } else if args.baseline.exists() {
        Some(nimbus::bench::load_baseline(&args.baseline).context("--baseline")?)
    } else {
        eprintln!(
            "no baseline at {} (write one with --update): showing this run alone",
            args.baseline.display()
        );
        None
    };
    let ctx = Context::new(&ContextDesc::from_env())?;
    let report = nimbus::bench::run(&ctx, args.case.as_deref())?;
    report_validation(&ctx)?;
    if let Some(path) = &args.json {
        nimbus::bench::save(&report, path).context("--json")?;
        eprintln!("wrote {}", path.display());
    }
    if args.update {
        nimbus::bench::save(&report, &args.baseline).context("--baseline")?;
        print!("{}", nimbus::bench::table(&report, None));
        eprintln!("wrote the baseline {}", args.baseline.display());
        return Ok(ExitCode::SUCCESS);
    }
    print!("{}", nimbus::bench::table(&report, base.as_ref()));
    let Some(base) = base else {
        return Ok(ExitCode::SUCCESS);
    };
    let regressions = nimbus::bench::regressions(&report, &base);
    if nimbus::bench::device_family(&base.device) != nimbus::bench::device_family(&report.device) {
        eprintln!(
            "the baseline was measured on '{}', this run on '{}': counters differ by device, \
             so they are shown but not judged",
            base.device, report.device
        );
        return Ok(ExitCode::SUCCESS);
    }
    if regressions.is_empty() {
        println!(
            "\nwork counters within {:.2}x of the baseline",
            nimbus::bench::COUNTER_MARGIN
        );
        return Ok(ExitCode::SUCCESS);
    }
    println!("\nwork counters past the margin:");
    for r in &regressions {
        println!("  {r}");
    }
    Ok(ExitCode::FAILURE)
}

/// Refuses an output file named by `flag` that cannot be written, before anything is
/// rendered: an empty path, a directory, or one whose directory does not exist.
fn check_file_writable(flag: &str, path: &std::path::Path) -> Result<()> {
    ensure!(
        !path.as_os_str().is_empty(),
        "{flag}: the path is empty; name a file"
    );
    ensure!(
        !path.is_dir(),
        "{flag} {}: is a directory, not a file",
        path.display()
    );
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => std::path::Path::new("."),
    };
    ensure!(
        dir.is_dir(),
        "{flag} {}: the directory {} does not exist",
        path.display(),
        dir.display()
    );
    Ok(())
}

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

/// `nimbus study ARGS`: run `nimbus-study ARGS` in this process's place. The study
/// harness is its own crate (crates/nimbus-study), so the renderer does not depend on
/// its plotting stack. The binary is looked up in `NIMBUS_STUDY` (a path), then beside
/// this executable (where `cargo build` puts it), then on `PATH`.
fn forward_to_study(args: ForwardArgs) -> Result<ExitCode> {
    let name = format!("nimbus-study{}", std::env::consts::EXE_SUFFIX);
    let beside = std::env::current_exe()
        .ok()
        .and_then(|exe| exe.parent().map(|dir| dir.join(&name)))
        .filter(|path| path.is_file());
    let program = match std::env::var_os("NIMBUS_STUDY") {
        Some(path) => PathBuf::from(path),
        None => beside.unwrap_or_else(|| PathBuf::from(&name)),
    };
    let mut command = std::process::Command::new(&program);
    command.args(&args.args);
    let not_found = |e: std::io::Error| {
        anyhow::anyhow!(
            "`nimbus study` runs {} ({e}); it is built beside `nimbus` by `cargo build` at the \
             repository root, or alone by `cargo build --release -p nimbus-study` (NIMBUS_STUDY \
             may name it)",
            program.display()
        )
    };
    #[cfg(unix)]
    {
        use std::os::unix::process::CommandExt as _;
        // exec returns only when it failed; the study then is this process (signals, exit
        // status and standard streams are its own).
        Err(not_found(command.exec()))
    }
    #[cfg(not(unix))]
    {
        let status = command.status().map_err(not_found)?;
        Ok(ExitCode::from(
            u8::try_from(status.code().unwrap_or(1)).unwrap_or(1),
        ))
    }
}
