//! A specialized compute pipeline with push constants, checked on the CPU.

use nimbus_gpu::{
    compute_barrier, vk, BindingDesc, BufferDesc, ComputePipelineDesc, DescriptorWrite, SpecValue,
};

const SHADER: &str = r#"
#version 450
layout(local_size_x = 64) in;
layout(constant_id = 0) const uint SPEC = 1u;
layout(constant_id = 1) const bool FLAG = false;
layout(constant_id = 2) const float BIAS = 0.0;
layout(push_constant) uniform Push { uint add; uint count; } push;
layout(std430, set = 0, binding = 0) writeonly buffer Out { uint data[]; } out_buf;
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= push.count) {
        return;
    }
    out_buf.data[i] = i * SPEC + push.add + (FLAG ? 1000000u : 0u) + uint(BIAS);
}
"#;

#[test]
fn specialization_and_push_constants_reach_the_shader() {
    let ctx = crate::common::validated_context();
    let spirv = crate::common::compile_compute(SHADER, "spec_push.comp");
    let count: u32 = 1000;
    let (spec, add, bias) = (7u32, 11u32, 3.0f32);

    let bindings = [BindingDesc::storage_buffer(0)];
    let pipeline = ctx
        .create_compute_pipeline(
            &ComputePipelineDesc {
                spirv: &spirv,
                entry: "main",
                bindings: &bindings,
                push_constant_size: 8,
                specialization: &[
                    (0, SpecValue::U32(spec)),
                    (1, SpecValue::Bool(true)),
                    (2, SpecValue::F32(bias)),
                ],
            },
            "spec push",
        )
        .expect("pipeline");
    let out = ctx
        .create_buffer(
            &BufferDesc::gpu_only(u64::from(count) * 4, vk::BufferUsageFlags::STORAGE_BUFFER),
            "spec push out",
        )
        .expect("buffer");
    let set = ctx
        .create_descriptor_set(
            &pipeline,
            &[DescriptorWrite::StorageBuffer {
                binding: 0,
                buffer: &out,
            }],
            "spec push set",
        )
        .expect("descriptor set");

    let push: [u32; 2] = [add, count];
    let push_bytes: &[u8] = bytemuck::cast_slice(&push);
    ctx.submit_one_shot("spec push dispatch", |cmd| {
        // Dispatch twice to exercise the barrier; the second overwrites the first.
        pipeline.dispatch(&ctx, cmd, &set, push_bytes, [count.div_ceil(64), 1, 1])?;
        compute_barrier(&ctx, cmd);
        pipeline.dispatch(&ctx, cmd, &set, push_bytes, [count.div_ceil(64), 1, 1])
    })
    .expect("dispatch");

    let bytes = ctx.readback_buffer(&out).expect("readback");
    let values: &[u32] = bytemuck::cast_slice(&bytes);
    for (i, &v) in values.iter().enumerate() {
        let expected = i as u32 * spec + add + 1_000_000 + bias as u32;
        assert_eq!(v, expected, "out[{i}]");
    }

    // Wrong push-constant size is refused before anything is recorded.
    let err = ctx
        .submit_one_shot("bad push", |cmd| {
            pipeline.dispatch(&ctx, cmd, &set, &[0; 4], [1, 1, 1])
        })
        .unwrap_err();
    assert!(
        format!("{err:#}").contains("takes 8 bytes of push constants, got 4"),
        "{err:#}"
    );

    // A set that leaves a binding unwritten is refused.
    let err = ctx
        .create_descriptor_set(&pipeline, &[], "empty set")
        .unwrap_err();
    assert!(format!("{err:#}").contains("binding 0"), "{err:#}");

    ctx.destroy_descriptor_set(set);
    ctx.destroy_buffer(out);
    ctx.destroy_compute_pipeline(pipeline);
    crate::common::assert_no_validation_errors(&ctx);
}

#[test]
fn bad_pipeline_descriptions_are_errors() {
    let ctx = crate::common::validated_context();
    let not_spirv = [0u32, 1, 2, 3];
    let err = ctx
        .create_compute_pipeline(
            &ComputePipelineDesc {
                spirv: &not_spirv,
                entry: "main",
                bindings: &[],
                push_constant_size: 0,
                specialization: &[],
            },
            "garbage",
        )
        .unwrap_err();
    assert!(format!("{err:#}").contains("not SPIR-V"), "{err:#}");

    let spirv = crate::common::compile_compute(SHADER, "spec_push.comp");
    let err = ctx
        .create_compute_pipeline(
            &ComputePipelineDesc {
                spirv: &spirv,
                entry: "main",
                bindings: &[BindingDesc::storage_buffer(0)],
                push_constant_size: 6,
                specialization: &[],
            },
            "odd push",
        )
        .unwrap_err();
    assert!(format!("{err:#}").contains("multiple of 4"), "{err:#}");
    crate::common::assert_no_validation_errors(&ctx);
}

#[test]
fn synchronization_validation_catches_a_missing_barrier() {
    let ctx = crate::common::validated_context();
    let spirv = crate::common::compile_compute(SHADER, "spec_push.comp");
    let pipeline = ctx
        .create_compute_pipeline(
            &ComputePipelineDesc {
                spirv: &spirv,
                entry: "main",
                bindings: &[BindingDesc::storage_buffer(0)],
                push_constant_size: 8,
                specialization: &[
                    (0, SpecValue::U32(1)),
                    (1, SpecValue::Bool(false)),
                    (2, SpecValue::F32(0.0)),
                ],
            },
            "hazard",
        )
        .expect("pipeline");
    let out = ctx
        .create_buffer(
            &BufferDesc::gpu_only(256, vk::BufferUsageFlags::STORAGE_BUFFER),
            "hazard out",
        )
        .expect("buffer");
    let set = ctx
        .create_descriptor_set(
            &pipeline,
            &[DescriptorWrite::StorageBuffer {
                binding: 0,
                buffer: &out,
            }],
            "hazard set",
        )
        .expect("set");
    let push: [u32; 2] = [0, 64];
    // A transfer write followed by a shader write with no barrier between them.
    ctx.submit_one_shot("hazard", |cmd| {
        // SAFETY: `cmd` is this one-shot's buffer, recording, and `out` is alive with
        // TRANSFER_DST usage; the missing barrier after the fill is the hazard this test
        // wants the synchronization layer to report, not undefined behaviour on the host.
        unsafe {
            ctx.device()
                .cmd_fill_buffer(cmd, out.raw, 0, vk::WHOLE_SIZE, 0)
        };
        pipeline.dispatch(&ctx, cmd, &set, bytemuck::cast_slice(&push), [1, 1, 1])
    })
    .expect("dispatch");
    let errors = ctx.take_validation_errors();
    assert!(
        errors.iter().any(|e| e.contains("SYNC-HAZARD")),
        "synchronization validation did not flag a missing barrier: {errors:?}"
    );

    ctx.destroy_descriptor_set(set);
    ctx.destroy_buffer(out);
    ctx.destroy_compute_pipeline(pipeline);
    crate::common::assert_no_validation_errors(&ctx);
}

/// The module's own declarations are checked against the description (nimbus_gpu::spirv):
/// each of these breaks one on purpose and is refused, naming what is out of step.
#[test]
fn a_pipeline_out_of_step_with_its_spirv_is_refused() {
    let ctx = crate::common::validated_context();
    let spirv = crate::common::compile_compute(SHADER, "spec_push.comp");
    let all = [
        (0, SpecValue::U32(1)),
        (1, SpecValue::Bool(false)),
        (2, SpecValue::F32(0.0)),
    ];
    let reflection = nimbus_gpu::spirv::reflect(&spirv);
    assert_eq!(
        reflection.spec_ids.iter().copied().collect::<Vec<_>>(),
        [0, 1, 2]
    );
    assert_eq!(reflection.push_constant_size, Some(8));
    assert_eq!(
        reflection.bindings.get(&0),
        Some(&nimbus_gpu::spirv::ResourceKind::Buffer)
    );
    let attempt = |bindings: &[BindingDesc], push: u32, spec: &[(u32, SpecValue)]| {
        ctx.create_compute_pipeline(
            &ComputePipelineDesc {
                spirv: &spirv,
                entry: "main",
                bindings,
                push_constant_size: push,
                specialization: spec,
            },
            "out of step",
        )
        .map(|p| ctx.destroy_compute_pipeline(p))
        .map_err(|e| format!("{e:#}"))
    };
    let storage = [BindingDesc::storage_buffer(0)];
    attempt(&storage, 8, &all).expect("in step");
    // A forgotten specialization constant.
    let err = attempt(&storage, 8, &all[..2]).unwrap_err();
    assert!(err.contains("specialization constant(s) [2]"), "{err}");
    // A binding missing from the layout, and one of the wrong kind.
    let err = attempt(&[], 8, &all).unwrap_err();
    assert!(err.contains("binding 0"), "{err}");
    let err = attempt(&[BindingDesc::sampled_image(0)], 8, &all).unwrap_err();
    assert!(err.contains("binding 0 is a Buffer"), "{err}");
    // A push-constant range shorter than the block.
    let err = attempt(&storage, 4, &all).unwrap_err();
    assert!(err.contains("push constants take 8 bytes"), "{err}");
    crate::common::assert_no_validation_errors(&ctx);
}
