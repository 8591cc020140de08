//! A validated lavapipe context and a checked render, shared by the render tests.

use std::path::Path;

use nimbus::plan;
use nimbus::renderer::{render, RenderOptions, RenderResult};
use nimbus_gpu::{Context, ContextDesc};
use nimbus_scene::Scene;

use super::check_adapter;

/// A context with validation layers on, on the device CI uses (checked under CI).
pub fn context() -> Context {
    let ctx = Context::new(&ContextDesc {
        validation: true,
        device_filter: std::env::var("NIMBUS_DEVICE").ok(),
        app_name: "nimbus-tests".into(),
    })
    .expect("a Vulkan device (install mesa-vulkan-drivers for lavapipe)");
    check_adapter(&ctx.info().name);
    ctx
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
pub fn se_of_mean(se: &nimbus::output::ImageRgb) -> f64 {
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
