//! Intel Open Image Denoise (OIDN 2.x) for final frames: one call that takes a linear RGB
//! image (and optionally the albedo and normal AOVs) and returns the denoised RGB.
//!
//! The library is not packaged by Debian 12; `tools/install-oidn.sh` installs OIDN 2.5.1
//! from a hash-pinned PyPI wheel into /opt/oidn-2.5.1. This crate is only built with the
//! root package's `oidn` feature. See docs/oidn.md.
//!
//! Images are tightly packed, row-major, 3 floats per pixel (RGB, or XYZ for normals),
//! `width * height * 3` floats each. The inputs are checked before OIDN sees them, so a
//! bad image is an error naming the image and the first bad pixel, not a garbage result.

use anyhow::{bail, Context, Result};

/// An OIDN device, kept so that a sequence of frames pays for creating it once
/// (loading the device module and its TBB thread pool: see docs/oidn.md for the cost).
pub struct Denoiser {
    device: oidn::Device,
}

impl Denoiser {
    /// The fastest device OIDN finds: its CUDA device where an NVIDIA driver is present,
    /// otherwise the CPU.
    pub fn new() -> Result<Self> {
        let device = oidn::Device::new()
            .map_err(|e| anyhow::anyhow!("{e}"))
            .context(
                "Open Image Denoise could not create a device (are its device modules \
                 installed beside libOpenImageDenoise? see tools/install-oidn.sh)",
            )?;
        Ok(Self { device })
    }

    /// OIDN's CPU device, whatever else the machine has.
    pub fn cpu() -> Result<Self> {
        let device = oidn::Device::cpu()
            .map_err(|e| anyhow::anyhow!("{e}"))
            .context("Open Image Denoise could not create its CPU device")?;
        Ok(Self { device })
    }

    /// Denoises `color` (linear RGB; `hdr` = true for radiance, which may exceed 1;
    /// false for an image already in [0, 1]). `albedo` (RGB in [0, 1]) and `normal`
    /// (any-length vectors) are optional feature images; OIDN takes a normal image only
    /// together with an albedo image. Returns `width * height * 3` floats.
    pub fn denoise(
        &self,
        width: u32,
        height: u32,
        color: &[f32],
        albedo: Option<&[f32]>,
        normal: Option<&[f32]>,
        hdr: bool,
    ) -> Result<Vec<f32>> {
        let len = image_len(width, height)?;
        let color_range = if hdr { Range::NonNegative } else { Range::Unit };
        check_image("color", color, len, width, color_range)?;
        if let Some(albedo) = albedo {
            check_image("albedo", albedo, len, width, Range::Unit)?;
        }
        if let Some(normal) = normal {
            check_image("normal", normal, len, width, Range::Finite)?;
        }

        let mut filter = oidn::RayTracing::try_new(&self.device)
            .map_err(|e| anyhow::anyhow!("{e}"))
            .context("Open Image Denoise could not create its RT filter")?;
        filter
            .srgb(false)
            .hdr(hdr)
            .image_dimensions(width as usize, height as usize);
        match (albedo, normal) {
            (Some(albedo), Some(normal)) => {
                filter.albedo_normal(albedo, normal);
            }
            (Some(albedo), None) => {
                filter.albedo(albedo);
            }
            (None, Some(_)) => bail!(
                "denoise: a normal image was given without an albedo image; Open Image \
                 Denoise uses normals only together with albedo"
            ),
            (None, None) => {}
        }
        let mut output = vec![0.0_f32; len];
        filter
            .filter(color, &mut output)
            .map_err(|e| anyhow::anyhow!("{e}"))
            .with_context(|| format!("Open Image Denoise failed on a {width}x{height} image"))?;
        Ok(output)
    }
}

/// Denoises one image with a fresh [`Denoiser::new`] device; see [`Denoiser::denoise`].
/// For a sequence of frames, keep a [`Denoiser`] instead.
pub fn denoise(
    width: u32,
    height: u32,
    color: &[f32],
    albedo: Option<&[f32]>,
    normal: Option<&[f32]>,
    hdr: bool,
) -> Result<Vec<f32>> {
    Denoiser::new()?.denoise(width, height, color, albedo, normal, hdr)
}

#[derive(Clone, Copy)]
enum Range {
    Finite,
    NonNegative,
    Unit,
}

fn image_len(width: u32, height: u32) -> Result<usize> {
    if width == 0 || height == 0 {
        bail!("denoise: the image is {width}x{height}; both sides must be at least 1");
    }
    (width as usize)
        .checked_mul(height as usize)
        .and_then(|pixels| pixels.checked_mul(3))
        .with_context(|| format!("denoise: a {width}x{height} RGB image does not fit in memory"))
}

fn check_image(name: &str, image: &[f32], len: usize, width: u32, range: Range) -> Result<()> {
    if image.len() != len {
        bail!(
            "denoise: the {name} image has {} floats; {len} expected (3 per pixel)",
            image.len()
        );
    }
    let bad = |v: f32| match range {
        Range::Finite => !v.is_finite(),
        Range::NonNegative => !(v.is_finite() && v >= 0.0),
        Range::Unit => !(0.0..=1.0).contains(&v),
    };
    if let Some(index) = image.iter().position(|&v| bad(v)) {
        let pixel = index / 3;
        let want = match range {
            Range::Finite => "finite values",
            Range::NonNegative => "finite values >= 0",
            Range::Unit => "values in [0, 1]",
        };
        bail!(
            "denoise: the {name} image has {} at pixel ({}, {}) channel {}; it must hold {want}",
            image[index],
            pixel % width as usize,
            pixel / width as usize,
            index % 3
        );
    }
    Ok(())
}
