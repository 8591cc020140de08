//! Runs a render plan: creates the passes, records one submission per frame, reads the
//! accumulated image back.
//!
//! Every frame adds one estimate per pixel (the mean of its `spp` samples) to a running
//! sum and a running sum of squares, so the output is the mean over frames and each
//! pixel also carries the standard error of that mean.

use std::time::{Duration, Instant};

use anyhow::{bail, Context as _, Result};
use nimbus_gpu::{vk, Buffer, BufferDesc, Context, GpuObjects, Handle, Profiler, ScopeResult};
use nimbus_scene::Scene;

use crate::gpu::{bindings, FrameUniforms};
use crate::output::ImageRgb;
use crate::passes::{self, Pass, Targets};
use crate::plan::RenderPlan;

/// How to run a render.
#[derive(Clone, Debug, Default)]
pub struct RenderOptions {
    /// Show a progress bar once the render has run for a second.
    pub progress: bool,
    /// Frames to render and discard before the measured ones (for profiling, and to
    /// fill ReSTIR's temporal history before measuring).
    pub warmup_frames: u32,
    /// Write every measured frame's image into this directory as
    /// `frame_NNNN.<sequence_ext>` (the result is still the mean of all frames).
    pub sequence: Option<std::path::PathBuf>,
    /// Extension of the sequence images: "exr" (linear) or "png" (tonemapped).
    pub sequence_ext: String,
    /// Exposure of tonemapped sequence images.
    pub sequence_exposure: f32,
    /// Keep every measured frame's own image in [`RenderResult::frame_images`].
    pub keep_frames: bool,
}

/// The result of a render.
#[derive(Clone, Debug)]
pub struct RenderResult {
    /// Mean radiance over frames, W/(m²·sr).
    pub image: ImageRgb,
    /// Per-pixel standard error of `image` (zero with a single frame).
    pub std_error: ImageRgb,
    pub frames: u32,
    /// Samples whose radiance was NaN or infinite; they were dropped, never written.
    pub non_finite_samples: u64,
    /// Walks through a grid cut short at `GRID_MAX_STEPS` (their estimates are biased;
    /// exact tracking of hot spans should keep this 0).
    pub step_cap_hits: u64,
    /// Shader invocations whose loops the device cut short (lavapipe's 65535-iteration
    /// limit per invocation); their estimates are wrong.
    pub loops_cut: u64,
    /// GPU timestamps of each measured frame (empty if the device has none).
    pub frame_timings: Vec<Vec<ScopeResult>>,
    /// Wall-clock time of the whole render, warm-up included.
    pub wall_time: Duration,
    /// Each measured frame's own estimate, with [`RenderOptions::keep_frames`].
    pub frame_images: Vec<ImageRgb>,
    /// Bytes of every GPU buffer and image the render created.
    pub device_bytes: u64,
    /// What the passes decided from the scene's content (see `Pass::notes`).
    pub notes: Vec<String>,
}

/// Render `scene` with `plan` on `ctx`.
pub fn render(
    ctx: &Context,
    scene: &Scene,
    plan: &RenderPlan,
    opts: &RenderOptions,
) -> Result<RenderResult> {
    let start = Instant::now();
    let r = &scene.render;
    let pixels = u64::from(r.width) * u64::from(r.height);
    let accum_bytes = pixels * 16;
    // Everything this render allocates, checked against the device and the host
    // budget before anything is.
    crate::budget::Footprint::of(scene, plan)?.check(ctx.info(), crate::budget::host_budget()?)?;

    // Create the render targets; `objects` frees them whatever happens next.
    let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let (objects, handles) = GpuObjects::build(ctx, |o| {
        let uniforms = o.add(ctx.create_buffer(
            &BufferDesc::gpu_only(
                std::mem::size_of::<FrameUniforms>() as u64,
                vk::BufferUsageFlags::UNIFORM_BUFFER,
            ),
            "frame uniforms",
        )?);
        let accum = o.add(ctx.create_buffer(&BufferDesc::gpu_only(accum_bytes, storage), "accum")?);
        let accum_sq =
            o.add(ctx.create_buffer(&BufferDesc::gpu_only(accum_bytes, storage), "accum squares")?);
        let stats = o.add(ctx.create_buffer(
            &BufferDesc::gpu_only((bindings::STAT_COUNT * 4) as u64, storage),
            "stats",
        )?);
        Ok(TargetHandles {
            uniforms,
            accum,
            accum_sq,
            stats,
        })
    })?;
    let result = (|| {
        let targets = handles.targets(&objects);
        let mut pass = passes::create(ctx, scene, plan, &targets)?;
        let device_bytes = objects.bytes() + pass.device_bytes();
        let notes = pass.notes();
        let run = run_frames(ctx, scene, pass.as_mut(), &targets, opts);
        pass.destroy(ctx);
        let (frame_timings, frames, sequence_sums, frame_images) = run?;
        let mut result = read_result(
            ctx,
            scene,
            &targets,
            frames,
            frame_timings,
            sequence_sums,
            start,
        )?;
        result.frame_images = frame_images;
        result.device_bytes = device_bytes;
        result.notes = notes;
        if result.loops_cut > 0 {
            bail!(
                "{}: device '{}' cut the loops of {} shader invocation(s) short (llvmpipe ends \
                 every loop of an invocation after 65535 iterations in all), so the image would \
                 be wrong; less work per pixel per frame renders right (lower [render] spp, \
                 [integrator] box_samples or max_bounces, [integrator.restir] \
                 spatial_neighbors), or use a GPU",
                scene.source.display(),
                ctx.info().name,
                result.loops_cut
            );
        }
        Ok(result)
    })();
    objects.destroy(ctx);
    result
}

/// The render targets in the renderer's object bag.
struct TargetHandles {
    uniforms: Handle<Buffer>,
    accum: Handle<Buffer>,
    accum_sq: Handle<Buffer>,
    stats: Handle<Buffer>,
}

impl TargetHandles {
    fn targets<'a>(&self, objects: &'a GpuObjects) -> Targets<'a> {
        Targets {
            uniforms: &objects[self.uniforms],
            accum: &objects[self.accum],
            accum_sq: &objects[self.accum_sq],
            stats: &objects[self.stats],
        }
    }
}

/// Frames loop: uniforms for the frame's camera, one submission, timestamps resolved.
fn run_frames(
    ctx: &Context,
    scene: &Scene,
    pass: &mut dyn Pass,
    targets: &Targets,
    opts: &RenderOptions,
) -> Result<FramesRun> {
    let r = &scene.render;
    let mut profiler = if ctx.info().timestamp_valid_bits > 0 {
        Some(Profiler::new(ctx, 8, "frame")?)
    } else {
        None
    };
    let total = opts.warmup_frames + r.frames;
    let progress = Progress::new(opts.progress, u64::from(total));
    let mut timings = Vec::new();
    let mut last_camera = None;
    let mut outcome = Ok(());
    let per_frame = opts.sequence.is_some() || opts.keep_frames;
    let mut frame_images = Vec::new();
    let mut sequence_sums = per_frame.then(|| {
        let n = r.width as usize * r.height as usize;
        (vec![[0.0f32; 4]; n], vec![[0.0f32; 4]; n])
    });
    for i in 0..total {
        // Warm-up frames render into the sums too; they are cleared afterwards.
        if i == opts.warmup_frames && i > 0 {
            if let Err(e) = clear_targets(ctx, targets) {
                outcome = Err(e);
                break;
            }
        }
        let frame = i.saturating_sub(opts.warmup_frames);
        let camera = scene.camera.frame_at(frame);
        let uniforms = pass.frame_uniforms(scene, &camera);
        if last_camera != Some(camera) || i == 0 {
            if let Err(e) = ctx.upload_buffer(targets.uniforms, 0, bytemuck::bytes_of(&uniforms)) {
                outcome = Err(e);
                break;
            }
            last_camera = Some(camera);
        }
        if i == 0 {
            if let Err(e) = clear_targets(ctx, targets) {
                outcome = Err(e);
                break;
            }
        }
        if let Err(e) = pass.prepare(ctx, scene, frame) {
            outcome = Err(e);
            break;
        }
        let recorded = ctx.submit_one_shot(&format!("frame {i}"), |cmd| {
            if let Some(p) = profiler.as_mut() {
                p.begin_frame(cmd);
                p.begin_scope(ctx, cmd, "frame")?;
            }
            if let Some(p) = profiler.as_mut() {
                p.begin_scope(ctx, cmd, pass.label())?;
            }
            pass.record(ctx, cmd, &uniforms, i, profiler.as_mut())?;
            if let Some(p) = profiler.as_mut() {
                p.end_scope(ctx, cmd)?;
            }
            if let Some(p) = profiler.as_mut() {
                p.end_scope(ctx, cmd)?;
            }
            Ok(())
        });
        if let Err(e) = recorded {
            outcome = Err(e);
            break;
        }
        if let Some(p) = profiler.as_mut() {
            match p.resolve(ctx) {
                Ok(scopes) if i >= opts.warmup_frames => timings.push(scopes),
                Ok(_) => {}
                Err(e) => {
                    outcome = Err(e);
                    break;
                }
            }
        }
        if let Some(sums) = sequence_sums.as_mut() {
            if i >= opts.warmup_frames {
                match sequence_frame(ctx, scene, targets, frame, opts, sums) {
                    Ok(image) if opts.keep_frames => frame_images.push(image),
                    Ok(_) => {}
                    Err(e) => {
                        outcome = Err(e);
                        break;
                    }
                }
            }
        }
        progress.tick();
    }
    progress.finish();
    if let Some(p) = profiler {
        p.destroy(ctx);
    }
    outcome.map(|()| (timings, r.frames, sequence_sums, frame_images))
}

/// Sums of x and x² per pixel (rgb, w = frame count), kept on the CPU in sequence mode.
type Sums = (Vec<[f32; 4]>, Vec<[f32; 4]>);

/// What the frames loop returns: per-frame timings, the measured frame count, the CPU
/// sums (per-frame mode) and the kept frame images.
type FramesRun = (Vec<Vec<ScopeResult>>, u32, Option<Sums>, Vec<ImageRgb>);

/// Per-frame mode: reads this frame's estimate back (the GPU sums hold only this
/// frame), writes it as an image in sequence mode, adds it to the CPU sums, clears the
/// GPU sums and returns the frame's image.
fn sequence_frame(
    ctx: &Context,
    scene: &Scene,
    targets: &Targets,
    frame: u32,
    opts: &RenderOptions,
    sums: &mut Sums,
) -> Result<ImageRgb> {
    let r = &scene.render;
    let sum: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&ctx.readback_buffer(targets.accum)?);
    let sum_sq: Vec<[f32; 4]> =
        bytemuck::pod_collect_to_vec(&ctx.readback_buffer(targets.accum_sq)?);
    let mut image = ImageRgb::new(r.width, r.height);
    for (i, (s, q)) in sum.iter().zip(&sum_sq).enumerate() {
        let n = s[3].max(1.0);
        image.data[i] = [s[0] / n, s[1] / n, s[2] / n];
        for c in 0..4 {
            sums.0[i][c] += s[c];
            sums.1[i][c] += q[c];
        }
    }
    if let Some(dir) = &opts.sequence {
        let path = dir.join(format!("frame_{frame:04}.{}", opts.sequence_ext));
        crate::output::write_image(&path, &image, opts.sequence_exposure)
            .with_context(|| format!("writing sequence frame {}", path.display()))?;
    }
    ctx.fill_buffer(targets.accum, 0)?;
    ctx.fill_buffer(targets.accum_sq, 0)?;
    Ok(image)
}

fn clear_targets(ctx: &Context, targets: &Targets) -> Result<()> {
    ctx.fill_buffer(targets.accum, 0)?;
    ctx.fill_buffer(targets.accum_sq, 0)?;
    ctx.fill_buffer(targets.stats, 0)
}

/// Read the sums back and turn them into the mean image and its standard error.
fn read_result(
    ctx: &Context,
    scene: &Scene,
    targets: &Targets,
    frames: u32,
    frame_timings: Vec<Vec<ScopeResult>>,
    sequence_sums: Option<Sums>,
    start: Instant,
) -> Result<RenderResult> {
    let r = &scene.render;
    let (sum, sum_sq) = match sequence_sums {
        Some(sums) => sums,
        None => (
            bytemuck::pod_collect_to_vec(&ctx.readback_buffer(targets.accum)?),
            bytemuck::pod_collect_to_vec(&ctx.readback_buffer(targets.accum_sq)?),
        ),
    };
    let stats: Vec<u32> = bytemuck::pod_collect_to_vec(&ctx.readback_buffer(targets.stats)?);
    let mut image = ImageRgb::new(r.width, r.height);
    let mut std_error = ImageRgb::new(r.width, r.height);
    for (i, (s, q)) in sum.iter().zip(&sum_sq).enumerate() {
        let n = f64::from(s[3]).max(1.0);
        for c in 0..3 {
            let mean = f64::from(s[c]) / n;
            // Unbiased sample variance of the frame estimates, clamped against rounding.
            let var = if n > 1.0 {
                ((f64::from(q[c]) / n - mean * mean) * n / (n - 1.0)).max(0.0)
            } else {
                0.0
            };
            image.data[i][c] = mean as f32;
            std_error.data[i][c] = (var / n).sqrt() as f32;
        }
    }
    Ok(RenderResult {
        image,
        std_error,
        frames,
        non_finite_samples: u64::from(stats[bindings::STAT_NON_FINITE]),
        step_cap_hits: u64::from(stats[bindings::STAT_STEP_CAP]),
        loops_cut: u64::from(stats[bindings::STAT_LOOPS_CUT]),
        frame_timings,
        wall_time: start.elapsed(),
        frame_images: Vec::new(),
        device_bytes: 0,
        notes: Vec::new(),
    })
}

/// A progress bar that appears only once a render has taken more than a second.
struct Progress {
    bar: Option<indicatif::ProgressBar>,
    start: Instant,
}

impl Progress {
    fn new(enabled: bool, total: u64) -> Self {
        let bar = enabled.then(|| {
            let bar = indicatif::ProgressBar::with_draw_target(
                Some(total),
                indicatif::ProgressDrawTarget::hidden(),
            );
            if let Ok(style) = indicatif::ProgressStyle::with_template(
                "{msg} [{bar:40}] {pos}/{len} frames, {elapsed} elapsed, ETA {eta}",
            ) {
                bar.set_style(style.progress_chars("=> "));
            }
            bar.set_message("rendering");
            bar
        });
        Self {
            bar,
            start: Instant::now(),
        }
    }

    fn tick(&self) {
        if let Some(bar) = &self.bar {
            if bar.is_hidden() && self.start.elapsed() > Duration::from_secs(1) {
                bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
            }
            bar.inc(1);
        }
    }

    fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}
