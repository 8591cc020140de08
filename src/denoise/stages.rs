//! The denoiser's GPU side: the buffers and pipelines of one image size and guide set
//! ([`State`]), the bindings of each stage, and the recording of one run of the stages
//! (see the module above for what each stage does).

use anyhow::{bail, Result};
use nimbus_gpu::{
    compute_barrier, vk, BindingDesc, Buffer, BufferDesc, ComputePipeline, ComputePipelineDesc,
    Context, DescriptorSet, DescriptorWrite, GpuObjects, Handle, Profiler, ScopeResult,
};

use super::*;
use crate::passes::{spirv_words, GROUP_SIZE};
use crate::shader_data::bindings as b;
use crate::shader_data::{DenoisePush, DENOISE_TEMPORAL, DENOISE_WRITE_HISTORY};

/// Which buffers the denoiser holds: its size and which guides it was made for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Shape {
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) geometry: bool,
    pub(super) depth: bool,
    pub(super) albedo: bool,
    pub(super) motion: bool,
    pub(super) temporal: bool,
}

/// The GPU objects of one [`Shape`].
pub(super) struct State {
    pub(super) shape: Shape,
    pub(super) objects: GpuObjects,
    pub(super) noisy: Handle<Buffer>,
    pub(super) film_variance: Handle<Buffer>,
    pub(super) guides: Handle<Buffer>,
    pub(super) albedo: Handle<Buffer>,
    pub(super) motion: Handle<Buffer>,
    pub(super) output: Handle<Buffer>,
    pub(super) prepare: (Handle<ComputePipeline>, Handle<DescriptorSet>),
    pub(super) residual: (Handle<ComputePipeline>, Handle<DescriptorSet>),
    pub(super) variance: (Handle<ComputePipeline>, Handle<DescriptorSet>),
    /// The à-trous pipeline and its sets A → B and B → A.
    pub(super) atrous: (Handle<ComputePipeline>, [Handle<DescriptorSet>; 2]),
    pub(super) finish: (Handle<ComputePipeline>, Handle<DescriptorSet>),
}

/// The bindings of each stage (all storage buffers).
const PREPARE_BINDINGS: [u32; 12] = [
    b::DENOISE_NOISY,
    b::DENOISE_FILM_VARIANCE,
    b::DENOISE_GUIDES,
    b::DENOISE_ALBEDO,
    b::DENOISE_MOTION,
    b::DENOISE_GRADIENT,
    b::DENOISE_COLOR_DST,
    b::DENOISE_VARIANCE_DST,
    b::DENOISE_HISTORY,
    b::DENOISE_MOMENTS,
    b::DENOISE_MOMENTS_PREV,
    b::DENOISE_GUIDES_PREV,
];
const RESIDUAL_BINDINGS: [u32; 2] = [b::DENOISE_COLOR_SRC, b::DENOISE_RESIDUAL];
const VARIANCE_BINDINGS: [u32; 5] = [
    b::DENOISE_RESIDUAL,
    b::DENOISE_VARIANCE_SRC,
    b::DENOISE_VARIANCE_DST,
    b::DENOISE_GUIDES,
    b::DENOISE_GRADIENT,
];
const ATROUS_BINDINGS: [u32; 7] = [
    b::DENOISE_COLOR_SRC,
    b::DENOISE_VARIANCE_SRC,
    b::DENOISE_COLOR_DST,
    b::DENOISE_VARIANCE_DST,
    b::DENOISE_GUIDES,
    b::DENOISE_GRADIENT,
    b::DENOISE_HISTORY,
];
const FINAL_BINDINGS: [u32; 8] = [
    b::DENOISE_COLOR_SRC,
    b::DENOISE_ALBEDO,
    b::DENOISE_OUTPUT,
    b::DENOISE_GUIDES,
    b::DENOISE_GUIDES_PREV,
    b::DENOISE_MOMENTS,
    b::DENOISE_MOMENTS_PREV,
    b::DENOISE_HISTORY,
];

/// The five pipelines: name, SPIR-V, bindings.
pub(super) fn stages() -> [(&'static str, &'static [u8], &'static [u32]); 5] {
    [
        (
            "denoise prepare",
            crate::shaders::DENOISE_PREPARE,
            &PREPARE_BINDINGS,
        ),
        (
            "denoise residual",
            crate::shaders::DENOISE_RESIDUAL,
            &RESIDUAL_BINDINGS,
        ),
        (
            "denoise variance",
            crate::shaders::DENOISE_VARIANCE,
            &VARIANCE_BINDINGS,
        ),
        (
            "denoise atrous",
            crate::shaders::DENOISE_ATROUS,
            &ATROUS_BINDINGS,
        ),
        (
            "denoise final",
            crate::shaders::DENOISE_FINAL,
            &FINAL_BINDINGS,
        ),
    ]
}

pub(super) fn layout(bindings: &[u32]) -> Vec<BindingDesc> {
    bindings
        .iter()
        .map(|&n| BindingDesc::storage_buffer(n))
        .collect()
}

impl State {
    pub(super) fn new(ctx: &Context, shape: Shape, iterations: u32) -> Result<State> {
        let pixels = u64::from(shape.width) * u64::from(shape.height);
        let (objects, state) = GpuObjects::build(ctx, |o| {
            let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
            let buffer = |o: &mut GpuObjects, bytes: u64, name: &str| -> Result<_> {
                Ok(o.add(ctx.create_buffer(&BufferDesc::gpu_only(bytes.max(16), storage), name)?))
            };
            // A guide the image lacks gets a 16-byte buffer the shaders never read.
            let per = |on: bool, bytes: u64| if on { pixels * bytes } else { 16 };
            let noisy = buffer(o, pixels * 16, "denoise noisy")?;
            let film_variance = buffer(o, pixels * 16, "denoise film variance")?;
            let guides = buffer(o, per(shape.geometry, 16), "denoise guides")?;
            let albedo = buffer(o, per(shape.albedo, 16), "denoise albedo")?;
            let motion = buffer(o, per(shape.motion, 8), "denoise motion")?;
            let gradient = buffer(o, per(shape.depth, 8), "denoise depth gradient")?;
            let color = [
                buffer(o, pixels * 16, "denoise colour A")?,
                buffer(o, pixels * 16, "denoise colour B")?,
            ];
            let variance = [
                buffer(o, pixels * 4, "denoise variance A")?,
                buffer(o, pixels * 4, "denoise variance B")?,
            ];
            let history = buffer(o, per(shape.temporal, 16), "denoise history")?;
            let moments = buffer(o, per(shape.temporal, 16), "denoise moments")?;
            let moments_prev = buffer(o, per(shape.temporal, 16), "denoise moments (previous)")?;
            let guides_prev = buffer(
                o,
                per(shape.temporal && shape.geometry, 16),
                "denoise guides (previous)",
            )?;
            let output = buffer(o, pixels * 16, "denoise output")?;
            let residual = buffer(o, pixels * 4, "denoise residuals")?;

            let mut pipelines = Vec::new();
            for (name, spirv, bindings) in stages() {
                let words = spirv_words(spirv)?;
                let pipeline = ctx.create_compute_pipeline(
                    &ComputePipelineDesc {
                        spirv: &words,
                        entry: "main",
                        bindings: &layout(bindings),
                        push_constant_size: std::mem::size_of::<DenoisePush>() as u32,
                        specialization: &[],
                    },
                    name,
                )?;
                pipelines.push(o.add(pipeline));
            }
            let [prepare, residual_p, variance_p, atrous, finish] = pipelines[..] else {
                bail!("internal: the denoiser has five pipelines");
            };
            // Every binding's buffer, by binding number, for one set.
            let set = |o: &mut GpuObjects,
                       pipeline: Handle<ComputePipeline>,
                       roles: &[(u32, Handle<Buffer>)],
                       name: &str|
             -> Result<Handle<DescriptorSet>> {
                let writes: Vec<DescriptorWrite> = roles
                    .iter()
                    .map(|&(binding, buffer)| DescriptorWrite::StorageBuffer {
                        binding,
                        buffer: &o[buffer],
                    })
                    .collect();
                let set = ctx.create_descriptor_set(&o[pipeline], &writes, name)?;
                Ok(o.add(set))
            };
            let prepare_set = set(
                o,
                prepare,
                &[
                    (b::DENOISE_NOISY, noisy),
                    (b::DENOISE_FILM_VARIANCE, film_variance),
                    (b::DENOISE_GUIDES, guides),
                    (b::DENOISE_ALBEDO, albedo),
                    (b::DENOISE_MOTION, motion),
                    (b::DENOISE_GRADIENT, gradient),
                    (b::DENOISE_COLOR_DST, color[0]),
                    (b::DENOISE_VARIANCE_DST, variance[1]),
                    (b::DENOISE_HISTORY, history),
                    (b::DENOISE_MOMENTS, moments),
                    (b::DENOISE_MOMENTS_PREV, moments_prev),
                    (b::DENOISE_GUIDES_PREV, guides_prev),
                ],
                "denoise prepare",
            )?;
            let residual_set = set(
                o,
                residual_p,
                &[
                    (b::DENOISE_COLOR_SRC, color[0]),
                    (b::DENOISE_RESIDUAL, residual),
                ],
                "denoise residual",
            )?;
            let variance_set = set(
                o,
                variance_p,
                &[
                    (b::DENOISE_RESIDUAL, residual),
                    (b::DENOISE_VARIANCE_SRC, variance[1]),
                    (b::DENOISE_VARIANCE_DST, variance[0]),
                    (b::DENOISE_GUIDES, guides),
                    (b::DENOISE_GRADIENT, gradient),
                ],
                "denoise variance",
            )?;
            let mut atrous_sets = Vec::new();
            for (src, dst) in [(0, 1), (1, 0)] {
                atrous_sets.push(set(
                    o,
                    atrous,
                    &[
                        (b::DENOISE_COLOR_SRC, color[src]),
                        (b::DENOISE_VARIANCE_SRC, variance[src]),
                        (b::DENOISE_COLOR_DST, color[dst]),
                        (b::DENOISE_VARIANCE_DST, variance[dst]),
                        (b::DENOISE_GUIDES, guides),
                        (b::DENOISE_GRADIENT, gradient),
                        (b::DENOISE_HISTORY, history),
                    ],
                    if src == 0 {
                        "denoise atrous A->B"
                    } else {
                        "denoise atrous B->A"
                    },
                )?);
            }
            // Iteration k reads colour (k % 2) and writes the other: the last writes B
            // for an odd count, A for an even one (A: prepare's output when there is none).
            let result = color[(iterations % 2) as usize];
            let finish_set = set(
                o,
                finish,
                &[
                    (b::DENOISE_COLOR_SRC, result),
                    (b::DENOISE_ALBEDO, albedo),
                    (b::DENOISE_OUTPUT, output),
                    (b::DENOISE_GUIDES, guides),
                    (b::DENOISE_GUIDES_PREV, guides_prev),
                    (b::DENOISE_MOMENTS, moments),
                    (b::DENOISE_MOMENTS_PREV, moments_prev),
                    (b::DENOISE_HISTORY, history),
                ],
                "denoise final",
            )?;
            Ok(StateHandles {
                noisy,
                film_variance,
                guides,
                albedo,
                motion,
                output,
                prepare: (prepare, prepare_set),
                residual: (residual_p, residual_set),
                variance: (variance_p, variance_set),
                atrous: (atrous, [atrous_sets[0], atrous_sets[1]]),
                finish: (finish, finish_set),
            })
        })?;
        Ok(State {
            shape,
            objects,
            noisy: state.noisy,
            film_variance: state.film_variance,
            guides: state.guides,
            albedo: state.albedo,
            motion: state.motion,
            output: state.output,
            prepare: state.prepare,
            residual: state.residual,
            variance: state.variance,
            atrous: state.atrous,
            finish: state.finish,
        })
    }

    /// Uploads the image and its guides (non-finite guide values made harmless: no
    /// depth, a zero normal or albedo, no motion).
    pub(super) fn upload(
        &self,
        ctx: &Context,
        image: &NoisyImage<'_>,
        guides: &Guides,
    ) -> Result<()> {
        let pixels = image.color.data.len();
        let rgba: Vec<[f32; 4]> = (0..pixels)
            .map(|i| {
                let c = image.color.data[i];
                [c[0], c[1], c[2], image.alpha[i]]
            })
            .collect();
        ctx.upload_buffer(&self.objects[self.noisy], 0, bytemuck::cast_slice(&rgba))?;
        let variance: Vec<[f32; 4]> = (0..pixels)
            .map(|i| {
                let s = image.std_error.data[i];
                let a = image.alpha_std_error[i];
                [s[0] * s[0], s[1] * s[1], s[2] * s[2], a * a]
            })
            .collect();
        ctx.upload_buffer(
            &self.objects[self.film_variance],
            0,
            bytemuck::cast_slice(&variance),
        )?;
        let finite = |v: f32| if v.is_finite() { v } else { 0.0 };
        if self.shape.geometry {
            let texels: Vec<[f32; 4]> = (0..pixels)
                .map(|i| {
                    let n = guides.normal.as_ref().map_or([0.0; 3], |n| {
                        [finite(n[0][i]), finite(n[1][i]), finite(n[2][i])]
                    });
                    let z = guides.depth.as_ref().map_or(-1.0, |d| {
                        let z = d[i];
                        if z.is_finite() && z >= 0.0 {
                            z
                        } else {
                            -1.0
                        }
                    });
                    [n[0], n[1], n[2], z]
                })
                .collect();
            ctx.upload_buffer(&self.objects[self.guides], 0, bytemuck::cast_slice(&texels))?;
        }
        if let Some(a) = &guides.albedo {
            let texels: Vec<[f32; 4]> = (0..pixels)
                .map(|i| [finite(a[0][i]), finite(a[1][i]), finite(a[2][i]), 0.0])
                .collect();
            ctx.upload_buffer(&self.objects[self.albedo], 0, bytemuck::cast_slice(&texels))?;
        }
        if let Some(m) = &guides.motion {
            let texels: Vec<[f32; 2]> = (0..pixels)
                .map(|i| [finite(m[0][i]), finite(m[1][i])])
                .collect();
            ctx.upload_buffer(&self.objects[self.motion], 0, bytemuck::cast_slice(&texels))?;
        }
        Ok(())
    }

    /// Records and submits the stages; returns the timestamps (the `denoise` scope with
    /// one child per dispatch) when there is a profiler.
    pub(super) fn record(
        &self,
        ctx: &Context,
        push: &DenoisePush,
        iterations: u32,
        mut profiler: Option<&mut Profiler>,
    ) -> Result<Vec<ScopeResult>> {
        let groups = [
            push.width.div_ceil(GROUP_SIZE[0]),
            push.height.div_ceil(GROUP_SIZE[1]),
            1,
        ];
        let o = &self.objects;
        let temporal = push.flags & DENOISE_TEMPORAL != 0;
        ctx.submit_one_shot("denoise", |cmd| {
            if let Some(p) = profiler.as_deref_mut() {
                p.begin_frame(cmd);
                p.begin_scope(ctx, cmd, "denoise")?;
            }
            let mut stage = |label: &str,
                             (pipeline, set): (Handle<ComputePipeline>, Handle<DescriptorSet>),
                             push: &DenoisePush,
                             first: bool|
             -> Result<()> {
                if !first {
                    compute_barrier(ctx, cmd);
                }
                if let Some(p) = profiler.as_deref_mut() {
                    p.begin_scope(ctx, cmd, label)?;
                }
                o[pipeline].dispatch(ctx, cmd, &o[set], bytemuck::bytes_of(push), groups)?;
                if let Some(p) = profiler.as_deref_mut() {
                    p.end_scope(ctx, cmd)?;
                }
                Ok(())
            };
            stage("prepare", self.prepare, push, true)?;
            stage("residual", self.residual, push, false)?;
            stage("variance", self.variance, push, false)?;
            for k in 0..iterations {
                let mut it = *push;
                it.step = 1 << k;
                if k == 0 && temporal {
                    it.flags |= DENOISE_WRITE_HISTORY;
                }
                let set = self.atrous.1[(k % 2) as usize];
                stage(
                    &format!("atrous {}", k + 1),
                    (self.atrous.0, set),
                    &it,
                    false,
                )?;
            }
            let mut last = *push;
            if iterations == 0 && temporal {
                last.flags |= DENOISE_WRITE_HISTORY;
            }
            stage("final", self.finish, &last, false)?;
            if let Some(p) = profiler.as_deref_mut() {
                p.end_scope(ctx, cmd)?;
            }
            Ok(())
        })?;
        match profiler {
            Some(p) => p.resolve(ctx),
            None => Ok(Vec::new()),
        }
    }
}

/// The handles [`State::new`] builds.
pub(super) struct StateHandles {
    pub(super) noisy: Handle<Buffer>,
    pub(super) film_variance: Handle<Buffer>,
    pub(super) guides: Handle<Buffer>,
    pub(super) albedo: Handle<Buffer>,
    pub(super) motion: Handle<Buffer>,
    pub(super) output: Handle<Buffer>,
    pub(super) prepare: (Handle<ComputePipeline>, Handle<DescriptorSet>),
    pub(super) residual: (Handle<ComputePipeline>, Handle<DescriptorSet>),
    pub(super) variance: (Handle<ComputePipeline>, Handle<DescriptorSet>),
    pub(super) atrous: (Handle<ComputePipeline>, [Handle<DescriptorSet>; 2]),
    pub(super) finish: (Handle<ComputePipeline>, Handle<DescriptorSet>),
}
