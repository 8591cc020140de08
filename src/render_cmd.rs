//! `nimbus render`: which frames to render, when to stop, where the images go, what
//! their headers record, and what an interrupt leaves behind.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{bail, ensure, Context as _, Result};
use nimbus::merge::{settings_of, RenderInfo};
use nimbus::output::{self, Display, Tonemap};
use nimbus::renderer::{self, FrameSelection, RenderOptions, RenderResult, StopReason, StopRule};
use nimbus::{load_scene_text, plan};
use nimbus_gpu::{Context, ContextDesc};
use nimbus_scene::Scene;

use super::{report_validation, RenderArgs, EXIT_INTERRUPTED};

/// What every image of the render records besides its own numbers.
struct Identity {
    scene: String,
    scene_hash: String,
    animated: bool,
    device: String,
}

impl Identity {
    fn info(&self, scene: &Scene, result: &RenderResult, selection: &str) -> RenderInfo {
        let (settings, settings_hash) = settings_of(scene, self.animated, selection);
        RenderInfo {
            version: env!("CARGO_PKG_VERSION").to_string(),
            scene: self.scene.clone(),
            scene_hash: self.scene_hash.clone(),
            settings_hash,
            settings,
            seeds: vec![scene.render.seed],
            spp: scene.render.spp,
            frames: u64::from(result.frames),
            samples: u64::from(result.frames) * u64::from(scene.render.spp),
            estimates: u64::from(result.estimates),
            error_batch: result.error_batch,
            rel_error: result.rel_error,
            device: self.device.clone(),
            gpu_ms: result.gpu_ms(),
            wall_s: result.image_time.as_secs_f64(),
            stop: result.stop.describe().to_string(),
        }
    }
}

/// What the interrupt handler says when a second signal ends the render at once.
const SECOND_SIGNAL_EXIT: &[u8] =
    b"\nnimbus: a second interrupt: exiting now; nothing was written \
(the image in progress is lost; a single interrupt stops after the current frame and \
writes what was rendered)\n";
/// ... and when it arrives while an image is being written.
const SECOND_SIGNAL_WRITING: &[u8] =
    b"\nnimbus: a second interrupt while an image is written: finishing the write, then \
exiting (a third interrupt exits at once)\n";

/// Sets a flag on SIGINT and SIGTERM (Ctrl-C; Slurm's scancel and time limit) that the
/// frames loop checks, so the render stops after the current frame and writes what it
/// has. A second signal ends the process at once (exit 130) and says that nothing was
/// written, unless an image is being written: then the write finishes first (the flag
/// already stops the render right after it); a third signal exits regardless.
fn interrupt_flag() -> Result<Arc<AtomicBool>> {
    use std::sync::atomic::{AtomicU32, Ordering};
    static SIGNALS: AtomicU32 = AtomicU32::new(0);
    let flag = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        let flag = Arc::clone(&flag);
        let action = move || {
            let n = SIGNALS.fetch_add(1, Ordering::SeqCst) + 1;
            flag.store(true, Ordering::SeqCst);
            if n < 2 {
                return;
            }
            let writing = output::WRITING.load(Ordering::SeqCst);
            let message = if writing && n == 2 {
                SECOND_SIGNAL_WRITING
            } else {
                SECOND_SIGNAL_EXIT
            };
            // SAFETY: write(2) and _exit(2) are async-signal-safe; the message is a
            // static byte string, valid for its length.
            unsafe {
                libc::write(2, message.as_ptr().cast(), message.len());
                if !(writing && n == 2) {
                    libc::_exit(i32::from(EXIT_INTERRUPTED));
                }
            }
        };
        // SAFETY: the action only touches atomics and calls the async-signal-safe
        // write(2) and _exit(2): no allocation, no lock, nothing that a signal arriving
        // in the middle of the program could find half-done.
        unsafe { signal_hook::low_level::register(signal, action) }
            .context("installing the interrupt handler")?;
    }
    Ok(flag)
}

/// The image path of scene frame `frame` in a sequence directory.
fn sequence_path(dir: &Path, frame: u32, ext: &str, partial: bool) -> PathBuf {
    let partial = if partial { ".partial" } else { "" };
    dir.join(format!("frame_{frame:04}{partial}.{ext}"))
}

/// Why the sequence image at `path` must be rendered (again), or `None` when it is a
/// finished frame of this render: it exists, reads back whole, and its header records
/// this scene and its files (`scene_hash`) and this frame's settings (`settings_hash`).
fn stale_frame(path: &Path, scene_hash: &str, settings_hash: &str) -> Option<String> {
    if !path.exists() {
        return Some("is missing".to_string());
    }
    let attributes = match output::read_metadata(path) {
        Ok(a) => a,
        Err(e) => return Some(format!("cannot be read ({e:#})")),
    };
    let recorded = |key: &str| attributes.get(key).map(String::as_str);
    if recorded("scene_hash") != Some(scene_hash) {
        return Some(format!(
            "was rendered from another scene or other data (nimbus/scene_hash {:?}, this \
             render's {scene_hash:?})",
            recorded("scene_hash").unwrap_or("none")
        ));
    }
    if recorded("settings_hash") != Some(settings_hash) {
        return Some(format!(
            "was rendered with other settings (nimbus/settings {:?})",
            recorded("settings").unwrap_or("none")
        ));
    }
    None
}

/// "wrote X (...)": the one-line summary of an image.
fn summary(path: &Path, scene: &Scene, result: &RenderResult) -> String {
    let r = &scene.render;
    let error = match result.rel_error {
        None => "unknown (fewer than 2 estimates)".to_string(),
        Some(e) if result.error_batch > 1 && result.error_independent => format!(
            "{e:.4} (batch means of {} correlated frames)",
            result.error_batch
        ),
        Some(e) if !result.error_independent => format!(
            "{e:.4} (from correlated frames: an underestimate; fewer than 2 batches of {})",
            result.error_batch
        ),
        Some(e) => format!("{e:.4}"),
    };
    let dropped = match result.non_finite_samples {
        0 => String::new(),
        n => format!(", {n} non-finite sample(s) dropped"),
    };
    // One scene frame rendered `passes` times (--frame, --frame-range) is not `passes`
    // frames of the animation.
    let frames = match result.scene_frame {
        Some(f) => format!("frame {f}: {} pass(es)", result.frames),
        None => format!("{} frame(s)", result.frames),
    };
    format!(
        "wrote {} ({}x{}, {frames} x {} spp = {} samples per pixel) in {:.2} s, \
         GPU {:.1} ms, relative error {error}, stopped: {}{dropped}",
        path.display(),
        r.width,
        r.height,
        r.spp,
        u64::from(result.frames) * u64::from(r.spp),
        result.image_time.as_secs_f64(),
        result.gpu_ms(),
        result.stop.describe()
    )
}

pub(super) fn render(args: RenderArgs) -> Result<ExitCode> {
    if let Some(engine) = args.denoise {
        engine.check_available()?;
    }
    let mut fields = args.overrides.fields(args.frames)?;
    if args.transparent {
        fields.insert(
            0,
            nimbus_scene::FieldOverride::new("render.transparent_background", true),
        );
    }
    if let Some(list) = &args.aovs {
        // Checked here so that a refusal names the flag.
        let names: Vec<&str> = list.split(',').filter(|n| !n.trim().is_empty()).collect();
        let aovs = nimbus_scene::Aov::parse_list(names.iter().copied())
            .map_err(|e| anyhow::anyhow!("--aovs {list}: {e}"))?;
        let value: Vec<String> = aovs.iter().map(|a| a.name().to_string()).collect();
        fields.push(nimbus_scene::FieldOverride::from_flag(
            "--aovs",
            "render.aovs",
            value,
        ));
    }
    let (mut scene, scene_text) = load_scene_text(args.scene.as_deref(), &fields)?;
    // What the user asked for ([render] aovs / --aovs): the layers an image must hold.
    let asked_aovs = !scene.render.aovs.is_empty();
    if let Some(engine) = args.denoise {
        // The denoiser's guides (docs/denoise.md, "Guides"): the albedo; for the GPU
        // filter the motion that carries its history from frame to frame in a frame
        // range, for Open Image Denoise the normal. They are layers of a denoised .exr too.
        let mut guides = vec![nimbus_scene::Aov::Albedo];
        match engine {
            nimbus::denoise::Engine::Svgf if args.frame_range.is_some() => {
                guides.push(nimbus_scene::Aov::Motion);
            }
            nimbus::denoise::Engine::Oidn => guides.push(nimbus_scene::Aov::Normal),
            nimbus::denoise::Engine::Svgf => {}
        }
        for aov in guides {
            if !scene.render.aovs.contains(&aov) {
                scene.render.aovs.push(aov);
            }
        }
    }
    // A static scene renders a still, the mean of its frames (an animation's frames are
    // its images): that decides ReSTIR's `temporal = "auto"`.
    let plan = plan::build_for(&scene, None, plan::Product::Still)?;
    if !args.explain && args.frame.is_none() && args.frame_range.is_none() {
        if let Some(note) = plan.stills_note(&scene) {
            eprintln!("note: {note}");
        }
    }
    if args.explain {
        print!("{}", plan.explain(&scene));
        let f = nimbus::budget::Footprint::of(&scene, &plan)?;
        let mib = |b: u64| b as f64 / f64::from(1u32 << 20);
        println!(
            "  memory: {:.1} MiB of GPU buffers and images, about {:.1} MiB of host memory at the peak for the scene's data",
            mib(f.device_bytes()),
            mib(f.host_peak)
        );
        return Ok(ExitCode::SUCCESS);
    }
    let animated = scene.is_animated();
    let source = scene.source.display().to_string();
    let frames = scene.render.frames;

    // Which frames make which images.
    let picked = match (args.frame, args.frame_range) {
        (Some(n), _) => Some((n, n)),
        (None, Some(range)) => Some(range),
        (None, None) => None,
    };
    if let Some((a, b)) = picked {
        ensure!(
            animated,
            "{source}: --frame/--frame-range pick frames of an animation, and this scene is \
             static (no [[camera.keyframe]], [[light.keyframe]] or [[medium.frame]]); its \
             frames only accumulate: use --frames N"
        );
        ensure!(
            b < frames,
            "--frame{} {}: the animation has frames 0..{} ([render] frames = {frames} in \
             {source})",
            if a == b { "" } else { "-range" },
            if a == b {
                a.to_string()
            } else {
                format!("{a}..{b}")
            },
            frames.saturating_sub(1)
        );
    } else {
        ensure!(
            args.passes.is_none(),
            "--passes is for --frame / --frame-range; a static scene accumulates --frames"
        );
        ensure!(
            !(animated && (args.target_error.is_some() || args.time_limit.is_some())),
            "{source} is animated: its image is the mean of the whole animation, which a \
             target error or time limit cannot cut short; pick a frame with --frame N (or \
             --frame-range A..B)"
        );
    }
    let out = match (&args.out, args.frame_range) {
        (Some(out), _) => {
            output::check_writable(out).context("--out")?;
            // A transparent render's .png is RGBA (straight alpha).
            Some(out.clone())
        }
        (None, Some(_)) => None,
        (None, None) => {
            bail!("--out FILE is required to render (or pass --explain to print the plan)")
        }
    };
    // AOVs are EXR layers: an image that cannot hold them is refused, not written without.
    if asked_aovs {
        if let Some(out) = &out {
            ensure!(
                output::image_extension(out)? == "exr",
                "--out {}: the AOVs ([render] aovs / --aovs) are layers of an .exr; a .png holds \
                 the beauty only: write --out x.exr",
                out.display()
            );
        }
        ensure!(
            !(args.frame_range.is_some() && args.sequence_format == "png"),
            "--sequence-format png: the AOVs ([render] aovs / --aovs) are layers of an .exr; \
             use the exr sequence format"
        );
    }
    if let Some(dir) = &args.sequence {
        ensure!(
            !(args.sequence_format == "png" && scene.render.transparent_background),
            "--sequence-format png: a transparent render needs its alpha, and Nimbus writes \
             sequence frames as RGB PNGs: use the exr sequence format (premultiplied RGBA), \
             or --out x.png for one RGBA image"
        );
        ensure!(
            args.frame.is_none(),
            "--sequence with --frame: a single frame goes to --out"
        );
        std::fs::create_dir_all(dir).with_context(|| {
            format!("--sequence {}: cannot create the directory", dir.display())
        })?;
    }
    let display = Display {
        exposure: args.exposure,
        tonemap: Tonemap::from_name(&args.tonemap).unwrap_or_default(),
    };

    // The bytes the scene was parsed from: read once (a second read could see another
    // file, or hang on a pipe). The hash covers every file the scene reads too.
    let scene_bytes = scene_text.into_bytes();
    let scene_hash = nimbus::hashing::scene_hash(&scene_bytes, &scene)
        .with_context(|| format!("{source}: hashing the files the scene reads"))?;

    // The frames of a range still to render, as runs of consecutive frames: each run
    // starts with its own warm-up frames, so that a frame rendered again in the middle of
    // a sequence has the history a sequential render would have given it.
    let mut runs: Vec<Vec<u32>> = Vec::new();
    let mut warmups: Vec<u32> = Vec::new();
    if let Some((a, b)) = picked {
        let list: Vec<u32> = (a..=b).collect();
        let todo: Vec<u32> = match (&args.sequence, args.resume) {
            (Some(dir), true) => {
                let mut todo = Vec::new();
                for &f in &list {
                    let path = sequence_path(dir, f, &args.sequence_format, false);
                    let (_, settings_hash) = settings_of(&scene, animated, &format!("frame {f}"));
                    if let Some(why) = stale_frame(&path, &scene_hash, &settings_hash) {
                        if path.exists() {
                            eprintln!("resume: {} {why}: rendering it again", path.display());
                        }
                        todo.push(f);
                    }
                }
                if !todo.is_empty() && todo.len() < list.len() {
                    eprintln!(
                        "resume: {} of frames {a}..{b} are in {} already; rendering the \
                         other {}",
                        list.len() - todo.len(),
                        dir.display(),
                        todo.len()
                    );
                }
                todo
            }
            _ => list,
        };
        if todo.is_empty() {
            eprintln!("resume: every frame of {a}..{b} is already rendered");
            return Ok(ExitCode::SUCCESS);
        }
        for f in todo {
            match runs.last_mut() {
                Some(run) if run.last() == Some(&(f - 1)) => run.push(f),
                _ => runs.push(vec![f]),
            }
        }
        let history = renderer::error_batch(&plan);
        warmups = runs
            .iter()
            .map(|run| {
                args.warmup
                    .unwrap_or(if history > 1 { run[0].min(history) } else { 0 })
            })
            .collect();
    }

    let interrupt = interrupt_flag()?;
    let ctx = Context::new(&ContextDesc::from_env())?;
    eprintln!("device: {}", ctx.info().name);
    let identity = Identity {
        scene: source.clone(),
        scene_hash,
        animated,
        device: ctx.info().name.clone(),
    };
    let opts_for = |frames: FrameSelection, warmup: u32| RenderOptions {
        progress: true,
        warmup_frames: warmup,
        // The mean of an animation is of its frames from 0 (its warm-up repeats frame 0).
        first_frame: 0,
        sequence: if picked.is_some() {
            None
        } else {
            args.sequence.clone()
        },
        sequence_ext: args.sequence_format.clone(),
        sequence_display: display,
        keep_frames: false,
        frames,
        stop: StopRule {
            target_error: args.target_error,
            time_limit: args.time_limit.map(Duration::from_secs_f64),
        },
        interrupt: Some(Arc::clone(&interrupt)),
        counters: false,
        skip_alpha: false,
        coherent_lanes: false,
        // A render is not a timing: no device time spent on clocks.
        settle: Duration::ZERO,
    };
    let selection_words = |result: &RenderResult| match result.scene_frame {
        Some(f) => format!("frame {f}"),
        None if animated => format!("mean of frames 0..{}", frames.saturating_sub(1)),
        None => "accumulated frames".to_string(),
    };

    // `--denoise`: the images are denoised as they are written (docs/denoise.md).
    let mut writer = nimbus::denoise::Writer::new(args.denoise)?;
    // Each image of a frame range goes into the sequence as soon as it is done.
    let range_dir = args.sequence.clone().filter(|_| args.frame_range.is_some());
    let mut sink = |result: &RenderResult| -> Result<()> {
        let (Some(dir), Some(frame)) = (&range_dir, result.scene_frame) else {
            return Ok(());
        };
        let partial = result.stop == StopReason::Interrupted;
        let path = sequence_path(dir, frame, &args.sequence_format, partial);
        let info = identity.info(&scene, result, &selection_words(result));
        let denoised = writer
            .write(
                &ctx,
                &path,
                result,
                &info,
                &display,
                scene.render.transparent_background,
                Some(view_of(&scene, result)),
            )
            .with_context(|| format!("writing frame {frame}"))?;
        eprintln!("{}", summary(&path, &scene, result));
        denoised.into_iter().for_each(|line| eprintln!("{line}"));
        Ok(())
    };
    let result = if picked.is_some() {
        let mut last = None;
        for (run, &warmup) in runs.iter().zip(&warmups) {
            let selection = FrameSelection::Each {
                frames: run.clone(),
                passes: args.passes.unwrap_or(1),
            };
            let opts = opts_for(selection, warmup);
            let result = renderer::render_each(&ctx, &scene, &plan, &opts, &mut sink)?;
            let stop = result.stop;
            last = Some(result);
            if stop == StopReason::Interrupted {
                break;
            }
        }
        last.context("internal: a frame range with nothing to render")?
    } else {
        let opts = opts_for(FrameSelection::Mean, args.warmup.unwrap_or(0));
        renderer::render_each(&ctx, &scene, &plan, &opts, &mut sink)?
    };
    let mib = |b: u64| b as f64 / f64::from(1u32 << 20);
    let growth = nimbus::budget::host_growth_since_mark().map_or_else(String::new, |b| {
        format!(" (frames after the second added {:.0} MiB)", mib(b))
    });
    let host = nimbus::budget::peak_host_bytes().map_or_else(String::new, |b| {
        format!(", peak host memory {:.0} MiB{growth}", mib(b))
    });
    let memory = format!(
        "GPU memory {:.1} MiB{host}, {:.2} s in all",
        mib(result.device_bytes),
        result.wall_time.as_secs_f64()
    );
    match &out {
        Some(out) => {
            let info = identity.info(&scene, &result, &selection_words(&result));
            let denoised = writer.write(
                &ctx,
                out,
                &result,
                &info,
                &display,
                scene.render.transparent_background,
                Some(view_of(&scene, &result)),
            )?;
            eprintln!("{}, {memory}", summary(out, &scene, &result));
            denoised.into_iter().for_each(|line| eprintln!("{line}"));
        }
        None => eprintln!("rendered the frames, {memory}"),
    }
    for note in &result.notes {
        eprintln!("note: {note}");
    }
    result.warnings().iter().for_each(|w| eprintln!("{w}"));
    writer.destroy(&ctx);
    report_validation(&ctx)?;
    if result.stop == StopReason::Interrupted {
        eprintln!(
            "interrupted: the image{} holds the {} frame(s) rendered before the signal",
            if range_dir.is_some() {
                " marked .partial"
            } else {
                ""
            },
            result.frames
        );
        return Ok(ExitCode::from(EXIT_INTERRUPTED));
    }
    Ok(ExitCode::SUCCESS)
}

/// The camera of `result`'s image for its EXR header: the camera of its scene frame (of
/// frame 0 for the mean of an animation's frames, which has no one camera; a still
/// camera's for a static scene).
fn view_of(scene: &nimbus_scene::Scene, result: &RenderResult) -> nimbus::output::layers::ExrView {
    let frame = result.scene_frame.unwrap_or(0);
    nimbus::output::layers::ExrView::of(
        &scene.camera.frame_at(frame),
        scene.render.width,
        scene.render.height,
        result.scene_frame,
    )
}
