//! Built pipelines kept by the context and handed out again for the same description.
//!
//! A renderer builds its pipelines for every render, and one process often renders the
//! same pipelines many times: a study's configurations and seeds, a test suite's
//! independent runs. Building is not cheap on every device: lavapipe runs its NIR passes
//! when the pipeline is created and JIT-compiles it at its first dispatch, a few seconds
//! for a large shader such as ReSTIR's spatial pass. The context therefore keeps each
//! pipeline (with its layouts) under a key of everything that defines it (the SPIR-V,
//! entry point, bindings, push-constant size and specialization data) and hands it out
//! again, counting its users. [`crate::Context::destroy_compute_pipeline`] gives a user back;
//! a pipeline without users stays until [`IDLE_PIPELINES`] younger idle ones exist, then
//! it is destroyed, so memory stays bounded however many distinct pipelines a process
//! builds. The context destroys whatever is left when it is dropped.
//!
//! A handed-out pipeline is the same Vulkan object for every user: binding one pipeline
//! in several command buffers (also on several threads) is allowed, and it is never
//! modified after creation.

use std::collections::hash_map::DefaultHasher;
use std::collections::HashMap;
use std::hash::{Hash, Hasher};

use ash::vk;

use crate::pipeline::ComputePipelineDesc;

/// Pipelines without users that are kept for later requests.
pub const IDLE_PIPELINES: usize = 48;

/// Everything that defines a pipeline. The SPIR-V enters by its length and a 64-bit
/// hash (two different shaders of equal length colliding is not a practical concern,
/// and every other part is compared exactly).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(crate) struct PipelineKey {
    spirv_len: usize,
    spirv_hash: u64,
    entry: String,
    bindings: Vec<(u32, i32)>,
    push_constant_size: u32,
    specialization: Vec<(u32, [u8; 4])>,
}

impl PipelineKey {
    pub(crate) fn new(desc: &ComputePipelineDesc<'_>) -> Self {
        let mut h = DefaultHasher::new();
        desc.spirv.hash(&mut h);
        Self {
            spirv_len: desc.spirv.len(),
            spirv_hash: h.finish(),
            entry: desc.entry.to_owned(),
            bindings: desc
                .bindings
                .iter()
                .map(|b| (b.binding, b.ty.as_raw()))
                .collect(),
            push_constant_size: desc.push_constant_size,
            specialization: desc
                .specialization
                .iter()
                .map(|(id, v)| (*id, v.to_bytes()))
                .collect(),
        }
    }
}

/// The Vulkan objects of one pipeline.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Built {
    pub raw: vk::Pipeline,
    pub layout: vk::PipelineLayout,
    pub set_layout: vk::DescriptorSetLayout,
}

struct Entry {
    built: Built,
    users: u32,
    /// When it was last handed out or given back (a counter), for choosing which idle
    /// pipeline to destroy.
    last_use: u64,
}

/// The context's pipelines (behind its mutex).
#[derive(Default)]
pub(crate) struct PipelineCache {
    entries: HashMap<PipelineKey, Entry>,
    clock: u64,
}

impl PipelineCache {
    /// The pipeline of `key`, if built, with one more user.
    pub(crate) fn take(&mut self, key: &PipelineKey) -> Option<Built> {
        self.clock += 1;
        let entry = self.entries.get_mut(key)?;
        entry.users += 1;
        entry.last_use = self.clock;
        Some(entry.built)
    }

    /// Records a newly built pipeline with one user. When another thread built the same
    /// key meanwhile, that one is handed out instead and `built` comes back in the
    /// second value, for the caller to destroy.
    pub(crate) fn insert(&mut self, key: PipelineKey, built: Built) -> (Built, Option<Built>) {
        if let Some(existing) = self.take(&key) {
            return (existing, Some(built));
        }
        self.entries.insert(
            key,
            Entry {
                built,
                users: 1,
                last_use: self.clock,
            },
        );
        (built, None)
    }

    /// Gives one user of `raw` back. Returns the pipelines to destroy now: `raw` itself
    /// when the cache does not hold it, and the idle pipelines beyond
    /// [`IDLE_PIPELINES`], oldest first.
    pub(crate) fn give_back(&mut self, built: Built) -> Vec<Built> {
        self.clock += 1;
        let clock = self.clock;
        let Some(entry) = self.entries.values_mut().find(|e| e.built.raw == built.raw) else {
            return vec![built];
        };
        entry.users = entry.users.saturating_sub(1);
        entry.last_use = clock;
        let mut idle: Vec<(u64, PipelineKey)> = self
            .entries
            .iter()
            .filter(|(_, e)| e.users == 0)
            .map(|(k, e)| (e.last_use, k.clone()))
            .collect();
        if idle.len() <= IDLE_PIPELINES {
            return Vec::new();
        }
        idle.sort_by_key(|(t, _)| *t);
        let excess = idle.len() - IDLE_PIPELINES;
        idle.into_iter()
            .take(excess)
            .filter_map(|(_, k)| self.entries.remove(&k).map(|e| e.built))
            .collect()
    }

    /// Every pipeline, emptying the cache (the context's teardown).
    pub(crate) fn drain(&mut self) -> Vec<Built> {
        self.entries.drain().map(|(_, e)| e.built).collect()
    }

    #[cfg(test)]
    fn len(&self) -> usize {
        self.entries.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::{BindingDesc, SpecValue};
    use ash::vk::Handle;

    fn key(spirv: &[u32], spec: u32) -> PipelineKey {
        PipelineKey::new(&ComputePipelineDesc {
            spirv,
            entry: "main",
            bindings: &[BindingDesc::storage_buffer(0)],
            push_constant_size: 16,
            specialization: &[(1, SpecValue::U32(spec))],
        })
    }

    fn built(n: u64) -> Built {
        Built {
            raw: vk::Pipeline::from_raw(n),
            layout: vk::PipelineLayout::from_raw(n),
            set_layout: vk::DescriptorSetLayout::from_raw(n),
        }
    }

    #[test]
    fn keys_tell_apart_code_and_every_setting() {
        let a = key(&[1, 2, 3], 0);
        assert_eq!(a, key(&[1, 2, 3], 0));
        assert_ne!(a, key(&[1, 2, 4], 0));
        assert_ne!(a, key(&[1, 2, 3], 1));
        let other_binding = PipelineKey::new(&ComputePipelineDesc {
            spirv: &[1, 2, 3],
            entry: "main",
            bindings: &[BindingDesc::uniform_buffer(0)],
            push_constant_size: 16,
            specialization: &[(1, SpecValue::U32(0))],
        });
        assert_ne!(a, other_binding);
    }

    #[test]
    fn a_pipeline_is_shared_and_outlives_its_users_until_evicted() {
        let mut cache = PipelineCache::default();
        let k = key(&[7], 0);
        assert_eq!(cache.take(&k), None);
        assert_eq!(cache.insert(k.clone(), built(1)), (built(1), None));
        // A second user gets the same objects; a racing builder's copy is returned to
        // be destroyed.
        assert_eq!(cache.take(&k), Some(built(1)));
        assert_eq!(
            cache.insert(k.clone(), built(2)),
            (built(1), Some(built(2)))
        );
        // Three users; giving them back destroys nothing (it stays for later renders).
        for _ in 0..3 {
            assert!(cache.give_back(built(1)).is_empty());
        }
        assert_eq!(cache.take(&k), Some(built(1)));
        assert!(cache.give_back(built(1)).is_empty());
        // Something the cache never held is destroyed at once.
        assert_eq!(cache.give_back(built(99)), vec![built(99)]);
    }

    #[test]
    fn idle_pipelines_beyond_the_limit_are_destroyed_oldest_first() {
        let mut cache = PipelineCache::default();
        let n = IDLE_PIPELINES as u32 + 3;
        for i in 0..n {
            cache.insert(key(&[i], 0), built(u64::from(i) + 1));
        }
        // The first one stays in use throughout.
        let mut destroyed = Vec::new();
        for i in 1..n {
            destroyed.extend(cache.give_back(built(u64::from(i) + 1)));
        }
        // n - 1 idle, IDLE_PIPELINES kept: the two given back first went.
        assert_eq!(destroyed, vec![built(2), built(3)]);
        assert_eq!(cache.len(), IDLE_PIPELINES + 1);
        assert_eq!(cache.take(&key(&[0], 0)), Some(built(1)));
        assert_eq!(cache.drain().len(), IDLE_PIPELINES + 1);
    }
}
