//! A validated lavapipe context and a checked render, shared by the render tests.

use std::path::Path;

use nimbus::output::ImageRgb;
use nimbus::plan;
use nimbus::renderer::{render, RenderOptions, RenderResult};
use nimbus_gpu::{Context, ContextDesc};
use nimbus_scene::Scene;

use super::check_adapter;

/// A context with validation layers on, on the device CI uses (checked under CI); the
/// test is named if the suite dies of a signal while it runs ([`super::crash`]).
pub fn context() -> Context {
    super::crash::enter();
    let ctx = Context::new(&ContextDesc {
        validation: true,
        device_filter: std::env::var("NIMBUS_DEVICE").ok(),
        app_name: "nimbus-tests".into(),
    })
    .expect("a Vulkan device (install mesa-vulkan-drivers for lavapipe)");
    check_adapter(&ctx.info().name);
    ctx
}

/// Scene frame `frame` of the animated scene `s` alone, `passes` dispatches of it
/// accumulated (no warm-up frames), checked for non-finite samples.
pub fn render_scene_frame(ctx: &Context, s: &Scene, frame: u32, passes: u32) -> RenderResult {
    let plan = plan::build(s, None).expect("plan");
    let opts = RenderOptions {
        frames: nimbus::renderer::FrameSelection::Each {
            frames: vec![frame],
            passes,
        },
        ..Default::default()
    };
    let r = render(ctx, s, &plan, &opts).expect("render");
    assert_eq!(r.non_finite_samples, 0, "non-finite samples");
    r
}

/// Parse a test scene given as text; `name` stands for its file in messages.
pub fn scene(text: &str, name: &str) -> Scene {
    nimbus_scene::parse_str(text, Path::new(name)).expect("test scene parses")
}

/// Render and check what every render must satisfy: no validation errors, no
/// non-finite samples, a finite image.
pub fn render_checked(ctx: &Context, scene: &Scene, box_samples: Option<u32>) -> RenderResult {
    let plan = plan::build(scene, box_samples).expect("plan");
    let result = render(ctx, scene, &plan, &RenderOptions::default()).expect("render");
    assert_no_validation_errors(ctx);
    assert_eq!(result.non_finite_samples, 0, "non-finite samples");
    assert_eq!(result.step_cap_hits, 0, "walks stopped at the step limit");
    assert!(result.image.first_non_finite().is_none());
    result
}

/// Standard error of an image's mean (largest channel) from per-pixel standard errors,
/// pixels independent.
pub fn se_of_mean(se: &ImageRgb) -> f64 {
    let n = se.data.len() as f64;
    (0..3)
        .map(|c| {
            se.data
                .iter()
                .map(|s| f64::from(s[c]).powi(2))
                .sum::<f64>()
                .sqrt()
                / n
        })
        .fold(0.0, f64::max)
}

/// Fail with every validation error the context has collected so far.
pub fn assert_no_validation_errors(ctx: &Context) {
    let errors = ctx.validation_errors();
    assert!(
        errors.is_empty(),
        "{} validation error(s):\n{}",
        errors.len(),
        errors.join("\n")
    );
}

/// Embedded SPIR-V of a test shader as words.
pub fn spirv(bytes: &[u8]) -> Vec<u32> {
    nimbus::passes::spirv_words(bytes).expect("embedded SPIR-V is whole words")
}

/// An image with its per-pixel standard errors (of the mean).
pub type Estimate<'a> = (&'a ImageRgb, &'a ImageRgb);

/// Asserts per channel that the image means of `a` and `b` agree within `k` combined
/// standard errors of the mean ([`se_of_mean`] of each) plus `rel` of `b`'s mean, after
/// printing both under `what`.
pub fn assert_means_agree(what: &str, a: Estimate, b: Estimate, k: f64, rel: f64) {
    let se = (se_of_mean(a.1).powi(2) + se_of_mean(b.1).powi(2)).sqrt();
    let (ma, mb) = (a.0.mean(), b.0.mean());
    println!("{what}: {ma:?} vs {mb:?} (SE {se:.2e})");
    for c in 0..3 {
        assert!(
            (ma[c] - mb[c]).abs() <= k * se + rel * mb[c],
            "{what} channel {c}: {} vs {} (combined SE {se:.2e})",
            ma[c],
            mb[c]
        );
    }
}

/// How many pixel channels of `a` and `b` differ by more than `z` combined per-pixel
/// standard errors (+ 1e-6 for rounding).
pub fn channels_beyond(a: Estimate, b: Estimate, z: f64) -> usize {
    let mut beyond = 0;
    for ((pa, pb), (sa, sb)) in
        a.0.data
            .iter()
            .zip(&b.0.data)
            .zip(a.1.data.iter().zip(&b.1.data))
    {
        for c in 0..3 {
            let s = (f64::from(sa[c]).powi(2) + f64::from(sb[c]).powi(2)).sqrt();
            if f64::from((pa[c] - pb[c]).abs()) > z * s + 1e-6 {
                beyond += 1;
            }
        }
    }
    beyond
}
