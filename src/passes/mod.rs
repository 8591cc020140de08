//! The passes: each one Rust module implementing [`Pass`] and one shader folder.
//!
//! A pass owns its GPU objects in one [`GpuObjects`] bag and keeps them as named
//! [`nimbus_gpu::Handle`]s, so a half-built pass frees what it made with one call and no
//! resource is addressed by its position in a vector. The renderer knows passes only
//! through the [`Pass`] trait; [`create`] is the one place that maps a plan's
//! [`Integrator`] to a pass.
//!
//! # How to add a pass
//!
//! Six source files (`docs/architecture.md`, "Adding a pass", is the checklist), each
//! step checked by a test or by the compiler:
//!
//! 1. **Shader**: `shaders/<pass>/<name>.comp` (shared code in `shaders/include/`). New
//!    specialization-constant IDs, estimator IDs or limits go into
//!    `src/shader_data/contract/features.rs`, new bindings into
//!    `src/shader_data/contract/bindings.rs`, a new uniform or record struct into
//!    `src/shader_data/contract/records.rs` (with named scalar members): each is written
//!    once, and `build.rs` generates the GLSL the shaders include from it (see
//!    [`crate::shader_data::contract`]). When the pipeline is created,
//!    `nimbus_gpu::spirv` reads the compiled module and refuses it if the pass leaves a
//!    specialization constant the shader declares unset (it would take the shader's
//!    default silently), lacks a binding the shader uses or gives it another kind, or
//!    gives a push-constant range shorter than the shader's block; the pass's
//!    `pipeline_contracts` (see [`pipeline_contracts`]) lets
//!    `tests/suite/contracts/contract.rs` check the same without a device.
//! 2. **Pass**: `src/passes/<pass>.rs`, a struct implementing [`Pass`]: `new` creates its
//!    pipelines and resources inside [`GpuObjects::build`], `record` dispatches.
//! 3. **Dispatch**: its `mod` line here, one arm in [`create`] below, and one in
//!    [`pipeline_contracts`].
//! 4. **Plan**: a settings struct and a variant of [`Integrator`] in `src/plan/mod.rs`
//!    (its `PASSES` row, its arm in `effective_scene`), and
//! 5. the builder that picks it, with its decision rows (what runs, which features are
//!    on, and why; `--explain` prints them): `src/plan/boxes.rs`, `src/plan/volume.rs` or
//!    a new one beside them.
//! 6. **Footprint**: what it allocates, in `src/plan/footprint.rs`, so the renderer
//!    refuses a render that does not fit before anything is created.
//!
//! Then a test: a golden image or a comparison with a CPU oracle under `tests/suite/`.
//! `build.rs` compiles every `.comp` it finds, and `crate::shaders` names its SPIR-V by
//! path (`shaders/box/crepuscular.comp` is `shaders::BOX_CREPUSCULAR`).

pub mod baseline;
pub mod baseline_frames;
pub mod crepuscular;
pub mod restir;

use anyhow::{bail, Context as _, Result};
use glam::Vec3;
use nimbus_gpu::{
    compute_barrier, vk, BindingDesc, Buffer, BufferDesc, ComputePipeline, ComputePipelineDesc,
    Context, DescriptorSet, DescriptorWrite, GpuObjects, Handle, Image, ImageDesc, Profiler,
    SpecValue,
};
use nimbus_scene::{BrickGrid, GridMedium, Medium, Scene};

use crate::plan::{Integrator, RenderPlan};
use crate::shader_data::sparse::{SparseLayout, TexelFormat};
use crate::shader_data::{
    bindings, frame_uniforms, FrameUniforms, GpuEnvMap, GpuGrid, PassPush, RecordCounts,
};

/// Workgroup size of every image-space shader (`local_size_x`, `local_size_y`).
pub const GROUP_SIZE: [u32; 2] = [
    crate::shader_data::features::GROUP_SIZE_X,
    crate::shader_data::features::GROUP_SIZE_Y,
];

/// A render pass: created once per render from its plan, then recorded once per frame.
pub trait Pass {
    /// The scope name in profiles (`frame/<label>/…`).
    fn label(&self) -> &'static str;

    /// The frame uniforms of scene frame `frame` (its camera and environment map turn):
    /// the pass knows its record counts and the constant environment radiance.
    fn frame_uniforms(&self, scene: &Scene, frame: u32) -> FrameUniforms;

    /// Uploads what changes for the scene's frame `scene_frame` (animated lights,
    /// density frames, the previous camera) before that frame is recorded.
    /// `previous_frame` is the scene frame the previous dispatch rendered: usually
    /// `scene_frame - 1`, `scene_frame` itself when a frame is rendered again to
    /// accumulate it (the previous camera and density are then this frame's).
    fn prepare(
        &mut self,
        _ctx: &Context,
        _scene: &Scene,
        _scene_frame: u32,
        _previous_frame: u32,
    ) -> Result<()> {
        Ok(())
    }

    /// Records the frame's dispatches. `dispatch_index` counts every recorded frame,
    /// warm-up included (it seeds the random numbers). A pass with several dispatches
    /// opens one profiler scope per stage inside the renderer's scope.
    fn record(
        &mut self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        uniforms: &FrameUniforms,
        dispatch_index: u32,
        profiler: Option<&mut Profiler>,
    ) -> Result<()>;

    /// Bytes of every buffer and image the pass created.
    fn device_bytes(&self) -> u64;

    /// What the pass decided from the scene's content that the user should know (e.g.
    /// settings it refined), one sentence each.
    fn notes(&self) -> Vec<String> {
        Vec::new()
    }

    /// The stages whose work counters the pass reports, by counter slot (slot i counts
    /// `counter_labels()[i]`; see [`crate::shader_data::counters`]).
    fn counter_labels(&self) -> Vec<&'static str> {
        vec![self.label()]
    }

    /// Frees every GPU object of the pass.
    fn destroy(self: Box<Self>, ctx: &Context);
}

/// Creates the pass of `plan`.
pub fn create(
    ctx: &Context,
    scene: &Scene,
    plan: &RenderPlan,
    targets: &Targets,
) -> Result<Box<dyn Pass>> {
    Ok(match &plan.integrator {
        Integrator::Crepuscular(p) => Box::new(crepuscular::create(ctx, p, scene, targets)?),
        Integrator::Baseline(p) if crate::plan::has_density_frames(scene) => {
            Box::new(baseline_frames::create(ctx, p, scene, targets)?)
        }
        Integrator::Baseline(p) => Box::new(baseline::create(
            ctx,
            p,
            scene,
            GpuGrid::build(scene)?,
            targets,
        )?),
        Integrator::Restir(p) => Box::new(restir::RestirPass::new(
            ctx,
            p,
            scene,
            GpuGrid::build(scene)?,
            targets,
        )?),
    })
}

/// Buffers shared with the renderer: written by the pass, read back by the renderer.
/// Every pass binds them (their layout entries and writes are [`Targets::layout`] and
/// [`Targets::writes`]), the AOV buffers included: without AOVs those are one-element
/// dummies and the shaders' AOV code is specialized out (`crate::plan::AovPlan`).
pub struct Targets<'a> {
    pub uniforms: &'a Buffer,
    pub accum: &'a Buffer,
    pub accum_sq: &'a Buffer,
    pub stats: &'a Buffer,
    /// A frame's partial sums while its samples are shared among dispatches (pixels x
    /// 32 bytes on a device with a loop budget, 32 bytes elsewhere).
    pub film_partial: &'a Buffer,
    /// The geometric AOVs of the last frame (`bindings::AOV_GEOMETRY`).
    pub aov_geometry: &'a Buffer,
    /// The path AOVs' sums over frames and their squares.
    pub aov_accum: &'a Buffer,
    pub aov_accum_sq: &'a Buffer,
    /// The path AOVs' partial sums of a frame shared among dispatches.
    pub aov_partial: &'a Buffer,
    /// `AovUniformsGpu`: the previous frame's camera, the environment's light group.
    pub aov_uniforms: &'a Buffer,
    /// Which AOVs the render writes: the specialization constants, and the light groups
    /// a pass writes into its light records ([`crate::plan::AovPlan::assign_groups`]).
    pub aov: &'a crate::plan::AovPlan,
    /// Whether the passes count their work into the stats buffer
    /// ([`crate::shader_data::counters`]): `nimbus profile --counters` and `nimbus bench`.
    pub counters: bool,
    /// Whether anything reads the film's alpha (else the passes leave the camera ray's
    /// transmittance out and every pixel reads as opaque).
    pub alpha: bool,
    /// The coherent-lanes diagnostic ([`FilmSpec::coherent_lanes`]).
    pub coherent_lanes: bool,
}

impl<'a> Targets<'a> {
    /// The film's specialization constants for a pipeline counting into counter slot
    /// `slot` (when this render counts work): `SC_ALPHA`, the counters' and the AOVs'.
    pub fn film_spec(&self, slot: u32) -> FilmSpec {
        FilmSpec {
            counter_slot: self.counters.then_some(slot),
            alpha: self.alpha,
            aov: AovSpec::of(self.aov),
            coherent_lanes: self.coherent_lanes,
        }
    }

    /// The descriptor writes of the frame uniforms, the film buffers and the AOV
    /// buffers, which every pass binds at the same binding numbers.
    pub fn writes(&self) -> [DescriptorWrite<'a>; 10] {
        let buffer = |binding, buffer| DescriptorWrite::StorageBuffer { binding, buffer };
        [
            buffer(bindings::FRAME_UNIFORMS, self.uniforms),
            buffer(bindings::ACCUM, self.accum),
            buffer(bindings::ACCUM_SQ, self.accum_sq),
            buffer(bindings::STATS, self.stats),
            buffer(bindings::FILM_PARTIAL, self.film_partial),
            buffer(bindings::AOV_GEOMETRY, self.aov_geometry),
            buffer(bindings::AOV_ACCUM, self.aov_accum),
            buffer(bindings::AOV_ACCUM_SQ, self.aov_accum_sq),
            buffer(bindings::AOV_PARTIAL, self.aov_partial),
            buffer(bindings::AOV_UNIFORMS, self.aov_uniforms),
        ]
    }

    /// The layout entries of [`Targets::writes`].
    pub fn layout() -> [BindingDesc; 10] {
        [
            BindingDesc::storage_buffer(bindings::FRAME_UNIFORMS),
            BindingDesc::storage_buffer(bindings::ACCUM),
            BindingDesc::storage_buffer(bindings::ACCUM_SQ),
            BindingDesc::storage_buffer(bindings::STATS),
            BindingDesc::storage_buffer(bindings::FILM_PARTIAL),
            BindingDesc::storage_buffer(bindings::AOV_GEOMETRY),
            BindingDesc::storage_buffer(bindings::AOV_ACCUM),
            BindingDesc::storage_buffer(bindings::AOV_ACCUM_SQ),
            BindingDesc::storage_buffer(bindings::AOV_PARTIAL),
            BindingDesc::storage_buffer(bindings::AOV_UNIFORMS),
        ]
    }
}

/// The AOV specialization constants of a pipeline (`shaders/include/aov.glsl`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AovSpec {
    /// `SC_AOV_GEOMETRY`.
    pub geometry: bool,
    /// `SC_AOV_PATHS`.
    pub paths: bool,
    /// `SC_AOV_GROUPS`.
    pub groups: u32,
}

impl AovSpec {
    pub fn of(plan: &crate::plan::AovPlan) -> AovSpec {
        AovSpec {
            geometry: plan.geometry,
            paths: plan.paths,
            groups: plan.group_count(),
        }
    }
}

/// The per-frame constants every pass puts into [`FrameUniforms`]: the constant
/// environment radiance, the environment map's size (1 × 1 without one) and the pass's
/// record counts.
#[derive(Clone, Copy, Debug)]
pub struct FrameConstants {
    pub env_radiance: Vec3,
    pub env_size: [u32; 2],
    pub counts: RecordCounts,
}

impl FrameConstants {
    /// The uniforms of scene frame `frame`: its camera, and its environment map's turn.
    pub fn uniforms(&self, scene: &Scene, frame: u32) -> FrameUniforms {
        let camera = scene.camera.frame_at(frame);
        let rotation = if scene.lights_animated() {
            nimbus_scene::environment_rotation(&scene.lights_at(frame))
        } else {
            nimbus_scene::environment_rotation(&scene.lights)
        };
        FrameUniforms {
            env_size: self.env_size,
            ..frame_uniforms(scene, &camera, self.env_radiance, rotation, self.counts)
        }
    }
}

/// What every pipeline's film (`shaders/include/film.glsl`) is specialized with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FilmSpec {
    /// The work-counter slot, when the render counts work.
    pub counter_slot: Option<u32>,
    /// Whether the film's alpha is computed.
    pub alpha: bool,
    /// The AOVs computed.
    pub aov: AovSpec,
    /// Every workgroup traces its first pixel's samples in all its invocations
    /// (`SC_COHERENT_LANES`, `nimbus profile --coherent-lanes`).
    pub coherent_lanes: bool,
}

/// A pass of one pipeline dispatched once per frame, one invocation per pixel, with
/// [`PassPush`] push constants: what the crepuscular and baseline passes are once
/// created. It owns their objects.
pub struct ImagePass {
    label: &'static str,
    objects: GpuObjects,
    pipeline: Handle<ComputePipeline>,
    set: Handle<DescriptorSet>,
    constants: FrameConstants,
    /// Camera samples per pixel one dispatch takes: all of the frame's where the device
    /// has no loop limit, else as many as fit its loop budget (the frame's dispatches
    /// then carry their sums in the film's partial buffer; the last adds the frame's
    /// estimate).
    samples_per_dispatch: u32,
}

/// Loop iterations one ray may typically run through the scene's meshes, for the
/// passes' sample costs: per mesh, 8 node visits (each with its leaf's triangle loop)
/// per level of its BVH, a few times the one path to a leaf that a ray needs at the
/// least. 0 without meshes.
pub fn mesh_ray_cost(scene: &Scene) -> u32 {
    scene
        .shapes
        .iter()
        .map(|s| match s {
            nimbus_scene::Shape::Mesh { mesh, .. } => 8 * (mesh.bvh.depth() + 1),
            _ => 0,
        })
        .fold(0u32, u32::saturating_add)
}

/// Camera samples one dispatch may take on a device with a loop budget (see
/// [`nimbus_gpu::DeviceInfo::loop_budget`]) when one sample may run `sample_cost` loop
/// iterations: a quarter of the budget (the walk's random collisions and a margin), at
/// least 1. Few dispatches per frame keep a render fast on lavapipe, where every
/// dispatch costs host time and memory.
pub fn samples_per_dispatch(budget: Option<u32>, sample_cost: u32) -> u32 {
    match budget {
        None => u32::MAX,
        Some(b) => (b / 4 / sample_cost.max(1)).max(1),
    }
}

impl ImagePass {
    pub fn new(
        ctx: &Context,
        label: &'static str,
        objects: GpuObjects,
        pipeline: Handle<ComputePipeline>,
        set: Handle<DescriptorSet>,
        constants: FrameConstants,
        sample_cost: u32,
    ) -> ImagePass {
        ImagePass {
            label,
            objects,
            pipeline,
            set,
            constants,
            samples_per_dispatch: samples_per_dispatch(ctx.info().loop_budget(), sample_cost),
        }
    }
}

impl Pass for ImagePass {
    fn label(&self) -> &'static str {
        self.label
    }

    fn frame_uniforms(&self, scene: &Scene, frame: u32) -> FrameUniforms {
        self.constants.uniforms(scene, frame)
    }

    fn record(
        &mut self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        uniforms: &FrameUniforms,
        dispatch_index: u32,
        _profiler: Option<&mut Profiler>,
    ) -> Result<()> {
        let spp = uniforms.spp.max(1);
        let per = self.samples_per_dispatch.clamp(1, spp);
        let mut base = 0;
        while base < spp {
            if base > 0 {
                compute_barrier(ctx, cmd);
            }
            let push = PassPush {
                frame: dispatch_index,
                sample_base: base,
                sample_count: per.min(spp - base),
                _pad1: 0,
            };
            self.objects[self.pipeline].dispatch(
                ctx,
                cmd,
                &self.objects[self.set],
                bytemuck::bytes_of(&push),
                image_groups(uniforms),
            )?;
            base += per;
        }
        Ok(())
    }

    fn device_bytes(&self) -> u64 {
        self.objects.bytes()
    }

    fn destroy(self: Box<Self>, ctx: &Context) {
        self.objects.destroy(ctx);
    }
}

/// Whether a pass holding the light records of scene frame `held` (`None`: the scene's
/// un-keyed lights, which any keyed frame may differ from) must upload those of `frame`:
/// only where light keyframes make them differ. An environment map's turn is no part of
/// the records (it reaches the shaders in the frame uniforms), so a turn alone uploads
/// nothing (and traces no moment map again).
pub fn lights_change(scene: &Scene, held: Option<u32>, frame: u32) -> bool {
    let unturned = |f: u32| {
        let mut lights = scene.lights_at(f);
        for light in &mut lights {
            if let nimbus_scene::Light::Environment { rotation_deg, .. } = light {
                *rotation_deg = 0.0;
            }
        }
        lights
    };
    scene.lights_animated() && held.is_none_or(|f| unturned(frame) != unturned(f))
}

/// Workgroups covering the frame's image, one invocation per pixel.
pub fn image_groups(uniforms: &FrameUniforms) -> [u32; 3] {
    [
        uniforms.width.div_ceil(GROUP_SIZE[0]),
        uniforms.height.div_ceil(GROUP_SIZE[1]),
        1,
    ]
}

/// SPIR-V bytes as words (the embedded bytes carry no alignment guarantee).
pub fn spirv_words(bytes: &[u8]) -> Result<Vec<u32>> {
    if !bytes.len().is_multiple_of(4) {
        bail!(
            "embedded SPIR-V of {} bytes is not a whole number of words",
            bytes.len()
        );
    }
    Ok(bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

/// An image-space compute pipeline from embedded SPIR-V, with push constants of type
/// `P`, owned by `objects`.
pub fn compute_pipeline<P>(
    ctx: &Context,
    objects: &mut GpuObjects,
    spirv: &[u8],
    bindings: &[BindingDesc],
    specialization: &[(u32, SpecValue)],
    film: FilmSpec,
    name: &str,
) -> Result<Handle<ComputePipeline>> {
    let job = PipelineJob {
        spirv,
        specialization,
        film,
        name: name.to_owned(),
    };
    compute_pipelines::<P>(ctx, objects, bindings, std::slice::from_ref(&job))?
        .pop()
        .context("internal: one pipeline asked for, none built")
}

/// One pipeline of [`compute_pipelines`].
pub struct PipelineJob<'a> {
    pub spirv: &'a [u8],
    pub specialization: &'a [(u32, SpecValue)],
    pub film: FilmSpec,
    pub name: String,
}

/// Several image-space compute pipelines with one layout and push constants of type `P`,
/// built at once ([`Context::create_compute_pipelines`]: one thread each) and added to
/// `objects` in the order of `jobs`. If any fails, none is kept.
pub fn compute_pipelines<P>(
    ctx: &Context,
    objects: &mut GpuObjects,
    bindings: &[BindingDesc],
    jobs: &[PipelineJob<'_>],
) -> Result<Vec<Handle<ComputePipeline>>> {
    let words = jobs
        .iter()
        .map(|job| spirv_words(job.spirv))
        .collect::<Result<Vec<_>>>()?;
    let specializations: Vec<_> = jobs
        .iter()
        .map(|job| pipeline_specialization(job.specialization, job.film))
        .collect();
    let descs: Vec<(ComputePipelineDesc<'_>, &str)> = words
        .iter()
        .zip(&specializations)
        .zip(jobs)
        .map(|((spirv, specialization), job)| {
            (
                ComputePipelineDesc {
                    spirv,
                    entry: "main",
                    bindings,
                    push_constant_size: std::mem::size_of::<P>() as u32,
                    specialization,
                },
                job.name.as_str(),
            )
        })
        .collect();
    let pipelines = ctx.create_compute_pipelines(&descs)?;
    Ok(pipelines.into_iter().map(|p| objects.add(p)).collect())
}

/// Every specialization constant of a pipeline: the pass's own and the film's
/// (`SC_ALPHA` and the counters').
pub fn pipeline_specialization(
    specialization: &[(u32, SpecValue)],
    film: FilmSpec,
) -> Vec<(u32, SpecValue)> {
    let mut all = specialization.to_vec();
    all.push((
        crate::shader_data::features::SC_ID_ALPHA,
        SpecValue::Bool(film.alpha),
    ));
    all.push((
        crate::shader_data::features::SC_ID_COHERENT_LANES,
        SpecValue::Bool(film.coherent_lanes),
    ));
    all.extend(crate::shader_data::counters::specialization(
        film.counter_slot,
    ));
    all.extend([
        (
            crate::shader_data::features::SC_ID_AOV_GEOMETRY,
            SpecValue::Bool(film.aov.geometry),
        ),
        (
            crate::shader_data::features::SC_ID_AOV_PATHS,
            SpecValue::Bool(film.aov.paths),
        ),
        (
            crate::shader_data::features::SC_ID_AOV_GROUPS,
            SpecValue::U32(film.aov.groups),
        ),
    ]);
    all
}

/// What one pipeline of a pass gives its shader, known without a device: the module,
/// the descriptor layout, every specialization constant and the push-constant size, from
/// the same functions the pass creates the pipeline with. `tests/suite/contracts/contract.rs`
/// checks each against its SPIR-V.
pub struct PipelineContract {
    pub name: String,
    pub spirv: &'static [u8],
    pub bindings: Vec<BindingDesc>,
    pub specialization: Vec<(u32, SpecValue)>,
    pub push_constant_size: u32,
}

impl PipelineContract {
    /// The contract of an image-space pipeline made by [`compute_pipeline`] with push
    /// constants of type `P` (film: no counters, no alpha; the same constants are set).
    pub fn of<P>(
        name: &str,
        spirv: &'static [u8],
        bindings: Vec<BindingDesc>,
        specialization: &[(u32, SpecValue)],
    ) -> PipelineContract {
        let film = FilmSpec {
            counter_slot: None,
            alpha: false,
            aov: AovSpec::default(),
            coherent_lanes: false,
        };
        PipelineContract {
            name: name.to_owned(),
            spirv,
            bindings,
            specialization: pipeline_specialization(specialization, film),
            push_constant_size: std::mem::size_of::<P>() as u32,
        }
    }
}

/// The pipelines the pass of `plan` creates, as [`PipelineContract`]s (scene-dependent
/// constants, like exact spans or two-level bricks, off).
pub fn pipeline_contracts(plan: &RenderPlan) -> Vec<PipelineContract> {
    match &plan.integrator {
        Integrator::Crepuscular(p) => crepuscular::pipeline_contracts(p),
        Integrator::Baseline(p) => vec![baseline::pipeline_contract(p)],
        Integrator::Restir(p) => restir::resources::pipeline_contracts(p),
    }
}

/// Whether a pass reads a volume from a storage buffer of `bytes` instead of its atlas
/// image, by the scene's `fetch` (`[integrator.baseline] density_fetch`, `[integrator.restir]
/// pc_fetch`): "auto" takes the buffer on CPU devices (lavapipe, where a texelFetch is a
/// call into the sampler's code and a buffer load one loop over the lanes) where it fits
/// one binding and `AUTO_DENSITY_BUFFER_MAX` (which every device binds, so the footprint
/// knows without a device what it allocates); "buffer" is refused where it does not fit,
/// naming `source`, `field` and `what` the buffer holds.
pub fn volume_in_buffer(
    info: &nimbus_gpu::DeviceInfo,
    fetch: nimbus_scene::DensityFetch,
    bytes: u64,
    source: &std::path::Path,
    field: &str,
    what: &str,
) -> Result<bool> {
    let alloc = info.max_memory_allocation_size;
    let fits = bytes <= u64::from(info.max_storage_buffer_range) && (alloc == 0 || bytes <= alloc);
    Ok(match fetch {
        nimbus_scene::DensityFetch::Image => false,
        nimbus_scene::DensityFetch::Auto => {
            info.device_type == vk::PhysicalDeviceType::CPU
                && fits
                && bytes <= crate::shader_data::sparse::AUTO_DENSITY_BUFFER_MAX
        }
        nimbus_scene::DensityFetch::Buffer => {
            if !fits {
                anyhow::bail!(
                    "{}: {field} = \"buffer\": {what} take {bytes} bytes, more than {} allows \
                     in one storage buffer ({} bytes); use \"image\" or \"auto\"",
                    source.display(),
                    info.name,
                    info.max_storage_buffer_range
                );
            }
            true
        }
    })
}

/// A storage buffer for `slots` slots of a density's quads ([`upload_density_quads`]),
/// owned by `o`.
pub fn density_quads_buffer(
    ctx: &Context,
    o: &mut GpuObjects,
    slots: u64,
) -> Result<Handle<Buffer>> {
    let bytes = crate::shader_data::sparse::density_buffer_bytes(slots.max(1));
    Ok(o.add(ctx.create_buffer(
        &BufferDesc::gpu_only(bytes, vk::BufferUsageFlags::STORAGE_BUFFER),
        "grid density texels",
    )?))
}

/// Writes a density's slots into `buffer` (made by [`density_quads_buffer`]) as the
/// shaders read them where SC_DENSITY_BUFFER: slot after slot from slot 0, each slot's
/// 10^3 texels x fastest, a quad of R32 per texel ([`SparseLayout::slot_major_quads`]);
/// slots before the layout's first hold zeros. Uploaded a chunk of slots at a time, so the
/// host never holds more than a chunk (the memory estimate counts the atlas's layers the
/// same way).
///
/// [`SparseLayout::slot_major_quads`]: crate::shader_data::sparse::SparseLayout::slot_major_quads
pub fn upload_density_quads(
    ctx: &Context,
    buffer: &Buffer,
    layout: &SparseLayout,
    density: &BrickGrid,
) -> Result<()> {
    use crate::shader_data::sparse::{density_buffer_bytes, DENSITY_SLOT_TEXELS};
    /// Slots per upload: 4 MB of quads.
    const CHUNK: usize = 256;
    let first = layout.first_slot as usize;
    let slot_bytes = density_buffer_bytes(1);
    let mut quads = Vec::with_capacity(CHUNK * DENSITY_SLOT_TEXELS);
    for start in (0..first).step_by(CHUNK) {
        let n = CHUNK.min(first - start);
        quads.clear();
        quads.resize(n * DENSITY_SLOT_TEXELS, [0f32; 4]);
        ctx.upload_buffer(
            buffer,
            start as u64 * slot_bytes,
            bytemuck::cast_slice(&quads),
        )?;
    }
    for (c, bricks) in layout.bricks.chunks(CHUNK).enumerate() {
        quads.clear();
        SparseLayout::slot_major_quads(density, bricks, 1.0, &mut quads);
        let offset = (first + c * CHUNK) as u64 * slot_bytes;
        ctx.upload_buffer(buffer, offset, bytemuck::cast_slice(&quads))?;
    }
    Ok(())
}

/// A GPU-only storage buffer holding `records`, owned by `objects`.
pub fn upload_records<T: bytemuck::Pod>(
    ctx: &Context,
    objects: &mut GpuObjects,
    records: &[T],
    name: &str,
) -> Result<Handle<Buffer>> {
    let bytes: &[u8] = bytemuck::cast_slice(records);
    let buffer = objects.add(ctx.create_buffer(
        &BufferDesc::gpu_only(bytes.len() as u64, vk::BufferUsageFlags::STORAGE_BUFFER),
        name,
    )?);
    ctx.upload_buffer(&objects[buffer], 0, bytes)?;
    Ok(buffer)
}

/// A GPU-only read-only parameter block holding `value` (a storage buffer: see
/// shaders/include/film.glsl for why no pass uses uniform buffers), owned by `objects`.
pub fn upload_params<T: bytemuck::Pod>(
    ctx: &Context,
    objects: &mut GpuObjects,
    value: &T,
    name: &str,
) -> Result<Handle<Buffer>> {
    let buffer = objects.add(ctx.create_buffer(
        &BufferDesc::gpu_only(
            std::mem::size_of::<T>() as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER,
        ),
        name,
    )?);
    ctx.upload_buffer(&objects[buffer], 0, bytemuck::bytes_of(value))?;
    Ok(buffer)
}

/// A sampled 3D image of `dims` texels holding `bytes`, owned by `objects`.
pub fn image_3d(
    ctx: &Context,
    objects: &mut GpuObjects,
    dims: [u32; 3],
    format: vk::Format,
    bytes: &[u8],
    name: &str,
) -> Result<Handle<Image>> {
    let image = objects.add(ctx.create_image(
        &ImageDesc::sampled_3d(dims[0], dims[1], dims[2], format),
        name,
    )?);
    ctx.upload_image(&objects[image], bytes)?;
    Ok(image)
}

/// The images of a grid's static grids (uploaded once): the emission, the temperature
/// with its blackbody table, the albedo. A grid the medium lacks is compiled out, and its
/// binding sees the density (the blackbody table: the super-voxels) instead.
pub struct StaticGrids {
    pub emission: Handle<Image>,
    pub temperature: Handle<Image>,
    pub blackbody: Handle<Buffer>,
    pub albedo: Handle<Image>,
}

impl StaticGrids {
    /// Uploads `grid`'s static grids into `o`; `density` and `super_voxels` are the
    /// grid's density atlas and super-voxel buffer, bound where a grid is missing.
    pub fn upload(
        ctx: &Context,
        o: &mut GpuObjects,
        grid: &GpuGrid,
        density: Handle<Image>,
        super_voxels: Handle<Buffer>,
    ) -> Result<StaticGrids> {
        let emission = match &grid.emission {
            Some((e, layout, format)) => {
                atlas_image(ctx, o, layout, e, 1.0, *format, "grid emission")?
            }
            None => density,
        };
        let (temperature, blackbody) = match &grid.temperature {
            Some((t, layout)) => (
                atlas_image(ctx, o, layout, t, 1.0, TexelFormat::R32, "grid temperature")?,
                upload_records(
                    ctx,
                    o,
                    &nimbus_scene::blackbody::BlackbodyTable::get().entries,
                    "blackbody table",
                )?,
            ),
            None => (density, super_voxels),
        };
        let albedo = match &grid.albedo_grid {
            Some((a, layout, format)) => {
                atlas_image(ctx, o, layout, a, 1.0, *format, "grid albedo")?
            }
            None => density,
        };
        Ok(StaticGrids {
            emission,
            temperature,
            blackbody,
            albedo,
        })
    }
}

/// A 3D atlas of `layout`'s slots holding `grid`'s texels times `scale` in `format`,
/// uploaded one layer of slots at a time, owned by `objects`.
pub fn atlas_image(
    ctx: &Context,
    objects: &mut GpuObjects,
    layout: &SparseLayout,
    grid: &BrickGrid,
    scale: f32,
    format: TexelFormat,
    name: &str,
) -> Result<Handle<Image>> {
    let [w, h, d] = layout.atlas_dims();
    let image = objects.add(ctx.create_image(&ImageDesc::sampled_3d(w, h, d, format.vk()), name)?);
    layout.upload(ctx, &objects[image], grid, scale, format)?;
    Ok(image)
}

/// The environment map's texels and sampling tables as two storage buffers; without a
/// map the (compiled-out) bindings get one zero record each.
pub fn upload_env_map(
    ctx: &Context,
    objects: &mut GpuObjects,
    env_map: Option<&GpuEnvMap>,
) -> Result<(Handle<Buffer>, Handle<Buffer>)> {
    let (texels, tables): (&[[f32; 4]], &[f32]) = match env_map {
        Some(map) => (&map.texels, &map.tables),
        None => (&[[0.0; 4]], &[0.0]),
    };
    Ok((
        upload_records(ctx, objects, texels, "environment texels")?,
        upload_records(ctx, objects, tables, "environment tables")?,
    ))
}

/// The scene's grid medium and its index among the media.
pub fn scene_grid(scene: &Scene) -> Result<(usize, &GridMedium)> {
    scene
        .media
        .iter()
        .enumerate()
        .find_map(|(i, m)| match m {
            Medium::Grid(g) => Some((i, g)),
            _ => None,
        })
        .context("internal: a grid pass was given no grid medium")
}
