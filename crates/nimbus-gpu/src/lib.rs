//! Thin Vulkan compute runtime for Nimbus.
//!
//! One module per Vulkan concept, in the manner of kajiya's backend: [`context`] (instance,
//! device, queue, validation), [`buffer`] and [`image`] (memory through gpu-allocator),
//! [`pipeline`] (compute pipelines with specialization constants), [`descriptor`],
//! [`command`] (one-shot submission, upload, readback, barriers), [`profiler`]
//! (timestamp scopes and a Chrome trace writer) and [`objects`] (one cleanup bag for the
//! objects of a half-built pass, with typed handles). Nothing here knows about light.
//!
//! # Invariants
//!
//! - **Errors** name the object and carry the `vk::Result` (as [`VkError`], so callers may
//!   downcast); no library code unwraps a Vulkan result.
//! - **Names**: every object created here is given its debug-utils name, so validation
//!   messages and captures show `'reservoirs[0]'` rather than a handle.
//! - **Memory**: every buffer and image is bound at its gpu-allocator allocation's offset.
//!   Resources are freed explicitly (`destroy_*`); one dropped without that is leaked with a
//!   message on stderr, never freed behind the caller's back. The allocator is dropped
//!   before the device.
//! - **Locations**: a `GpuOnly` buffer is never written or read through a mapping, even on
//!   devices (lavapipe, integrated GPUs) where its memory happens to be host-visible:
//!   upload and readback go through a staging buffer, so the path a discrete GPU takes is the
//!   path every device takes. `CpuToGpu` / `GpuToCpu` buffers are accessed through their
//!   persistent mapping.
//! - **Image layouts**: every image lives in `GENERAL` for its whole life. `create_image`
//!   moves it from `UNDEFINED` to `GENERAL` with a one-shot; uploads, readbacks, storage and
//!   sampled access all use `GENERAL`, so no pass ever transitions a layout.
//! - **Barriers**: upload inserts `compute/transfer write -> transfer write` before its copy
//!   and `transfer write -> compute shader read|write` after it. Readback inserts
//!   `compute/transfer write -> transfer read` before its copy and `transfer write -> host
//!   read` after it (a mapped readback gets `compute/transfer write -> host read`). All are
//!   global memory barriers; passes separate dependent dispatches with
//!   [`compute_barrier`]. With validation on, synchronization validation flags hazards
//!   inside one command buffer (a missing `compute_barrier` between passes); the layer in
//!   Debian 12 (1.3.239) does not flag hazards across fenced submissions, so the barriers
//!   of separate uploads and readbacks hold by construction, not by the layer's check.
//! - **Submission**: [`Context::submit_one_shot`] waits on a fence before it returns
//!   (timing out with an error after ten minutes rather than hanging), so after any call
//!   into this crate returns, the GPU is idle with respect to the work it submitted.

pub mod buffer;
pub mod command;
pub mod context;
pub mod descriptor;
pub mod device;
pub mod error;
pub mod image;
pub mod objects;
pub mod pipeline;
pub mod pipeline_cache;
pub mod profiler;
pub mod spirv;
pub mod spirv_strip;

pub use ash::vk;
pub use buffer::{Buffer, BufferDesc};
pub use command::compute_barrier;
pub use context::{enumerate_devices, select_device, Context, ContextDesc, DeviceInfo};
pub use descriptor::{DescriptorSet, DescriptorWrite};
pub use error::VkError;
pub use gpu_allocator::MemoryLocation;
pub use image::{format_texel_size, Image, ImageDesc, SamplerDesc};
pub use objects::{GpuObject, GpuObjects, Handle};
pub use pipeline::{BindingDesc, ComputePipeline, ComputePipelineDesc, SpecValue};
pub use profiler::{summarize, ticks_to_ns, write_chrome_trace, PassStats, Profiler, ScopeResult};

#[cfg(test)]
mod tests {
    fn assert_send_sync<T: Send + Sync>() {}

    #[test]
    fn handles_are_send_and_sync() {
        assert_send_sync::<crate::Context>();
        assert_send_sync::<crate::Buffer>();
        assert_send_sync::<crate::Image>();
        assert_send_sync::<crate::Profiler>();
    }
}
