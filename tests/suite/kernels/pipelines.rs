//! Pipelines built at once (`nimbus::passes::compute_pipelines`, ReSTIR's four passes):
//! each is the one its description asks for, in the order given, and if one fails none
//! is kept.

use nimbus::passes::{compute_pipelines, AovSpec, FilmSpec, PipelineJob};
use nimbus_gpu::{BindingDesc, GpuObjects};

use crate::common::gpu::{assert_no_validation_errors, context};

fn job<'a>(spirv: &'a [u8], name: &str) -> PipelineJob<'a> {
    PipelineJob {
        spirv,
        specialization: &[],
        film: FilmSpec {
            counter_slot: None,
            alpha: false,
            aov: AovSpec::default(),
            coherent_lanes: false,
        },
        name: name.to_owned(),
    }
}

#[test]
fn pipelines_built_at_once_come_in_order_or_not_at_all() {
    let ctx = context();
    let bindings = [BindingDesc::storage_buffer(0)];
    let shader = nimbus::shaders::TOOLS_SETTLE;
    let mut objects = GpuObjects::default();
    let jobs = [
        job(shader, "first"),
        job(shader, "second"),
        job(shader, "third"),
    ];
    let built = compute_pipelines::<[u32; 4]>(&ctx, &mut objects, &bindings, &jobs).unwrap();
    let names: Vec<&str> = built.iter().map(|&h| objects[h].name.as_str()).collect();
    assert_eq!(names, ["first", "second", "third"]);

    // The second is not SPIR-V: an error that names it, and nothing added.
    let mut none = GpuObjects::default();
    let broken = [0u8; 64];
    let jobs = [
        job(shader, "good"),
        job(&broken, "broken"),
        job(shader, "good too"),
    ];
    let err = compute_pipelines::<[u32; 4]>(&ctx, &mut none, &bindings, &jobs).unwrap_err();
    assert!(format!("{err:#}").contains("broken"), "{err:#}");
    assert_eq!(none.len(), 0);
    objects.destroy(&ctx);
    assert_no_validation_errors(&ctx);
}
