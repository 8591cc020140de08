//! Runs a render plan: creates the passes, records one submission per frame, reads the
//! accumulated image back.
//!
//! Every frame adds one estimate per pixel (the mean of its `spp` samples) to a running
//! sum and a running sum of squares, so an image is the mean over its frames and each
//! pixel also carries the standard error of that mean ([`film`]).
//!
//! Which scene frames make which image is [`FrameSelection`]: by default (`Mean`) frame
//! i of the render is scene frame i and the one image is the mean of all of them (a
//! static scene's accumulation); `Each` renders chosen frames of an animation, each its
//! own image accumulated over `passes` dispatches, after warm-up frames that give
//! ReSTIR its temporal history. A [`StopRule`] ends an image early: at a target
//! relative error, at a time limit, or when the user interrupts (the image so far is
//! still returned).
use std::time::{Duration, Instant};

pub mod aovs;
pub mod film;
pub mod progress;
pub mod settle;
mod stop;

pub use stop::{StopReason, StopRule, MAX_STOP_RULE_FRAMES, MIN_ESTIMATES};

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::{bail, Context as _, Result};
use nimbus_gpu::{vk, Buffer, BufferDesc, Context, GpuObjects, Handle, Profiler, ScopeResult};
use nimbus_scene::Scene;

use crate::budget::film_partial_bytes;
use crate::output::ImageRgb;
use crate::passes::{self, Pass, Targets};
use crate::plan::aovs::AovBytes;
pub use crate::plan::error_batch;
use crate::plan::{AovPlan, RenderPlan};
use crate::shader_data::counters::{self, WorkCounts};
use crate::shader_data::{bindings, AovUniformsGpu, FrameUniforms};
use bytemuck::Zeroable as _;
use film::{Batches, Totals};
use progress::{Progress, Status};

/// Frames dispatched before the host memory is marked
/// ([`crate::budget::mark_host_memory`]): by the end of the second every pass has run
/// each of its pipelines (ReSTIR's temporal reuse first runs in the second).
const HOST_MARK_AFTER_FRAMES: u32 = 2;

/// Which scene frames the render draws, and which images they make.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum FrameSelection {
    /// Frame i of the render is scene frame [`RenderOptions::first_frame`] + i, for i in
    /// 0..`[render] frames`; one image, the mean of all of them. Warm-up frames render
    /// the scene frames just before the first one (scene frame 0 in place of those
    /// before it: with `first_frame` 0, every warm-up frame is scene frame 0).
    #[default]
    Mean,
    /// Each listed scene frame is its own image, the mean of `passes` dispatches of that
    /// frame. Warm-up frames render the scene frames just before the first one.
    Each { frames: Vec<u32>, passes: u32 },
}

/// How to run a render.
#[derive(Clone, Debug, Default)]
pub struct RenderOptions {
    /// Show progress (a bar on a terminal, lines every few seconds otherwise).
    pub progress: bool,
    /// Frames to render and discard before the measured ones (for profiling, and to
    /// fill ReSTIR's temporal history before measuring).
    pub warmup_frames: u32,
    /// `Mean` mode: the scene frame of the first measured frame. 0 for a render of an
    /// animation from its start (its warm-up repeats scene frame 0); the timing commands
    /// (`nimbus profile`, `nimbus bench`) set it to `warmup_frames`, so that an
    /// animation's warm-up renders its scene frames 0, 1, ... and the measured frames
    /// continue it: a moving camera is measured on moving frames with the history of
    /// moving frames, never on a repeat of the warm-up's still frame.
    pub first_frame: u32,
    /// `Mean` mode: write every measured frame's image into this directory as
    /// `frame_NNNN.<sequence_ext>` (the result is still the mean of all frames).
    pub sequence: Option<std::path::PathBuf>,
    /// Extension of the sequence images: "exr" (linear) or "png" (tonemapped).
    pub sequence_ext: String,
    /// Exposure and tone map of tonemapped sequence images.
    pub sequence_display: crate::output::Display,
    /// `Mean` mode: keep every measured frame's own image in
    /// [`RenderResult::frame_images`].
    pub keep_frames: bool,
    /// Which scene frames make which images.
    pub frames: FrameSelection,
    pub stop: StopRule,
    /// Set (by a SIGINT handler) to stop: the current image ends with the frames done.
    pub interrupt: Option<Arc<AtomicBool>>,
    /// Count every pass's work ([`crate::shader_data::counters`]): the pipelines are specialized
    /// to count, and [`RenderResult::work`] holds the counts of the image's frames.
    pub counters: bool,
    /// Leave the film's alpha out (every pixel opaque): for renders whose alpha nobody
    /// reads (profiles, studies, benchmarks), which then pay nothing for it.
    pub skip_alpha: bool,
    /// A cost diagnostic (`nimbus profile --coherent-lanes`): every workgroup of the path
    /// tracers traces its first pixel's samples in all its invocations, so its lanes never
    /// diverge. The image is not the scene's.
    pub coherent_lanes: bool,
    /// Keep the device busy this long right before the first measured frame (after the
    /// warm-up), so that a GPU that lowered its clocks while the scene loaded is at its
    /// working clocks when timing starts ([`settle`]); zero for none, and never on a CPU
    /// device. Timing commands set [`settle::DEFAULT_SETTLE`].
    pub settle: Duration,
}

/// The result of rendering one image.
#[derive(Clone, Debug)]
pub struct RenderResult {
    /// Mean radiance over frames, W/(m²·sr).
    pub image: ImageRgb,
    /// Per-pixel standard error of `image` (zero with a single frame).
    pub std_error: ImageRgb,
    /// Mean coverage per pixel (1 − the camera ray's transmittance through the media).
    pub alpha: Vec<f32>,
    /// Standard error of `alpha`.
    pub alpha_std_error: Vec<f32>,
    /// Frames (dispatches) accumulated into the image.
    pub frames: u32,
    /// The scene frame of this image (`Each` mode).
    pub scene_frame: Option<u32>,
    /// The image's relative standard error ([`film::relative_error`]), with two or
    /// more estimates.
    pub rel_error: Option<f64>,
    /// Frames per independent estimate behind `std_error` (1: frames are independent;
    /// more: batch means of ReSTIR's correlated frames).
    pub error_batch: u32,
    /// Independent estimates behind `std_error`.
    pub estimates: u32,
    /// False when too few batches were whole and the frames' own (correlated) spread
    /// stands in: `std_error` then understates the error.
    pub error_independent: bool,
    pub stop: StopReason,
    /// Samples whose radiance was NaN or infinite; they were dropped, never written.
    pub non_finite_samples: u64,
    /// Walks through a grid cut short at `GRID_MAX_STEPS` (their estimates are biased;
    /// exact tracking of hot spans should keep this 0).
    pub step_cap_hits: u64,
    /// GPU timestamps of each measured frame of this image (empty if the device has
    /// none).
    pub frame_timings: Vec<Vec<ScopeResult>>,
    /// Wall-clock time of the whole render so far, warm-up included.
    pub wall_time: Duration,
    /// Wall-clock time of this image's measured frames.
    pub image_time: Duration,
    /// Each measured frame's own estimate, with [`RenderOptions::keep_frames`].
    pub frame_images: Vec<ImageRgb>,
    /// Bytes of every GPU buffer and image the render created.
    pub device_bytes: u64,
    /// What the pass and the plan decided from the scene's content (`Pass::notes`,
    /// `RenderPlan::notes`).
    pub notes: Vec<String>,
    /// The work counters of the image's frames, when [`RenderOptions::counters`] asked
    /// for them.
    pub work: Option<WorkCounts>,
    /// The output layers beside the beauty (`[render] aovs`), named as the EXR names
    /// them (`Z`, `N.X`, `albedo.R`, `direct.R`, `direct_stderr.R`,
    /// `lightgroup.<name>.R`, `motion.X`, ...; see [`aovs`]): the geometric ones of the
    /// image's last frame, the path ones the mean over its frames with their standard
    /// errors (batch means where the beauty's use them). Look one up by its channel name
    /// with [`crate::output::layers::find_channel`].
    pub aovs: Vec<crate::output::layers::Aov>,
}

impl RenderResult {
    /// What a command must say about this result besides the image: dropped non-finite
    /// samples and walks cut at the step limit (biased samples), one line each.
    pub fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        if self.non_finite_samples > 0 {
            out.push(format!(
                "warning: {} sample(s) were not finite and were dropped",
                self.non_finite_samples
            ));
        }
        if self.step_cap_hits > 0 {
            out.push(format!(
                "warning: {} walk(s) through the grid stopped at the step limit; their samples are biased",
                self.step_cap_hits
            ));
        }
        out
    }

    /// GPU milliseconds of the image's measured frames (0 without timestamps).
    pub fn gpu_ms(&self) -> f64 {
        self.frame_timings
            .iter()
            .filter_map(|f| f.first())
            .map(|s| s.duration_ms())
            .sum()
    }
}

/// Render `scene` with `plan` on `ctx`: the one image of `Mean` mode, or the last image
/// of `Each` mode (see [`render_each`] to receive every one).
pub fn render(
    ctx: &Context,
    scene: &Scene,
    plan: &RenderPlan,
    opts: &RenderOptions,
) -> Result<RenderResult> {
    render_each(ctx, scene, plan, opts, &mut |_| Ok(()))
}

/// Render `scene` with `plan` on `ctx`, handing every finished image to `sink` (in
/// `Each` mode one per scene frame, in order; in `Mean` mode the one image) and
/// returning the last.
pub fn render_each(
    ctx: &Context,
    scene: &Scene,
    plan: &RenderPlan,
    opts: &RenderOptions,
    sink: &mut dyn FnMut(&RenderResult) -> Result<()>,
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
            &BufferDesc::gpu_only(std::mem::size_of::<FrameUniforms>() as u64, storage),
            "frame uniforms",
        )?);
        let accum = o.add(ctx.create_buffer(&BufferDesc::gpu_only(accum_bytes, storage), "accum")?);
        let accum_sq =
            o.add(ctx.create_buffer(&BufferDesc::gpu_only(accum_bytes, storage), "accum squares")?);
        let stats = o.add(ctx.create_buffer(
            &BufferDesc::gpu_only((counters::STATS_WORDS * 4) as u64, storage),
            "stats",
        )?);
        let partial_bytes = film_partial_bytes(ctx.info().loop_budget().is_some(), pixels);
        let film_partial = o.add(ctx.create_buffer(
            &BufferDesc::gpu_only(partial_bytes, storage),
            "film partial sums",
        )?);
        // The AOV buffers: one-element dummies for what the render does not ask for.
        let aov = AovBytes::of(&plan.aov, pixels, ctx.info().loop_budget().is_some());
        let mut buffer = |bytes: u64, name: &str| -> Result<Handle<Buffer>> {
            Ok(o.add(ctx.create_buffer(&BufferDesc::gpu_only(bytes, storage), name)?))
        };
        let aov_geometry = buffer(aov.geometry, "AOV geometry")?;
        let aov_accum = buffer(aov.accum, "AOV sums")?;
        let aov_accum_sq = buffer(aov.accum, "AOV squares")?;
        let aov_partial = buffer(aov.partial, "AOV partial sums")?;
        let aov_uniforms = buffer(std::mem::size_of::<AovUniformsGpu>() as u64, "AOV uniforms")?;
        Ok(TargetHandles {
            uniforms,
            accum,
            accum_sq,
            stats,
            film_partial,
            aov_geometry,
            aov_accum,
            aov_accum_sq,
            aov_partial,
            aov_uniforms,
            counters: opts.counters,
            alpha: !opts.skip_alpha,
            coherent_lanes: opts.coherent_lanes,
        })
    })?;
    let result = (|| {
        let targets = handles.targets(&objects, &plan.aov);
        // Defined contents even where nothing reads them.
        ctx.upload_buffer(
            targets.aov_uniforms,
            0,
            bytemuck::bytes_of(&AovUniformsGpu::zeroed()),
        )?;
        let pass = passes::create(ctx, scene, plan, &targets);
        // The pass took what the plan loaded for it; nothing else outlives this point.
        crate::plan::levels::forget_loaded();
        let mut pass = pass?;
        let device_bytes = objects.bytes() + pass.device_bytes();
        // The pass's notes, then the plan's (what it chose from the grid's content).
        let mut notes = pass.notes();
        notes.extend(plan.notes());
        let mut run = Run {
            ctx,
            scene,
            targets: &targets,
            opts,
            start,
            device_bytes,
            notes,
            batch: error_batch(plan),
            profiler: None,
            dispatches: 0,
            last_uniforms: None,
            last_scene_frame: None,
            progress: Progress::new(opts.progress),
            counter_labels: pass.counter_labels(),
            aov: &plan.aov,
            last_aov_uniforms: None,
        };
        let outcome = run.all(pass.as_mut(), sink);
        run.progress.finish();
        if let Some(p) = run.profiler.take() {
            p.destroy(ctx);
        }
        pass.destroy(ctx);
        outcome
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
    film_partial: Handle<Buffer>,
    aov_geometry: Handle<Buffer>,
    aov_accum: Handle<Buffer>,
    aov_accum_sq: Handle<Buffer>,
    aov_partial: Handle<Buffer>,
    aov_uniforms: Handle<Buffer>,
    counters: bool,
    alpha: bool,
    coherent_lanes: bool,
}

impl TargetHandles {
    fn targets<'a>(&self, objects: &'a GpuObjects, aov: &'a AovPlan) -> Targets<'a> {
        Targets {
            uniforms: &objects[self.uniforms],
            accum: &objects[self.accum],
            accum_sq: &objects[self.accum_sq],
            stats: &objects[self.stats],
            film_partial: &objects[self.film_partial],
            aov_geometry: &objects[self.aov_geometry],
            aov_accum: &objects[self.aov_accum],
            aov_accum_sq: &objects[self.aov_accum_sq],
            aov_partial: &objects[self.aov_partial],
            aov_uniforms: &objects[self.aov_uniforms],
            aov,
            counters: self.counters,
            alpha: self.alpha,
            coherent_lanes: self.coherent_lanes,
        }
    }
}

/// One image being accumulated: its frames' sums on the CPU (when frames are read back
/// one by one) or on the GPU, and its batches.
struct ImageState {
    /// The context's dispatch count when the image started (work counters).
    first_dispatch: u64,
    /// Frames read back one by one and summed here (sequence and keep-frames modes);
    /// `None`: the GPU sums hold every frame of the image.
    cpu: Option<Totals>,
    batches: Option<Batches>,
    frames: u32,
    frame_images: Vec<ImageRgb>,
    timings: Vec<Vec<ScopeResult>>,
    start: Instant,
    /// Wall time of the slowest frame so far, to stop before a time limit.
    slowest_frame: Duration,
    /// When the error was last estimated (to keep read-backs to about one a second).
    last_check: Option<Instant>,
    rel_error: Option<f64>,
    /// The path AOVs' batches (one per slot), like `batches`.
    aov_batches: Option<Vec<Batches>>,
}

/// The frames loop and what it carries between frames.
struct Run<'a> {
    ctx: &'a Context,
    scene: &'a Scene,
    targets: &'a Targets<'a>,
    opts: &'a RenderOptions,
    start: Instant,
    device_bytes: u64,
    notes: Vec<String>,
    /// Frames per batch of the error estimate ([`error_batch`]).
    batch: u32,
    profiler: Option<Profiler>,
    /// Dispatches so far, warm-up included (they seed the random numbers).
    dispatches: u32,
    /// The frame uniforms last uploaded (their bytes).
    last_uniforms: Option<Vec<u8>>,
    last_scene_frame: Option<u32>,
    progress: Progress,
    /// The pass's counter slots by label ([`Pass::counter_labels`]).
    counter_labels: Vec<&'static str>,
    /// The AOVs the render writes.
    aov: &'a AovPlan,
    /// The AOV uniforms last uploaded (their bytes).
    last_aov_uniforms: Option<Vec<u8>>,
}

/// The scene frames of a warm-up of `count` frames before scene frame `first`: the
/// `count` frames just before it, scene frame 0 in place of those before 0.
fn warmup_scene_frames(first: u32, count: u32) -> Vec<u32> {
    (0..count)
        .map(|j| first.saturating_add(j).saturating_sub(count))
        .collect()
}

impl Run<'_> {
    fn interrupted(&self) -> bool {
        self.opts
            .interrupt
            .as_ref()
            .is_some_and(|flag| flag.load(Ordering::Relaxed))
    }

    /// Warm-up, then every image of the selection.
    fn all(
        &mut self,
        pass: &mut dyn Pass,
        sink: &mut dyn FnMut(&RenderResult) -> Result<()>,
    ) -> Result<RenderResult> {
        if self.ctx.info().timestamp_valid_bits > 0 {
            self.profiler = Some(Profiler::new(self.ctx, 8, "frame")?);
        }
        let opts = self.opts;
        let r = &self.scene.render;
        let stop_set = opts.stop.is_set();
        // (scene frames of the warm-up, then per image: its scene frame for each
        // dispatch, the most dispatches, the image's scene frame).
        let (warmup, images): (Vec<u32>, Vec<(Option<u32>, u32)>) = match &opts.frames {
            FrameSelection::Mean => {
                let count = if stop_set {
                    MAX_STOP_RULE_FRAMES
                } else {
                    r.frames
                };
                (
                    warmup_scene_frames(opts.first_frame, opts.warmup_frames),
                    vec![(None, count)],
                )
            }
            FrameSelection::Each { frames, passes } => {
                let first = frames.first().copied().unwrap_or(0);
                let warmup = warmup_scene_frames(first, opts.warmup_frames);
                let count = if stop_set {
                    MAX_STOP_RULE_FRAMES
                } else {
                    *passes
                };
                (warmup, frames.iter().map(|&f| (Some(f), count)).collect())
            }
        };
        clear_targets(self.ctx, self.targets)?;
        // The warm-up stops at the time limit too (it is not part of the measured
        // frames' budget, but a limit must bound the whole render: issue 24).
        let warmup_start = Instant::now();
        for (done, &frame) in warmup.iter().enumerate() {
            if self.interrupted() {
                bail!("interrupted during the warm-up frames; no image was rendered");
            }
            if let Some(limit) = opts.stop.time_limit {
                if done > 0 && warmup_start.elapsed() >= limit {
                    self.notes.push(format!(
                        "the warm-up stopped at the time limit ({:.1} s) after {done} of its \
                         {} frames",
                        limit.as_secs_f64(),
                        warmup.len()
                    ));
                    break;
                }
            }
            self.dispatch(pass, frame)?;
        }
        if !opts.settle.is_zero() && settle::applies(self.ctx) && !self.interrupted() {
            settle::settle(self.ctx, opts.settle)
                .context("keeping the device busy before the measured frames")?;
        }
        let mut last = None;
        for (index, &(scene_frame, count)) in images.iter().enumerate() {
            let result = self.image(pass, scene_frame, count, (index, images.len()))?;
            sink(&result)?;
            let stop = result.stop;
            last = Some(result);
            if stop == StopReason::Interrupted {
                break;
            }
        }
        last.context("internal: a render selected no frames")
    }

    /// Records and submits one frame of scene frame `frame`; returns its timestamps.
    fn dispatch(&mut self, pass: &mut dyn Pass, frame: u32) -> Result<Option<Vec<ScopeResult>>> {
        let ctx = self.ctx;
        // The camera and the environment map's turn change per frame in an animation.
        let uniforms = pass.frame_uniforms(self.scene, frame);
        let bytes = bytemuck::bytes_of(&uniforms);
        if self.last_uniforms.as_deref() != Some(bytes) {
            ctx.upload_buffer(self.targets.uniforms, 0, bytes)?;
            self.last_uniforms = Some(bytes.to_vec());
        }
        if self.aov.any() {
            // Motion is against the animation's previous scene frame (none at frame 0).
            let aov = AovUniformsGpu {
                prev: if frame > 0 {
                    pass.frame_uniforms(self.scene, frame - 1)
                } else {
                    uniforms
                },
                has_prev: u32::from(frame > 0),
                env_group: self.aov.env_group(self.scene),
                default_group: self.aov.default_group(),
                _pad0: 0,
            };
            let bytes = bytemuck::bytes_of(&aov);
            if self.last_aov_uniforms.as_deref() != Some(bytes) {
                ctx.upload_buffer(self.targets.aov_uniforms, 0, bytes)?;
                self.last_aov_uniforms = Some(bytes.to_vec());
            }
        }
        let previous = self
            .last_scene_frame
            .unwrap_or_else(|| frame.saturating_sub(1));
        pass.prepare(ctx, self.scene, frame, previous)?;
        self.last_scene_frame = Some(frame);
        let i = self.dispatches;
        let profiler = &mut self.profiler;
        ctx.submit_one_shot(&format!("frame {i}"), |cmd| {
            if let Some(p) = profiler.as_mut() {
                p.begin_frame(cmd);
                p.begin_scope(ctx, cmd, "frame")?;
                p.begin_scope(ctx, cmd, pass.label())?;
            }
            pass.record(ctx, cmd, &uniforms, i, profiler.as_mut())?;
            if let Some(p) = profiler.as_mut() {
                p.end_scope(ctx, cmd)?;
                p.end_scope(ctx, cmd)?;
            }
            Ok(())
        })?;
        self.dispatches += 1;
        if self.dispatches == HOST_MARK_AFTER_FRAMES {
            crate::budget::mark_host_memory();
        }
        match self.profiler.as_mut() {
            Some(p) => Ok(Some(p.resolve(ctx)?)),
            None => Ok(None),
        }
    }

    /// Renders one image: up to `count` frames of scene frame `scene_frame` (`Mean`
    /// mode: scene frames `first_frame`, `first_frame` + 1, ...), stopping early by the
    /// stop rule or an interrupt.
    fn image(
        &mut self,
        pass: &mut dyn Pass,
        scene_frame: Option<u32>,
        count: u32,
        (index, images): (usize, usize),
    ) -> Result<RenderResult> {
        let opts = self.opts;
        let r = &self.scene.render;
        let pixels = r.width as usize * r.height as usize;
        // `Mean` mode's warm-up shares the targets; every image starts from zero.
        clear_targets(self.ctx, self.targets)?;
        let per_frame = scene_frame.is_none() && (opts.sequence.is_some() || opts.keep_frames);
        let mut state = ImageState {
            first_dispatch: self.ctx.dispatch_count(),
            cpu: per_frame.then(|| Totals::new(pixels)),
            batches: (self.batch > 1).then(|| Batches::new(self.batch, pixels)),
            frames: 0,
            frame_images: Vec::new(),
            timings: Vec::new(),
            start: Instant::now(),
            slowest_frame: Duration::ZERO,
            last_check: None,
            rel_error: None,
            aov_batches: (self.batch > 1 && self.aov.path_slots() > 0).then(|| {
                (0..self.aov.path_slots())
                    .map(|_| Batches::new(self.batch, pixels))
                    .collect()
            }),
        };
        let mut stop = StopReason::Done;
        while state.frames < count {
            if self.interrupted() {
                stop = StopReason::Interrupted;
                break;
            }
            if let Some(limit) = opts.stop.time_limit {
                if state.frames > 0 && state.start.elapsed() + state.slowest_frame > limit {
                    stop = StopReason::TimeLimit;
                    break;
                }
            }
            let frame_start = Instant::now();
            let frame = scene_frame.unwrap_or(opts.first_frame.saturating_add(state.frames));
            if let Some(scopes) = self.dispatch(pass, frame)? {
                state.timings.push(scopes);
            }
            state.frames += 1;
            if let Some(totals) = state.cpu.as_mut() {
                let image = read_frame(self.ctx, self.scene, self.targets, totals)?;
                if let Some(dir) = &opts.sequence {
                    let path = dir.join(format!("frame_{:04}.{}", frame, opts.sequence_ext));
                    crate::output::write_image_with(&path, &image, &opts.sequence_display)
                        .with_context(|| format!("writing sequence frame {}", path.display()))?;
                }
                if opts.keep_frames {
                    state.frame_images.push(image);
                }
            }
            let closes_batch = state
                .batches
                .as_ref()
                .is_some_and(|b| b.ends_batch(state.frames));
            if closes_batch {
                let sum = match &state.cpu {
                    Some(t) => t.sum.clone(),
                    None => self
                        .ctx
                        .readback_buffer(self.targets.accum)
                        .map(|b| bytemuck::pod_collect_to_vec(&b))?,
                };
                if let Some(b) = state.batches.as_mut() {
                    b.close(&sum);
                }
                if let Some(batches) = state.aov_batches.as_mut() {
                    let sums: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(
                        &self.ctx.readback_buffer(self.targets.aov_accum)?,
                    );
                    for (slot, b) in batches.iter_mut().enumerate() {
                        b.close(&sums[slot * pixels..(slot + 1) * pixels]);
                    }
                }
            }
            state.slowest_frame = state.slowest_frame.max(frame_start.elapsed());
            if self.target_reached(&mut state, closes_batch)? {
                stop = StopReason::TargetError;
                break;
            }
            self.progress.tick(&Status {
                frames: state.frames,
                frames_total: (!opts.stop.is_set()).then_some(count),
                scene_frame: scene_frame.map(|f| (f, index, images)),
                rel_error: state.rel_error,
            });
        }
        if state.frames == 0 {
            bail!("interrupted before the first frame of the image; nothing was rendered");
        }
        self.finish(state, scene_frame, stop)
    }

    /// Whether the target error is reached, estimating it at most about once a second
    /// (every batch with batches) once there are [`MIN_ESTIMATES`] estimates.
    fn target_reached(&self, state: &mut ImageState, closed_batch: bool) -> Result<bool> {
        let Some(target) = self.opts.stop.target_error else {
            return Ok(false);
        };
        let estimates = match &state.batches {
            Some(b) => b.count,
            None => state.frames,
        };
        let due = match &state.batches {
            Some(_) => closed_batch,
            None => state
                .last_check
                .is_none_or(|t| t.elapsed() >= Duration::from_secs(1)),
        };
        if estimates < MIN_ESTIMATES || !due {
            return Ok(false);
        }
        state.last_check = Some(Instant::now());
        let totals = self.totals(state)?;
        let e = film::estimate(&totals, state.batches.as_ref());
        state.rel_error = e.rel_error;
        Ok(e.rel_error.is_some_and(|x| x <= target))
    }

    /// The image's sums: the CPU's, or the GPU's read back.
    fn totals(&self, state: &ImageState) -> Result<Totals> {
        if let Some(t) = &state.cpu {
            return Ok(t.clone());
        }
        Ok(Totals {
            sum: bytemuck::pod_collect_to_vec(&self.ctx.readback_buffer(self.targets.accum)?),
            sum_sq: bytemuck::pod_collect_to_vec(&self.ctx.readback_buffer(self.targets.accum_sq)?),
            frames: state.frames,
        })
    }

    /// The image's mean and standard error.
    fn finish(
        &self,
        state: ImageState,
        scene_frame: Option<u32>,
        stop: StopReason,
    ) -> Result<RenderResult> {
        let r = &self.scene.render;
        let totals = self.totals(&state)?;
        let e = film::estimate(&totals, state.batches.as_ref());
        let stats: Vec<u32> =
            bytemuck::pod_collect_to_vec(&self.ctx.readback_buffer(self.targets.stats)?);
        let loops_cut = stats[bindings::STAT_LOOPS_CUT];
        if loops_cut > 0 {
            bail!(
                "{}: device '{}' cut the loops of {loops_cut} shader invocation(s) short \
                 (llvmpipe ends every loop of an invocation after 65535 iterations in all), so \
                 the image would be wrong; less work per pixel per frame renders right (lower \
                 [render] spp, [integrator] box_samples or max_bounces, [integrator.restir] \
                 spatial_neighbors), or use a GPU",
                self.scene.source.display(),
                self.ctx.info().name,
            );
        }
        let aovs = self.aov_layers(&state)?;
        let mut image = ImageRgb::new(r.width, r.height);
        let mut std_error = ImageRgb::new(r.width, r.height);
        for (i, (m, s)) in e.mean.iter().zip(&e.std_error).enumerate() {
            image.data[i] = [m[0], m[1], m[2]];
            std_error.data[i] = [s[0], s[1], s[2]];
        }
        Ok(RenderResult {
            image,
            std_error,
            alpha: e.mean.iter().map(|m| m[3]).collect(),
            alpha_std_error: e.std_error.iter().map(|s| s[3]).collect(),
            frames: state.frames,
            scene_frame,
            rel_error: e.rel_error,
            error_batch: state.batches.as_ref().map_or(1, |b| b.size),
            estimates: e.estimates,
            error_independent: e.independent,
            stop,
            non_finite_samples: u64::from(stats[bindings::STAT_NON_FINITE]),
            step_cap_hits: u64::from(stats[bindings::STAT_STEP_CAP]),
            frame_timings: state.timings,
            wall_time: self.start.elapsed(),
            image_time: state.start.elapsed(),
            frame_images: state.frame_images,
            device_bytes: self.device_bytes,
            notes: self.notes.clone(),
            work: self.opts.counters.then(|| {
                WorkCounts::from_stats(
                    &stats,
                    &self.counter_labels,
                    self.ctx.dispatch_count() - state.first_dispatch,
                    state.frames,
                )
            }),
            aovs,
        })
    }

    /// The image's AOV layers: the geometric buffer and the path AOVs' sums read back.
    fn aov_layers(&self, state: &ImageState) -> Result<Vec<crate::output::layers::Aov>> {
        if !self.aov.any() {
            return Ok(Vec::new());
        }
        let r = &self.scene.render;
        let geometry: Vec<[f32; 4]> = if self.aov.geometry {
            bytemuck::pod_collect_to_vec(&self.ctx.readback_buffer(self.targets.aov_geometry)?)
        } else {
            Vec::new()
        };
        let (sum, sum_sq): (Vec<[f32; 4]>, Vec<[f32; 4]>) = if self.aov.path_slots() > 0 {
            (
                bytemuck::pod_collect_to_vec(&self.ctx.readback_buffer(self.targets.aov_accum)?),
                bytemuck::pod_collect_to_vec(&self.ctx.readback_buffer(self.targets.aov_accum_sq)?),
            )
        } else {
            (Vec::new(), Vec::new())
        };
        Ok(aovs::layers(
            self.aov,
            (r.width, r.height),
            &geometry,
            &aovs::PathSums {
                sum: &sum,
                sum_sq: &sum_sq,
                frames: state.frames,
                batches: state.aov_batches.as_deref(),
            },
        ))
    }
}

/// Per-frame mode: reads the frame's estimate back (the GPU sums hold only this frame),
/// adds it to `totals`, clears the GPU sums and returns the frame's image.
fn read_frame(
    ctx: &Context,
    scene: &Scene,
    targets: &Targets,
    totals: &mut Totals,
) -> Result<ImageRgb> {
    let sum: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&ctx.readback_buffer(targets.accum)?);
    totals.add_frame(&sum);
    ctx.fill_buffer(targets.accum, 0)?;
    ctx.fill_buffer(targets.accum_sq, 0)?;
    Ok(ImageRgb {
        width: scene.render.width,
        height: scene.render.height,
        data: sum.iter().map(|s| [s[0], s[1], s[2]]).collect(),
    })
}

fn clear_targets(ctx: &Context, targets: &Targets) -> Result<()> {
    ctx.fill_buffer(targets.accum, 0)?;
    ctx.fill_buffer(targets.accum_sq, 0)?;
    if targets.aov.path_slots() > 0 {
        ctx.fill_buffer(targets.aov_accum, 0)?;
        ctx.fill_buffer(targets.aov_accum_sq, 0)?;
    }
    ctx.fill_buffer(targets.stats, 0)
}

#[cfg(test)]
mod warmup_tests {
    use super::warmup_scene_frames;

    #[test]
    fn a_warmup_renders_the_scene_frames_just_before_the_first() {
        // A render from the start repeats scene frame 0.
        assert_eq!(warmup_scene_frames(0, 3), vec![0, 0, 0]);
        // Profile and bench (first = warm-up): the animation's first frames.
        assert_eq!(warmup_scene_frames(2, 2), vec![0, 1]);
        // A per-frame image after a longer warm-up than frames before it.
        assert_eq!(warmup_scene_frames(2, 4), vec![0, 0, 0, 1]);
        assert_eq!(warmup_scene_frames(80, 2), vec![78, 79]);
        // At the top of the range the frames saturate instead of overflowing.
        assert_eq!(warmup_scene_frames(u32::MAX, 2), vec![u32::MAX - 2; 2]);
        assert!(warmup_scene_frames(7, 0).is_empty());
    }
}
