//! Descriptor sets: one small pool per set, written once at creation.
//!
//! A set is created for one pipeline's set layout and must write every binding of it exactly
//! once with a resource of the declared type; buffers are bound whole, images in `GENERAL`.
//! Mismatches, missing usage flags and buffers larger than the device's descriptor range
//! limits (128 MiB storage on lavapipe) are errors here rather than validation messages.

use crate::buffer::Buffer;
use crate::context::Context;
use crate::error::{vk_error, VkResultExt};
use crate::image::Image;
use crate::pipeline::ComputePipeline;
use anyhow::{bail, Result};
use ash::vk;
use std::collections::HashMap;

/// One resource for one binding.
#[derive(Clone, Copy, Debug)]
pub enum DescriptorWrite<'a> {
    StorageBuffer {
        binding: u32,
        buffer: &'a Buffer,
    },
    UniformBuffer {
        binding: u32,
        buffer: &'a Buffer,
    },
    StorageImage {
        binding: u32,
        image: &'a Image,
    },
    /// A `COMBINED_IMAGE_SAMPLER`.
    SampledImage {
        binding: u32,
        image: &'a Image,
        sampler: vk::Sampler,
    },
}

impl DescriptorWrite<'_> {
    pub fn binding(&self) -> u32 {
        match *self {
            Self::StorageBuffer { binding, .. }
            | Self::UniformBuffer { binding, .. }
            | Self::StorageImage { binding, .. }
            | Self::SampledImage { binding, .. } => binding,
        }
    }

    pub fn descriptor_type(&self) -> vk::DescriptorType {
        match self {
            Self::StorageBuffer { .. } => vk::DescriptorType::STORAGE_BUFFER,
            Self::UniformBuffer { .. } => vk::DescriptorType::UNIFORM_BUFFER,
            Self::StorageImage { .. } => vk::DescriptorType::STORAGE_IMAGE,
            Self::SampledImage { .. } => vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
        }
    }

    fn resource_name(&self) -> &str {
        match self {
            Self::StorageBuffer { buffer, .. } | Self::UniformBuffer { buffer, .. } => &buffer.name,
            Self::StorageImage { image, .. } | Self::SampledImage { image, .. } => &image.name,
        }
    }
}

/// A descriptor set and the pool it came from. Free it with
/// [`Context::destroy_descriptor_set`].
#[derive(Debug)]
pub struct DescriptorSet {
    pub raw: vk::DescriptorSet,
    pub name: String,
    pub(crate) set_layout: vk::DescriptorSetLayout,
    pool: vk::DescriptorPool,
}

enum Info {
    Buffer(vk::DescriptorBufferInfo),
    Image(vk::DescriptorImageInfo),
}

impl Context {
    /// Allocates a set for `pipeline`'s layout and writes every binding.
    pub fn create_descriptor_set(
        &self,
        pipeline: &ComputePipeline,
        writes: &[DescriptorWrite<'_>],
        name: &str,
    ) -> Result<DescriptorSet> {
        self.check_writes(pipeline, writes, name)?;
        let device = self.device();

        let mut counts: HashMap<vk::DescriptorType, u32> = HashMap::new();
        for b in &pipeline.bindings {
            *counts.entry(b.ty).or_default() += 1;
        }
        let pool_sizes: Vec<_> = counts
            .into_iter()
            .map(|(ty, descriptor_count)| vk::DescriptorPoolSize {
                ty,
                descriptor_count,
            })
            .collect();
        let pool_info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(1)
            .pool_sizes(&pool_sizes);
        // SAFETY: `pool_info` (one set, one descriptor per binding of the pipeline's
        // layout) and `pool_sizes` outlive the call; the pool is this set's alone and is
        // destroyed with it.
        let pool = unsafe { device.create_descriptor_pool(&pool_info, None) }
            .vk_context(|| format!("vkCreateDescriptorPool for '{name}'"))?;
        self.set_name(pool, &format!("{name} (pool)"));

        let layouts = [pipeline.set_layout];
        let alloc_info = vk::DescriptorSetAllocateInfo::default()
            .descriptor_pool(pool)
            .set_layouts(&layouts);
        // SAFETY: `pool` was created above for exactly one set of this layout, and
        // `pipeline.set_layout` is alive while `pipeline` is borrowed.
        let raw = match unsafe { device.allocate_descriptor_sets(&alloc_info) } {
            Ok(sets) if !sets.is_empty() => sets[0],
            Ok(_) => {
                // SAFETY: `pool` was created above and holds no set anyone has seen.
                unsafe { device.destroy_descriptor_pool(pool, None) };
                bail!("vkAllocateDescriptorSets for '{name}' returned no set");
            }
            Err(e) => {
                // SAFETY: `pool` was created above and holds no set anyone has seen.
                unsafe { device.destroy_descriptor_pool(pool, None) };
                return Err(vk_error(
                    e,
                    format!("vkAllocateDescriptorSets for '{name}'"),
                ));
            }
        };
        self.set_name(raw, name);

        let infos: Vec<Info> = writes
            .iter()
            .map(|w| match *w {
                DescriptorWrite::StorageBuffer { buffer, .. }
                | DescriptorWrite::UniformBuffer { buffer, .. } => {
                    Info::Buffer(vk::DescriptorBufferInfo {
                        buffer: buffer.raw,
                        offset: 0,
                        range: vk::WHOLE_SIZE,
                    })
                }
                DescriptorWrite::StorageImage { image, .. } => {
                    Info::Image(vk::DescriptorImageInfo {
                        sampler: vk::Sampler::null(),
                        image_view: image.view,
                        image_layout: vk::ImageLayout::GENERAL,
                    })
                }
                DescriptorWrite::SampledImage { image, sampler, .. } => {
                    Info::Image(vk::DescriptorImageInfo {
                        sampler,
                        image_view: image.view,
                        image_layout: vk::ImageLayout::GENERAL,
                    })
                }
            })
            .collect();
        let vk_writes: Vec<_> = writes
            .iter()
            .zip(&infos)
            .map(|(w, info)| {
                let write = vk::WriteDescriptorSet::default()
                    .dst_set(raw)
                    .dst_binding(w.binding())
                    .dst_array_element(0)
                    .descriptor_type(w.descriptor_type());
                match info {
                    Info::Buffer(b) => write.buffer_info(std::slice::from_ref(b)),
                    Info::Image(i) => write.image_info(std::slice::from_ref(i)),
                }
            })
            .collect();
        // SAFETY: `raw` is the set allocated above, not yet bound in any command buffer;
        // `check_writes` matched every write to a binding and type of its layout, and the
        // buffers and images they name are borrowed (alive) for the call; `infos` outlives
        // `vk_writes`.
        unsafe { device.update_descriptor_sets(&vk_writes, &[]) };
        Ok(DescriptorSet {
            raw,
            name: name.to_owned(),
            set_layout: pipeline.set_layout,
            pool,
        })
    }

    /// Destroys the set's pool (and with it the set). The GPU must be done with it.
    pub fn destroy_descriptor_set(&self, set: DescriptorSet) {
        // SAFETY: the set is owned (moved in) and its pool is its own; by this function's
        // contract the GPU is done with it, so destroying the pool (and the set with it)
        // frees nothing in use.
        unsafe { self.device().destroy_descriptor_pool(set.pool, None) };
    }

    fn check_writes(
        &self,
        pipeline: &ComputePipeline,
        writes: &[DescriptorWrite<'_>],
        name: &str,
    ) -> Result<()> {
        let info = self.info();
        let mut written = HashMap::new();
        for w in writes {
            let binding = w.binding();
            let resource = w.resource_name();
            let Some(declared) = pipeline.bindings.iter().find(|b| b.binding == binding) else {
                bail!(
                    "descriptor set '{name}': pipeline '{}' has no binding {binding} (for '{resource}')",
                    pipeline.name
                );
            };
            if declared.ty != w.descriptor_type() {
                bail!(
                    "descriptor set '{name}': binding {binding} of pipeline '{}' is {:?}, \
                     but '{resource}' is written as {:?}",
                    pipeline.name,
                    declared.ty,
                    w.descriptor_type()
                );
            }
            if let Some(previous) = written.insert(binding, resource) {
                bail!(
                    "descriptor set '{name}': binding {binding} written twice ('{previous}' and '{resource}')"
                );
            }
            let (needed, limit) = match *w {
                DescriptorWrite::StorageBuffer { buffer, .. } => (
                    buffer
                        .desc
                        .usage
                        .contains(vk::BufferUsageFlags::STORAGE_BUFFER),
                    Some((buffer.size, info.max_storage_buffer_range)),
                ),
                DescriptorWrite::UniformBuffer { buffer, .. } => (
                    buffer
                        .desc
                        .usage
                        .contains(vk::BufferUsageFlags::UNIFORM_BUFFER),
                    Some((buffer.size, info.max_uniform_buffer_range)),
                ),
                DescriptorWrite::StorageImage { image, .. } => (
                    image.desc.usage.contains(vk::ImageUsageFlags::STORAGE),
                    None,
                ),
                DescriptorWrite::SampledImage { image, .. } => (
                    image.desc.usage.contains(vk::ImageUsageFlags::SAMPLED),
                    None,
                ),
            };
            if !needed {
                bail!(
                    "descriptor set '{name}': '{resource}' lacks the usage flag for {:?}",
                    w.descriptor_type()
                );
            }
            if let Some((size, max)) = limit {
                if size > u64::from(max) {
                    bail!(
                        "descriptor set '{name}': '{resource}' is {size} bytes, over the device's \
                         {:?} range limit of {max} bytes on '{}'",
                        w.descriptor_type(),
                        info.name
                    );
                }
            }
        }
        if let Some(missing) = pipeline
            .bindings
            .iter()
            .find(|b| !written.contains_key(&b.binding))
        {
            bail!(
                "descriptor set '{name}': binding {} ({:?}) of pipeline '{}' is not written",
                missing.binding,
                missing.ty,
                pipeline.name
            );
        }
        Ok(())
    }
}
