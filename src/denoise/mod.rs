//! `nimbus render --denoise`: a GPU denoiser of the SVGF family (Schied et al. 2017,
//! *Spatiotemporal Variance-Guided Filtering*), as compute stages in
//! `shaders/denoise/` that run on a render's final image. `docs/denoise.md` has the
//! measurements; in short:
//!
//! 1. **prepare** (`prepare.comp`): the noisy premultiplied colour is divided by the albedo
//!    guide where there is one (and the albedo is at least `albedo_epsilon`), so that the
//!    filter smooths lighting, not texture; the depth gradient is taken from the depth
//!    guide. With temporal accumulation (a sequence of frames with a motion guide) the
//!    previous frame's filtered colour is reprojected through the motion vectors
//!    (bilinearly, taps whose depth or normal differ left out) and blended in by an
//!    exponential moving average (weight of the new frame `max(temporal_alpha, 1/n)`
//!    for a history of n frames, at most `max_history`), with the luminance's first
//!    two moments beside it.
//! 2. **residual**, **variance** (`residual.comp`, `variance.comp`): the per-pixel
//!    variance of the luminance that steers
//!    the filter: the film's variance of the mean (its standard error squared) where
//!    the image has two or more independent estimates; else the temporal moments' after
//!    four frames of history; else a 7×7 spatial estimate (the mean squared residual of
//!    the luminance from its 4 neighbours' mean, the neighbours weighted by the geometry
//!    guides), times `variance_boost`.
//! 3. **à-trous** (`atrous.comp`) × `iterations`: the edge-avoiding à-trous wavelet
//!    filter, a 5×5 B3-spline kernel with holes of 1, 2, 4, 8, 16 pixels; each tap is
//!    weighted by exp(−|l_p − l_q| / (σ_l √var_p)) (var_p 3×3-prefiltered), by the
//!    depth, exp(−|z_p − z_q| / (σ_z |∇z·Δ| + r z |Δ|)) (0 between a pixel with a depth and
//!    one without), and by the normals, max(0, n_p·n_q)^σ_n. The variance goes through
//!    the squared weights, so every iteration stops at the noise left after the
//!    previous one. The first iteration's output is the next frame's history.
//! 4. **final** (`final.comp`): multiplies the albedo back in.
//!
//! Alpha is filtered with the colour's weights. Without guides the filter runs on the
//! colour and its variance alone. Nothing of this is created unless a render asks for
//! `--denoise` (the SPIR-V is in the binary, like every shader's).

mod writer;

pub use writer::{Engine, Writer};

use anyhow::{bail, ensure, Context as _, Result};
use nimbus_gpu::{
    compute_barrier, vk, BindingDesc, Buffer, BufferDesc, ComputePipeline, ComputePipelineDesc,
    Context, DescriptorSet, DescriptorWrite, GpuObjects, Handle, Profiler, ScopeResult,
};

use crate::output::layers::Aov;
use crate::output::ImageRgb;
use crate::passes::{spirv_words, PipelineContract, GROUP_SIZE};
use crate::renderer::RenderResult;
use crate::shader_data::bindings as b;
use crate::shader_data::{
    DenoisePush, DENOISE_FILM_VARIANCE, DENOISE_HAS_ALBEDO, DENOISE_HAS_DEPTH, DENOISE_HAS_MOTION,
    DENOISE_HAS_NORMAL, DENOISE_HISTORY, DENOISE_TEMPORAL, DENOISE_WRITE_HISTORY,
};

/// The denoiser's settings. The defaults are SVGF's, tuned on the benchmark clouds
/// (`docs/denoise.md`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DenoiseParams {
    /// À-trous iterations (holes of 1, 2, 4, ... pixels): 5, a 61-pixel footprint.
    pub iterations: u32,
    /// Luminance edge-stopping σ_l, in standard deviations of the pixel's noise: 4.
    pub sigma_luminance: f32,
    /// Depth edge-stopping σ_z, in units of the depth gradient's prediction: 1.
    pub sigma_depth: f32,
    /// Relative depth difference per pixel of offset tolerated besides the gradient: 0.02.
    pub depth_relative: f32,
    /// Normal edge-stopping exponent σ_n: 128.
    pub sigma_normal: f32,
    /// Temporal accumulation in a sequence with a motion guide: on.
    pub temporal: bool,
    /// Weight of the new frame in the colour's moving average once the history is long: 0.2.
    pub temporal_alpha: f32,
    /// The same for the luminance moments: 0.2.
    pub moments_alpha: f32,
    /// Longest history (frames) a pixel accumulates: 32.
    pub max_history: u32,
    /// Factor of the 7×7 spatial variance estimate (images of one frame): 1.
    pub variance_boost: f32,
    /// Albedo below this is not divided out: 0.01.
    pub albedo_epsilon: f32,
    /// Independent estimates (frames, or ReSTIR's batches) from which the film's
    /// per-pixel variance is used instead of the spatial estimate: 2.
    pub min_film_estimates: u32,
}

impl Default for DenoiseParams {
    fn default() -> Self {
        Self {
            iterations: 5,
            sigma_luminance: 4.0,
            sigma_depth: 1.0,
            depth_relative: 0.02,
            sigma_normal: 128.0,
            temporal: true,
            temporal_alpha: 0.2,
            moments_alpha: 0.2,
            max_history: 32,
            variance_boost: 1.0,
            albedo_epsilon: 0.01,
            min_film_estimates: 2,
        }
    }
}

/// Most à-trous iterations (a hole of 2^9 = 512 pixels).
pub const MAX_ITERATIONS: u32 = 10;

impl DenoiseParams {
    /// Refuses settings the filter cannot use, naming the field.
    pub fn check(&self) -> Result<()> {
        ensure!(
            self.iterations <= MAX_ITERATIONS,
            "denoise iterations = {}: at most {MAX_ITERATIONS}",
            self.iterations
        );
        for (name, value) in [
            ("sigma_luminance", self.sigma_luminance),
            ("sigma_depth", self.sigma_depth),
            ("sigma_normal", self.sigma_normal),
            ("variance_boost", self.variance_boost),
        ] {
            ensure!(
                value.is_finite() && value > 0.0,
                "denoise {name} = {value}: must be finite and > 0"
            );
        }
        for (name, value) in [
            ("depth_relative", self.depth_relative),
            ("albedo_epsilon", self.albedo_epsilon),
        ] {
            ensure!(
                value.is_finite() && value >= 0.0,
                "denoise {name} = {value}: must be finite and >= 0"
            );
        }
        for (name, value) in [
            ("temporal_alpha", self.temporal_alpha),
            ("moments_alpha", self.moments_alpha),
        ] {
            ensure!(
                value.is_finite() && value > 0.0 && value <= 1.0,
                "denoise {name} = {value}: must be in (0, 1]"
            );
        }
        ensure!(self.max_history >= 1, "denoise max_history = 0: at least 1");
        Ok(())
    }

    /// The settings in words, for the EXR header (`nimbus/denoise`).
    pub fn describe(&self) -> String {
        format!(
            "svgf: iterations {}, sigma_luminance {}, sigma_depth {}, depth_relative {}, \
             sigma_normal {}, temporal {} (alpha {}, moments {}, max_history {}), \
             variance_boost {}, albedo_epsilon {}, min_film_estimates {}",
            self.iterations,
            self.sigma_luminance,
            self.sigma_depth,
            self.depth_relative,
            self.sigma_normal,
            self.temporal,
            self.temporal_alpha,
            self.moments_alpha,
            self.max_history,
            self.variance_boost,
            self.albedo_epsilon,
            self.min_film_estimates
        )
    }
}

/// The optional guides of the filter, one plane per channel, `width * height` values
/// each, row-major: the render's AOVs `Z`, `N.X/Y/Z`, `albedo.R/G/B`, `motion.X/Y`
/// ([`Guides::from_aovs`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Guides {
    /// Camera-space depth; a non-finite or negative value means nothing is there.
    pub depth: Option<Vec<f32>>,
    /// World-space normal (X, Y, Z); a zero normal is unknown (no normal weight).
    pub normal: Option<[Vec<f32>; 3]>,
    /// Albedo (R, G, B); below `albedo_epsilon` a channel is not divided out.
    pub albedo: Option<[Vec<f32>; 3]>,
    /// Screen-space motion in pixels per frame (x right, y down): this frame's position
    /// minus the previous frame's.
    pub motion: Option<[Vec<f32>; 2]>,
}

impl Guides {
    /// No guides: the colour and its variance alone.
    pub fn none() -> Self {
        Self::default()
    }

    /// The guides among a render's AOVs, by their EXR names: `Z` (a layer `Z`, or the
    /// channel `Z` outside any layer), `N.X/Y/Z`, `albedo.R/G/B`, `motion.X/Y`. A guide
    /// with a channel missing is left out.
    pub fn from_aovs(aovs: &[Aov]) -> Self {
        let channel = |layer: &str, name: &str| -> Option<Vec<f32>> {
            aovs.iter()
                .filter(|a| a.name == layer)
                .flat_map(|a| a.channels.iter())
                .find(|(c, _)| c == name)
                .map(|(_, v)| v.clone())
        };
        let depth = channel("", "Z").or_else(|| {
            aovs.iter()
                .find(|a| a.name == "Z" && a.channels.len() == 1)
                .map(|a| a.channels[0].1.clone())
        });
        let three = |layer: &str, names: [&str; 3]| -> Option<[Vec<f32>; 3]> {
            Some([
                channel(layer, names[0])?,
                channel(layer, names[1])?,
                channel(layer, names[2])?,
            ])
        };
        Self {
            depth,
            normal: three("N", ["X", "Y", "Z"]),
            albedo: three("albedo", ["R", "G", "B"]),
            motion: (|| Some([channel("motion", "X")?, channel("motion", "Y")?]))(),
        }
    }

    /// Which guides there are, in words ("none", "albedo, normal, depth", ...).
    pub fn describe(&self) -> String {
        let names: Vec<&str> = [
            (self.albedo.is_some(), "albedo"),
            (self.normal.is_some(), "normal"),
            (self.depth.is_some(), "depth"),
            (self.motion.is_some(), "motion"),
        ]
        .iter()
        .filter(|(on, _)| *on)
        .map(|(_, n)| *n)
        .collect();
        if names.is_empty() {
            "none".to_string()
        } else {
            names.join(", ")
        }
    }

    fn check(&self, pixels: usize) -> Result<()> {
        let mut planes: Vec<(&str, &Vec<f32>)> = Vec::new();
        if let Some(d) = &self.depth {
            planes.push(("Z", d));
        }
        for (name, set) in [("N", &self.normal), ("albedo", &self.albedo)] {
            if let Some(set) = set {
                planes.extend(set.iter().map(|p| (name, p)));
            }
        }
        if let Some(m) = &self.motion {
            planes.extend(m.iter().map(|p| ("motion", p)));
        }
        for (name, plane) in planes {
            ensure!(
                plane.len() == pixels,
                "denoise guide {name}: {} values for {pixels} pixels",
                plane.len()
            );
        }
        Ok(())
    }
}

/// What the denoiser reads of a render: the mean (premultiplied RGB and A) and its
/// standard error, and how many independent estimates that error comes from.
#[derive(Clone, Copy, Debug)]
pub struct NoisyImage<'a> {
    pub color: &'a ImageRgb,
    pub alpha: &'a [f32],
    pub std_error: &'a ImageRgb,
    pub alpha_std_error: &'a [f32],
    /// Independent estimates behind `std_error` (0 or 1: it is unknown).
    pub estimates: u32,
}

impl<'a> NoisyImage<'a> {
    /// The image of a render.
    pub fn of(result: &'a RenderResult) -> Self {
        Self {
            color: &result.image,
            alpha: &result.alpha,
            std_error: &result.std_error,
            alpha_std_error: &result.alpha_std_error,
            estimates: result.estimates,
        }
    }
}

/// Where the variance that steered the filter came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VarianceSource {
    /// The film's per-pixel standard error (two or more estimates).
    Film,
    /// The 7×7 spatial estimate, or the temporal moments where a pixel's history is long
    /// enough.
    Estimated,
}

/// A denoised image.
#[derive(Clone, Debug)]
pub struct Denoised {
    /// Premultiplied RGB.
    pub color: ImageRgb,
    pub alpha: Vec<f32>,
    /// GPU milliseconds of the whole denoiser (timestamps; `None` without them).
    pub gpu_ms: Option<f64>,
    /// The timestamps of each stage (`denoise/prepare`, `.../atrous 1`, ...).
    pub timings: Vec<ScopeResult>,
    pub variance: VarianceSource,
    /// Whether a reprojected history was blended in.
    pub temporal: bool,
}

/// Which buffers the denoiser holds: its size and which guides it was made for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Shape {
    width: u32,
    height: u32,
    geometry: bool,
    depth: bool,
    albedo: bool,
    motion: bool,
    temporal: bool,
}

/// The GPU objects of one [`Shape`].
struct State {
    shape: Shape,
    objects: GpuObjects,
    noisy: Handle<Buffer>,
    film_variance: Handle<Buffer>,
    guides: Handle<Buffer>,
    albedo: Handle<Buffer>,
    motion: Handle<Buffer>,
    output: Handle<Buffer>,
    prepare: (Handle<ComputePipeline>, Handle<DescriptorSet>),
    residual: (Handle<ComputePipeline>, Handle<DescriptorSet>),
    variance: (Handle<ComputePipeline>, Handle<DescriptorSet>),
    /// The à-trous pipeline and its sets A → B and B → A.
    atrous: (Handle<ComputePipeline>, [Handle<DescriptorSet>; 2]),
    finish: (Handle<ComputePipeline>, Handle<DescriptorSet>),
}

/// The bindings of each stage (all storage buffers).
const PREPARE_BINDINGS: [u32; 12] = [
    b::DENOISE_NOISY,
    b::DENOISE_FILM_VARIANCE,
    b::DENOISE_GUIDES,
    b::DENOISE_ALBEDO,
    b::DENOISE_MOTION,
    b::DENOISE_GRADIENT,
    b::DENOISE_COLOR_DST,
    b::DENOISE_VARIANCE_DST,
    b::DENOISE_HISTORY,
    b::DENOISE_MOMENTS,
    b::DENOISE_MOMENTS_PREV,
    b::DENOISE_GUIDES_PREV,
];
const RESIDUAL_BINDINGS: [u32; 2] = [b::DENOISE_COLOR_SRC, b::DENOISE_RESIDUAL];
const VARIANCE_BINDINGS: [u32; 5] = [
    b::DENOISE_RESIDUAL,
    b::DENOISE_VARIANCE_SRC,
    b::DENOISE_VARIANCE_DST,
    b::DENOISE_GUIDES,
    b::DENOISE_GRADIENT,
];
const ATROUS_BINDINGS: [u32; 7] = [
    b::DENOISE_COLOR_SRC,
    b::DENOISE_VARIANCE_SRC,
    b::DENOISE_COLOR_DST,
    b::DENOISE_VARIANCE_DST,
    b::DENOISE_GUIDES,
    b::DENOISE_GRADIENT,
    b::DENOISE_HISTORY,
];
const FINAL_BINDINGS: [u32; 8] = [
    b::DENOISE_COLOR_SRC,
    b::DENOISE_ALBEDO,
    b::DENOISE_OUTPUT,
    b::DENOISE_GUIDES,
    b::DENOISE_GUIDES_PREV,
    b::DENOISE_MOMENTS,
    b::DENOISE_MOMENTS_PREV,
    b::DENOISE_HISTORY,
];

/// The five pipelines: name, SPIR-V, bindings.
fn stages() -> [(&'static str, &'static [u8], &'static [u32]); 5] {
    [
        (
            "denoise prepare",
            crate::shaders::DENOISE_PREPARE,
            &PREPARE_BINDINGS,
        ),
        (
            "denoise residual",
            crate::shaders::DENOISE_RESIDUAL,
            &RESIDUAL_BINDINGS,
        ),
        (
            "denoise variance",
            crate::shaders::DENOISE_VARIANCE,
            &VARIANCE_BINDINGS,
        ),
        (
            "denoise atrous",
            crate::shaders::DENOISE_ATROUS,
            &ATROUS_BINDINGS,
        ),
        (
            "denoise final",
            crate::shaders::DENOISE_FINAL,
            &FINAL_BINDINGS,
        ),
    ]
}

fn layout(bindings: &[u32]) -> Vec<BindingDesc> {
    bindings
        .iter()
        .map(|&n| BindingDesc::storage_buffer(n))
        .collect()
}

/// The denoiser's pipelines as [`PipelineContract`]s (no specialization constants;
/// [`DenoisePush`] push constants), for the contract check against their SPIR-V.
pub fn pipeline_contracts() -> Vec<PipelineContract> {
    stages()
        .iter()
        .map(|(name, spirv, bindings)| PipelineContract {
            name: (*name).to_string(),
            spirv,
            bindings: layout(bindings),
            specialization: Vec::new(),
            push_constant_size: std::mem::size_of::<DenoisePush>() as u32,
        })
        .collect()
}

/// The denoiser: its GPU buffers and pipelines (made on the first image, made again when
/// the size or the guides change) and the temporal history between the images of a
/// sequence.
pub struct Denoiser {
    params: DenoiseParams,
    state: Option<State>,
    profiler: Option<Profiler>,
    /// The history holds the previous image of the sequence.
    history: bool,
}

impl Denoiser {
    /// A denoiser with `params` (checked); it creates nothing on the GPU until its first
    /// image.
    pub fn new(params: DenoiseParams) -> Result<Self> {
        params.check()?;
        Ok(Self {
            params,
            state: None,
            profiler: None,
            history: false,
        })
    }

    pub fn params(&self) -> &DenoiseParams {
        &self.params
    }

    /// Forgets the temporal history: the next image starts a new sequence.
    pub fn reset(&mut self) {
        self.history = false;
    }

    /// Bytes of every GPU buffer the denoiser holds.
    pub fn device_bytes(&self) -> u64 {
        self.state.as_ref().map_or(0, |s| s.objects.bytes())
    }

    /// Denoises `image` with `guides`. In a sequence, call it for each frame in order
    /// (the history carries over when the guides include motion and `temporal` is on;
    /// [`Denoiser::reset`] between sequences).
    pub fn run(
        &mut self,
        ctx: &Context,
        image: &NoisyImage<'_>,
        guides: &Guides,
    ) -> Result<Denoised> {
        let (width, height) = (image.color.width, image.color.height);
        let pixels = width as usize * height as usize;
        ensure!(pixels > 0, "denoise: the image is empty ({width}x{height})");
        ensure!(
            image.color.data.len() == pixels
                && image.alpha.len() == pixels
                && image.std_error.data.len() == pixels
                && image.alpha_std_error.len() == pixels,
            "denoise: the image's planes do not all have {pixels} pixels"
        );
        guides.check(pixels)?;
        let shape = Shape {
            width,
            height,
            geometry: guides.depth.is_some() || guides.normal.is_some(),
            depth: guides.depth.is_some(),
            albedo: guides.albedo.is_some(),
            motion: guides.motion.is_some(),
            temporal: self.params.temporal && guides.motion.is_some(),
        };
        if self.state.as_ref().map(|s| s.shape) != Some(shape) {
            if let Some(old) = self.state.take() {
                old.objects.destroy(ctx);
            }
            self.history = false;
            self.state = Some(State::new(ctx, shape, self.params.iterations)?);
        }
        if self.profiler.is_none() && ctx.info().timestamp_valid_bits > 0 {
            // Scopes: the whole, prepare, residual, variance, each iteration, final.
            self.profiler = Some(Profiler::new(ctx, 5 + MAX_ITERATIONS, "denoise")?);
        }
        let state = self
            .state
            .as_ref()
            .context("internal: the denoiser's buffers were not made")?;
        state.upload(ctx, image, guides)?;

        let film = image.estimates >= self.params.min_film_estimates.max(2);
        let p = &self.params;
        let mut flags = 0;
        for (on, bit) in [
            (guides.depth.is_some(), DENOISE_HAS_DEPTH),
            (guides.normal.is_some(), DENOISE_HAS_NORMAL),
            (guides.albedo.is_some(), DENOISE_HAS_ALBEDO),
            (guides.motion.is_some(), DENOISE_HAS_MOTION),
            (film, DENOISE_FILM_VARIANCE),
            (shape.temporal, DENOISE_TEMPORAL),
            (shape.temporal && self.history, DENOISE_HISTORY),
        ] {
            if on {
                flags |= bit;
            }
        }
        let push = DenoisePush {
            width,
            height,
            step: 1,
            flags,
            sigma_luminance: p.sigma_luminance,
            sigma_depth: p.sigma_depth,
            sigma_normal: p.sigma_normal,
            temporal_alpha: p.temporal_alpha,
            moments_alpha: p.moments_alpha,
            variance_boost: p.variance_boost,
            albedo_epsilon: p.albedo_epsilon,
            max_history: p.max_history as f32,
            depth_relative: p.depth_relative,
            ..Default::default()
        };
        let timings = state.record(ctx, &push, p.iterations, self.profiler.as_mut())?;
        let bytes = ctx.readback_buffer(&state.objects[state.output])?;
        let texels: &[[f32; 4]] = bytemuck::try_cast_slice(&bytes)
            .map_err(|e| anyhow::anyhow!("denoise: reading the output back: {e}"))?;
        ensure!(
            texels.len() >= pixels,
            "denoise: the output holds {} pixels, expected {pixels}",
            texels.len()
        );
        let texels = &texels[..pixels];
        let color = ImageRgb {
            width,
            height,
            data: texels.iter().map(|t| [t[0], t[1], t[2]]).collect(),
        };
        let alpha = texels.iter().map(|t| t[3]).collect();
        let temporal = shape.temporal && self.history;
        self.history = shape.temporal;
        Ok(Denoised {
            color,
            alpha,
            gpu_ms: timings.first().map(ScopeResult::duration_ms),
            timings,
            variance: if film {
                VarianceSource::Film
            } else {
                VarianceSource::Estimated
            },
            temporal,
        })
    }

    /// Frees every GPU object.
    pub fn destroy(self, ctx: &Context) {
        if let Some(state) = self.state {
            state.objects.destroy(ctx);
        }
        if let Some(profiler) = self.profiler {
            profiler.destroy(ctx);
        }
    }
}

/// Denoises one image with a denoiser made for it and freed after.
pub fn denoise(
    ctx: &Context,
    image: &NoisyImage<'_>,
    guides: &Guides,
    params: DenoiseParams,
) -> Result<Denoised> {
    let mut denoiser = Denoiser::new(params)?;
    let result = denoiser.run(ctx, image, guides);
    denoiser.destroy(ctx);
    result
}

impl State {
    fn new(ctx: &Context, shape: Shape, iterations: u32) -> Result<State> {
        let pixels = u64::from(shape.width) * u64::from(shape.height);
        let (objects, state) = GpuObjects::build(ctx, |o| {
            let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
            let buffer = |o: &mut GpuObjects, bytes: u64, name: &str| -> Result<_> {
                Ok(o.add(ctx.create_buffer(&BufferDesc::gpu_only(bytes.max(16), storage), name)?))
            };
            // A guide the image lacks gets a 16-byte buffer the shaders never read.
            let per = |on: bool, bytes: u64| if on { pixels * bytes } else { 16 };
            let noisy = buffer(o, pixels * 16, "denoise noisy")?;
            let film_variance = buffer(o, pixels * 16, "denoise film variance")?;
            let guides = buffer(o, per(shape.geometry, 16), "denoise guides")?;
            let albedo = buffer(o, per(shape.albedo, 16), "denoise albedo")?;
            let motion = buffer(o, per(shape.motion, 8), "denoise motion")?;
            let gradient = buffer(o, per(shape.depth, 8), "denoise depth gradient")?;
            let color = [
                buffer(o, pixels * 16, "denoise colour A")?,
                buffer(o, pixels * 16, "denoise colour B")?,
            ];
            let variance = [
                buffer(o, pixels * 4, "denoise variance A")?,
                buffer(o, pixels * 4, "denoise variance B")?,
            ];
            let history = buffer(o, per(shape.temporal, 16), "denoise history")?;
            let moments = buffer(o, per(shape.temporal, 16), "denoise moments")?;
            let moments_prev = buffer(o, per(shape.temporal, 16), "denoise moments (previous)")?;
            let guides_prev = buffer(
                o,
                per(shape.temporal && shape.geometry, 16),
                "denoise guides (previous)",
            )?;
            let output = buffer(o, pixels * 16, "denoise output")?;
            let residual = buffer(o, pixels * 4, "denoise residuals")?;

            let mut pipelines = Vec::new();
            for (name, spirv, bindings) in stages() {
                let words = spirv_words(spirv)?;
                let pipeline = ctx.create_compute_pipeline(
                    &ComputePipelineDesc {
                        spirv: &words,
                        entry: "main",
                        bindings: &layout(bindings),
                        push_constant_size: std::mem::size_of::<DenoisePush>() as u32,
                        specialization: &[],
                    },
                    name,
                )?;
                pipelines.push(o.add(pipeline));
            }
            let [prepare, residual_p, variance_p, atrous, finish] = pipelines[..] else {
                bail!("internal: the denoiser has five pipelines");
            };
            // Every binding's buffer, by binding number, for one set.
            let set = |o: &mut GpuObjects,
                       pipeline: Handle<ComputePipeline>,
                       roles: &[(u32, Handle<Buffer>)],
                       name: &str|
             -> Result<Handle<DescriptorSet>> {
                let writes: Vec<DescriptorWrite> = roles
                    .iter()
                    .map(|&(binding, buffer)| DescriptorWrite::StorageBuffer {
                        binding,
                        buffer: &o[buffer],
                    })
                    .collect();
                let set = ctx.create_descriptor_set(&o[pipeline], &writes, name)?;
                Ok(o.add(set))
            };
            let prepare_set = set(
                o,
                prepare,
                &[
                    (b::DENOISE_NOISY, noisy),
                    (b::DENOISE_FILM_VARIANCE, film_variance),
                    (b::DENOISE_GUIDES, guides),
                    (b::DENOISE_ALBEDO, albedo),
                    (b::DENOISE_MOTION, motion),
                    (b::DENOISE_GRADIENT, gradient),
                    (b::DENOISE_COLOR_DST, color[0]),
                    (b::DENOISE_VARIANCE_DST, variance[1]),
                    (b::DENOISE_HISTORY, history),
                    (b::DENOISE_MOMENTS, moments),
                    (b::DENOISE_MOMENTS_PREV, moments_prev),
                    (b::DENOISE_GUIDES_PREV, guides_prev),
                ],
                "denoise prepare",
            )?;
            let residual_set = set(
                o,
                residual_p,
                &[
                    (b::DENOISE_COLOR_SRC, color[0]),
                    (b::DENOISE_RESIDUAL, residual),
                ],
                "denoise residual",
            )?;
            let variance_set = set(
                o,
                variance_p,
                &[
                    (b::DENOISE_RESIDUAL, residual),
                    (b::DENOISE_VARIANCE_SRC, variance[1]),
                    (b::DENOISE_VARIANCE_DST, variance[0]),
                    (b::DENOISE_GUIDES, guides),
                    (b::DENOISE_GRADIENT, gradient),
                ],
                "denoise variance",
            )?;
            let mut atrous_sets = Vec::new();
            for (src, dst) in [(0, 1), (1, 0)] {
                atrous_sets.push(set(
                    o,
                    atrous,
                    &[
                        (b::DENOISE_COLOR_SRC, color[src]),
                        (b::DENOISE_VARIANCE_SRC, variance[src]),
                        (b::DENOISE_COLOR_DST, color[dst]),
                        (b::DENOISE_VARIANCE_DST, variance[dst]),
                        (b::DENOISE_GUIDES, guides),
                        (b::DENOISE_GRADIENT, gradient),
                        (b::DENOISE_HISTORY, history),
                    ],
                    if src == 0 {
                        "denoise atrous A->B"
                    } else {
                        "denoise atrous B->A"
                    },
                )?);
            }
            // Iteration k reads colour (k % 2) and writes the other: the last writes B
            // for an odd count, A for an even one (A: prepare's output when there is none).
            let result = color[(iterations % 2) as usize];
            let finish_set = set(
                o,
                finish,
                &[
                    (b::DENOISE_COLOR_SRC, result),
                    (b::DENOISE_ALBEDO, albedo),
                    (b::DENOISE_OUTPUT, output),
                    (b::DENOISE_GUIDES, guides),
                    (b::DENOISE_GUIDES_PREV, guides_prev),
                    (b::DENOISE_MOMENTS, moments),
                    (b::DENOISE_MOMENTS_PREV, moments_prev),
                    (b::DENOISE_HISTORY, history),
                ],
                "denoise final",
            )?;
            Ok(StateHandles {
                noisy,
                film_variance,
                guides,
                albedo,
                motion,
                output,
                prepare: (prepare, prepare_set),
                residual: (residual_p, residual_set),
                variance: (variance_p, variance_set),
                atrous: (atrous, [atrous_sets[0], atrous_sets[1]]),
                finish: (finish, finish_set),
            })
        })?;
        Ok(State {
            shape,
            objects,
            noisy: state.noisy,
            film_variance: state.film_variance,
            guides: state.guides,
            albedo: state.albedo,
            motion: state.motion,
            output: state.output,
            prepare: state.prepare,
            residual: state.residual,
            variance: state.variance,
            atrous: state.atrous,
            finish: state.finish,
        })
    }

    /// Uploads the image and its guides (non-finite guide values made harmless: no
    /// depth, a zero normal or albedo, no motion).
    fn upload(&self, ctx: &Context, image: &NoisyImage<'_>, guides: &Guides) -> Result<()> {
        let pixels = image.color.data.len();
        let rgba: Vec<[f32; 4]> = (0..pixels)
            .map(|i| {
                let c = image.color.data[i];
                [c[0], c[1], c[2], image.alpha[i]]
            })
            .collect();
        ctx.upload_buffer(&self.objects[self.noisy], 0, bytemuck::cast_slice(&rgba))?;
        let variance: Vec<[f32; 4]> = (0..pixels)
            .map(|i| {
                let s = image.std_error.data[i];
                let a = image.alpha_std_error[i];
                [s[0] * s[0], s[1] * s[1], s[2] * s[2], a * a]
            })
            .collect();
        ctx.upload_buffer(
            &self.objects[self.film_variance],
            0,
            bytemuck::cast_slice(&variance),
        )?;
        let finite = |v: f32| if v.is_finite() { v } else { 0.0 };
        if self.shape.geometry {
            let texels: Vec<[f32; 4]> = (0..pixels)
                .map(|i| {
                    let n = guides.normal.as_ref().map_or([0.0; 3], |n| {
                        [finite(n[0][i]), finite(n[1][i]), finite(n[2][i])]
                    });
                    let z = guides.depth.as_ref().map_or(-1.0, |d| {
                        let z = d[i];
                        if z.is_finite() && z >= 0.0 {
                            z
                        } else {
                            -1.0
                        }
                    });
                    [n[0], n[1], n[2], z]
                })
                .collect();
            ctx.upload_buffer(&self.objects[self.guides], 0, bytemuck::cast_slice(&texels))?;
        }
        if let Some(a) = &guides.albedo {
            let texels: Vec<[f32; 4]> = (0..pixels)
                .map(|i| [finite(a[0][i]), finite(a[1][i]), finite(a[2][i]), 0.0])
                .collect();
            ctx.upload_buffer(&self.objects[self.albedo], 0, bytemuck::cast_slice(&texels))?;
        }
        if let Some(m) = &guides.motion {
            let texels: Vec<[f32; 2]> = (0..pixels)
                .map(|i| [finite(m[0][i]), finite(m[1][i])])
                .collect();
            ctx.upload_buffer(&self.objects[self.motion], 0, bytemuck::cast_slice(&texels))?;
        }
        Ok(())
    }

    /// Records and submits the stages; returns the timestamps (the `denoise` scope with
    /// one child per dispatch) when there is a profiler.
    fn record(
        &self,
        ctx: &Context,
        push: &DenoisePush,
        iterations: u32,
        mut profiler: Option<&mut Profiler>,
    ) -> Result<Vec<ScopeResult>> {
        let groups = [
            push.width.div_ceil(GROUP_SIZE[0]),
            push.height.div_ceil(GROUP_SIZE[1]),
            1,
        ];
        let o = &self.objects;
        let temporal = push.flags & DENOISE_TEMPORAL != 0;
        ctx.submit_one_shot("denoise", |cmd| {
            if let Some(p) = profiler.as_deref_mut() {
                p.begin_frame(cmd);
                p.begin_scope(ctx, cmd, "denoise")?;
            }
            let mut stage = |label: &str,
                             (pipeline, set): (Handle<ComputePipeline>, Handle<DescriptorSet>),
                             push: &DenoisePush,
                             first: bool|
             -> Result<()> {
                if !first {
                    compute_barrier(ctx, cmd);
                }
                if let Some(p) = profiler.as_deref_mut() {
                    p.begin_scope(ctx, cmd, label)?;
                }
                o[pipeline].dispatch(ctx, cmd, &o[set], bytemuck::bytes_of(push), groups)?;
                if let Some(p) = profiler.as_deref_mut() {
                    p.end_scope(ctx, cmd)?;
                }
                Ok(())
            };
            stage("prepare", self.prepare, push, true)?;
            stage("residual", self.residual, push, false)?;
            stage("variance", self.variance, push, false)?;
            for k in 0..iterations {
                let mut it = *push;
                it.step = 1 << k;
                if k == 0 && temporal {
                    it.flags |= DENOISE_WRITE_HISTORY;
                }
                let set = self.atrous.1[(k % 2) as usize];
                stage(
                    &format!("atrous {}", k + 1),
                    (self.atrous.0, set),
                    &it,
                    false,
                )?;
            }
            let mut last = *push;
            if iterations == 0 && temporal {
                last.flags |= DENOISE_WRITE_HISTORY;
            }
            stage("final", self.finish, &last, false)?;
            if let Some(p) = profiler.as_deref_mut() {
                p.end_scope(ctx, cmd)?;
            }
            Ok(())
        })?;
        match profiler {
            Some(p) => p.resolve(ctx),
            None => Ok(Vec::new()),
        }
    }
}

/// The handles [`State::new`] builds.
struct StateHandles {
    noisy: Handle<Buffer>,
    film_variance: Handle<Buffer>,
    guides: Handle<Buffer>,
    albedo: Handle<Buffer>,
    motion: Handle<Buffer>,
    output: Handle<Buffer>,
    prepare: (Handle<ComputePipeline>, Handle<DescriptorSet>),
    residual: (Handle<ComputePipeline>, Handle<DescriptorSet>),
    variance: (Handle<ComputePipeline>, Handle<DescriptorSet>),
    atrous: (Handle<ComputePipeline>, [Handle<DescriptorSet>; 2]),
    finish: (Handle<ComputePipeline>, Handle<DescriptorSet>),
}

/// Root-mean-square difference of two images' RGB over the mean of `reference`'s
/// (normalised RMSE: 0 is exact); `None` when the sizes differ or the reference is
/// black.
pub fn nrmse(image: &ImageRgb, reference: &ImageRgb) -> Option<f64> {
    if (image.width, image.height) != (reference.width, reference.height) {
        return None;
    }
    let n = (reference.data.len() * 3) as f64;
    let mean: f64 = reference
        .data
        .iter()
        .flat_map(|p| p.iter())
        .map(|&v| f64::from(v))
        .sum::<f64>()
        / n;
    if mean <= 0.0 || !mean.is_finite() {
        return None;
    }
    let se: f64 = image
        .data
        .iter()
        .zip(&reference.data)
        .flat_map(|(a, b)| a.iter().zip(b.iter()))
        .map(|(&a, &b)| (f64::from(a) - f64::from(b)).powi(2))
        .sum();
    Some((se / n).sqrt() / mean)
}
