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

/// Which denoiser `nimbus render --denoise[=ENGINE]` runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Engine {
    /// The SVGF-style à-trous filter on the GPU ([`Denoiser`]), with temporal history.
    Svgf,
    /// Intel Open Image Denoise (crates/nimbus-oidn, the `oidn` feature): a neural
    /// denoiser for final frames, on the CPU or CUDA; no temporal history.
    Oidn,
}

impl Engine {
    /// The engine named `text` (`svgf` or `oidn`), for the command line.
    pub fn parse(text: &str) -> std::result::Result<Engine, String> {
        match text {
            "svgf" => Ok(Engine::Svgf),
            "oidn" => Ok(Engine::Oidn),
            _ => Err(format!("unknown denoiser {text:?}; valid: svgf, oidn")),
        }
    }

    /// Refuses an engine this build lacks (Open Image Denoise without the `oidn`
    /// feature), so that a render is refused before it starts.
    pub fn check_available(self) -> Result<()> {
        if self == Engine::Oidn && !cfg!(feature = "oidn") {
            anyhow::bail!(
                "--denoise=oidn: this nimbus was built without Open Image Denoise; install it \
                 with tools/install-oidn.sh and build with `cargo build --release --features \
                 oidn` (docs/oidn.md), or use --denoise (the GPU filter)"
            );
        }
        Ok(())
    }
}

/// The denoiser a [`Writer`] holds.
enum Held {
    Svgf(Box<Denoiser>),
    #[cfg(feature = "oidn")]
    Oidn(nimbus_oidn::Denoiser),
}

/// Writes a render's images, denoised when asked for; in a sequence it carries the
/// denoiser's temporal history from one frame to the next.
pub struct Writer {
    denoiser: Option<Held>,
    /// The scene frame last denoised (a gap in the frames restarts the history), and the
    /// last image in and out: the same result written twice (the last frame of a range
    /// to --out too) is denoised once.
    last: Option<(Option<u32>, ImageRgb, Denoised)>,
}

impl Writer {
    /// A writer that denoises with `engine` (the SVGF filter with its default
    /// parameters, or Open Image Denoise), or writes the noisy image as it is (`None`).
    pub fn new(engine: Option<Engine>) -> Result<Self> {
        let denoiser = match engine {
            None => None,
            Some(Engine::Svgf) => Some(Held::Svgf(Box::new(Denoiser::new(
                DenoiseParams::default(),
            )?))),
            #[cfg(feature = "oidn")]
            Some(Engine::Oidn) => Some(Held::Oidn(nimbus_oidn::Denoiser::new()?)),
            #[cfg(not(feature = "oidn"))]
            Some(Engine::Oidn) => {
                Engine::Oidn.check_available()?;
                None
            }
        };
        Ok(Self {
            denoiser,
            last: None,
        })
    }

    /// The guides of a render's image for the GPU filter: its albedo and motion AOVs
    /// where it has them (`nimbus render --denoise` asks for them). Not its depth and
    /// normal, even where `--aovs` renders them: in a medium the normal is the density's
    /// gradient, which turns from pixel to pixel, and on the benchmark media the normal
    /// guide left 0.77-1.02 of the noisy error where the albedo alone leaves 0.16-0.66,
    /// and the depth cost too on two scenes of three (docs/denoise.md, "Guides").
    fn guides_of(result: &RenderResult) -> Guides {
        let all = Guides::from_aovs(&result.aovs);
        Guides {
            albedo: all.albedo,
            motion: all.motion,
            ..Guides::none()
        }
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
            let guides = Self::guides_of(result);
            let denoised = match denoiser {
                Held::Svgf(d) => {
                    if !follows {
                        d.reset();
                    }
                    d.run(ctx, &NoisyImage::of(result), &guides)?
                }
                #[cfg(feature = "oidn")]
                // OIDN's network uses a medium's normals without harm (docs/denoise.md).
                Held::Oidn(d) => oidn_denoise(d, result, &Guides::from_aovs(&result.aovs))?,
            };
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
            layers.attributes.insert(
                "denoise".into(),
                match denoiser {
                    Held::Svgf(d) => d.params().describe(),
                    #[cfg(feature = "oidn")]
                    Held::Oidn(_) => {
                        "Open Image Denoise 2 (hdr, albedo and normal guides where present)".into()
                    }
                },
            );
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
        let ms = match (&*denoiser, denoised.gpu_ms) {
            #[cfg(feature = "oidn")]
            (Held::Oidn(_), _) => "Open Image Denoise".to_string(),
            (_, Some(ms)) => format!("GPU {ms:.2} ms"),
            (_, None) => "no GPU timestamps".to_string(),
        };
        // The variance steers the GPU filter only; Open Image Denoise reads none.
        let variance = match (&*denoiser, denoised.variance) {
            #[cfg(feature = "oidn")]
            (Held::Oidn(_), _) => "",
            (_, super::VarianceSource::Film) => "; variance from the film",
            (_, super::VarianceSource::Estimated) => "; variance from a spatial estimate",
        };
        Ok(Some(format!(
            "denoised {} ({ms}{variance}{}; guides: {})",
            path.display(),
            if denoised.temporal {
                ", temporal history"
            } else {
                ""
            },
            match denoiser {
                Held::Svgf(_) => Self::guides_of(result).describe(),
                #[cfg(feature = "oidn")]
                Held::Oidn(_) => Guides::from_aovs(&result.aovs).describe(),
            }
        )))
    }

    /// Frees the denoiser's GPU objects.
    pub fn destroy(self, ctx: &Context) {
        if let Some(Held::Svgf(d)) = self.denoiser {
            d.destroy(ctx);
        }
    }
}

/// Open Image Denoise on a render's image: the premultiplied RGB as an HDR image, with the
/// albedo and normal AOVs as its auxiliary images where the render has both (OIDN takes a
/// normal only beside an albedo); the alpha stays the render's.
#[cfg(feature = "oidn")]
fn oidn_denoise(
    d: &nimbus_oidn::Denoiser,
    result: &RenderResult,
    guides: &Guides,
) -> Result<Denoised> {
    let (w, h) = (result.image.width, result.image.height);
    let interleave = |planes: &[Vec<f32>; 3]| -> Vec<f32> {
        (0..planes[0].len())
            .flat_map(|i| [planes[0][i], planes[1][i], planes[2][i]])
            .collect()
    };
    let color: Vec<f32> = result.image.data.iter().flat_map(|p| *p).collect();
    let albedo = guides.albedo.as_ref().map(interleave);
    let normal = albedo.as_ref().and(guides.normal.as_ref()).map(interleave);
    let out = d.denoise(w, h, &color, albedo.as_deref(), normal.as_deref(), true)?;
    let mut image = ImageRgb::new(w, h);
    for (p, c) in image.data.iter_mut().zip(out.chunks_exact(3)) {
        *p = [c[0], c[1], c[2]];
    }
    Ok(Denoised {
        color: image,
        alpha: result.alpha.clone(),
        gpu_ms: None,
        timings: Vec::new(),
        variance: super::VarianceSource::Estimated,
        temporal: false,
    })
}
