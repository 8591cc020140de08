//! One cleanup bag for the GPU objects of a pass.
//!
//! A pass creates a dozen buffers, images, samplers, pipelines and descriptor sets, and
//! any of those creations can fail half-way. [`GpuObjects`] owns every object it is given
//! and hands back a typed, copyable [`Handle`], so a pass keeps its resources as *named*
//! handles (`lights: Handle<Buffer>`) instead of positions in a vector, and frees
//! everything with one call, whether creation finished or stopped at an error:
//!
//! ```ignore
//! let (objects, res) = GpuObjects::build(ctx, |o| {
//!     let lights = o.add(ctx.create_buffer(&desc, "lights")?);
//!     let pipeline = o.add(ctx.create_compute_pipeline(&pipeline_desc, "pass")?);
//!     Ok(Resources { lights, pipeline })
//! })?;
//! let lights: &Buffer = &objects[res.lights];
//! objects.destroy(ctx);
//! ```
//!
//! Objects are destroyed in the reverse order of their kinds' dependencies: descriptor
//! sets, pipelines, samplers, images, buffers.

use std::marker::PhantomData;
use std::ops::{Index, IndexMut};

use anyhow::Result;
use ash::vk;

use crate::{Buffer, ComputePipeline, Context, DescriptorSet, Image};

/// A typed index into a [`GpuObjects`] bag. Valid only for the bag that made it.
pub struct Handle<T> {
    index: usize,
    kind: PhantomData<fn() -> T>,
}

impl<T> Clone for Handle<T> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T> Copy for Handle<T> {}

impl<T> PartialEq for Handle<T> {
    fn eq(&self, other: &Self) -> bool {
        self.index == other.index
    }
}

impl<T> Eq for Handle<T> {}

impl<T> std::fmt::Debug for Handle<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Handle<{}>({})", std::any::type_name::<T>(), self.index)
    }
}

impl<T> Handle<T> {
    fn new(index: usize) -> Self {
        Self {
            index,
            kind: PhantomData,
        }
    }
}

/// Buffers, images, samplers, pipelines and descriptor sets owned together.
#[derive(Default)]
pub struct GpuObjects {
    buffers: Vec<Buffer>,
    images: Vec<Image>,
    samplers: Vec<vk::Sampler>,
    pipelines: Vec<ComputePipeline>,
    sets: Vec<DescriptorSet>,
}

/// A kind of object a [`GpuObjects`] bag can own.
pub trait GpuObject: Sized {
    #[doc(hidden)]
    fn list(bag: &GpuObjects) -> &Vec<Self>;
    #[doc(hidden)]
    fn list_mut(bag: &mut GpuObjects) -> &mut Vec<Self>;
}

macro_rules! gpu_object {
    ($ty:ty, $field:ident) => {
        impl GpuObject for $ty {
            fn list(bag: &GpuObjects) -> &Vec<Self> {
                &bag.$field
            }
            fn list_mut(bag: &mut GpuObjects) -> &mut Vec<Self> {
                &mut bag.$field
            }
        }
    };
}

gpu_object!(Buffer, buffers);
gpu_object!(Image, images);
gpu_object!(vk::Sampler, samplers);
gpu_object!(ComputePipeline, pipelines);
gpu_object!(DescriptorSet, sets);

impl GpuObjects {
    /// Runs `create` with an empty bag. On success returns the bag and what `create`
    /// returned (typically a struct of handles); on error destroys every object made so
    /// far and returns the error.
    pub fn build<T>(
        ctx: &Context,
        create: impl FnOnce(&mut GpuObjects) -> Result<T>,
    ) -> Result<(GpuObjects, T)> {
        let mut bag = GpuObjects::default();
        match create(&mut bag) {
            Ok(value) => Ok((bag, value)),
            Err(e) => {
                bag.destroy(ctx);
                Err(e)
            }
        }
    }

    /// Takes ownership of `object` and returns its handle.
    pub fn add<T: GpuObject>(&mut self, object: T) -> Handle<T> {
        let list = T::list_mut(self);
        list.push(object);
        Handle::new(list.len() - 1)
    }

    /// Number of objects of every kind.
    pub fn len(&self) -> usize {
        self.buffers.len()
            + self.images.len()
            + self.samplers.len()
            + self.pipelines.len()
            + self.sets.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Bytes of every buffer and image in the bag (their requested sizes; the
    /// allocator may round up).
    pub fn bytes(&self) -> u64 {
        let buffers: u64 = self.buffers.iter().map(|b| b.size).sum();
        let images: u64 = self
            .images
            .iter()
            .map(|i| i.desc.byte_size().unwrap_or(0))
            .sum();
        buffers + images
    }

    /// Frees every object: descriptor sets, pipelines, samplers, images, then buffers.
    pub fn destroy(self, ctx: &Context) {
        for set in self.sets {
            ctx.destroy_descriptor_set(set);
        }
        for pipeline in self.pipelines {
            ctx.destroy_compute_pipeline(pipeline);
        }
        for sampler in self.samplers {
            ctx.destroy_sampler(sampler);
        }
        for image in self.images {
            ctx.destroy_image(image);
        }
        for buffer in self.buffers {
            ctx.destroy_buffer(buffer);
        }
    }
}

impl<T: GpuObject> Index<Handle<T>> for GpuObjects {
    type Output = T;

    fn index(&self, handle: Handle<T>) -> &T {
        &T::list(self)[handle.index]
    }
}

impl<T: GpuObject> IndexMut<Handle<T>> for GpuObjects {
    fn index_mut(&mut self, handle: Handle<T>) -> &mut T {
        &mut T::list_mut(self)[handle.index]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn handles_index_their_own_kind() {
        let mut bag = GpuObjects::default();
        let a = bag.add(vk::Sampler::null());
        let b = bag.add(vk::Sampler::null());
        assert_ne!(a, b);
        assert_eq!(bag.len(), 2);
        assert_eq!(bag[b], vk::Sampler::null());
        assert!(format!("{a:?}").contains("Sampler"));
    }
}
