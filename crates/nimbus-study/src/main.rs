//! `nimbus-study` (also run as `nimbus study`): measure error against a converged
//! reference versus GPU milliseconds over a grid of settings (the crate's documentation
//! gives the protocol).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::{Args, Parser};
use nimbus_gpu::{Context, ContextDesc};
use nimbus_study as study;

/// Measure error against a converged reference versus GPU milliseconds over a grid of
/// settings; writes study.csv, study.md and study.png.
#[derive(Parser)]
#[command(name = "nimbus study", bin_name = "nimbus study", version)]
struct Cli {
    #[command(flatten)]
    args: StudyArgs,
}

#[derive(Args)]
struct StudyArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// KEY=V1,V2,... (repeatable; the configurations are the cartesian product). Keys:
    /// box_estimator, spp, box_samples, frames, seed, max_bounces, volume, and the
    /// [integrator.restir] fields candidates, candidates_settled, temporal, temporal_limit,
    /// temporal_limit_moving, spatial_neighbors, spatial_radius_px, spatial_when, spatial_rounds, spatial_shift,
    /// env_reuse, spatial_max_history, spatial_feature_tolerance, spatial_anchor, shade_cache, still_target, emission, reuse, mis, temporal_history, sigma_star_floor, nee, direct, candidate_tracking, pc_fetch, density_fetch, target, camera_emission, temporal_reprojection, temporal_shift, mip_candidates, mip_indirect, mip_reuse (a level or
    /// auto), final_transmittance. Each max_bounces gets its own reference; configurations that render the same
    /// image are measured and listed once. ReSTIR renders one path per pixel per frame,
    /// so spp varies the other integrators only (its spp > 1 configurations are left out
    /// and listed).
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
    /// of the error of the mean over the frames. An animated scene needs it: every
    /// configuration then measures the same --frames scene frames after the longest
    /// warm-up, each against a reference of that scene frame.
    #[arg(long)]
    per_frame: bool,
    /// Milliseconds of arithmetic load on the device right before each render's
    /// measured frames, so that every configuration is timed at the GPU's working
    /// clocks: an H200 lowers them within a second of idling (as it does while a scene
    /// loads) and a light configuration alone does not raise them again, which timed
    /// the baseline's 1-spp frames up to 4x too slow. 0 for none; never on a CPU device.
    #[arg(long, value_name = "MS", default_value_t = nimbus::renderer::settle::DEFAULT_SETTLE.as_millis() as u64, value_parser = clap::value_parser!(u64).range(0..=60_000))]
    settle_ms: u64,
}

fn main() -> ExitCode {
    match study_cmd(Cli::parse().args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
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
        settle: std::time::Duration::from_millis(args.settle_ms),
    })?;
    let ctx = Context::new(&ContextDesc::from_env())?;
    eprintln!("device: {}", ctx.info().name);
    study.run(&ctx)?;
    let errors = ctx.validation_errors();
    if !errors.is_empty() {
        bail!(
            "{} Vulkan validation error(s):\n{}",
            errors.len(),
            errors.join("\n")
        );
    }
    Ok(())
}
