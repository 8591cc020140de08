//! Rendered images and their files.
//!
//! An [`ImageRgb`] holds linear radiance in W/(m²·sr), one float RGB triple per pixel,
//! row-major with pixel (0, 0) at the top left (`docs/scene-format.md`).
//!
//! - `.exr`: linear float32 RGB, lossless ZIP compression, exactly the stored values.
//! - `.png`: 8-bit sRGB after an exposure and a tone curve ([`Display`], default the
//!   ACES filmic fit of Narkowicz 2015), with an sRGB chunk ([`tonemap`]).
//!
//! A render's own file carries more: [`layers`] writes the EXR a compositor reads
//! (premultiplied RGBA, a `stderr` layer, optional AOVs and the render's metadata in
//! the header) and reads it back for `nimbus merge`.
//!
//! Writers refuse images holding NaN or infinity: a non-finite pixel is a renderer bug,
//! and a file is no place to hide it.

pub mod layers;
pub mod tonemap;

use std::path::{Path, PathBuf};

use anyhow::{bail, ensure, Context};

pub use layers::{read_layers, write_layers, Layers};
pub use tonemap::{tonemap_srgb8, tonemap_srgb8_with, Display, Tonemap};

/// File extensions [`write_image`] understands.
pub const SUPPORTED_EXTENSIONS: [&str; 2] = ["exr", "png"];

/// A float RGB image, row-major, pixel (0, 0) at the top left.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageRgb {
    pub width: u32,
    pub height: u32,
    /// `width * height` pixels; pixel (x, y) is `data[y * width + x]`.
    pub data: Vec<[f32; 3]>,
}

impl ImageRgb {
    /// A black image.
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            data: vec![[0.0; 3]; width as usize * height as usize],
        }
    }

    /// An image from f64 pixels (row-major), rounded to f32.
    pub fn from_rgb_f64(width: u32, height: u32, pixels: &[[f64; 3]]) -> anyhow::Result<Self> {
        ensure!(
            pixels.len() == width as usize * height as usize,
            "{} pixels given for a {width}x{height} image",
            pixels.len()
        );
        let data = pixels
            .iter()
            .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32])
            .collect();
        Ok(Self {
            width,
            height,
            data,
        })
    }

    fn index(&self, x: u32, y: u32) -> usize {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside a {}x{} image",
            self.width,
            self.height
        );
        y as usize * self.width as usize + x as usize
    }

    /// The pixel at column `x`, row `y` (row 0 at the top).
    ///
    /// # Panics
    /// If (x, y) lies outside the image.
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.data[self.index(x, y)]
    }

    /// Sets the pixel at column `x`, row `y`.
    ///
    /// # Panics
    /// If (x, y) lies outside the image.
    pub fn set(&mut self, x: u32, y: u32, rgb: [f32; 3]) {
        let i = self.index(x, y);
        self.data[i] = rgb;
    }

    /// Mean of each channel over all pixels, accumulated in f64 (0 for an empty image).
    pub fn mean(&self) -> [f64; 3] {
        let mut sum = [0.0f64; 3];
        for p in &self.data {
            for c in 0..3 {
                sum[c] += f64::from(p[c]);
            }
        }
        let n = self.data.len().max(1) as f64;
        sum.map(|s| s / n)
    }

    /// The first pixel holding NaN or infinity, as (x, y, value).
    pub fn first_non_finite(&self) -> Option<(u32, u32, [f32; 3])> {
        let width = self.width.max(1) as usize;
        self.data
            .iter()
            .position(|p| p.iter().any(|v| !v.is_finite()))
            .map(|i| ((i % width) as u32, (i / width) as u32, self.data[i]))
    }
}

/// Writes `img` to `path`; the extension picks the format (`.exr` linear float32,
/// `.png` tonemapped 8-bit sRGB with `exposure` and the ACES curve, see
/// [`tonemap_srgb8`]).
///
/// Fails, naming the file, on an unknown extension, a pixel count that does not match
/// the size, or any non-finite pixel.
pub fn write_image(path: &Path, img: &ImageRgb, exposure: f32) -> anyhow::Result<()> {
    write_image_with(
        path,
        img,
        &Display {
            exposure,
            tonemap: Tonemap::Aces,
        },
    )
}

/// [`write_image`] with any [`Display`] for a `.png`.
pub fn write_image_with(path: &Path, img: &ImageRgb, display: &Display) -> anyhow::Result<()> {
    let extension = image_extension(path).context("cannot write")?;
    check_image(path, img)?;
    write_atomically(path, |tmp| match extension.as_str() {
        "exr" => write_exr(tmp, img),
        _ => tonemap::write_png(tmp, img, None, display, &[software_text()]),
    })
}

/// Writes `img` as a tonemapped sRGB PNG with `metadata` as tEXt chunks named
/// `nimbus/<key>` (beside `Software`); with `alpha` (the premultiplied image's coverage,
/// one value per pixel) an RGBA PNG of straight alpha.
pub fn write_png_with_metadata(
    path: &Path,
    img: &ImageRgb,
    alpha: Option<&[f32]>,
    display: &Display,
    metadata: &std::collections::BTreeMap<String, String>,
) -> anyhow::Result<()> {
    ensure!(
        image_extension(path)? == "png",
        "{}: expected a .png file",
        path.display()
    );
    check_image(path, img)?;
    let mut text = vec![software_text()];
    text.extend(
        metadata
            .iter()
            .map(|(k, v)| (format!("{}{k}", layers::ATTRIBUTE_PREFIX), v.clone())),
    );
    write_atomically(path, |tmp| {
        tonemap::write_png(tmp, img, alpha, display, &text)
    })
}

/// The PNG `Software` text: Nimbus and its version.
pub(crate) fn software_text() -> (String, String) {
    (
        "Software".to_string(),
        format!("Nimbus {}", env!("CARGO_PKG_VERSION")),
    )
}

/// Refuses an image whose pixel count does not match its size, or with a non-finite
/// pixel, naming `path`.
fn check_image(path: &Path, img: &ImageRgb) -> anyhow::Result<()> {
    ensure!(
        img.data.len() == img.width as usize * img.height as usize,
        "cannot write {}: {} pixels for a {}x{} image",
        path.display(),
        img.data.len(),
        img.width,
        img.height
    );
    if let Some((x, y, value)) = img.first_non_finite() {
        bail!(
            "cannot write {}: pixel ({x}, {y}) is not finite ({value:?}); the renderer \
             produced NaN or infinity",
            path.display()
        );
    }
    Ok(())
}

/// The lower-case extension of an image path, if Nimbus writes that format.
pub fn image_extension(path: &Path) -> anyhow::Result<String> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    ensure!(
        SUPPORTED_EXTENSIONS.contains(&extension.as_str()),
        "{}: unsupported image type {extension:?}; use .exr (linear radiance) or .png \
         (tonemapped)",
        path.display()
    );
    Ok(extension)
}

/// The temporary file beside `path` that [`write_atomically`] writes first: hidden,
/// in the same directory (so the rename stays on one file system), unique per process,
/// with the target's extension (the encoders pick formats by it).
fn temporary_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let ext = path
        .extension()
        .map(|e| format!(".{}", e.to_string_lossy()))
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.tmp{ext}", std::process::id()))
}

/// True while [`write_atomically`] writes an image: an interrupt handler lets the write
/// finish (the render stops right after it) instead of ending the process, which would
/// lose the image and leave its temporary file behind.
pub static WRITING: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Writes through `write` into a temporary file beside `path`, flushes it to disk and
/// renames it over `path`: a reader sees the old file or the complete new one, never a
/// partial file, and a failed write (full disk, interrupt) leaves the old file intact.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&Path) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    /// Clears [`WRITING`] however the write ends.
    struct Writing;
    impl Drop for Writing {
        fn drop(&mut self) {
            WRITING.store(false, std::sync::atomic::Ordering::SeqCst);
        }
    }
    WRITING.store(true, std::sync::atomic::Ordering::SeqCst);
    let _writing = Writing;
    let tmp = temporary_path(path);
    let result = write(&tmp).and_then(|()| {
        std::fs::File::open(&tmp)
            .and_then(|f| f.sync_all())
            .with_context(|| format!("flush {}", tmp.display()))?;
        std::fs::rename(&tmp, path)
            .with_context(|| format!("rename {} to {}", tmp.display(), path.display()))
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Checks, before any rendering, that an image can be written at `path`: a known
/// extension, an existing directory, and permission to create a file in it (tried by
/// creating and removing the temporary file [`write_atomically`] would use).
pub fn check_writable(path: &Path) -> anyhow::Result<()> {
    image_extension(path)?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    ensure!(
        dir.is_dir(),
        "{}: the directory {} does not exist",
        path.display(),
        dir.display()
    );
    ensure!(
        !path.is_dir(),
        "{}: is a directory, not an image file",
        path.display()
    );
    let tmp = temporary_path(path);
    std::fs::File::create(&tmp).with_context(|| {
        format!(
            "{}: cannot create a file in {}",
            path.display(),
            dir.display()
        )
    })?;
    let _ = std::fs::remove_file(&tmp);
    Ok(())
}

/// Writes linear float32 RGB with lossless compression.
fn write_exr(path: &Path, img: &ImageRgb) -> anyhow::Result<()> {
    use exr::prelude::{Encoding, Image, SpecificChannels, Vec2, WritableImage};

    let width = img.width as usize;
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let p = img.data[y * width + x];
        (p[0], p[1], p[2])
    });
    Image::from_encoded_channels(
        (width, img.height as usize),
        Encoding::SMALL_LOSSLESS,
        channels,
    )
    .write()
    .to_file(path)
    .with_context(|| format!("write EXR {}", path.display()))
}

/// The `nimbus/<key>` metadata of an image Nimbus wrote (keys without the prefix): an
/// EXR's header attributes or a PNG's tEXt chunks. The whole image is read and decoded,
/// so a truncated or damaged file is an error, not an image.
pub fn read_metadata(path: &Path) -> anyhow::Result<std::collections::BTreeMap<String, String>> {
    if image_extension(path)? == "exr" {
        return Ok(read_layers(path)?.attributes);
    }
    let file = std::fs::File::open(path).with_context(|| format!("open {}", path.display()))?;
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .with_context(|| format!("read PNG {}", path.display()))?;
    let size = reader
        .output_buffer_size()
        .with_context(|| format!("PNG {}: image too large", path.display()))?;
    let mut buffer = vec![0u8; size];
    reader
        .next_frame(&mut buffer)
        .and_then(|_| reader.finish())
        .with_context(|| format!("read PNG {}", path.display()))?;
    Ok(reader
        .info()
        .uncompressed_latin1_text
        .iter()
        .filter_map(|t| {
            t.keyword
                .strip_prefix(layers::ATTRIBUTE_PREFIX)
                .map(|k| (k.to_string(), t.text.clone()))
        })
        .collect())
}

/// Reads the R, G and B channels of the first RGB layer of an EXR file (any sample
/// type, converted to f32; alpha ignored).
pub fn read_exr(path: &Path) -> anyhow::Result<ImageRgb> {
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |resolution, _| ImageRgb::new(resolution.width() as u32, resolution.height() as u32),
        |img: &mut ImageRgb, position, (r, g, b, _a): (f32, f32, f32, f32)| {
            let i = position.y() * img.width as usize + position.x();
            img.data[i] = [r, g, b];
        },
    )
    .with_context(|| format!("read EXR {}", path.display()))?;
    Ok(image.layer_data.channel_data.pixels)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch_dir(test: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir()
            .join("nimbus-output-tests")
            .join(format!("{test}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn gradient(width: u32, height: u32) -> ImageRgb {
        let mut img = ImageRgb::new(width, height);
        for y in 0..height {
            for x in 0..width {
                let v = (x + width * y) as f32;
                img.set(x, y, [v * 0.37, 1.0 / (v + 1.0), -v * 1.0e-3 + 1.0e20]);
            }
        }
        img
    }

    #[test]
    fn exr_round_trip_is_exact() {
        let dir = scratch_dir("exr");
        let path = dir.join("gradient.exr");
        let img = gradient(13, 7);
        write_image(&path, &img, 1.0).unwrap();
        let back = read_exr(&path).unwrap();
        assert_eq!(back, img);
        assert_eq!(back.get(12, 0), img.data[12]);
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn png_has_the_image_size() {
        let dir = scratch_dir("png");
        let path = dir.join("gradient.PNG");
        write_image(&path, &gradient(13, 7), 0.5).unwrap();
        let back = image::open(&path).unwrap();
        assert_eq!((back.width(), back.height()), (13, 7));
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn unknown_extension_is_an_error_naming_the_file() {
        let err = write_image(Path::new("/tmp/out.pfm"), &gradient(2, 2), 1.0).unwrap_err();
        let message = format!("{err:#}");
        assert!(message.contains("/tmp/out.pfm"), "{message}");
        assert!(
            message.contains(".exr") && message.contains(".png"),
            "{message}"
        );
    }

    #[test]
    fn non_finite_pixels_are_an_error() {
        let dir = scratch_dir("nan");
        let mut img = gradient(4, 3);
        img.set(2, 1, [0.0, f32::NAN, 0.0]);
        for name in ["nan.exr", "nan.png"] {
            let path = dir.join(name);
            let message = format!("{:#}", write_image(&path, &img, 1.0).unwrap_err());
            assert!(message.contains("(2, 1)"), "{message}");
            assert!(!path.exists());
        }
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn tonemap_is_monotone_from_black_to_white() {
        // A ramp over [0, 10] in steps of 1e-4 is fine enough to hit every code.
        let values: Vec<f32> = (0..100_000).map(|i| i as f32 * 1e-4).collect();
        let img = ImageRgb {
            width: values.len() as u32,
            height: 1,
            data: values.iter().map(|&v| [v; 3]).collect(),
        };
        let codes = tonemap_srgb8(&img, 1.0);
        assert_eq!(codes[0], [0; 3]);
        assert_eq!(codes[codes.len() - 1], [255; 3]);
        assert!(codes.windows(2).all(|w| w[0][0] <= w[1][0]));
        let mut seen = [false; 256];
        for c in &codes {
            seen[usize::from(c[0])] = true;
        }
        assert!(seen.iter().all(|&s| s), "the ramp skips codes");
    }

    #[test]
    fn tonemap_handles_extremes_and_exposure() {
        let img = ImageRgb {
            width: 4,
            height: 1,
            data: vec![[-1.0; 3], [f32::NAN; 3], [f32::INFINITY; 3], [0.18; 3]],
        };
        let codes = tonemap_srgb8(&img, 1.0);
        assert_eq!(&codes[..3], &[[0; 3], [0; 3], [255; 3]]);
        let brighter = tonemap_srgb8(&img, 4.0);
        assert!(brighter[3][0] > codes[3][0]);
    }

    #[test]
    fn mean_is_per_channel() {
        let img = ImageRgb {
            width: 2,
            height: 1,
            data: vec![[1.0, 2.0, 3.0], [3.0, 4.0, 5.0]],
        };
        assert_eq!(img.mean(), [2.0, 3.0, 4.0]);
        assert_eq!(ImageRgb::new(0, 0).mean(), [0.0; 3]);
    }
}
