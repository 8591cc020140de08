//! The golden-image harness for integration tests (after the image comparison of wgpu's
//! test harness and vello's snapshot tests).
//!
//! A test renders an image and calls [`compare_with_golden`], which checks it against
//! `assets/golden/{name}.exr` with two metrics:
//!
//! - **relative MSE** on the linear float images,
//!   `mean over pixels and channels of (a − g)² / (g² + ε)` with ε = [`REL_MSE_EPSILON`]
//!   = 1e-2, a = actual, g = golden; ε keeps dark pixels from dominating (an error of
//!   0.01 in a black pixel counts as 0.01);
//! - **mean FLIP** (NVIDIA's perceptual error, the `nv-flip` crate) on both images
//!   tonemapped with [`nimbus::output::tonemap_srgb8`] at exposure 1, at
//!   `nv_flip::DEFAULT_PIXELS_PER_DEGREE`.
//!
//! Goldens are generated on lavapipe, the device CI runs (see [`check_adapter`]), and
//! only on request: `NIMBUS_UPDATE_GOLDEN=1 cargo test` writes `{name}.exr` and a
//! `{name}.png` preview and passes. Without that variable a missing golden is a
//! failure, never created silently. On failure the harness writes
//! `{name}-actual.png`, `{name}-actual.exr`, `{name}-expected.png` and
//! `{name}-difference.png` (the FLIP error map, magma colours) under
//! `target/nimbus-test-output/`.

#![allow(dead_code)]

pub mod cli;
pub mod crash;
pub mod gpu;
pub mod kernel;
pub mod rng;
pub mod scenes;

use std::path::{Path, PathBuf};

use anyhow::{bail, ensure, Context};
use nimbus::output::{read_exr, tonemap_srgb8, write_image, ImageRgb};

/// The environment variable that makes [`compare_with_golden`] (re)write goldens.
pub const UPDATE_GOLDEN_VAR: &str = "NIMBUS_UPDATE_GOLDEN";

/// ε in the relative MSE (a − g)² / (g² + ε).
pub const REL_MSE_EPSILON: f64 = 1e-2;

/// How far an image may stray from its golden. Both limits must hold.
///
/// Every test states why its numbers are what they are, in a comment next to them:
/// the noise its estimator leaves at the sample count it uses, what lavapipe's
/// threading may reorder, and what a real regression would cost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerance {
    /// Largest allowed mean FLIP error of the tonemapped images, in [0, 1].
    pub max_mean_flip: f32,
    /// Largest allowed relative MSE of the float images (see [`REL_MSE_EPSILON`]).
    pub max_rel_mse: f64,
}

/// The tolerance of a golden rendered with the same seed on the same device (lavapipe):
/// its output is deterministic, so the limits only leave room for floating-point
/// reassociation between Mesa/LLVM builds. They sit far below what a real change costs:
/// a shadow edge moved by a pixel, or a changed sample sequence at a few spp, raises
/// the mean FLIP by ~0.01 or more.
pub const SAME_DEVICE: Tolerance = Tolerance {
    max_mean_flip: 0.005,
    max_rel_mse: 1e-4,
};

/// What a comparison measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageMetrics {
    pub mean_flip: f32,
    pub rel_mse: f64,
}

/// Where goldens live, where failure images go, and whether to rewrite goldens.
#[derive(Clone, Debug)]
pub struct Harness {
    pub golden_dir: PathBuf,
    pub output_dir: PathBuf,
    /// Write the actual image as the golden instead of comparing.
    pub update: bool,
}

impl Harness {
    /// `assets/golden/`, `target/nimbus-test-output/`, and `update` when
    /// `NIMBUS_UPDATE_GOLDEN=1`.
    pub fn from_env() -> Self {
        Self {
            golden_dir: Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/golden"),
            output_dir: default_output_dir(),
            update: std::env::var(UPDATE_GOLDEN_VAR).is_ok_and(|v| v == "1"),
        }
    }

    pub fn golden_path(&self, name: &str) -> PathBuf {
        self.golden_dir.join(format!("{name}.exr"))
    }

    /// Compares `actual` with the golden `name`, or writes it as the golden when
    /// `update` is set. See the module docs.
    pub fn compare(
        &self,
        name: &str,
        actual: &ImageRgb,
        tol: Tolerance,
    ) -> anyhow::Result<Option<ImageMetrics>> {
        check_name(name)?;
        let golden_path = self.golden_path(name);

        // Write the golden and its preview on request.
        if self.update {
            std::fs::create_dir_all(&self.golden_dir)
                .with_context(|| format!("create {}", self.golden_dir.display()))?;
            write_image(&golden_path, actual, 1.0)?;
            write_image(&self.golden_dir.join(format!("{name}.png")), actual, 1.0)?;
            println!("{name}: wrote golden {}", golden_path.display());
            return Ok(None);
        }

        // Refuse to invent a missing golden.
        if !golden_path.exists() {
            let written = self.write_actual(name, actual)?;
            bail!(
                "{name}: golden image {} does not exist. Render it on lavapipe with \
                 `{UPDATE_GOLDEN_VAR}=1 cargo test --test <this test>`, look at the \
                 {name}.png preview written next to it, and commit both. The image this \
                 run produced is at {}.",
                golden_path.display(),
                written.join(", ")
            );
        }

        let expected = read_exr(&golden_path)?;
        if (expected.width, expected.height) != (actual.width, actual.height) {
            let written = self.write_actual(name, actual)?;
            bail!(
                "{name}: image is {}x{} but golden {} is {}x{} (actual written to {})",
                actual.width,
                actual.height,
                golden_path.display(),
                expected.width,
                expected.height,
                written.join(", ")
            );
        }

        let (metrics, error_map) = measure(actual, &expected)?;
        let passed = metrics.mean_flip <= tol.max_mean_flip && metrics.rel_mse <= tol.max_rel_mse;
        if passed {
            println!(
                "{name}: mean FLIP {:.5} (limit {}), relative MSE {:.3e} (limit {:.3e})",
                metrics.mean_flip, tol.max_mean_flip, metrics.rel_mse, tol.max_rel_mse
            );
            return Ok(Some(metrics));
        }

        // Leave the evidence next to the test output.
        let mut written = self.write_actual(name, actual)?;
        let expected_png = self.output_dir.join(format!("{name}-expected.png"));
        write_image(&expected_png, &expected, 1.0)?;
        written.push(expected_png.display().to_string());
        let difference_png = self.output_dir.join(format!("{name}-difference.png"));
        let colored = error_map.apply_color_lut(&nv_flip::magma_lut());
        image::save_buffer_with_format(
            &difference_png,
            &colored.to_vec(),
            colored.width(),
            colored.height(),
            image::ExtendedColorType::Rgb8,
            image::ImageFormat::Png,
        )
        .with_context(|| format!("write {}", difference_png.display()))?;
        written.push(difference_png.display().to_string());
        bail!(
            "{name}: image differs from golden {}: mean FLIP {:.5} (limit {}), relative \
             MSE {:.3e} (limit {:.3e}). Wrote {}",
            golden_path.display(),
            metrics.mean_flip,
            tol.max_mean_flip,
            metrics.rel_mse,
            tol.max_rel_mse,
            written.join(", ")
        )
    }

    /// Writes `{name}-actual.png` and `{name}-actual.exr`; returns their paths.
    fn write_actual(&self, name: &str, actual: &ImageRgb) -> anyhow::Result<Vec<String>> {
        std::fs::create_dir_all(&self.output_dir)
            .with_context(|| format!("create {}", self.output_dir.display()))?;
        let mut written = Vec::new();
        for extension in ["png", "exr"] {
            let path = self.output_dir.join(format!("{name}-actual.{extension}"));
            write_image(&path, actual, 1.0)?;
            written.push(path.display().to_string());
        }
        Ok(written)
    }
}

/// Compares `actual` with `assets/golden/{name}.exr` under `tol` (or rewrites the
/// golden when `NIMBUS_UPDATE_GOLDEN=1`); see the module docs.
pub fn compare_with_golden(name: &str, actual: &ImageRgb, tol: Tolerance) -> anyhow::Result<()> {
    Harness::from_env().compare(name, actual, tol).map(|_| ())
}

/// Relative MSE and the FLIP error map of `actual` against `expected` (same size).
pub fn measure(
    actual: &ImageRgb,
    expected: &ImageRgb,
) -> anyhow::Result<(ImageMetrics, nv_flip::FlipImageFloat)> {
    let (width, height) = (expected.width, expected.height);
    ensure!(
        (actual.width, actual.height) == (width, height),
        "cannot compare a {}x{} image with a {width}x{height} one",
        actual.width,
        actual.height
    );
    ensure!(width > 0 && height > 0, "cannot compare empty images");
    for (what, img) in [("actual", actual), ("expected", expected)] {
        if let Some((x, y, value)) = img.first_non_finite() {
            bail!("{what} image has a non-finite pixel ({x}, {y}) = {value:?}");
        }
    }

    // Relative MSE over all pixels and channels.
    let mut sum = 0.0;
    for (a, g) in actual.data.iter().zip(&expected.data) {
        for c in 0..3 {
            let (a, g) = (f64::from(a[c]), f64::from(g[c]));
            sum += (a - g) * (a - g) / (g * g + REL_MSE_EPSILON);
        }
    }
    let rel_mse = sum / (3 * actual.data.len()) as f64;

    // Mean FLIP of the tonemapped 8-bit images, the golden as reference.
    let to_flip = |img: &ImageRgb| {
        let bytes: Vec<u8> = tonemap_srgb8(img, 1.0).into_iter().flatten().collect();
        nv_flip::FlipImageRgb8::with_data(width, height, &bytes)
    };
    let error_map = nv_flip::flip(
        to_flip(expected),
        to_flip(actual),
        nv_flip::DEFAULT_PIXELS_PER_DEGREE,
    );
    let mean_flip = nv_flip::FlipPool::from_image(&error_map).mean();
    Ok((ImageMetrics { mean_flip, rel_mse }, error_map))
}

/// Prints the adapter the test renders on; under CI (`CI` set, not empty, `0` or
/// `false`) it must be lavapipe ("llvmpipe" in the device name), because goldens are
/// generated there.
///
/// # Panics
/// Under CI on any other adapter.
pub fn check_adapter(name: &str) {
    println!("adapter: {name}");
    let in_ci = std::env::var("CI")
        .is_ok_and(|v| !v.is_empty() && v != "0" && !v.eq_ignore_ascii_case("false"));
    if in_ci {
        assert!(
            name.to_ascii_lowercase().contains("llvmpipe"),
            "CI must render on lavapipe (device name containing \"llvmpipe\"), the device \
             the goldens were generated on, but the adapter is {name:?}"
        );
    }
}

/// `target/nimbus-test-output`, following `CARGO_TARGET_DIR` through cargo's
/// per-target temporary directory.
fn default_output_dir() -> PathBuf {
    let target_dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target"));
    target_dir.join("nimbus-test-output")
}

/// Golden names become file names: keep them to letters, digits, `-` and `_`.
fn check_name(name: &str) -> anyhow::Result<()> {
    ensure!(
        !name.is_empty()
            && name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_'),
        "golden name {name:?} must be non-empty and use only letters, digits, '-' and '_'"
    );
    Ok(())
}
