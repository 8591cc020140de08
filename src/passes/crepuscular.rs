//! The crepuscular-ray pass (`shaders/box/crepuscular.comp`): single scattering in
//! homogeneous box media under collimated light, direct lighting of the shapes, and the
//! background, accumulated per pixel.

use anyhow::Result;
use nimbus_gpu::{
    vk, BindingDesc, ComputePipeline, Context, DescriptorSet, DescriptorWrite, GpuObjects, Handle,
    Profiler, SpecValue,
};
use nimbus_scene::{CameraFrame, Scene};

use super::{compute_pipeline, image_groups, upload_records, FrameConstants, Pass, Targets};
use crate::gpu::features::*;
use crate::gpu::{bindings, non_empty, FrameUniforms, GpuScene, PassPush, RecordCounts};
use crate::plan::{estimator_id, CrepuscularPlan};
use crate::shaders;

/// The specialization constants of `crepuscular.comp` for a plan.
pub fn specialization(plan: &CrepuscularPlan) -> [(u32, SpecValue); 7] {
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
    ]
}

/// The pass's pipeline and the scene records it reads.
pub struct CrepuscularPass {
    objects: GpuObjects,
    pipeline: Handle<ComputePipeline>,
    set: Handle<DescriptorSet>,
    constants: FrameConstants,
}

impl CrepuscularPass {
    pub fn new(
        ctx: &Context,
        plan: &CrepuscularPlan,
        scene: &Scene,
        targets: &Targets,
    ) -> Result<Self> {
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
            let shapes = upload_records(ctx, o, &non_empty(&records.shapes), "shapes")?;
            let lights = upload_records(ctx, o, &non_empty(&records.lights), "lights")?;
            let gobo_planes =
                upload_records(ctx, o, &non_empty(&records.gobo_planes), "gobo planes")?;
            let mut writes = Vec::from(targets.writes());
            writes.extend([
                DescriptorWrite::StorageBuffer {
                    binding: bindings::BOX_MEDIA,
                    buffer: &o[media],
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
        Ok(Self {
            objects,
            pipeline,
            set,
            constants,
        })
    }
}

impl Pass for CrepuscularPass {
    fn label(&self) -> &'static str {
        "crepuscular"
    }

    fn frame_uniforms(&self, scene: &Scene, camera: &CameraFrame) -> FrameUniforms {
        self.constants.uniforms(scene, camera)
    }

    fn record(
        &mut self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        uniforms: &FrameUniforms,
        dispatch_index: u32,
        _profiler: Option<&mut Profiler>,
    ) -> Result<()> {
        let push = PassPush {
            frame: dispatch_index,
            ..Default::default()
        };
        self.objects[self.pipeline].dispatch(
            ctx,
            cmd,
            &self.objects[self.set],
            bytemuck::bytes_of(&push),
            image_groups(uniforms),
        )
    }

    fn device_bytes(&self) -> u64 {
        self.objects.bytes()
    }

    fn destroy(self: Box<Self>, ctx: &Context) {
        self.objects.destroy(ctx);
    }
}
