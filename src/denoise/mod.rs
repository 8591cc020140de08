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

mod stages;
mod writer;

use stages::{layout, stages, Shape, State};

pub use writer::{Engine, Writer};

use anyhow::{ensure, Context as _, Result};
use nimbus_gpu::{Context, Profiler, ScopeResult};

use crate::output::layers::Aov;
use crate::output::ImageRgb;
use crate::passes::PipelineContract;
use crate::renderer::RenderResult;
use crate::shader_data::{
    DenoisePush, DENOISE_FILM_VARIANCE, DENOISE_HAS_ALBEDO, DENOISE_HAS_DEPTH, DENOISE_HAS_MOTION,
    DENOISE_HAS_NORMAL, DENOISE_HISTORY, DENOISE_TEMPORAL,
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
