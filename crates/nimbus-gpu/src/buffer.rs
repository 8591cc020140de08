//! Buffers backed by gpu-allocator memory.
//!
//! A buffer is bound at its allocation's offset (sub-allocated from a larger memory block)
//! and freed by [`Context::destroy_buffer`]. Only `CpuToGpu` / `GpuToCpu` buffers expose
//! their mapping: a `GpuOnly` buffer reports no mapping even where its memory is
//! host-visible (lavapipe), so code written here works unchanged on a discrete GPU.

use crate::context::Context;
use crate::error::VkResultExt;
use anyhow::{bail, Context as _, Result};
use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

/// Size, usage and memory location of a buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BufferDesc {
    pub size: u64,
    pub usage: vk::BufferUsageFlags,
    pub location: MemoryLocation,
}

impl BufferDesc {
    /// Device-local buffer; adds TRANSFER_SRC | TRANSFER_DST for upload and readback.
    pub fn gpu_only(size: u64, usage: vk::BufferUsageFlags) -> Self {
        Self {
            size,
            usage: usage | vk::BufferUsageFlags::TRANSFER_SRC | vk::BufferUsageFlags::TRANSFER_DST,
            location: MemoryLocation::GpuOnly,
        }
    }

    /// Host-written, device-read buffer (staging, per-frame constants); adds TRANSFER_SRC.
    pub fn host_to_gpu(size: u64, usage: vk::BufferUsageFlags) -> Self {
        Self {
            size,
            usage: usage | vk::BufferUsageFlags::TRANSFER_SRC,
            location: MemoryLocation::CpuToGpu,
        }
    }

    /// Device-written, host-read buffer (readback); adds TRANSFER_DST.
    pub fn gpu_to_host(size: u64, usage: vk::BufferUsageFlags) -> Self {
        Self {
            size,
            usage: usage | vk::BufferUsageFlags::TRANSFER_DST,
            location: MemoryLocation::GpuToCpu,
        }
    }
}

/// A `vk::Buffer` with its memory. Free it with [`Context::destroy_buffer`].
#[derive(Debug)]
pub struct Buffer {
    pub raw: vk::Buffer,
    pub size: u64,
    pub desc: BufferDesc,
    pub name: String,
    allocation: Option<Allocation>,
}

impl Buffer {
    /// Whether the buffer is host-accessible through [`Buffer::mapped_slice`].
    pub fn is_mapped(&self) -> bool {
        self.desc.location != MemoryLocation::GpuOnly
            && self
                .allocation
                .as_ref()
                .is_some_and(|a| a.mapped_ptr().is_some())
    }

    /// The persistent mapping of a `CpuToGpu` / `GpuToCpu` buffer, `size` bytes long.
    ///
    /// Reading GPU-written data needs the host-read barrier and fence wait that
    /// [`Context::readback_buffer`] performs.
    pub fn mapped_slice(&self) -> Option<&[u8]> {
        if !self.is_mapped() {
            return None;
        }
        let size = self.size as usize;
        self.allocation.as_ref()?.mapped_slice().map(|s| &s[..size])
    }

    /// Mutable persistent mapping of a `CpuToGpu` / `GpuToCpu` buffer, `size` bytes long.
    /// Host writes become visible to commands submitted afterwards.
    pub fn mapped_slice_mut(&mut self) -> Option<&mut [u8]> {
        if !self.is_mapped() {
            return None;
        }
        let size = self.size as usize;
        self.allocation
            .as_mut()?
            .mapped_slice_mut()
            .map(|s| &mut s[..size])
    }

    /// Memory property flags of the backing allocation.
    pub fn memory_properties(&self) -> vk::MemoryPropertyFlags {
        self.allocation
            .as_ref()
            .map(|a| a.memory_properties())
            .unwrap_or_default()
    }

    /// Host pointer for writes into a mapped buffer through a shared reference, used by
    /// upload; `None` unless [`Buffer::is_mapped`].
    pub(crate) fn mapped_ptr(&self) -> Option<*mut u8> {
        if !self.is_mapped() {
            return None;
        }
        self.allocation
            .as_ref()?
            .mapped_ptr()
            .map(|p| p.as_ptr().cast::<u8>())
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        if self.allocation.is_some() && !std::thread::panicking() {
            eprintln!(
                "[nimbus-gpu] buffer '{}' dropped without Context::destroy_buffer; leaking it",
                self.name
            );
        }
    }
}

impl Context {
    /// Creates a buffer, allocates its memory and binds it at the allocation's offset.
    pub fn create_buffer(&self, desc: &BufferDesc, name: &str) -> Result<Buffer> {
        if desc.size == 0 {
            bail!("buffer '{name}' has size 0");
        }
        let device = self.device();
        let info = vk::BufferCreateInfo::default()
            .size(desc.size)
            .usage(desc.usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: `info` is a valid create info (size > 0 checked above, exclusive sharing)
        // for this context's device, which outlives the buffer.
        let raw = unsafe { device.create_buffer(&info, None) }.vk_context(|| {
            format!(
                "vkCreateBuffer for '{name}' ({} bytes, {:?})",
                desc.size, desc.usage
            )
        })?;
        // SAFETY: `raw` was just created on this device and is not yet destroyed.
        let requirements = unsafe { device.get_buffer_memory_requirements(raw) };
        let allocation = self.allocator().allocate(&AllocationCreateDesc {
            name,
            requirements,
            location: desc.location,
            linear: true,
            allocation_scheme: AllocationScheme::GpuAllocatorManaged,
        });
        let allocation = match allocation {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: `raw` was created above, has no memory bound and was never handed
                // out, so nothing uses it.
                unsafe { device.destroy_buffer(raw, None) };
                return Err(e).with_context(|| {
                    format!(
                        "allocating {} bytes of {:?} memory for buffer '{name}'",
                        requirements.size, desc.location
                    )
                });
            }
        };
        // SAFETY: `raw` was created above and has no memory yet; `allocation` was made for
        // its own requirements, so its memory and offset satisfy them.
        let bound =
            unsafe { device.bind_buffer_memory(raw, allocation.memory(), allocation.offset()) };
        if let Err(e) = bound {
            self.free_allocation(allocation, name);
            // SAFETY: binding failed, so `raw` has no memory and was never handed out; its
            // allocation was freed just above.
            unsafe { device.destroy_buffer(raw, None) };
            return Err(e).vk_context(|| format!("vkBindBufferMemory for '{name}'"));
        }
        self.set_name(raw, name);
        Ok(Buffer {
            raw,
            size: desc.size,
            desc: *desc,
            name: name.to_owned(),
            allocation: Some(allocation),
        })
    }

    /// Frees the buffer's memory and destroys it. The GPU must be done with it.
    pub fn destroy_buffer(&self, mut buffer: Buffer) {
        if let Some(allocation) = buffer.allocation.take() {
            self.free_allocation(allocation, &buffer.name);
        }
        // SAFETY: the buffer is owned (moved in) and so no longer reachable by the caller,
        // who by this function's contract waited for the GPU to be done with it; its memory
        // was freed above.
        unsafe { self.device().destroy_buffer(buffer.raw, None) };
        buffer.raw = vk::Buffer::null();
    }

    pub(crate) fn free_allocation(&self, allocation: Allocation, name: &str) {
        if let Err(e) = self.allocator().free(allocation) {
            eprintln!("[nimbus-gpu] freeing the memory of '{name}' failed: {e}");
        }
    }
}
