//! From linear radiance to 8-bit sRGB: exposure, a tone curve, the sRGB transfer
//! function; and the PNG file that carries it, marked as sRGB.

use std::path::Path;

use anyhow::Context as _;

use super::ImageRgb;

/// The tone curve applied per channel after exposure, before the sRGB OETF.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Tonemap {
    /// The ACES filmic fit of Krzysztof Narkowicz (2015).
    #[default]
    Aces,
    /// John Hable's filmic curve (Uncharted 2), white point 11.2, exposure bias 2.
    Filmic,
    /// No curve: values above 1 clip to white.
    Clamp,
}

impl Tonemap {
    pub const ALL: [Tonemap; 3] = [Tonemap::Aces, Tonemap::Filmic, Tonemap::Clamp];

    pub fn name(self) -> &'static str {
        match self {
            Tonemap::Aces => "aces",
            Tonemap::Filmic => "filmic",
            Tonemap::Clamp => "clamp",
        }
    }

    /// The curve by name (`aces`, `filmic`, `clamp`).
    pub fn from_name(name: &str) -> Option<Tonemap> {
        Tonemap::ALL.into_iter().find(|t| t.name() == name)
    }

    /// The curve at x ≥ 0 (exposed linear value), in [0, 1].
    pub fn apply(self, x: f32) -> f32 {
        // Clamp the input so x² cannot overflow; every curve is saturated long before.
        let x = x.clamp(0.0, 1.0e6);
        match self {
            Tonemap::Aces => aces_filmic(x),
            Tonemap::Filmic => (hable(2.0 * x) / hable(HABLE_WHITE)).clamp(0.0, 1.0),
            Tonemap::Clamp => x.min(1.0),
        }
    }
}

/// How a linear image becomes a displayable one: exposure multiplier and tone curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Display {
    /// Finite, > 0.
    pub exposure: f32,
    pub tonemap: Tonemap,
}

impl Default for Display {
    fn default() -> Self {
        Self {
            exposure: 1.0,
            tonemap: Tonemap::Aces,
        }
    }
}

/// The ACES filmic curve fit of Krzysztof Narkowicz (2015), clamped to [0, 1].
///
/// x(2.51x + 0.03) / (x(2.43x + 0.59) + 0.14); the denominator is ≥ 0.14 for x ≥ 0.
fn aces_filmic(x: f32) -> f32 {
    let y = (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14);
    y.clamp(0.0, 1.0)
}

/// Linear white of Hable's curve: inputs at or above it map to 1.
const HABLE_WHITE: f32 = 11.2;

/// Hable's filmic curve: ((x(Ax + CB) + DE) / (x(Ax + B) + DF)) − E/F with his
/// constants; the denominator is ≥ DF = 0.06 for x ≥ 0.
fn hable(x: f32) -> f32 {
    let (a, b, c, d, e, f) = (0.15, 0.50, 0.10, 0.20, 0.02, 0.30);
    (x * (a * x + c * b) + d * e) / (x * (a * x + b) + d * f) - e / f
}

/// The sRGB opto-electronic transfer function for linear c in [0, 1].
fn srgb_oetf(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// Tonemaps linear radiance to 8-bit sRGB with the default ACES curve (see
/// [`tonemap_srgb8_with`]).
pub fn tonemap_srgb8(img: &ImageRgb, exposure: f32) -> Vec<[u8; 3]> {
    tonemap_srgb8_with(
        img,
        &Display {
            exposure,
            tonemap: Tonemap::Aces,
        },
    )
}

/// Tonemaps linear radiance to 8-bit sRGB: multiply by the exposure, apply the tone
/// curve per channel, then the sRGB OETF, rounded to the nearest code.
///
/// Negative values and NaN map to 0 and +infinity to 255, so the result is defined
/// for every input (the file writers reject non-finite images before this).
pub fn tonemap_srgb8_with(img: &ImageRgb, display: &Display) -> Vec<[u8; 3]> {
    let to_code = |v: f32| {
        let x = v * display.exposure;
        let x = if x.is_nan() { 0.0 } else { x };
        (srgb_oetf(display.tonemap.apply(x)) * 255.0).round() as u8
    };
    img.data.iter().map(|p| p.map(to_code)).collect()
}

/// Writes `img` tonemapped as an 8-bit RGB PNG with an sRGB chunk (so colour-managed
/// viewers do not guess) and `text` as tEXt chunks (keyword, text; Latin-1 keywords).
pub(super) fn write_png(
    path: &Path,
    img: &ImageRgb,
    alpha: Option<&[f32]>,
    display: &Display,
    text: &[(String, String)],
) -> anyhow::Result<()> {
    let bytes: Vec<u8> = match alpha {
        None => tonemap_srgb8_with(img, display)
            .into_iter()
            .flatten()
            .collect(),
        Some(alpha) => {
            anyhow::ensure!(
                alpha.len() == img.data.len(),
                "PNG {}: {} alpha values for {} pixels",
                path.display(),
                alpha.len(),
                img.data.len()
            );
            // PNG alpha is straight: the premultiplied colour is divided by alpha before
            // the tone curve, and a pixel of alpha 0 is black.
            let straight = ImageRgb {
                width: img.width,
                height: img.height,
                data: img
                    .data
                    .iter()
                    .zip(alpha)
                    .map(|(c, &a)| {
                        if a > 0.0 {
                            c.map(|v| v / a.min(1.0))
                        } else {
                            [0.0; 3]
                        }
                    })
                    .collect(),
            };
            tonemap_srgb8_with(&straight, display)
                .into_iter()
                .zip(alpha)
                .flat_map(|(rgb, &a)| {
                    let a8 = (a.clamp(0.0, 1.0) * 255.0).round() as u8;
                    [rgb[0], rgb[1], rgb[2], a8]
                })
                .collect()
        }
    };
    let file =
        std::fs::File::create(path).with_context(|| format!("create PNG {}", path.display()))?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), img.width, img.height);
    encoder.set_color(if alpha.is_some() {
        png::ColorType::Rgba
    } else {
        png::ColorType::Rgb
    });
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    for (keyword, value) in text {
        encoder
            .add_text_chunk(keyword.clone(), value.clone())
            .with_context(|| format!("PNG {}: text chunk {keyword:?}", path.display()))?;
    }
    let mut writer = encoder
        .write_header()
        .with_context(|| format!("write PNG {}", path.display()))?;
    writer
        .write_image_data(&bytes)
        .and_then(|()| writer.finish())
        .with_context(|| format!("write PNG {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_curve_is_monotone_from_black_to_white() {
        for t in Tonemap::ALL {
            let mut previous = t.apply(0.0);
            // Hable's curve is 0 at 0 up to rounding (DE/DF − E/F).
            assert!(previous.abs() < 1e-6, "{t:?} at 0: {previous}");
            for i in 1..20_000 {
                let y = t.apply(i as f32 * 1e-3);
                assert!(y >= previous, "{t:?} falls at {}", i as f32 * 1e-3);
                previous = y;
            }
            assert_eq!(t.apply(1.0e7), 1.0, "{t:?} saturates");
            assert_eq!(Tonemap::from_name(t.name()), Some(t));
        }
        assert_eq!(Tonemap::from_name("reinhard"), None);
    }

    #[test]
    fn the_curves_differ_in_the_highlights() {
        // Clamp clips at 1; the filmic curves still separate 2 from 4.
        assert_eq!(Tonemap::Clamp.apply(2.0), Tonemap::Clamp.apply(4.0));
        for t in [Tonemap::Aces, Tonemap::Filmic] {
            assert!(t.apply(2.0) < t.apply(4.0), "{t:?}");
        }
        assert!((Tonemap::Filmic.apply(HABLE_WHITE / 2.0) - 1.0).abs() < 1e-6);
    }
}
