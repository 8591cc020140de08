//! Timestamp scopes around real dispatches on the device.

use nimbus_gpu::{
    compute_barrier, summarize, vk, write_chrome_trace, BindingDesc, BufferDesc, ComputePipeline,
    ComputePipelineDesc, Context, DescriptorSet, DescriptorWrite, Profiler, ScopeResult,
};

const SHADER: &str = r#"
#version 450
layout(local_size_x = 64) in;
layout(std430, set = 0, binding = 0) buffer Data { float data[]; } buf;
void main() {
    uint i = gl_GlobalInvocationID.x;
    float x = buf.data[i];
    for (int k = 0; k < 256; ++k) {
        x = x * 0.999 + 0.5;
    }
    buf.data[i] = x;
}
"#;

const ELEMENTS: u32 = 64 * 256;

struct Work {
    pipeline: ComputePipeline,
    set: DescriptorSet,
    buffer: nimbus_gpu::Buffer,
}

fn work(ctx: &Context) -> Work {
    let spirv = crate::common::compile_compute(SHADER, "busy.comp");
    let bindings = [BindingDesc::storage_buffer(0)];
    let pipeline = ctx
        .create_compute_pipeline(
            &ComputePipelineDesc {
                spirv: &spirv,
                entry: "main",
                bindings: &bindings,
                push_constant_size: 0,
                specialization: &[],
            },
            "busy",
        )
        .expect("pipeline");
    let buffer = ctx
        .create_buffer(
            &BufferDesc::gpu_only(
                u64::from(ELEMENTS) * 4,
                vk::BufferUsageFlags::STORAGE_BUFFER,
            ),
            "busy data",
        )
        .expect("buffer");
    ctx.fill_buffer(&buffer, 0).expect("fill");
    let set = ctx
        .create_descriptor_set(
            &pipeline,
            &[DescriptorWrite::StorageBuffer {
                binding: 0,
                buffer: &buffer,
            }],
            "busy set",
        )
        .expect("set");
    Work {
        pipeline,
        set,
        buffer,
    }
}

fn destroy(ctx: &Context, work: Work) {
    ctx.destroy_descriptor_set(work.set);
    ctx.destroy_compute_pipeline(work.pipeline);
    ctx.destroy_buffer(work.buffer);
}

fn record_frame(ctx: &Context, profiler: &mut Profiler, work: &Work) -> Vec<ScopeResult> {
    ctx.submit_one_shot("profiled frame", |cmd| {
        profiler.begin_frame(cmd);
        profiler.begin_scope(ctx, cmd, "frame")?;
        for pass in ["first", "second"] {
            profiler.begin_scope(ctx, cmd, pass)?;
            work.pipeline
                .dispatch(ctx, cmd, &work.set, &[], [ELEMENTS / 64, 1, 1])?;
            compute_barrier(ctx, cmd);
            profiler.end_scope(ctx, cmd)?;
        }
        profiler.end_scope(ctx, cmd)
    })
    .expect("profiled frame");
    profiler.resolve(ctx).expect("resolve")
}

#[test]
fn nested_scopes_resolve_into_a_consistent_tree() {
    let ctx = crate::common::validated_context();
    let work = work(&ctx);
    let mut profiler = Profiler::new(&ctx, 8, "test profiler").expect("profiler");

    let mut frames = Vec::new();
    for _ in 0..3 {
        let frame = record_frame(&ctx, &mut profiler, &work);
        assert_eq!(frame.len(), 1);
        let root = &frame[0];
        assert_eq!(root.label, "frame");
        assert_eq!(
            root.begin_ns, 0.0,
            "times are relative to the first timestamp"
        );
        assert!(root.duration_ns() >= 0.0);
        let labels: Vec<&str> = root.children.iter().map(|c| c.label.as_str()).collect();
        assert_eq!(labels, ["first", "second"]);
        for child in &root.children {
            assert!(child.duration_ns() >= 0.0, "{child:?}");
            assert!(
                child.begin_ns >= root.begin_ns && child.end_ns <= root.end_ns,
                "child {child:?} outside parent {root:?}"
            );
        }
        assert!(root.children[0].end_ns <= root.children[1].begin_ns);
        frames.push(frame);
    }

    let stats = summarize(&frames);
    let labels: Vec<&str> = stats.iter().map(|s| s.label.as_str()).collect();
    assert_eq!(labels, ["frame", "frame/first", "frame/second"]);
    assert!(stats
        .iter()
        .all(|s| s.samples == 3 && s.min_ms <= s.median_ms && s.median_ms <= s.max_ms));
    for s in &stats {
        eprintln!("{:<14} median {:.3} ms", s.label, s.median_ms);
    }

    let mut trace = Vec::new();
    write_chrome_trace(&frames, &mut trace).expect("trace");
    let json: serde_json::Value = serde_json::from_slice(&trace).expect("trace is JSON");
    assert_eq!(json["traceEvents"].as_array().map(Vec::len), Some(9));

    profiler.destroy(&ctx);
    destroy(&ctx, work);
    crate::common::assert_no_validation_errors(&ctx);
}

#[test]
fn misuse_is_reported_not_dropped() {
    let ctx = crate::common::validated_context();
    let mut profiler = Profiler::new(&ctx, 2, "small profiler").expect("profiler");
    assert_eq!(profiler.capacity(), 4);

    ctx.submit_one_shot("misuse", |cmd| {
        let err = profiler.begin_scope(&ctx, cmd, "early").unwrap_err();
        assert!(format!("{err:#}").contains("begin_frame"), "{err:#}");

        profiler.begin_frame(cmd);
        let err = profiler.end_scope(&ctx, cmd).unwrap_err();
        assert!(
            format!("{err:#}").contains("without an open scope"),
            "{err:#}"
        );

        profiler.begin_scope(&ctx, cmd, "one")?;
        profiler.begin_scope(&ctx, cmd, "two")?;
        let err = profiler.begin_scope(&ctx, cmd, "three").unwrap_err();
        assert!(
            format!("{err:#}").contains("profiler query pool overflow (capacity 4)"),
            "{err:#}"
        );
        profiler.end_scope(&ctx, cmd)?;
        let err = profiler.resolve(&ctx).unwrap_err();
        assert!(
            format!("{err:#}").contains("open scopes [\"one\"]"),
            "{err:#}"
        );
        profiler.end_scope(&ctx, cmd)
    })
    .expect("misuse frame");

    let frame = profiler.resolve(&ctx).expect("resolve");
    assert_eq!(frame.len(), 1);
    assert_eq!(frame[0].children.len(), 1);
    assert_eq!(frame[0].children[0].label, "two");

    profiler.destroy(&ctx);
    crate::common::assert_no_validation_errors(&ctx);
}
