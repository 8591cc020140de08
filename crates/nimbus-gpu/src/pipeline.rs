//! Compute pipelines: one descriptor set, optional push constants, specialization constants.
//!
//! Each pipeline owns its single set layout (set 0) and its pipeline layout; the shader
//! module is destroyed once the pipeline exists. The context keeps built pipelines and
//! hands them out again for the same description (`pipeline_cache`). Specialization constants are 4 bytes each
//! (`bool` is a `VkBool32`), which is how render-plan features are compiled in or out.
//!
//! The constants are written into the module as its defaults ([`crate::spirv::specialize`]),
//! the code they make dead is removed ([`crate::spirv_strip`]), and the pipeline is created
//! from that module without `VkSpecializationInfo`: the same program for the driver, from a
//! module 1.5-3.5x smaller. On lavapipe that took a ReSTIR pipeline's creation from
//! 1.5-4.6 s to 0.4-0.6 s (plus the strip's 0.1-0.7 s of CPU, once per module: the result
//! is kept in memory and on disk).

use crate::context::{lock, Context};
use crate::descriptor::DescriptorSet;
use crate::error::{vk_error, VkResultExt};
use crate::pipeline_cache::{Built, PipelineKey};
use anyhow::{bail, Context as _, Result};
use ash::vk;
use std::collections::HashSet;
use std::ffi::CString;

const SPIRV_MAGIC: u32 = 0x0723_0203;

/// One binding of set 0, visible to the compute stage, one descriptor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BindingDesc {
    pub binding: u32,
    pub ty: vk::DescriptorType,
}

impl BindingDesc {
    pub const fn storage_buffer(binding: u32) -> Self {
        Self {
            binding,
            ty: vk::DescriptorType::STORAGE_BUFFER,
        }
    }

    pub const fn uniform_buffer(binding: u32) -> Self {
        Self {
            binding,
            ty: vk::DescriptorType::UNIFORM_BUFFER,
        }
    }

    pub const fn storage_image(binding: u32) -> Self {
        Self {
            binding,
            ty: vk::DescriptorType::STORAGE_IMAGE,
        }
    }

    /// A `COMBINED_IMAGE_SAMPLER` (`sampler2D` / `sampler3D` in GLSL).
    pub const fn sampled_image(binding: u32) -> Self {
        Self {
            binding,
            ty: vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
        }
    }
}

/// A specialization constant's value; every variant is 4 bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SpecValue {
    U32(u32),
    I32(i32),
    F32(f32),
    /// Encoded as `VkBool32` (0 or 1).
    Bool(bool),
}

impl SpecValue {
    /// The 4 bytes the driver reads for this constant.
    pub fn to_bytes(self) -> [u8; 4] {
        match self {
            SpecValue::U32(v) => v.to_ne_bytes(),
            SpecValue::I32(v) => v.to_ne_bytes(),
            SpecValue::F32(v) => v.to_ne_bytes(),
            SpecValue::Bool(v) => u32::from(v).to_ne_bytes(),
        }
    }
}

/// Everything needed to build a compute pipeline.
#[derive(Clone, Copy, Debug)]
pub struct ComputePipelineDesc<'a> {
    pub spirv: &'a [u32],
    pub entry: &'a str,
    pub bindings: &'a [BindingDesc],
    /// Bytes of push constants, a multiple of 4; 0 for none.
    pub push_constant_size: u32,
    /// `(constant_id, value)` pairs.
    pub specialization: &'a [(u32, SpecValue)],
}

/// A compute pipeline with its layouts. Free it with [`Context::destroy_compute_pipeline`].
#[derive(Debug)]
pub struct ComputePipeline {
    pub raw: vk::Pipeline,
    pub layout: vk::PipelineLayout,
    pub set_layout: vk::DescriptorSetLayout,
    pub push_constant_size: u32,
    pub name: String,
    /// The set-0 bindings, used to check descriptor writes.
    pub bindings: Vec<BindingDesc>,
}

impl ComputePipeline {
    /// Binds the pipeline and `set`, pushes `push_constants` and dispatches `groups`.
    pub fn dispatch(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        set: &DescriptorSet,
        push_constants: &[u8],
        groups: [u32; 3],
    ) -> Result<()> {
        if set.set_layout != self.set_layout {
            bail!(
                "descriptor set '{}' was not created for pipeline '{}'",
                set.name,
                self.name
            );
        }
        if push_constants.len() != self.push_constant_size as usize {
            bail!(
                "pipeline '{}' takes {} bytes of push constants, got {}",
                self.name,
                self.push_constant_size,
                push_constants.len()
            );
        }
        let max = ctx.info().max_compute_work_group_count;
        if groups.iter().zip(max).any(|(&g, m)| g > m) {
            bail!(
                "pipeline '{}': dispatch of {groups:?} groups exceeds the device limit {max:?}",
                self.name
            );
        }
        ctx.dispatches
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let device = ctx.device();
        // SAFETY: the caller's `cmd` is recording (this crate's contract for every `cmd`);
        // the pipeline and the set are borrowed, hence alive, and were checked above to
        // match: the set was made for this layout, the push constants are exactly the
        // layout's range, and the group counts are within the device's limits.
        unsafe {
            device.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, self.raw);
            device.cmd_bind_descriptor_sets(
                cmd,
                vk::PipelineBindPoint::COMPUTE,
                self.layout,
                0,
                &[set.raw],
                &[],
            );
            if !push_constants.is_empty() {
                device.cmd_push_constants(
                    cmd,
                    self.layout,
                    vk::ShaderStageFlags::COMPUTE,
                    0,
                    push_constants,
                );
            }
            device.cmd_dispatch(cmd, groups[0], groups[1], groups[2]);
        }
        Ok(())
    }
}

impl Context {
    /// Several compute pipelines ([`Context::create_compute_pipeline`] each, `(description,
    /// name)` pairs) built at once, one thread each, in the order of `jobs`. A driver
    /// compiles one pipeline on one thread: lavapipe takes 1.6-3.4 s for each of ReSTIR's
    /// larger passes even with Mesa's shader cache warm, and an NVIDIA driver seconds on a
    /// cold cache. If any fails, none is kept and the first failure (in `jobs` order) is
    /// returned.
    pub fn create_compute_pipelines(
        &self,
        jobs: &[(ComputePipelineDesc<'_>, &str)],
    ) -> Result<Vec<ComputePipeline>> {
        let build = |(desc, name): &(ComputePipelineDesc<'_>, &str)| {
            self.create_compute_pipeline(desc, name)
        };
        let built: Vec<Result<ComputePipeline>> = if jobs.len() <= 1 {
            jobs.iter().map(build).collect()
        } else {
            std::thread::scope(|scope| {
                let threads: Vec<_> = jobs
                    .iter()
                    .map(|job| scope.spawn(move || build(job)))
                    .collect();
                threads
                    .into_iter()
                    .zip(jobs)
                    .map(|(thread, (_, name))| {
                        thread.join().unwrap_or_else(|_| {
                            Err(anyhow::anyhow!(
                                "internal: building pipeline '{name}' panicked"
                            ))
                        })
                    })
                    .collect()
            })
        };
        let mut pipelines = Vec::with_capacity(built.len());
        let mut error = None;
        for result in built {
            match result {
                Ok(p) => pipelines.push(p),
                Err(e) => {
                    error.get_or_insert(e);
                }
            }
        }
        if let Some(e) = error {
            for p in pipelines {
                self.destroy_compute_pipeline(p);
            }
            return Err(e);
        }
        Ok(pipelines)
    }

    /// A compute pipeline (set layout, pipeline layout, specialized pipeline): the one
    /// this context already built for the same description (`pipeline_cache`), or a
    /// new one.
    pub fn create_compute_pipeline(
        &self,
        desc: &ComputePipelineDesc<'_>,
        name: &str,
    ) -> Result<ComputePipeline> {
        if desc.spirv.first() != Some(&SPIRV_MAGIC) {
            bail!("pipeline '{name}': the shader code is not SPIR-V (missing magic number)");
        }
        let max_push = self.info().max_push_constants_size;
        if !desc.push_constant_size.is_multiple_of(4) || desc.push_constant_size > max_push {
            bail!(
                "pipeline '{name}': push constant size {} must be a multiple of 4 and at most {max_push}",
                desc.push_constant_size
            );
        }
        let mut seen = HashSet::new();
        if let Some(b) = desc.bindings.iter().find(|b| !seen.insert(b.binding)) {
            bail!("pipeline '{name}': binding {} is declared twice", b.binding);
        }
        let mut seen = HashSet::new();
        if let Some((id, _)) = desc.specialization.iter().find(|(id, _)| !seen.insert(*id)) {
            bail!("pipeline '{name}': specialization constant {id} is given twice");
        }
        // The module's own declarations against the description (crate::spirv).
        let layout: Vec<(u32, vk::DescriptorType)> =
            desc.bindings.iter().map(|b| (b.binding, b.ty)).collect();
        let given: Vec<u32> = desc.specialization.iter().map(|(id, _)| *id).collect();
        crate::spirv::check(name, desc.spirv, &layout, &given, desc.push_constant_size)?;
        let entry = CString::new(desc.entry)
            .with_context(|| format!("pipeline '{name}': entry point name contains NUL"))?;
        let key = PipelineKey::new(desc);
        let handle = |built: Built| ComputePipeline {
            raw: built.raw,
            layout: built.layout,
            set_layout: built.set_layout,
            push_constant_size: desc.push_constant_size,
            name: name.to_owned(),
            bindings: desc.bindings.to_vec(),
        };
        if let Some(built) = lock(&self.pipelines).take(&key) {
            return Ok(handle(built));
        }
        let device = self.device();
        let started = std::time::Instant::now();

        let set_bindings: Vec<_> = desc
            .bindings
            .iter()
            .map(|b| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b.binding)
                    .descriptor_type(b.ty)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        let set_layout_info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&set_bindings);
        // SAFETY: `set_layout_info` and the `set_bindings` it points to outlive the call;
        // bindings are unique (checked above).
        let set_layout = unsafe { device.create_descriptor_set_layout(&set_layout_info, None) }
            .vk_context(|| format!("vkCreateDescriptorSetLayout for '{name}'"))?;
        self.set_name(set_layout, &format!("{name} (set layout)"));

        let set_layouts = [set_layout];
        let push_ranges = [vk::PushConstantRange {
            stage_flags: vk::ShaderStageFlags::COMPUTE,
            offset: 0,
            size: desc.push_constant_size,
        }];
        let push_ranges: &[vk::PushConstantRange] = if desc.push_constant_size > 0 {
            &push_ranges
        } else {
            &[]
        };
        let layout_info = vk::PipelineLayoutCreateInfo::default()
            .set_layouts(&set_layouts)
            .push_constant_ranges(push_ranges);
        // SAFETY: `set_layout` was created above; `layout_info` and the push-constant range
        // it points to (a multiple of 4, within the device limit, checked above) outlive
        // the call.
        let layout = match unsafe { device.create_pipeline_layout(&layout_info, None) } {
            Ok(l) => l,
            Err(e) => {
                // SAFETY: `set_layout` was created above and nothing refers to it yet (the
                // pipeline layout failed).
                unsafe { device.destroy_descriptor_set_layout(set_layout, None) };
                return Err(vk_error(e, format!("vkCreatePipelineLayout for '{name}'")));
            }
        };
        self.set_name(layout, &format!("{name} (layout)"));
        // SAFETY: `destroy_layouts` runs only on the error paths below, where no pipeline
        // made with the two layouts exists; both were created above and never handed out.
        let destroy_layouts = || unsafe {
            device.destroy_pipeline_layout(layout, None);
            device.destroy_descriptor_set_layout(set_layout, None);
        };

        let values: Vec<(u32, u32)> = desc
            .specialization
            .iter()
            .map(|(id, v)| (*id, u32::from_ne_bytes(v.to_bytes())))
            .collect();
        let specialized = match crate::spirv::specialize(name, desc.spirv, &values) {
            Ok(words) => words,
            Err(e) => {
                destroy_layouts();
                return Err(e);
            }
        };
        let stripped = crate::spirv_strip::strip(name, &specialized);
        let strip_time = started.elapsed();
        let module_info = vk::ShaderModuleCreateInfo::default().code(&stripped);
        // SAFETY: `stripped` is `desc.spirv` (SPIR-V words that begin with the magic
        // number and that `crate::spirv::check` has parsed, both above) with its
        // specialization constants' defaults set and, unless SPIRV-Tools refused it, the
        // code they make dead removed (crate::spirv_strip); it outlives the call.
        let module = match unsafe { device.create_shader_module(&module_info, None) } {
            Ok(m) => m,
            Err(e) => {
                destroy_layouts();
                return Err(vk_error(e, format!("vkCreateShaderModule for '{name}'")));
            }
        };
        self.set_name(module, &format!("{name} (module)"));

        let stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(&entry);
        let info = vk::ComputePipelineCreateInfo::default()
            .stage(stage)
            .layout(layout);
        // SAFETY: `module` and `layout` are alive, `entry` outlives the call, and the
        // module's specialization IDs (now its defaults) and bindings were checked
        // against the description.
        let created =
            unsafe { device.create_compute_pipelines(vk::PipelineCache::null(), &[info], None) };
        // SAFETY: pipeline creation has returned, and a shader module may be destroyed once
        // the pipelines made from it exist; it is not used again.
        unsafe { device.destroy_shader_module(module, None) };
        let raw = match created {
            Ok(pipelines) => pipelines.first().copied(),
            Err((pipelines, e)) => {
                for p in pipelines.into_iter().filter(|p| *p != vk::Pipeline::null()) {
                    // SAFETY: `p` was created by the failed call above and never handed
                    // out.
                    unsafe { device.destroy_pipeline(p, None) };
                }
                destroy_layouts();
                return Err(vk_error(
                    e,
                    format!(
                        "vkCreateComputePipelines for '{name}' (entry '{}')",
                        desc.entry
                    ),
                ));
            }
        };
        let Some(raw) = raw else {
            destroy_layouts();
            bail!("vkCreateComputePipelines for '{name}' returned no pipeline");
        };
        self.set_name(raw, name);
        if crate::spirv_strip::log_times() {
            eprintln!(
                "[nimbus-gpu] pipeline '{name}': {} -> {} SPIR-V words, stripped in {:.3} s, \
                 built in {:.3} s",
                desc.spirv.len(),
                stripped.len(),
                strip_time.as_secs_f64(),
                (started.elapsed() - strip_time).as_secs_f64()
            );
        }
        let built = Built {
            raw,
            layout,
            set_layout,
        };
        let (built, duplicate) = lock(&self.pipelines).insert(key, built);
        if let Some(d) = duplicate {
            self.destroy_built(d);
        }
        Ok(handle(built))
    }

    /// Gives the pipeline back: the context keeps it for a later request of the same
    /// description and destroys pipelines nobody uses beyond
    /// [`crate::pipeline_cache::IDLE_PIPELINES`]. The GPU must be done with this
    /// handle's work.
    pub fn destroy_compute_pipeline(&self, pipeline: ComputePipeline) {
        let built = Built {
            raw: pipeline.raw,
            layout: pipeline.layout,
            set_layout: pipeline.set_layout,
        };
        let doomed = lock(&self.pipelines).give_back(built);
        for b in doomed {
            self.destroy_built(b);
        }
    }

    /// Destroys a pipeline and its layouts. No command buffer may still use it.
    pub(crate) fn destroy_built(&self, built: Built) {
        let device = self.device();
        // SAFETY: `built` is owned and out of the cache, and by the callers' contract
        // (`destroy_compute_pipeline`, or `Context::drop` after waiting idle) no command
        // buffer still uses it; the pipeline is destroyed before the layouts it was made
        // with.
        unsafe {
            device.destroy_pipeline(built.raw, None);
            device.destroy_pipeline_layout(built.layout, None);
            device.destroy_descriptor_set_layout(built.set_layout, None);
        }
    }
}
