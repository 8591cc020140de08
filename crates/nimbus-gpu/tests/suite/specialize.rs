//! Specialization constants written into the module as defaults, and the code they make
//! dead stripped before the driver sees it (`nimbus_gpu::spirv::specialize`,
//! `nimbus_gpu::spirv_strip`): the stripped pipelines compute what the constants ask,
//! the stripped modules hold only the branch the constants take, and a malformed module
//! is refused.

use nimbus_gpu::{vk, BindingDesc, BufferDesc, ComputePipelineDesc, DescriptorWrite, SpecValue};

const OP_SPEC_CONSTANT_TRUE: u32 = 48;
const OP_SPEC_CONSTANT_FALSE: u32 = 49;
const OP_SPEC_CONSTANT: u32 = 50;
const OP_SPEC_CONSTANT_OP: u32 = 52;

/// A feature switch (`HEAVY`) around a long loop, an integer constant and a constant
/// derived from it (an `OpSpecConstantOp`), and a float.
const SHADER: &str = r#"
#version 450
layout(local_size_x = 64) in;
layout(constant_id = 0) const bool HEAVY = false;
layout(constant_id = 1) const uint SCALE = 1u;
layout(constant_id = 2) const float OFFSET = 0.0;
const uint TWICE = SCALE * 2u;
layout(push_constant) uniform Push { uint count; } push;
layout(std430, set = 0, binding = 0) writeonly buffer Out { uint data[]; } out_buf;

uint heavy(uint x) {
    uint h = x;
    for (uint k = 0u; k < 37u; ++k) {
        h ^= h << 13u; h ^= h >> 17u; h ^= h << 5u;
        h = h * 2654435761u + k;
        if ((h & 1023u) == 3u) { h += uint(sin(float(h >> 20u)) * 1000.0 + 1000.0); }
        else if ((h & 7u) == 5u) { h ^= 1u << (h >> 28u); }
    }
    return h & 0xffffu;
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= push.count) {
        return;
    }
    uint v = i * TWICE + uint(OFFSET);
    if (HEAVY) {
        v += heavy(i);
    }
    out_buf.data[i] = v;
}
"#;

/// The CPU's `heavy`, for the expected values; `None` where the loop takes the `sin`
/// branch, whose last bits the GPU may round apart from the CPU.
fn heavy(x: u32) -> Option<u32> {
    let mut h = x;
    for k in 0..37u32 {
        h ^= h << 13;
        h ^= h >> 17;
        h ^= h << 5;
        h = h.wrapping_mul(2_654_435_761).wrapping_add(k);
        if h & 1023 == 3 {
            return None;
        } else if h & 7 == 5 {
            h ^= 1 << (h >> 28);
        }
    }
    Some(h & 0xffff)
}

/// (opcode, operands) of every instruction after the header.
fn instructions(words: &[u32]) -> Vec<(u32, Vec<u32>)> {
    let mut at = 5;
    let mut out = Vec::new();
    while at < words.len() {
        let count = (words[at] >> 16) as usize;
        assert!(
            count > 0 && at + count <= words.len(),
            "malformed at word {at}"
        );
        out.push((words[at] & 0xffff, words[at + 1..at + count].to_vec()));
        at += count;
    }
    out
}

fn spec_constant_ops(words: &[u32]) -> usize {
    instructions(words)
        .iter()
        .filter(|(op, _)| (OP_SPEC_CONSTANT_TRUE..=OP_SPEC_CONSTANT_OP).contains(op))
        .count()
}

#[test]
fn specialize_writes_each_value_as_the_constants_default() {
    let spirv = crate::common::compile_compute(SHADER, "specialize.comp");
    let ops = instructions(&spirv);
    assert!(
        ops.iter().any(|(op, _)| *op == OP_SPEC_CONSTANT_OP),
        "the shader should derive a constant by OpSpecConstantOp"
    );
    let specialized = nimbus_gpu::spirv::specialize(
        "test",
        &spirv,
        &[(0, 1), (1, 7), (2, 3.0f32.to_bits()), (9, 5)],
    )
    .unwrap();
    assert_eq!(
        specialized.len(),
        spirv.len(),
        "only literals and opcodes change"
    );
    // SpecId -> result id, from the decorations.
    let spec_id_of = |id: u32| {
        ops.iter()
            .find(|(op, o)| *op == 71 && o.len() >= 3 && o[0] == id && o[1] == 1)
            .map(|(_, o)| o[2])
    };
    let mut seen = 0;
    for (op, o) in instructions(&specialized) {
        match (op, o.get(1).and_then(|id| spec_id_of(*id))) {
            (OP_SPEC_CONSTANT_TRUE, Some(0)) => seen += 1,
            (OP_SPEC_CONSTANT_FALSE, Some(0)) => panic!("HEAVY stayed false"),
            (OP_SPEC_CONSTANT, Some(1)) => {
                assert_eq!(o[2], 7);
                seen += 1;
            }
            (OP_SPEC_CONSTANT, Some(2)) => {
                assert_eq!(f32::from_bits(o[2]), 3.0);
                seen += 1;
            }
            _ => {}
        }
    }
    assert_eq!(seen, 3, "every constant named was found and set");

    // A constant not named keeps its default; a boolean set to 0 becomes false.
    let only_bool = nimbus_gpu::spirv::specialize("test", &spirv, &[(0, 0)]).unwrap();
    let defaults: Vec<_> = instructions(&spirv)
        .into_iter()
        .filter(|(op, _)| *op == OP_SPEC_CONSTANT)
        .collect();
    let after: Vec<_> = instructions(&only_bool)
        .into_iter()
        .filter(|(op, _)| *op == OP_SPEC_CONSTANT)
        .collect();
    assert_eq!(defaults, after);

    // A module whose last instruction runs past its end is refused, naming the pipeline.
    let mut truncated = spirv.clone();
    truncated.push((5 << 16) | 1); // an OpNop of 5 words, of which 4 are missing
    let err = nimbus_gpu::spirv::specialize("cut", &truncated, &[(1, 2)]).unwrap_err();
    let err = format!("{err:#}");
    assert!(
        err.contains("pipeline 'cut'") && err.contains("ends at word"),
        "{err}"
    );
}

#[test]
fn the_stripped_module_holds_only_the_branch_its_constants_take() {
    let spirv = crate::common::compile_compute(SHADER, "specialize.comp");
    let strip = |values: &[(u32, u32)]| {
        let specialized = nimbus_gpu::spirv::specialize("test", &spirv, values).unwrap();
        nimbus_gpu::spirv_strip::strip_uncached(&specialized).unwrap()
    };
    let light = strip(&[(0, 0), (1, 3), (2, 0)]);
    let heavy = strip(&[(0, 1), (1, 3), (2, 0)]);
    assert_eq!(spec_constant_ops(&light), 0, "every constant frozen");
    assert_eq!(spec_constant_ops(&heavy), 0, "every constant frozen");
    // The loop's sin (a GLSL.std.450 extended instruction) goes with the branch.
    let ext_insts = |w: &[u32]| instructions(w).iter().filter(|(op, _)| *op == 12).count();
    assert_eq!(ext_insts(&light), 0, "the dead branch's code was removed");
    assert!(ext_insts(&heavy) >= 1, "the live branch's code stays");
    assert!(
        light.len() * 2 < heavy.len(),
        "{} words without the branch, {} with it",
        light.len(),
        heavy.len()
    );
    assert!(heavy.len() < spirv.len() * 2, "nothing grows beyond reason");
    // Garbage is refused, not passed on.
    assert!(
        nimbus_gpu::spirv_strip::strip_uncached(&[0x0723_0203, 0x0001_0500, 0, 9, 0, 7]).is_err()
    );
}

/// Both settings of the switch, run on the device through `create_compute_pipeline`
/// (which specializes and strips), against the CPU.
#[test]
fn stripped_pipelines_compute_what_the_constants_ask() {
    let ctx = crate::common::validated_context();
    let spirv = crate::common::compile_compute(SHADER, "specialize.comp");
    let count: u32 = 256;
    let bindings = [BindingDesc::storage_buffer(0)];
    let out = ctx
        .create_buffer(
            &BufferDesc::gpu_only(u64::from(count) * 4, vk::BufferUsageFlags::STORAGE_BUFFER),
            "specialize out",
        )
        .unwrap();
    for heavy_on in [false, true] {
        let (scale, offset) = (5u32, 9.0f32);
        let pipeline = ctx
            .create_compute_pipeline(
                &ComputePipelineDesc {
                    spirv: &spirv,
                    entry: "main",
                    bindings: &bindings,
                    push_constant_size: 4,
                    specialization: &[
                        (0, SpecValue::Bool(heavy_on)),
                        (1, SpecValue::U32(scale)),
                        (2, SpecValue::F32(offset)),
                    ],
                },
                "specialize",
            )
            .unwrap();
        let set = ctx
            .create_descriptor_set(
                &pipeline,
                &[DescriptorWrite::StorageBuffer {
                    binding: 0,
                    buffer: &out,
                }],
                "specialize set",
            )
            .unwrap();
        ctx.submit_one_shot("specialize dispatch", |cmd| {
            pipeline.dispatch(&ctx, cmd, &set, &count.to_ne_bytes(), [count / 64, 1, 1])
        })
        .unwrap();
        let bytes = ctx.readback_buffer(&out).unwrap();
        let values: &[u32] = bytemuck::cast_slice(&bytes);
        let mut checked = 0;
        for (i, &v) in values.iter().enumerate() {
            let i = i as u32;
            let base = i * 2 * scale + offset as u32;
            if !heavy_on {
                assert_eq!(v, base, "out[{i}] with HEAVY off");
                checked += 1;
            } else if let Some(h) = heavy(i) {
                assert_eq!(v, base + h, "out[{i}] with HEAVY on");
                checked += 1;
            }
        }
        assert!(checked >= 200, "only {checked} values checked");
        ctx.destroy_descriptor_set(set);
        ctx.destroy_compute_pipeline(pipeline);
    }
    ctx.destroy_buffer(out);
    crate::common::assert_no_validation_errors(&ctx);
}
