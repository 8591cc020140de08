//! The crepuscular-ray pass (`shaders/box/crepuscular.comp`): single scattering in
//! homogeneous box media under collimated light, direct lighting of the shapes, and the
//! background, accumulated per pixel.

use anyhow::Result;
use nimbus_gpu::{BindingDesc, Context, DescriptorWrite, GpuObjects, SpecValue};
use nimbus_scene::Scene;

use super::{compute_pipeline, upload_records, FrameConstants, ImagePass, Targets};
use crate::budget::{Binding, Footprint};
use crate::gpu::features::*;
use crate::gpu::{bindings, non_empty, GpuScene, PassPush, RecordCounts};
use crate::plan::{estimator_id, CrepuscularPlan};
use crate::shaders;

/// The specialization constants of `crepuscular.comp` for a plan.
pub fn specialization(plan: &CrepuscularPlan) -> [(u32, SpecValue); 9] {
    let f = plan.features;
    [
        (SC_ID_HAS_SHAPES, SpecValue::Bool(f.has_shapes)),
        (SC_ID_HAS_GOBOS, SpecValue::Bool(f.has_gobos)),
        (SC_ID_HAS_ENV, SpecValue::Bool(f.has_env)),
        (
            SC_ID_ESTIMATOR,
            SpecValue::U32(estimator_id(plan.estimator)),
        ),
        (SC_ID_HAS_MEDIA, SpecValue::Bool(f.has_media)),
        (SC_ID_MAX_BOUNCES, SpecValue::U32(plan.max_bounces)),
        (SC_ID_PIXEL_JITTER, SpecValue::Bool(f.pixel_jitter)),
        (SC_ID_HAS_CONVEX, SpecValue::Bool(f.has_convex)),
        (SC_ID_MAX_PIECES, SpecValue::U32(f.max_pieces)),
    ]
}

/// Creates the pass of `plan`.
pub fn create(
    ctx: &Context,
    plan: &CrepuscularPlan,
    scene: &Scene,
    targets: &Targets,
) -> Result<ImagePass> {
    let records = GpuScene::build(scene)?;
    let constants = FrameConstants {
        env_radiance: records.env_radiance,
        counts: RecordCounts {
            box_media: records.media.len() as u32,
            shapes: records.shapes.len() as u32,
            lights: records.lights.len() as u32,
            ray_samples: plan.samples_along_ray,
        },
    };
    let (objects, (pipeline, set)) = GpuObjects::build(ctx, |o| {
        let mut layout = Vec::from(Targets::layout());
        layout.extend([
            BindingDesc::storage_buffer(bindings::BOX_MEDIA),
            BindingDesc::storage_buffer(bindings::MEDIUM_PLANES),
            BindingDesc::storage_buffer(bindings::SHAPES),
            BindingDesc::storage_buffer(bindings::LIGHTS),
            BindingDesc::storage_buffer(bindings::GOBO_PLANES),
        ]);
        let pipeline = compute_pipeline::<PassPush>(
            ctx,
            o,
            shaders::BOX_CREPUSCULAR,
            &layout,
            &specialization(plan),
            "crepuscular",
        )?;
        let media = upload_records(ctx, o, &non_empty(&records.media), "box media")?;
        let planes = upload_records(ctx, o, &non_empty(&records.medium_planes), "medium planes")?;
        let shapes = upload_records(ctx, o, &non_empty(&records.shapes), "shapes")?;
        let lights = upload_records(ctx, o, &non_empty(&records.lights), "lights")?;
        let gobo_planes = upload_records(ctx, o, &non_empty(&records.gobo_planes), "gobo planes")?;
        let mut writes = Vec::from(targets.writes());
        writes.extend([
            DescriptorWrite::StorageBuffer {
                binding: bindings::BOX_MEDIA,
                buffer: &o[media],
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::MEDIUM_PLANES,
                buffer: &o[planes],
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::SHAPES,
                buffer: &o[shapes],
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::LIGHTS,
                buffer: &o[lights],
            },
            DescriptorWrite::StorageBuffer {
                binding: bindings::GOBO_PLANES,
                buffer: &o[gobo_planes],
            },
        ]);
        let set = ctx.create_descriptor_set(&o[pipeline], &writes, "crepuscular set")?;
        Ok((pipeline, o.add(set)))
    })?;
    let c = constants.counts;
    // Per segment: the media (and their planes) and shapes it crosses, and per light its
    // shadow and estimator loops (ray-marching samples, gobo and media crossings, and the
    // trapezoid-piece tables: pieces x planes per medium).
    let planes = records.medium_planes.len() as u32;
    let tables = c.box_media * plan.features.max_pieces.max(3) * (planes.max(6) + 4);
    let per_segment = c.box_media
        + planes
        + c.shapes
        + c.lights * (c.ray_samples + c.box_media + planes + c.shapes + tables + 16);
    let sample_cost = per_segment.saturating_mul(plan.max_bounces + 1);
    Ok(ImagePass::new(
        ctx,
        "crepuscular",
        objects,
        pipeline,
        set,
        constants,
        sample_cost,
    ))
}

/// What the crepuscular pass allocates besides the render targets: its scene records
/// (a few KiB; counted so that every pass reports its footprint).
pub fn footprint(scene: &Scene, f: &mut Footprint) -> Result<()> {
    let records = GpuScene::build(scene)?;
    let bytes = std::mem::size_of_val(records.media.as_slice())
        + std::mem::size_of_val(records.medium_planes.as_slice())
        + std::mem::size_of_val(records.shapes.as_slice())
        + std::mem::size_of_val(records.lights.as_slice())
        + std::mem::size_of_val(records.gobo_planes.as_slice());
    f.add(
        format!(
            "{}: box and convex media, shapes, lights, gobos",
            scene.source.display()
        ),
        Binding::Storage,
        bytes as u64,
    );
    Ok(())
}
