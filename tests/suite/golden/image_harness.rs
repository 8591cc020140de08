//! Tests of the golden-image harness itself (`tests/suite/common`). They keep their goldens in
//! cargo's temporary directory and never touch `assets/golden`.

use std::path::PathBuf;

use crate::common::{Harness, Tolerance};
use nimbus::output::ImageRgb;

/// Strict limits: these tests compare exact copies or deliberately broken images.
const STRICT: Tolerance = Tolerance {
    max_mean_flip: 1e-4,
    max_rel_mse: 1e-8,
};

/// A fresh golden and output directory for one test.
fn scratch_harness(test: &str) -> Harness {
    let root = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join("image-harness")
        .join(test);
    if root.exists() {
        std::fs::remove_dir_all(&root).unwrap();
    }
    Harness {
        golden_dir: root.join("golden"),
        output_dir: root.join("output"),
        update: false,
    }
}

/// A smooth HDR test pattern with a bright spot.
fn pattern() -> ImageRgb {
    let (width, height) = (48, 32);
    let mut img = ImageRgb::new(width, height);
    for y in 0..height {
        for x in 0..width {
            let (u, v) = (x as f32 / width as f32, y as f32 / height as f32);
            let spot = 20.0 * (-((u - 0.3).powi(2) + (v - 0.6).powi(2)) * 60.0).exp();
            img.set(x, y, [u + spot, v * 0.5 + spot, 0.2 + spot * 0.5]);
        }
    }
    img
}

/// Writes `img` as golden `name` through the explicit update path.
fn make_golden(harness: &Harness, name: &str, img: &ImageRgb) {
    let writer = Harness {
        update: true,
        ..harness.clone()
    };
    assert_eq!(writer.compare(name, img, STRICT).unwrap(), None);
    assert!(harness.golden_path(name).exists());
    assert!(harness.golden_dir.join(format!("{name}.png")).exists());
}

#[test]
fn identical_images_pass() {
    let harness = scratch_harness("identical");
    let img = pattern();
    make_golden(&harness, "pattern", &img);
    let metrics = harness.compare("pattern", &img, STRICT).unwrap().unwrap();
    assert_eq!(metrics.rel_mse, 0.0);
    assert_eq!(metrics.mean_flip, 0.0);
    assert!(
        !harness.output_dir.exists(),
        "a pass writes no failure images"
    );
}

#[test]
fn perturbed_image_fails_and_leaves_evidence() {
    let harness = scratch_harness("perturbed");
    let img = pattern();
    make_golden(&harness, "pattern", &img);

    // Darken a block of pixels by half.
    let mut perturbed = img.clone();
    for y in 4..20 {
        for x in 10..30 {
            perturbed.set(x, y, perturbed.get(x, y).map(|v| v * 0.5));
        }
    }
    let message = format!(
        "{:#}",
        harness.compare("pattern", &perturbed, STRICT).unwrap_err()
    );
    assert!(message.contains("mean FLIP"), "{message}");
    assert!(message.contains("relative MSE"), "{message}");
    for suffix in ["actual.png", "actual.exr", "expected.png", "difference.png"] {
        let path = harness.output_dir.join(format!("pattern-{suffix}"));
        assert!(path.exists(), "missing {}", path.display());
        assert!(message.contains(&path.display().to_string()), "{message}");
    }

    // Loose enough limits accept the same image.
    let loose = Tolerance {
        max_mean_flip: 1.0,
        max_rel_mse: 1.0,
    };
    assert!(harness.compare("pattern", &perturbed, loose).is_ok());
}

#[test]
fn relative_mse_has_the_documented_form() {
    // Golden 1 everywhere, actual 1.1: (0.1)² / (1 + 0.01) per channel.
    let golden = ImageRgb {
        width: 2,
        height: 2,
        data: vec![[1.0; 3]; 4],
    };
    let actual = ImageRgb {
        data: vec![[1.1; 3]; 4],
        ..golden.clone()
    };
    let (metrics, _) = crate::common::measure(&actual, &golden).unwrap();
    let expected = (1.1f32 as f64 - 1.0).powi(2) / 1.01;
    assert!((metrics.rel_mse - expected).abs() < 1e-12, "{metrics:?}");
}

#[test]
fn size_mismatch_fails() {
    let harness = scratch_harness("size");
    make_golden(&harness, "pattern", &pattern());
    let message = format!(
        "{:#}",
        harness
            .compare("pattern", &ImageRgb::new(8, 8), STRICT)
            .unwrap_err()
    );
    assert!(
        message.contains("8x8") && message.contains("48x32"),
        "{message}"
    );
}

#[test]
fn missing_golden_fails_with_instructions() {
    // The real golden directory, read-only: a missing golden must not be created.
    let name = "image-harness-no-such-golden";
    let harness = Harness {
        update: false,
        output_dir: scratch_harness("missing").output_dir,
        ..Harness::from_env()
    };
    let golden = harness.golden_path(name);
    assert!(!golden.exists(), "{} must not exist", golden.display());
    let message = format!(
        "{:#}",
        harness.compare(name, &pattern(), STRICT).unwrap_err()
    );
    assert!(message.contains("does not exist"), "{message}");
    assert!(message.contains("NIMBUS_UPDATE_GOLDEN=1"), "{message}");
    assert!(!golden.exists(), "the harness created {}", golden.display());
    assert!(harness
        .output_dir
        .join(format!("{name}-actual.exr"))
        .exists());

    // The public entry point behaves the same unless someone asked for an update.
    if !Harness::from_env().update {
        let result = crate::common::compare_with_golden(name, &pattern(), STRICT);
        assert!(result.is_err());
        assert!(!golden.exists());
    }
}

#[test]
fn bad_names_are_rejected() {
    let harness = scratch_harness("names");
    for name in ["", "../escape", "a/b", "with space"] {
        assert!(
            harness.compare(name, &pattern(), STRICT).is_err(),
            "{name:?}"
        );
    }
}

#[test]
fn adapter_check_prints_outside_ci() {
    if std::env::var("CI").is_err() {
        crate::common::check_adapter("SomeVendor GPU");
    }
    crate::common::check_adapter("llvmpipe (LLVM 15.0.6, 256 bits)");
}
