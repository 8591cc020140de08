//! Settling a GPU before a timed measurement.
//!
//! A GPU lowers its clocks when it idles and raises them under load, and a light load
//! does not raise them: on an H200 (2026-11-28, `docs/gpu/h200-2026-11-28-6fe5952`) the
//! SM clock fell from 1980 to 345 MHz within a second of idling, and a baseline render
//! of 16 one-spp frames at 960x540 that followed a scene upload then ran at 3.06 ms a
//! frame, against 0.78 ms for the same frames right after a busy one. Every equal-time
//! study on a GPU times many short renders, each after the CPU work of loading its
//! scene, so the cheap configurations were timed in the idle state and the expensive
//! ones in the working state.
//!
//! [`settle`] keeps the device busy with arithmetic (`shaders/tools/settle.comp`, no
//! memory traffic, no effect on any render's state) for a given time right before the
//! timed frames; `profile`, `study` and `bench` ask for it ([`DEFAULT_SETTLE`]) on every
//! device but a CPU one (lavapipe has no clocks to raise, and would only pay the time).

use std::time::{Duration, Instant};

use anyhow::Result;
use nimbus_gpu::{
    vk, BindingDesc, BufferDesc, ComputePipelineDesc, Context, DescriptorWrite, GpuObjects,
};

use crate::passes::spirv_words;

/// How long `profile`, `study` and `bench` keep a GPU busy before timing (`--settle-ms`).
pub const DEFAULT_SETTLE: Duration = Duration::from_millis(500);

/// FMA pairs per invocation of one dispatch: well under lavapipe's 65 535 loop
/// iterations, and short enough that one dispatch of the smallest size takes well under
/// a millisecond on a GPU at its idle clocks.
const ITERATIONS: u32 = 2048;

/// A dispatch grows (doubling its workgroups) until it takes at least this long, so that
/// the gaps between submissions stay a small part of the load.
const MIN_DISPATCH: Duration = Duration::from_millis(4);

/// What a [`settle`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Settled {
    /// Wall time spent.
    pub elapsed: Duration,
    /// Submissions of the settling kernel.
    pub dispatches: u32,
    /// Workgroups (of 64 invocations) in the last, largest dispatch.
    pub groups: u32,
}

/// Whether `settle` applies on this device: never on a CPU device.
pub fn applies(ctx: &Context) -> bool {
    ctx.info().device_type != vk::PhysicalDeviceType::CPU
}

/// Keeps the device busy with the settling kernel for `duration` (at least one dispatch
/// when `duration` is not zero), on any device; callers check [`applies`].
pub fn settle(ctx: &Context, duration: Duration) -> Result<Settled> {
    if duration.is_zero() {
        return Ok(Settled::default());
    }
    let words = spirv_words(crate::shaders::TOOLS_SETTLE)?;
    // The kernel's pipeline, its sink buffer and its set, freed together (also on error).
    let (objects, (pipeline, set)) = GpuObjects::build(ctx, |o| {
        let pipeline = o.add(ctx.create_compute_pipeline(
            &ComputePipelineDesc {
                spirv: &words,
                entry: "main",
                bindings: &[BindingDesc::storage_buffer(0)],
                push_constant_size: 16,
                specialization: &[],
            },
            "settle",
        )?);
        let sink = o.add(ctx.create_buffer(
            &BufferDesc::gpu_only(16, vk::BufferUsageFlags::STORAGE_BUFFER),
            "settle sink",
        )?);
        let set = ctx.create_descriptor_set(
            &o[pipeline],
            &[DescriptorWrite::StorageBuffer {
                binding: 0,
                buffer: &o[sink],
            }],
            "settle",
        )?;
        Ok((pipeline, o.add(set)))
    })?;
    let push: [u32; 4] = [ITERATIONS, 0, 0, 0];
    let max_groups = ctx.info().max_compute_work_group_count[0].min(1 << 20);
    let start = Instant::now();
    let mut settled = Settled::default();
    let mut groups = 16;
    let result = loop {
        let began = Instant::now();
        if let Err(e) = ctx.submit_one_shot("settle", |cmd| {
            objects[pipeline].dispatch(
                ctx,
                cmd,
                &objects[set],
                bytemuck::bytes_of(&push),
                [groups, 1, 1],
            )
        }) {
            break Err(e);
        }
        settled.dispatches += 1;
        settled.groups = groups;
        if start.elapsed() >= duration {
            settled.elapsed = start.elapsed();
            break Ok(settled);
        }
        if began.elapsed() < MIN_DISPATCH && groups < max_groups {
            groups = (groups * 2).min(max_groups);
        }
    };
    objects.destroy(ctx);
    result
}
