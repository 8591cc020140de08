//! 2D and 3D images, their views, and samplers.
//!
//! Images are optimally tiled, one mip level, one layer, device-local, and live in
//! `GENERAL` layout from the end of [`Context::create_image`] until they are destroyed:
//! storage writes, sampling and transfers all use `GENERAL`, so passes never transition
//! layouts. (`GENERAL` costs some bandwidth compression on discrete GPUs; for a compute
//! renderer that reads and writes the same images every frame it is the honest choice.)

use crate::context::Context;
use crate::error::VkResultExt;
use anyhow::{bail, Context as _, Result};
use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

/// Extent, dimensionality, format and usage of an image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ImageDesc {
    pub extent: vk::Extent3D,
    /// `TYPE_2D` or `TYPE_3D`.
    pub image_type: vk::ImageType,
    pub format: vk::Format,
    pub usage: vk::ImageUsageFlags,
}

impl ImageDesc {
    /// A 2D image written by shaders and read back: STORAGE | TRANSFER_SRC | TRANSFER_DST.
    pub fn storage_2d(width: u32, height: u32, format: vk::Format) -> Self {
        Self {
            extent: vk::Extent3D {
                width,
                height,
                depth: 1,
            },
            image_type: vk::ImageType::TYPE_2D,
            format,
            usage: vk::ImageUsageFlags::STORAGE
                | vk::ImageUsageFlags::TRANSFER_SRC
                | vk::ImageUsageFlags::TRANSFER_DST,
        }
    }

    /// A 2D texture (environment maps): SAMPLED | TRANSFER_DST | TRANSFER_SRC.
    pub fn sampled_2d(width: u32, height: u32, format: vk::Format) -> Self {
        Self {
            extent: vk::Extent3D {
                width,
                height,
                depth: 1,
            },
            image_type: vk::ImageType::TYPE_2D,
            format,
            usage: vk::ImageUsageFlags::SAMPLED
                | vk::ImageUsageFlags::TRANSFER_DST
                | vk::ImageUsageFlags::TRANSFER_SRC,
        }
    }

    /// A 3D volume: SAMPLED | STORAGE | TRANSFER_DST | TRANSFER_SRC.
    pub fn sampled_3d(width: u32, height: u32, depth: u32, format: vk::Format) -> Self {
        Self {
            extent: vk::Extent3D {
                width,
                height,
                depth,
            },
            image_type: vk::ImageType::TYPE_3D,
            format,
            usage: vk::ImageUsageFlags::SAMPLED
                | vk::ImageUsageFlags::STORAGE
                | vk::ImageUsageFlags::TRANSFER_DST
                | vk::ImageUsageFlags::TRANSFER_SRC,
        }
    }

    /// Number of texels.
    pub fn texel_count(&self) -> u64 {
        u64::from(self.extent.width) * u64::from(self.extent.height) * u64::from(self.extent.depth)
    }

    /// Bytes of tightly packed texel data for the whole image, if the format is known to
    /// [`format_texel_size`].
    pub fn byte_size(&self) -> Option<u64> {
        format_texel_size(self.format).map(|s| u64::from(s) * self.texel_count())
    }
}

/// Bytes per texel of the uncompressed colour formats upload and readback handle.
pub fn format_texel_size(format: vk::Format) -> Option<u32> {
    use vk::Format as F;
    Some(match format {
        F::R8_UNORM | F::R8_SNORM | F::R8_UINT | F::R8_SINT => 1,
        F::R8G8_UNORM | F::R8G8_UINT | F::R16_SFLOAT | F::R16_UNORM | F::R16_UINT => 2,
        F::R8G8B8A8_UNORM
        | F::R8G8B8A8_SRGB
        | F::R8G8B8A8_UINT
        | F::B8G8R8A8_UNORM
        | F::B8G8R8A8_SRGB
        | F::R16G16_SFLOAT
        | F::R16G16_UINT
        | F::R32_SFLOAT
        | F::R32_UINT
        | F::R32_SINT
        | F::B10G11R11_UFLOAT_PACK32
        | F::E5B9G9R9_UFLOAT_PACK32
        | F::A2B10G10R10_UNORM_PACK32 => 4,
        F::R16G16B16A16_SFLOAT
        | F::R16G16B16A16_UNORM
        | F::R16G16B16A16_UINT
        | F::R32G32_SFLOAT
        | F::R32G32_UINT => 8,
        F::R32G32B32_SFLOAT | F::R32G32B32_UINT => 12,
        F::R32G32B32A32_SFLOAT | F::R32G32B32A32_UINT | F::R32G32B32A32_SINT => 16,
        _ => return None,
    })
}

/// A `vk::Image` with its view and memory, in `GENERAL` layout. Free it with
/// [`Context::destroy_image`].
#[derive(Debug)]
pub struct Image {
    pub raw: vk::Image,
    pub view: vk::ImageView,
    pub desc: ImageDesc,
    pub name: String,
    allocation: Option<Allocation>,
}

impl Drop for Image {
    fn drop(&mut self) {
        if self.allocation.is_some() && !std::thread::panicking() {
            eprintln!(
                "[nimbus-gpu] image '{}' dropped without Context::destroy_image; leaking it",
                self.name
            );
        }
    }
}

/// Filtering of a sampler; addressing is the same on all three axes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SamplerDesc {
    pub filter: vk::Filter,
    pub address_mode: vk::SamplerAddressMode,
}

impl SamplerDesc {
    /// Linear filtering, clamp to edge.
    pub fn linear() -> Self {
        Self {
            filter: vk::Filter::LINEAR,
            address_mode: vk::SamplerAddressMode::CLAMP_TO_EDGE,
        }
    }

    /// Nearest filtering, clamp to edge.
    pub fn nearest() -> Self {
        Self {
            filter: vk::Filter::NEAREST,
            address_mode: vk::SamplerAddressMode::CLAMP_TO_EDGE,
        }
    }
}

impl Default for SamplerDesc {
    fn default() -> Self {
        Self::linear()
    }
}

const COLOR_RANGE: vk::ImageSubresourceRange = vk::ImageSubresourceRange {
    aspect_mask: vk::ImageAspectFlags::COLOR,
    base_mip_level: 0,
    level_count: 1,
    base_array_layer: 0,
    layer_count: 1,
};

impl Context {
    /// Creates an image, its memory and its view, and moves it to `GENERAL` layout.
    pub fn create_image(&self, desc: &ImageDesc, name: &str) -> Result<Image> {
        let vk::Extent3D {
            width,
            height,
            depth,
        } = desc.extent;
        let view_type = match desc.image_type {
            vk::ImageType::TYPE_2D if depth == 1 => vk::ImageViewType::TYPE_2D,
            vk::ImageType::TYPE_2D => bail!("2D image '{name}' has depth {depth}, must be 1"),
            vk::ImageType::TYPE_3D => vk::ImageViewType::TYPE_3D,
            other => bail!("image '{name}': type {other:?} unsupported (2D or 3D only)"),
        };
        if width == 0 || height == 0 || depth == 0 {
            bail!("image '{name}' has an empty extent {width}x{height}x{depth}");
        }
        let device = self.device();

        // Check format and size support first: a clear error beats a validation message.
        // SAFETY: the physical device is this context's, enumerated from its live instance;
        // the query takes no pointers of ours.
        let limits = unsafe {
            self.instance().get_physical_device_image_format_properties(
                self.physical_device(),
                desc.format,
                desc.image_type,
                vk::ImageTiling::OPTIMAL,
                desc.usage,
                vk::ImageCreateFlags::empty(),
            )
        }
        .vk_context(|| {
            format!(
                "image '{name}': format {:?} with usage {:?} ({:?}) is not supported on '{}'",
                desc.format,
                desc.usage,
                desc.image_type,
                self.info().name
            )
        })?;
        let max = limits.max_extent;
        if width > max.width || height > max.height || depth > max.depth {
            bail!(
                "image '{name}': extent {width}x{height}x{depth} exceeds the device maximum \
                 {}x{}x{} for {:?}",
                max.width,
                max.height,
                max.depth,
                desc.format
            );
        }

        let info = vk::ImageCreateInfo::default()
            .image_type(desc.image_type)
            .format(desc.format)
            .extent(desc.extent)
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(desc.usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        // SAFETY: `info` is a valid create info for this device (2D or 3D with a non-empty
        // extent within the format's maximum and a format and usage the device supports,
        // all checked above); the device outlives the image.
        let raw = unsafe { device.create_image(&info, None) }.vk_context(|| {
            format!(
                "vkCreateImage for '{name}' ({width}x{height}x{depth} {:?})",
                desc.format
            )
        })?;
        // SAFETY: `raw` was just created on this device and is not yet destroyed.
        let requirements = unsafe { device.get_image_memory_requirements(raw) };
        let allocation = self.allocator().allocate(&AllocationCreateDesc {
            name,
            requirements,
            location: MemoryLocation::GpuOnly,
            linear: false,
            allocation_scheme: AllocationScheme::GpuAllocatorManaged,
        });
        let allocation = match allocation {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: `raw` was created above, has no memory bound and was never handed
                // out, so nothing uses it.
                unsafe { device.destroy_image(raw, None) };
                return Err(e).with_context(|| {
                    format!(
                        "allocating {} bytes of device memory for image '{name}'",
                        requirements.size
                    )
                });
            }
        };
        // SAFETY: `raw` was created above and has no memory yet; `allocation` was made for
        // its own requirements, so its memory and offset satisfy them.
        let bound =
            unsafe { device.bind_image_memory(raw, allocation.memory(), allocation.offset()) };
        if let Err(e) = bound {
            self.free_allocation(allocation, name);
            // SAFETY: binding failed, so `raw` has no memory and was never handed out; its
            // allocation was freed just above.
            unsafe { device.destroy_image(raw, None) };
            return Err(e).vk_context(|| format!("vkBindImageMemory for '{name}'"));
        }
        self.set_name(raw, name);
        let mut image = Image {
            raw,
            view: vk::ImageView::null(),
            desc: *desc,
            name: name.to_owned(),
            allocation: Some(allocation),
        };

        let view_info = vk::ImageViewCreateInfo::default()
            .image(raw)
            .view_type(view_type)
            .format(desc.format)
            .subresource_range(COLOR_RANGE);
        // SAFETY: `raw` is bound to its memory above, and the view's format, type and
        // single colour subresource match how it was created.
        match unsafe { device.create_image_view(&view_info, None) } {
            Ok(view) => image.view = view,
            Err(e) => {
                self.destroy_image(image);
                return Err(e).vk_context(|| format!("vkCreateImageView for '{name}'"));
            }
        }
        self.set_name(image.view, &format!("{name} (view)"));

        // Move the image to GENERAL, where it stays for its whole life.
        let transition = self.submit_one_shot(&format!("layout GENERAL for '{name}'"), |cmd| {
            let barrier = vk::ImageMemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::empty())
                .dst_access_mask(
                    vk::AccessFlags::SHADER_READ
                        | vk::AccessFlags::SHADER_WRITE
                        | vk::AccessFlags::TRANSFER_READ
                        | vk::AccessFlags::TRANSFER_WRITE,
                )
                .old_layout(vk::ImageLayout::UNDEFINED)
                .new_layout(vk::ImageLayout::GENERAL)
                .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .image(raw)
                .subresource_range(COLOR_RANGE);
            // SAFETY: `cmd` is this one-shot's buffer, recording; `raw` is alive, not yet
            // used by anything, and the barrier covers its one subresource, moving it out
            // of UNDEFINED.
            unsafe {
                device.cmd_pipeline_barrier(
                    cmd,
                    vk::PipelineStageFlags::TOP_OF_PIPE,
                    vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
                    vk::DependencyFlags::empty(),
                    &[],
                    &[],
                    &[barrier],
                )
            };
            Ok(())
        });
        if let Err(e) = transition {
            self.destroy_image(image);
            return Err(e);
        }
        Ok(image)
    }

    /// Destroys the view and the image and frees its memory. The GPU must be done with it.
    pub fn destroy_image(&self, mut image: Image) {
        let device = self.device();
        // SAFETY: the image is owned (moved in) and by this function's contract the GPU is
        // done with it; the view (null when `create_image` failed before making one, and
        // then skipped) goes before the image it views, and the memory is freed after both.
        unsafe {
            if image.view != vk::ImageView::null() {
                device.destroy_image_view(image.view, None);
            }
            device.destroy_image(image.raw, None);
        }
        if let Some(allocation) = image.allocation.take() {
            self.free_allocation(allocation, &image.name);
        }
        image.raw = vk::Image::null();
        image.view = vk::ImageView::null();
    }

    /// Creates a sampler without mipmapping or anisotropy.
    pub fn create_sampler(&self, desc: &SamplerDesc, name: &str) -> Result<vk::Sampler> {
        let info = vk::SamplerCreateInfo::default()
            .mag_filter(desc.filter)
            .min_filter(desc.filter)
            .mipmap_mode(vk::SamplerMipmapMode::NEAREST)
            .address_mode_u(desc.address_mode)
            .address_mode_v(desc.address_mode)
            .address_mode_w(desc.address_mode)
            .min_lod(0.0)
            .max_lod(0.0)
            .unnormalized_coordinates(false);
        // SAFETY: `info` is a valid create info (no anisotropy, no compare, LOD range [0,
        // 0]) and outlives the call.
        let sampler = unsafe { self.device().create_sampler(&info, None) }
            .vk_context(|| format!("vkCreateSampler for '{name}'"))?;
        self.set_name(sampler, name);
        Ok(sampler)
    }

    pub fn destroy_sampler(&self, sampler: vk::Sampler) {
        // SAFETY: the caller gives back a sampler it made with `create_sampler` on this
        // context, once no descriptor set the GPU still uses refers to it (the contract of
        // every destroy function here).
        unsafe { self.device().destroy_sampler(sampler, None) };
    }
}
