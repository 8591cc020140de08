//! One-shot command submission, barriers, upload and readback.
//!
//! [`Context::submit_one_shot`] records a primary command buffer from a pooled transient
//! command pool, submits it with a fence under the queue lock, and waits on the fence for at
//! most [`ONE_SHOT_TIMEOUT_NS`] before returning "GPU timeout". After a timeout or a device
//! loss the command buffer may still be pending, so its pool and fence are leaked rather
//! than reset under the GPU. One-shots may nest (an upload recorded from inside another
//! one-shot's closure takes a different pool).
//!
//! Every transfer is fenced, so separate calls never overlap on the GPU; the barriers below
//! still order them in the device's memory model, which is what a discrete GPU's caches and
//! the synchronization validation layer check:
//!
//! | operation              | before the copy                                | after the copy                               |
//! |------------------------|------------------------------------------------|----------------------------------------------|
//! | upload (staging)       | compute/transfer write -> transfer write       | transfer write -> compute shader read/write  |
//! | readback (staging)     | compute/transfer write -> transfer read        | transfer write -> host read                  |
//! | readback (mapped)      | compute/transfer write -> host read            |                                              |
//! | upload (mapped)        | none: host writes before a submit are visible  |                                              |

use crate::buffer::{Buffer, BufferDesc};
use crate::context::{lock, Context};
use crate::error::{vk_error, VkResultExt};
use crate::image::Image;
use anyhow::{bail, Context as _, Result};
use ash::vk;

/// How long a one-shot may run before [`Context::submit_one_shot`] reports a GPU timeout.
pub const ONE_SHOT_TIMEOUT_NS: u64 = 600 * 1_000_000_000;

const WRITES_BEFORE: vk::AccessFlags = vk::AccessFlags::from_raw(
    vk::AccessFlags::SHADER_WRITE.as_raw() | vk::AccessFlags::TRANSFER_WRITE.as_raw(),
);
const STAGES_BEFORE: vk::PipelineStageFlags = vk::PipelineStageFlags::from_raw(
    vk::PipelineStageFlags::COMPUTE_SHADER.as_raw() | vk::PipelineStageFlags::TRANSFER.as_raw(),
);
const SHADER_ACCESS: vk::AccessFlags = vk::AccessFlags::from_raw(
    vk::AccessFlags::SHADER_READ.as_raw()
        | vk::AccessFlags::SHADER_WRITE.as_raw()
        | vk::AccessFlags::UNIFORM_READ.as_raw(),
);

/// Records a global memory barrier.
pub fn memory_barrier(
    ctx: &Context,
    cmd: vk::CommandBuffer,
    src_stage: vk::PipelineStageFlags,
    src_access: vk::AccessFlags,
    dst_stage: vk::PipelineStageFlags,
    dst_access: vk::AccessFlags,
) {
    let barrier = vk::MemoryBarrier::default()
        .src_access_mask(src_access)
        .dst_access_mask(dst_access);
    // SAFETY: the caller passes a command buffer of `ctx`'s device in the recording state
    // (the contract of every `cmd` in this crate); a global memory barrier names no
    // resource, and `barrier` outlives the call.
    unsafe {
        ctx.device().cmd_pipeline_barrier(
            cmd,
            src_stage,
            dst_stage,
            vk::DependencyFlags::empty(),
            &[barrier],
            &[],
            &[],
        )
    };
}

/// Orders a dispatch's shader writes before the next dispatch's shader reads and writes.
pub fn compute_barrier(ctx: &Context, cmd: vk::CommandBuffer) {
    memory_barrier(
        ctx,
        cmd,
        vk::PipelineStageFlags::COMPUTE_SHADER,
        vk::AccessFlags::SHADER_WRITE,
        vk::PipelineStageFlags::COMPUTE_SHADER,
        vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
    );
}

/// Whether a failed one-shot's command pool may be reused.
enum PoolState {
    Reusable,
    MaybePending,
}

impl Context {
    fn acquire_command_pool(&self) -> Result<vk::CommandPool> {
        if let Some(pool) = lock(&self.command_pools).pop() {
            return Ok(pool);
        }
        let info = vk::CommandPoolCreateInfo::default()
            .flags(vk::CommandPoolCreateFlags::TRANSIENT)
            .queue_family_index(self.queue_family_index());
        // SAFETY: `info` names this device's compute queue family; the pool is destroyed
        // only in `Context::drop`, after the device is idle.
        let pool = unsafe { self.device().create_command_pool(&info, None) }
            .vk_context(|| "vkCreateCommandPool for the one-shot pool")?;
        self.set_name(pool, "nimbus one-shot pool");
        Ok(pool)
    }

    fn release_command_pool(&self, pool: vk::CommandPool) {
        lock(&self.command_pools).push(pool);
    }

    /// Records `record` into a fresh command buffer, submits it, and waits for it to finish.
    pub fn submit_one_shot<R>(
        &self,
        name: &str,
        record: impl FnOnce(vk::CommandBuffer) -> Result<R>,
    ) -> Result<R> {
        let pool = self.acquire_command_pool()?;
        match self.one_shot_in(pool, name, record) {
            Ok(value) => {
                self.release_command_pool(pool);
                Ok(value)
            }
            Err((PoolState::Reusable, e)) => {
                self.release_command_pool(pool);
                Err(e)
            }
            Err((PoolState::MaybePending, e)) => Err(e),
        }
    }

    fn one_shot_in<R>(
        &self,
        pool: vk::CommandPool,
        name: &str,
        record: impl FnOnce(vk::CommandBuffer) -> Result<R>,
    ) -> std::result::Result<R, (PoolState, anyhow::Error)> {
        let device = self.device();
        let reusable = |e: anyhow::Error| (PoolState::Reusable, e);
        let alloc_info = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: `pool` came from `acquire_command_pool`, so it belongs to this device
        // and, being out of the shared list until released, is used by this thread alone.
        let cmd = unsafe { device.allocate_command_buffers(&alloc_info) }
            .vk_context(|| format!("vkAllocateCommandBuffers for one-shot '{name}'"))
            .and_then(|v| {
                v.first()
                    .copied()
                    .context("driver returned no command buffer")
            })
            .map_err(reusable)?;
        self.set_name(cmd, name);
        // SAFETY: `cmd` was allocated from `pool` above, and `free` runs only while `cmd`
        // is not pending: before submission, or after its fence was waited on.
        let free = || unsafe { device.free_command_buffers(pool, &[cmd]) };

        let recorded = (|| {
            let begin = vk::CommandBufferBeginInfo::default()
                .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            // SAFETY: `cmd` was just allocated from `pool`, which no other thread uses, so
            // it is in the initial state.
            unsafe { device.begin_command_buffer(cmd, &begin) }
                .vk_context(|| format!("vkBeginCommandBuffer for one-shot '{name}'"))?;
            let value = record(cmd).with_context(|| format!("recording one-shot '{name}'"))?;
            // SAFETY: `cmd` was begun above and `record` only records commands into it.
            unsafe { device.end_command_buffer(cmd) }
                .vk_context(|| format!("vkEndCommandBuffer for one-shot '{name}'"))?;
            Ok(value)
        })();
        let value = match recorded {
            Ok(v) => v,
            Err(e) => {
                free();
                return Err(reusable(e));
            }
        };

        // SAFETY: a default create info; the fence is destroyed below on every path but a
        // timeout or a device loss, where it is leaked with the pool rather than destroyed
        // under the GPU.
        let fence = match unsafe { device.create_fence(&vk::FenceCreateInfo::default(), None) } {
            Ok(f) => f,
            Err(e) => {
                free();
                return Err(reusable(vk_error(
                    e,
                    format!("vkCreateFence for one-shot '{name}'"),
                )));
            }
        };
        self.set_name(fence, name);
        let cmds = [cmd];
        let submit = vk::SubmitInfo::default().command_buffers(&cmds);
        let submitted = {
            let queue = self.lock_queue();
            // SAFETY: the queue mutex is held (vkQueueSubmit needs the queue externally
            // synchronized), `cmd` has ended recording, and `fence` is new and unsignalled.
            unsafe { device.queue_submit(*queue, &[submit], fence) }
        };
        if let Err(e) = submitted {
            // SAFETY: the submission failed, so no queue operation refers to the fence or
            // to `cmd`.
            unsafe { device.destroy_fence(fence, None) };
            free();
            return Err(reusable(vk_error(
                e,
                format!("vkQueueSubmit for one-shot '{name}'"),
            )));
        }
        // SAFETY: `fence` is alive (created above) and was submitted with `cmd`.
        match unsafe { device.wait_for_fences(&[fence], true, ONE_SHOT_TIMEOUT_NS) } {
            Ok(()) => {}
            Err(vk::Result::TIMEOUT) => {
                return Err((
                    PoolState::MaybePending,
                    anyhow::anyhow!(
                        "GPU timeout: one-shot '{name}' did not finish within {} s",
                        ONE_SHOT_TIMEOUT_NS / 1_000_000_000
                    ),
                ));
            }
            Err(e) => {
                return Err((
                    PoolState::MaybePending,
                    vk_error(e, format!("vkWaitForFences for one-shot '{name}'")),
                ));
            }
        }
        // SAFETY: the wait above succeeded, so the submission is complete and nothing
        // refers to the fence.
        unsafe { device.destroy_fence(fence, None) };
        free();
        Ok(value)
    }

    /// Writes `data` into `dst` at byte `offset`: through the mapping for a mapped buffer,
    /// else through a staging buffer and a copy between the barriers in the module docs.
    pub fn upload_buffer(&self, dst: &Buffer, offset: u64, data: &[u8]) -> Result<()> {
        let len = data.len() as u64;
        let end = offset.checked_add(len).filter(|&end| end <= dst.size);
        if end.is_none() {
            bail!(
                "upload of {len} bytes at offset {offset} overflows buffer '{}' ({} bytes)",
                dst.name,
                dst.size
            );
        }
        if data.is_empty() {
            return Ok(());
        }
        if let Some(ptr) = dst.mapped_ptr() {
            // SAFETY: the range is inside the mapping (checked above) and all submitted work
            // has been waited on, so the GPU is not accessing it.
            unsafe {
                std::ptr::copy_nonoverlapping(data.as_ptr(), ptr.add(offset as usize), data.len())
            };
            return Ok(());
        }
        if !dst.desc.usage.contains(vk::BufferUsageFlags::TRANSFER_DST) {
            bail!(
                "buffer '{}' lacks TRANSFER_DST usage; cannot upload into it",
                dst.name
            );
        }
        self.upload_staged(&dst.name, data, |cmd, staging| {
            let region = vk::BufferCopy {
                src_offset: 0,
                dst_offset: offset,
                size: len,
            };
            // SAFETY: `cmd` is the staged one-shot's buffer, recording; the staging buffer
            // holds `len` bytes, `offset + len <= dst.size` was checked above, and `dst`
            // has TRANSFER_DST usage.
            unsafe {
                self.device()
                    .cmd_copy_buffer(cmd, staging, dst.raw, &[region])
            };
        })
    }

    /// Reads the whole of `src` back to the host.
    pub fn readback_buffer(&self, src: &Buffer) -> Result<Vec<u8>> {
        self.readback_buffer_range(src, 0, src.size)
    }

    /// Reads `size` bytes of `src` from byte `offset`, after making compute and transfer
    /// writes visible to the host (see the module docs for the barriers).
    pub fn readback_buffer_range(&self, src: &Buffer, offset: u64, size: u64) -> Result<Vec<u8>> {
        if offset.checked_add(size).is_none_or(|end| end > src.size) {
            bail!(
                "readback of {size} bytes at offset {offset} overflows buffer '{}' ({} bytes)",
                src.name,
                src.size
            );
        }
        if size == 0 {
            return Ok(Vec::new());
        }
        if src.is_mapped() {
            self.submit_one_shot(&format!("readback '{}'", src.name), |cmd| {
                memory_barrier(
                    self,
                    cmd,
                    STAGES_BEFORE,
                    WRITES_BEFORE,
                    vk::PipelineStageFlags::HOST,
                    vk::AccessFlags::HOST_READ,
                );
                Ok(())
            })?;
            let slice = src
                .mapped_slice()
                .with_context(|| format!("buffer '{}' lost its mapping", src.name))?;
            return Ok(slice[offset as usize..(offset + size) as usize].to_vec());
        }
        if !src.desc.usage.contains(vk::BufferUsageFlags::TRANSFER_SRC) {
            bail!(
                "buffer '{}' lacks TRANSFER_SRC usage; cannot read it back",
                src.name
            );
        }
        self.readback_staged(&src.name, size, |cmd, staging| {
            let region = vk::BufferCopy {
                src_offset: offset,
                dst_offset: 0,
                size,
            };
            // SAFETY: `cmd` is the staged one-shot's buffer, recording; `offset + size <=
            // src.size` was checked above, the staging buffer holds `size` bytes, and `src`
            // has TRANSFER_SRC usage.
            unsafe {
                self.device()
                    .cmd_copy_buffer(cmd, src.raw, staging, &[region])
            };
        })
    }

    /// Fills the whole of `dst` with the 32-bit `value`, ordered like an upload.
    pub fn fill_buffer(&self, dst: &Buffer, value: u32) -> Result<()> {
        if !dst.desc.usage.contains(vk::BufferUsageFlags::TRANSFER_DST) {
            bail!(
                "buffer '{}' lacks TRANSFER_DST usage; cannot fill it",
                dst.name
            );
        }
        self.submit_one_shot(&format!("fill '{}'", dst.name), |cmd| {
            memory_barrier(
                self,
                cmd,
                STAGES_BEFORE,
                WRITES_BEFORE,
                vk::PipelineStageFlags::TRANSFER,
                vk::AccessFlags::TRANSFER_WRITE,
            );
            // SAFETY: `cmd` is this one-shot's buffer, recording; `dst` is alive for the
            // call and has TRANSFER_DST usage (checked above).
            unsafe {
                self.device()
                    .cmd_fill_buffer(cmd, dst.raw, 0, vk::WHOLE_SIZE, value)
            };
            memory_barrier(
                self,
                cmd,
                vk::PipelineStageFlags::TRANSFER,
                vk::AccessFlags::TRANSFER_WRITE,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                SHADER_ACCESS,
            );
            Ok(())
        })
    }

    /// Copies `data` into a mapped staging buffer and submits `copy` (which records the
    /// copy out of the staging buffer) between the upload barriers of the module docs.
    fn upload_staged(
        &self,
        dst_name: &str,
        data: &[u8],
        copy: impl FnOnce(vk::CommandBuffer, vk::Buffer),
    ) -> Result<()> {
        self.staged(
            Staged::Upload,
            dst_name,
            data.len() as u64,
            |staging| {
                staging
                    .mapped_slice_mut()
                    .map(|slice| slice.copy_from_slice(data))
                    .with_context(|| format!("staging buffer for '{dst_name}' is not mapped"))
            },
            copy,
            |_| Ok(()),
        )
    }

    fn image_byte_size(image: &Image) -> Result<u64> {
        image.desc.byte_size().with_context(|| {
            format!(
                "image '{}': format {:?} has no known texel size for upload/readback",
                image.name, image.desc.format
            )
        })
    }

    /// Writes tightly packed texels covering the whole image; the image stays `GENERAL`.
    pub fn upload_image(&self, dst: &Image, data: &[u8]) -> Result<()> {
        let e = dst.desc.extent;
        self.upload_image_region(dst, [0; 3], [e.width, e.height, e.depth], data)
    }

    /// Writes tightly packed texels (x fastest, then y, then z) into the box of `extent`
    /// texels at `offset` of `dst`; the rest of the image is left as it is. Large images
    /// are uploaded region by region so that neither the host nor the staging buffer
    /// ever holds all of them.
    pub fn upload_image_region(
        &self,
        dst: &Image,
        offset: [u32; 3],
        extent: [u32; 3],
        data: &[u8],
    ) -> Result<()> {
        let texel = Self::image_byte_size(dst)? / dst.desc.texel_count().max(1);
        let e = dst.desc.extent;
        let full = [e.width, e.height, e.depth];
        if (0..3).any(|a| u64::from(offset[a]) + u64::from(extent[a]) > u64::from(full[a])) {
            bail!(
                "upload region {offset:?} + {extent:?} lies outside image '{}' ({full:?})",
                dst.name
            );
        }
        let size = extent.iter().map(|&n| u64::from(n)).product::<u64>() * texel;
        if data.len() as u64 != size {
            bail!(
                "upload of a {extent:?} region to image '{}' needs {size} bytes, got {}",
                dst.name,
                data.len()
            );
        }
        if data.is_empty() {
            return Ok(());
        }
        if !dst.desc.usage.contains(vk::ImageUsageFlags::TRANSFER_DST) {
            bail!(
                "image '{}' lacks TRANSFER_DST usage; cannot upload into it",
                dst.name
            );
        }
        self.upload_staged(&dst.name, data, |cmd, staging| {
            let mut region = whole_image_copy(dst);
            region.image_offset = vk::Offset3D {
                x: offset[0] as i32,
                y: offset[1] as i32,
                z: offset[2] as i32,
            };
            region.image_extent = vk::Extent3D {
                width: extent[0],
                height: extent[1],
                depth: extent[2],
            };
            // SAFETY: `cmd` is the staged one-shot's buffer, recording; the region lies
            // inside `dst` and the staging buffer holds exactly its texels (both checked
            // above); `dst` is in `GENERAL`, the layout every image keeps after
            // `create_image`, and has TRANSFER_DST usage.
            unsafe {
                self.device().cmd_copy_buffer_to_image(
                    cmd,
                    staging,
                    dst.raw,
                    vk::ImageLayout::GENERAL,
                    &[region],
                )
            };
        })
    }

    /// Reads the whole image back as tightly packed texels (x fastest, then y, then z).
    pub fn readback_image(&self, src: &Image) -> Result<Vec<u8>> {
        let size = Self::image_byte_size(src)?;
        if !src.desc.usage.contains(vk::ImageUsageFlags::TRANSFER_SRC) {
            bail!(
                "image '{}' lacks TRANSFER_SRC usage; cannot read it back",
                src.name
            );
        }
        self.readback_staged(&src.name, size, |cmd, staging| {
            let region = whole_image_copy(src);
            // SAFETY: `cmd` is the staged one-shot's buffer, recording; the region is the
            // whole image and the staging buffer holds its `byte_size`; `src` is in
            // `GENERAL` (kept since `create_image`) and has TRANSFER_SRC usage.
            unsafe {
                self.device().cmd_copy_image_to_buffer(
                    cmd,
                    src.raw,
                    vk::ImageLayout::GENERAL,
                    staging,
                    &[region],
                )
            };
        })
    }

    /// Submits `copy` (which records a copy of `size` bytes into the staging buffer)
    /// between the readback barriers of the module docs and returns the staged bytes.
    fn readback_staged(
        &self,
        src_name: &str,
        size: u64,
        copy: impl FnOnce(vk::CommandBuffer, vk::Buffer),
    ) -> Result<Vec<u8>> {
        self.staged(
            Staged::Readback,
            src_name,
            size,
            |_| Ok(()),
            copy,
            |staging| {
                staging
                    .mapped_slice()
                    .map(<[u8]>::to_vec)
                    .with_context(|| format!("staging buffer for '{src_name}' is not mapped"))
            },
        )
    }

    /// The skeleton of a staged transfer: a mapped staging buffer of `size` bytes,
    /// `fill`ed on the host, a one-shot that records `copy` between `direction`'s barriers
    /// (module docs) and waits for it, then `finish` reads the staging buffer. The staging
    /// buffer is destroyed on every path.
    fn staged<R>(
        &self,
        direction: Staged,
        name: &str,
        size: u64,
        fill: impl FnOnce(&mut Buffer) -> Result<()>,
        copy: impl FnOnce(vk::CommandBuffer, vk::Buffer),
        finish: impl FnOnce(&Buffer) -> Result<R>,
    ) -> Result<R> {
        let (desc, what, transfer_access, after_stage, after_access) = match direction {
            Staged::Upload => (
                BufferDesc::host_to_gpu(size, vk::BufferUsageFlags::empty()),
                "upload",
                vk::AccessFlags::TRANSFER_WRITE,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                SHADER_ACCESS,
            ),
            Staged::Readback => (
                BufferDesc::gpu_to_host(size, vk::BufferUsageFlags::empty()),
                "readback",
                vk::AccessFlags::TRANSFER_READ,
                vk::PipelineStageFlags::HOST,
                vk::AccessFlags::HOST_READ,
            ),
        };
        let mut staging = self.create_buffer(&desc, &format!("staging {what} for '{name}'"))?;
        let result = fill(&mut staging)
            .and_then(|()| {
                self.submit_one_shot(&format!("{what} '{name}'"), |cmd| {
                    memory_barrier(
                        self,
                        cmd,
                        STAGES_BEFORE,
                        WRITES_BEFORE,
                        vk::PipelineStageFlags::TRANSFER,
                        transfer_access,
                    );
                    copy(cmd, staging.raw);
                    memory_barrier(
                        self,
                        cmd,
                        vk::PipelineStageFlags::TRANSFER,
                        vk::AccessFlags::TRANSFER_WRITE,
                        after_stage,
                        after_access,
                    );
                    Ok(())
                })
            })
            .and_then(|()| finish(&staging));
        self.destroy_buffer(staging);
        result
    }
}

/// Which way a staged transfer goes (see [`Context::staged`]).
#[derive(Clone, Copy)]
enum Staged {
    /// Host -> staging -> the resource, then read or written by compute shaders.
    Upload,
    /// The resource -> staging -> host.
    Readback,
}

fn whole_image_copy(image: &Image) -> vk::BufferImageCopy {
    vk::BufferImageCopy {
        buffer_offset: 0,
        buffer_row_length: 0,
        buffer_image_height: 0,
        image_subresource: vk::ImageSubresourceLayers {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            mip_level: 0,
            base_array_layer: 0,
            layer_count: 1,
        },
        image_offset: vk::Offset3D::default(),
        image_extent: image.desc.extent,
    }
}
