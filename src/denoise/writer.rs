//! What `nimbus render --denoise` writes: the denoised image as the main RGBA, the noisy
//! one as the EXR layer `noisy` (`noisy.R/G/B/A`), the denoiser's settings as the header
//! attribute `nimbus/denoise`. Without `--denoise` it writes exactly what
//! [`crate::merge::write_render`] writes.

use std::path::Path;

use anyhow::Result;
use nimbus_gpu::Context;

use super::{DenoiseParams, Denoised, Denoiser, Guides, NoisyImage};
use crate::merge::{layers_of, write_render, RenderInfo};
use crate::output::layers::{write_layers, Aov, ExrView};
use crate::output::{image_extension, Display, ImageRgb};
use crate::renderer::RenderResult;

/// The layer that keeps the noisy image in a denoised EXR.
pub const NOISY_LAYER: &str = "noisy";

/// Writes a render's images, denoised when asked for; in a sequence it carries the
/// denoiser's temporal history from one frame to the next.
pub struct Writer {
    denoiser: Option<Denoiser>,
    /// The scene frame last denoised (a gap in the frames restarts the history), and the
    /// last image in and out: the same result written twice (the last frame of a range
    /// to --out too) is denoised once.
    last: Option<(Option<u32>, ImageRgb, Denoised)>,
}

impl Writer {
    /// A writer that denoises with `params`, or writes the noisy image as it is (`None`).
    pub fn new(params: Option<DenoiseParams>) -> Result<Self> {
        Ok(Self {
            denoiser: params.map(Denoiser::new).transpose()?,
            last: None,
        })
    }

    /// The guides of a render's image: its depth, normal, albedo and motion AOVs where it
    /// has them. (The render's AOVs reach [`RenderResult`] on the AOV branch; until they
    /// do, a render has none and the denoiser runs on the colour and its variance.)
    fn guides_of(_result: &RenderResult) -> Guides {
        Guides::none()
    }

    /// Writes `result` to `path` like [`write_render`], denoised when this writer
    /// denoises; returns a line saying what the denoiser did.
    #[allow(clippy::too_many_arguments)]
    pub fn write(
        &mut self,
        ctx: &Context,
        path: &Path,
        result: &RenderResult,
        info: &RenderInfo,
        display: &Display,
        transparent: bool,
        view: Option<ExrView>,
    ) -> Result<Option<String>> {
        let Some(denoiser) = self.denoiser.as_mut() else {
            write_render(path, result, info, display, transparent, view)?;
            return Ok(None);
        };
        let reuse = matches!(&self.last, Some((frame, image, _))
            if *frame == result.scene_frame && *image == result.image);
        if !reuse {
            let follows = match (&self.last, result.scene_frame) {
                (Some((Some(prev), _, _)), Some(frame)) => frame == prev + 1,
                _ => false,
            };
            if !follows {
                denoiser.reset();
            }
            let guides = Self::guides_of(result);
            let denoised = denoiser.run(ctx, &NoisyImage::of(result), &guides)?;
            self.last = Some((result.scene_frame, result.image.clone(), denoised));
        }
        let Some((_, _, denoised)) = &self.last else {
            anyhow::bail!("internal: no denoised image");
        };
        if image_extension(path)? == "exr" {
            let mut layers = layers_of(result, info, view);
            layers.aovs.push(Aov {
                name: NOISY_LAYER.to_string(),
                channels: vec![
                    ("R".into(), result.image.data.iter().map(|p| p[0]).collect()),
                    ("G".into(), result.image.data.iter().map(|p| p[1]).collect()),
                    ("B".into(), result.image.data.iter().map(|p| p[2]).collect()),
                    ("A".into(), result.alpha.clone()),
                ],
            });
            layers.color = denoised.color.clone();
            layers.alpha = denoised.alpha.clone();
            layers
                .attributes
                .insert("denoise".into(), denoiser.params().describe());
            write_layers(path, &layers)?;
        } else {
            let alpha = transparent.then_some(denoised.alpha.as_slice());
            crate::output::write_png_with_metadata(
                path,
                &denoised.color,
                alpha,
                display,
                &info.attributes(),
            )?;
        }
        let ms = denoised.gpu_ms.map_or_else(
            || "no GPU timestamps".to_string(),
            |ms| format!("GPU {ms:.2} ms"),
        );
        Ok(Some(format!(
            "denoised {} ({ms}; variance from {}{}; guides: {})",
            path.display(),
            match denoised.variance {
                super::VarianceSource::Film => "the film",
                super::VarianceSource::Estimated => "a spatial estimate",
            },
            if denoised.temporal {
                ", temporal history"
            } else {
                ""
            },
            Self::guides_of(result).describe()
        )))
    }

    /// Frees the denoiser's GPU objects.
    pub fn destroy(self, ctx: &Context) {
        if let Some(d) = self.denoiser {
            d.destroy(ctx);
        }
    }
}
