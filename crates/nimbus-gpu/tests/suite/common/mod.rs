//! Shared test scaffolding: a validated context on lavapipe (or `NIMBUS_DEVICE`) and GLSL
//! compilation through shaderc.

#![allow(dead_code)]

use nimbus_gpu::{Context, ContextDesc};

/// A context with validation on; the device comes from `NIMBUS_DEVICE` or the default order.
pub fn validated_context() -> Context {
    let desc = ContextDesc {
        validation: true,
        app_name: "nimbus-gpu-tests".to_owned(),
        ..ContextDesc::from_env()
    };
    let ctx = match Context::new(&desc) {
        Ok(ctx) => ctx,
        Err(e) => panic!("creating a validated context: {e:#}"),
    };
    eprintln!("device: {}", ctx.info());
    ctx
}

/// Compiles a GLSL compute shader to SPIR-V for Vulkan 1.2, panicking with the log on error.
pub fn compile_compute(source: &str, name: &str) -> Vec<u32> {
    let compiler = shaderc::Compiler::new().expect("shaderc compiler");
    let mut options = shaderc::CompileOptions::new().expect("shaderc options");
    options.set_target_env(
        shaderc::TargetEnv::Vulkan,
        shaderc::EnvVersion::Vulkan1_2 as u32,
    );
    match compiler.compile_into_spirv(
        source,
        shaderc::ShaderKind::Compute,
        name,
        "main",
        Some(&options),
    ) {
        Ok(artifact) => artifact.as_binary().to_vec(),
        Err(e) => panic!("compiling {name}: {e}"),
    }
}

/// Fails the test if the validation layer reported any error.
pub fn assert_no_validation_errors(ctx: &Context) {
    let errors = ctx.validation_errors();
    assert!(
        errors.is_empty(),
        "{} validation error(s):\n{}",
        errors.len(),
        errors.join("\n")
    );
}

/// Deterministic pseudo-random bytes (xorshift64*).
pub fn pattern(len: usize, seed: u64) -> Vec<u8> {
    let mut state = seed | 1;
    (0..len)
        .map(|_| {
            state ^= state >> 12;
            state ^= state << 25;
            state ^= state >> 27;
            (state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 56) as u8
        })
        .collect()
}
