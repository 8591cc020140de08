//! Volumetric ReSTIR (`shaders/restir/*.comp`): initial candidates, temporal reuse,
//! spatial reuse and final shading, with reservoirs that persist across frames.
//!
//! Reservoirs live in one storage buffer of three slots of `pixels × stride` u32 each
//! (`stride = 8 + 2K`: a 32-byte header and 8 bytes per path vertex, see restir.glsl).
//! A frame writes its initial candidates into a slot other than the previous frame's
//! result, reuses temporally in place, ping-pongs spatial rounds between the two free
//! slots, and its last output becomes the next frame's "previous" slot.

use std::cell::Cell;
use std::collections::HashMap;

use anyhow::{bail, Context as _, Result};
use nimbus_gpu::{
    compute_barrier, vk, BindingDesc, Buffer, BufferDesc, ComputePipeline, ComputePipelineDesc,
    Context, DescriptorSet, DescriptorWrite, Image, ImageDesc, Profiler, SamplerDesc, SpecValue,
};
use nimbus_scene::{GridMedium, Medium, Scene, VoxelGrid};

use crate::bindings;
use crate::gpu_scene::{self, non_empty, FrameUniforms, GpuGrid, LightGpu, LightSet};
use crate::passes::crepuscular::{image_groups, spirv_words, upload_records, Targets};
use crate::plan::RestirPlan;
use crate::shaders;

/// `RestirUniforms` in restir.glsl (std140).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct RestirUniformsGpu {
    pub pc_primary: [u32; 4],
    pub pc_indirect: [u32; 4],
    pub factors: [u32; 4],
    pub march_dims: [u32; 4],
    pub nee_dims: [u32; 4],
    pub settings: [u32; 4],
    pub spatial: [f32; 4],
    pub velocity_dims: [u32; 4],
}

/// `RestirPush` in restir.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct RestirPush {
    pub frame: u32,
    pub src: u32,
    pub dst: u32,
    pub aux: u32,
}

/// Bytes per pixel of one reservoir slot for K = `max_bounces`: a 32-byte header
/// (w_sum, M, p_hat, packed info, light point, octahedral light direction) and per vertex
/// z (f32) plus an octahedral direction (2 × 16 bits).
pub fn reservoir_bytes(max_bounces: u32) -> u64 {
    4 * u64::from(8 + 2 * max_bounces)
}

/// The densities derived for one density grid: the conservative piecewise-constant
/// levels for regular tracking and the averaged mip textures for ray marching.
struct DerivedVolume {
    /// σ_t* (scaled) of the primary level, then of the indirect level.
    pc: Vec<f32>,
    pc_primary: [u32; 4],
    pc_indirect: [u32; 4],
    /// Unscaled density, half floats, at mip_reuse and mip_indirect.
    march_reuse: (Vec<u16>, [u32; 3]),
    march_nee: (Vec<u16>, [u32; 3]),
    density: VoxelGrid,
}

/// Mip level `level` of a chain, clamped to the last (1×1×1) one, with its block edge.
fn level_of(chain: &[VoxelGrid], level: u32) -> (&VoxelGrid, u32) {
    let l = (level as usize).min(chain.len() - 1);
    (&chain[l], 1u32 << l)
}

fn to_half(grid: &VoxelGrid) -> (Vec<u16>, [u32; 3]) {
    (
        grid.data
            .iter()
            .map(|v| half::f16::from_f32(*v).to_bits())
            .collect(),
        grid.dims,
    )
}

impl DerivedVolume {
    fn build(density: VoxelGrid, scale: f32, plan: &RestirPlan) -> DerivedVolume {
        let conservative = density.conservative_piecewise_constant().mip_chain();
        let (primary, _) = level_of(&conservative, plan.mip_candidates);
        let (indirect, _) = level_of(&conservative, plan.mip_indirect);
        let mut pc: Vec<f32> = primary.data.iter().map(|v| v * scale).collect();
        let offset = pc.len() as u32;
        pc.extend(indirect.data.iter().map(|v| v * scale));
        let d = primary.dims;
        let e = indirect.dims;
        let mips = density.mip_chain();
        let march_reuse = to_half(level_of(&mips, plan.mip_reuse).0);
        let march_nee = to_half(level_of(&mips, plan.mip_indirect).0);
        DerivedVolume {
            pc,
            pc_primary: [d[0], d[1], d[2], 0],
            pc_indirect: [e[0], e[1], e[2], offset],
            march_reuse,
            march_nee,
            density,
        }
    }
}

// The pass's images, by index: this frame's density (full resolution) and its ray-march
// mips for reuse and for NEE, the previous frame's density and reuse mip (what the
// temporal pass evaluates the previous reservoirs with), emission, velocity.
const IMAGE_DENSITY: usize = 0;
const IMAGE_MARCH_REUSE: usize = 1;
const IMAGE_MARCH_NEE: usize = 2;
const IMAGE_DENSITY_PREV: usize = 3;
const IMAGE_MARCH_REUSE_PREV: usize = 4;
const IMAGE_EMISSION: usize = 5;
const IMAGE_VELOCITY: usize = 6;

/// The four pipelines, their descriptor sets and everything they read.
pub struct RestirPass {
    plan: RestirPlan,
    pipelines: Vec<ComputePipeline>,
    sets: Vec<DescriptorSet>,
    buffers: Buffers,
    /// Indexed by the IMAGE_* constants.
    images: Vec<Image>,
    nearest: vk::Sampler,
    linear: vk::Sampler,
    grid: GridMedium,
    grid_label: String,
    scene_lights_radius: f32,
    env_map_luminance: Option<f32>,
    base_uniforms: gpu_scene::BaselineUniformsGpu,
    /// Derived volumes by density index (0 = base, i + 1 = [[medium.frame]] i).
    volumes: HashMap<usize, DerivedVolume>,
    /// Density indices loaded into `current` / `previous`.
    loaded: Cell<(usize, usize)>,
    /// The slot holding the previous frame's final reservoirs.
    prev_slot: Cell<Option<u32>>,
    /// The constant environment radiance (frame uniforms).
    env_radiance: glam::Vec3,
    /// The previous-frame uniforms last uploaded.
    prev_uploaded: std::cell::RefCell<Option<Vec<u8>>>,
}

struct Buffers {
    lights: Buffer,
    super_voxels: Buffer,
    env_texels: Buffer,
    env_cdf: Buffer,
    base_uniforms: Buffer,
    restir_uniforms: Buffer,
    prev_frame: Buffer,
    pc_grid: Buffer,
    reservoirs: Buffer,
}

const PASS_NAMES: [&str; 4] = ["initial", "temporal", "spatial", "shade"];

fn spirv_of(index: usize) -> &'static [u8] {
    match index {
        0 => shaders::RESTIR_INITIAL,
        1 => shaders::RESTIR_TEMPORAL,
        2 => shaders::RESTIR_SPATIAL,
        _ => shaders::RESTIR_SHADE,
    }
}

/// The specialization constants of the ReSTIR shaders for a plan.
pub fn specialization(plan: &RestirPlan) -> [(u32, SpecValue); 8] {
    [
        (2, SpecValue::Bool(plan.has_env)),
        (5, SpecValue::U32(plan.max_bounces)),
        (6, SpecValue::Bool(plan.pixel_jitter)),
        (7, SpecValue::Bool(plan.has_emission)),
        (8, SpecValue::Bool(plan.has_env_map)),
        (9, SpecValue::Bool(plan.vertex_reuse)),
        (10, SpecValue::Bool(plan.final_ratio_tracking)),
        (11, SpecValue::Bool(plan.has_velocity)),
    ]
}

fn layout() -> Vec<BindingDesc> {
    vec![
        BindingDesc::uniform_buffer(bindings::FRAME_UNIFORMS),
        BindingDesc::uniform_buffer(bindings::PREV_FRAME_UNIFORMS),
        BindingDesc::storage_buffer(bindings::ACCUM),
        BindingDesc::storage_buffer(bindings::ACCUM_SQ),
        BindingDesc::storage_buffer(bindings::STATS),
        BindingDesc::storage_buffer(bindings::LIGHTS),
        BindingDesc::uniform_buffer(bindings::BASELINE_UNIFORMS),
        BindingDesc::uniform_buffer(bindings::RESTIR_UNIFORMS),
        BindingDesc::sampled_image(bindings::GRID_DENSITY),
        BindingDesc::sampled_image(bindings::GRID_DENSITY_PREV),
        BindingDesc::sampled_image(bindings::GRID_EMISSION),
        BindingDesc::sampled_image(bindings::MARCH_REUSE),
        BindingDesc::sampled_image(bindings::MARCH_REUSE_PREV),
        BindingDesc::sampled_image(bindings::MARCH_NEE),
        BindingDesc::sampled_image(bindings::VELOCITY),
        BindingDesc::storage_buffer(bindings::SUPER_VOXELS),
        BindingDesc::storage_buffer(bindings::PC_GRID),
        BindingDesc::storage_buffer(bindings::RESERVOIRS),
        BindingDesc::storage_buffer(bindings::ENV_TEXELS),
        BindingDesc::storage_buffer(bindings::ENV_CDF),
    ]
}

/// Objects created so far, destroyed together if creation fails half-way.
#[derive(Default)]
struct Partial {
    buffers: Vec<Buffer>,
    images: Vec<Image>,
    samplers: Vec<vk::Sampler>,
    pipelines: Vec<ComputePipeline>,
    sets: Vec<DescriptorSet>,
}

impl Partial {
    fn destroy(self, ctx: &Context) {
        for s in self.sets {
            ctx.destroy_descriptor_set(s);
        }
        for p in self.pipelines {
            ctx.destroy_compute_pipeline(p);
        }
        for b in self.buffers {
            ctx.destroy_buffer(b);
        }
        for i in self.images {
            ctx.destroy_image(i);
        }
        for s in self.samplers {
            ctx.destroy_sampler(s);
        }
    }
}

fn image_3d(
    ctx: &Context,
    dims: [u32; 3],
    format: vk::Format,
    bytes: &[u8],
    name: &str,
) -> Result<Image> {
    let image = ctx.create_image(
        &ImageDesc::sampled_3d(dims[0], dims[1], dims[2], format),
        name,
    )?;
    if let Err(e) = ctx.upload_image(&image, bytes) {
        ctx.destroy_image(image);
        return Err(e);
    }
    Ok(image)
}

/// The scene's grid medium and its index among the media.
fn scene_grid(scene: &Scene) -> Result<(usize, &GridMedium)> {
    scene
        .media
        .iter()
        .enumerate()
        .find_map(|(i, m)| match m {
            Medium::Grid(g) => Some((i, g)),
            Medium::Box(_) => None,
        })
        .context("internal: the ReSTIR pass was given no grid medium")
}

impl RestirPass {
    pub fn new(
        ctx: &Context,
        plan: &RestirPlan,
        scene: &Scene,
        grid_gpu: &GpuGrid,
        targets: &Targets,
    ) -> Result<Self> {
        let (index, grid) = scene_grid(scene)?;
        let grid_label = format!("{}: [[medium]] #{}", scene.source.display(), index + 1);
        let r = &scene.render;
        let pixels = u64::from(r.width) * u64::from(r.height);
        let stride_bytes = reservoir_bytes(plan.max_bounces);
        let reservoir_total = 3 * pixels * stride_bytes;
        let max_range = u64::from(ctx.info().max_storage_buffer_range);
        if reservoir_total > max_range {
            bail!(
                "{}: [render] {}x{} pixels with K = {} need {} MiB of reservoirs (3 slots of {} bytes per pixel); device '{}' allows {} MiB per storage buffer",
                scene.source.display(),
                r.width,
                r.height,
                plan.max_bounces,
                reservoir_total >> 20,
                stride_bytes,
                ctx.info().name,
                max_range >> 20
            );
        }

        let mut volumes = HashMap::new();
        let first = DerivedVolume::build(grid_gpu.density.clone(), grid.density_scale, plan);
        let velocity = match &grid.velocity {
            Some(source) if plan.has_velocity => {
                let what = format!("{grid_label} > velocity");
                let v = nimbus_scene::load_grid(source, 3, &what)?;
                Some(v)
            }
            _ => None,
        };

        let mut p = Partial::default();
        let result = (|| -> Result<()> {
            let spec = specialization(plan);
            let layout = layout();
            for (i, name) in PASS_NAMES.iter().enumerate() {
                let spirv = spirv_words(spirv_of(i))?;
                p.pipelines.push(ctx.create_compute_pipeline(
                    &ComputePipelineDesc {
                        spirv: &spirv,
                        entry: "main",
                        bindings: &layout,
                        push_constant_size: std::mem::size_of::<RestirPush>() as u32,
                        specialization: &spec,
                    },
                    &format!("restir {name}"),
                )?);
            }
            // Buffers, in the order of `Buffers`.
            let light_records =
                non_empty(&[grid_gpu.lights.clone(), grid_gpu.lights.clone()].concat());
            p.buffers
                .push(upload_records(ctx, &light_records, "restir lights")?);
            p.buffers
                .push(upload_records(ctx, &grid_gpu.super_voxels, "super-voxels")?);
            let (texels, tables) = grid_gpu
                .env_map
                .clone()
                .unwrap_or_else(|| (vec![[0.0; 4]], vec![0.0]));
            p.buffers
                .push(upload_records(ctx, &texels, "environment texels")?);
            p.buffers
                .push(upload_records(ctx, &tables, "environment tables")?);
            let uniform = vk::BufferUsageFlags::UNIFORM_BUFFER;
            for (size, name) in [
                (
                    std::mem::size_of::<gpu_scene::BaselineUniformsGpu>(),
                    "grid uniforms",
                ),
                (std::mem::size_of::<RestirUniformsGpu>(), "restir uniforms"),
                (
                    std::mem::size_of::<FrameUniforms>(),
                    "previous frame uniforms",
                ),
            ] {
                p.buffers
                    .push(ctx.create_buffer(&BufferDesc::gpu_only(size as u64, uniform), name)?);
            }
            ctx.upload_buffer(&p.buffers[4], 0, bytemuck::bytes_of(&grid_gpu.uniforms))?;
            let restir_uniforms = RestirUniformsGpu {
                pc_primary: first.pc_primary,
                pc_indirect: first.pc_indirect,
                factors: [
                    plan.mip_candidates,
                    plan.mip_indirect,
                    plan.mip_reuse,
                    plan.mip_indirect,
                ]
                .map(|level| 1 << level.min(last_level(first.density.dims))),
                march_dims: [
                    first.march_reuse.1[0],
                    first.march_reuse.1[1],
                    first.march_reuse.1[2],
                    0,
                ],
                nee_dims: [
                    first.march_nee.1[0],
                    first.march_nee.1[1],
                    first.march_nee.1[2],
                    0,
                ],
                settings: [
                    plan.candidates,
                    plan.temporal_limit,
                    plan.spatial_neighbors,
                    (stride_bytes / 4) as u32,
                ],
                spatial: [
                    plan.spatial_radius_px,
                    march_step(grid, first.density.dims, plan.mip_reuse),
                    march_step(grid, first.density.dims, plan.mip_indirect),
                    0.0,
                ],
                velocity_dims: velocity
                    .as_ref()
                    .map_or([1, 1, 1, 0], |v| [v.dims[0], v.dims[1], v.dims[2], 0]),
            };
            ctx.upload_buffer(&p.buffers[5], 0, bytemuck::bytes_of(&restir_uniforms))?;
            p.buffers
                .push(upload_records(ctx, &first.pc, "piecewise-constant levels")?);
            p.buffers.push(ctx.create_buffer(
                &BufferDesc::gpu_only(reservoir_total, vk::BufferUsageFlags::STORAGE_BUFFER),
                "reservoirs",
            )?);
            ctx.fill_buffer(&p.buffers[8], 0)?;

            // Images, in the order of the IMAGE_* constants.
            let density: &[u8] = bytemuck::cast_slice(&first.density.data);
            let reuse: &[u8] = bytemuck::cast_slice(&first.march_reuse.0);
            let nee: &[u8] = bytemuck::cast_slice(&first.march_nee.0);
            let (r32, r16) = (vk::Format::R32_SFLOAT, vk::Format::R16_SFLOAT);
            for (dims, format, bytes, name) in [
                (first.density.dims, r32, density, "density"),
                (first.march_reuse.1, r16, reuse, "march (reuse)"),
                (first.march_nee.1, r16, nee, "march (NEE)"),
                (first.density.dims, r32, density, "previous density"),
                (first.march_reuse.1, r16, reuse, "previous march (reuse)"),
            ] {
                p.images.push(image_3d(ctx, dims, format, bytes, name)?);
            }
            let emission = match &grid_gpu.emission {
                Some(e) => image_3d(
                    ctx,
                    e.dims,
                    vk::Format::R32_SFLOAT,
                    bytemuck::cast_slice(&e.data),
                    "grid emission",
                )?,
                // Without emission the (compiled-out) binding gets a 1-texel image.
                None => image_3d(
                    ctx,
                    [1, 1, 1],
                    vk::Format::R32_SFLOAT,
                    bytemuck::bytes_of(&0.0f32),
                    "no emission",
                )?,
            };
            p.images.push(emission);
            let velocity_image = match &velocity {
                Some(v) => {
                    let texels: Vec<u16> = v
                        .data
                        .chunks_exact(3)
                        .flat_map(|c| [c[0], c[1], c[2], 0.0])
                        .map(|x| half::f16::from_f32(x).to_bits())
                        .collect();
                    image_3d(
                        ctx,
                        v.dims,
                        vk::Format::R16G16B16A16_SFLOAT,
                        bytemuck::cast_slice(&texels),
                        "velocity",
                    )?
                }
                None => image_3d(
                    ctx,
                    [1, 1, 1],
                    vk::Format::R16G16B16A16_SFLOAT,
                    &[0u8; 8],
                    "no velocity",
                )?,
            };
            p.images.push(velocity_image);
            p.samplers
                .push(ctx.create_sampler(&SamplerDesc::nearest(), "restir nearest")?);
            p.samplers
                .push(ctx.create_sampler(&SamplerDesc::linear(), "restir linear")?);

            let (b, im) = (&p.buffers, &p.images);
            let (nearest, linear) = (p.samplers[0], p.samplers[1]);
            for (i, pipeline) in p.pipelines.iter().enumerate() {
                let mut writes = Vec::from(targets.writes());
                writes.extend([
                    DescriptorWrite::UniformBuffer {
                        binding: bindings::PREV_FRAME_UNIFORMS,
                        buffer: &b[6],
                    },
                    DescriptorWrite::StorageBuffer {
                        binding: bindings::LIGHTS,
                        buffer: &b[0],
                    },
                    DescriptorWrite::UniformBuffer {
                        binding: bindings::BASELINE_UNIFORMS,
                        buffer: &b[4],
                    },
                    DescriptorWrite::UniformBuffer {
                        binding: bindings::RESTIR_UNIFORMS,
                        buffer: &b[5],
                    },
                    DescriptorWrite::SampledImage {
                        binding: bindings::GRID_DENSITY,
                        image: &im[IMAGE_DENSITY],
                        sampler: nearest,
                    },
                    DescriptorWrite::SampledImage {
                        binding: bindings::GRID_DENSITY_PREV,
                        image: &im[IMAGE_DENSITY_PREV],
                        sampler: nearest,
                    },
                    DescriptorWrite::SampledImage {
                        binding: bindings::GRID_EMISSION,
                        image: &im[IMAGE_EMISSION],
                        sampler: nearest,
                    },
                    DescriptorWrite::SampledImage {
                        binding: bindings::MARCH_REUSE,
                        image: &im[IMAGE_MARCH_REUSE],
                        sampler: linear,
                    },
                    DescriptorWrite::SampledImage {
                        binding: bindings::MARCH_REUSE_PREV,
                        image: &im[IMAGE_MARCH_REUSE_PREV],
                        sampler: linear,
                    },
                    DescriptorWrite::SampledImage {
                        binding: bindings::MARCH_NEE,
                        image: &im[IMAGE_MARCH_NEE],
                        sampler: linear,
                    },
                    DescriptorWrite::SampledImage {
                        binding: bindings::VELOCITY,
                        image: &im[IMAGE_VELOCITY],
                        sampler: linear,
                    },
                    DescriptorWrite::StorageBuffer {
                        binding: bindings::SUPER_VOXELS,
                        buffer: &b[1],
                    },
                    DescriptorWrite::StorageBuffer {
                        binding: bindings::PC_GRID,
                        buffer: &b[7],
                    },
                    DescriptorWrite::StorageBuffer {
                        binding: bindings::RESERVOIRS,
                        buffer: &b[8],
                    },
                    DescriptorWrite::StorageBuffer {
                        binding: bindings::ENV_TEXELS,
                        buffer: &b[2],
                    },
                    DescriptorWrite::StorageBuffer {
                        binding: bindings::ENV_CDF,
                        buffer: &b[3],
                    },
                ]);
                let set = ctx.create_descriptor_set(
                    pipeline,
                    &writes,
                    &format!("restir {} set", PASS_NAMES[i]),
                )?;
                p.sets.push(set);
            }
            Ok(())
        })();
        if let Err(e) = result {
            p.destroy(ctx);
            return Err(e);
        }
        volumes.insert(0, first);
        let mut buffers = p.buffers.into_iter();
        let mut next = || buffers.next().expect("all buffers were created");
        let buffers = Buffers {
            lights: next(),
            super_voxels: next(),
            env_texels: next(),
            env_cdf: next(),
            base_uniforms: next(),
            restir_uniforms: next(),
            prev_frame: next(),
            pc_grid: next(),
            reservoirs: next(),
        };
        Ok(RestirPass {
            plan: plan.clone(),
            pipelines: p.pipelines,
            sets: p.sets,
            buffers,
            images: p.images,
            nearest: p.samplers[0],
            linear: p.samplers[1],
            grid: grid.clone(),
            grid_label,
            scene_lights_radius: grid_gpu.light_radius,
            env_map_luminance: grid_gpu.env_map_luminance,
            base_uniforms: grid_gpu.uniforms,
            volumes,
            loaded: Cell::new((0, 0)),
            prev_slot: Cell::new(None),
            env_radiance: grid_gpu.env_radiance,
            prev_uploaded: std::cell::RefCell::new(None),
        })
    }
}

/// The ray-marching step at mip `level`: the diagonal of one of its voxels, in metres
/// (sec. 5.1: "our step size for ray marching is the diagonal of a Mip 1 voxel").
fn march_step(grid: &GridMedium, dims: [u32; 3], level: u32) -> f32 {
    let factor = (1u64 << level.min(last_level(dims))) as f32;
    let size = grid.bounds_max - grid.bounds_min;
    let voxel = glam::Vec3::new(
        size.x / dims[0] as f32,
        size.y / dims[1] as f32,
        size.z / dims[2] as f32,
    ) * factor;
    voxel.length()
}

/// ceil(log2(largest dim)): the index of the 1×1×1 level of a mip chain.
fn last_level(dims: [u32; 3]) -> u32 {
    let max = dims.iter().copied().max().unwrap_or(1).max(1);
    32 - (max - 1).leading_zeros()
}

impl RestirPass {
    /// Uploads what changes per frame: the lights of this frame and the previous one,
    /// the previous camera, and the density grids of both frames when they change.
    pub fn prepare(&self, ctx: &Context, scene: &Scene, camera_frame: u32) -> Result<()> {
        let prev_camera_frame = camera_frame.saturating_sub(1);
        // Lights: the current set, then the previous frame's (uploaded at creation when
        // nothing is animated).
        if scene.lights_animated() {
            let cur = LightSet::build(
                &scene.lights_at(camera_frame),
                self.scene_lights_radius,
                self.env_map_luminance,
            );
            let prev = LightSet::build(
                &scene.lights_at(prev_camera_frame),
                self.scene_lights_radius,
                self.env_map_luminance,
            );
            let records: Vec<LightGpu> = non_empty(&[cur.lights, prev.lights].concat());
            ctx.upload_buffer(&self.buffers.lights, 0, bytemuck::cast_slice(&records))?;
            let mut base = self.base_uniforms;
            base.env_select[0] = cur.env_select;
            ctx.upload_buffer(&self.buffers.base_uniforms, 0, bytemuck::bytes_of(&base))?;
        }
        // The previous frame's camera (the first frame's own camera on frame 0), uploaded
        // when it changes.
        let camera = scene.camera.frame_at(prev_camera_frame);
        let counts = [0, 0, self.light_count(scene), 0];
        let prev = gpu_scene::frame_uniforms(scene, &camera, self.env_radiance, counts);
        let bytes = bytemuck::bytes_of(&prev);
        if self.prev_uploaded.borrow().as_deref() != Some(bytes) {
            ctx.upload_buffer(&self.buffers.prev_frame, 0, bytes)?;
            *self.prev_uploaded.borrow_mut() = Some(bytes.to_vec());
        }
        // Density of this frame and of the previous one.
        let want = (
            self.grid.density_index_at(camera_frame),
            self.grid.density_index_at(prev_camera_frame),
        );
        if want != self.loaded.get() {
            for index in [want.0, want.1] {
                if !self.volumes.contains_key(&index) {
                    bail!("internal: density frame {index} was not loaded before rendering");
                }
            }
            let cur = &self.volumes[&want.0];
            let prev = &self.volumes[&want.1];
            ctx.upload_image(
                &self.images[IMAGE_DENSITY],
                bytemuck::cast_slice(&cur.density.data),
            )?;
            ctx.upload_image(
                &self.images[IMAGE_MARCH_REUSE],
                bytemuck::cast_slice(&cur.march_reuse.0),
            )?;
            ctx.upload_image(
                &self.images[IMAGE_MARCH_NEE],
                bytemuck::cast_slice(&cur.march_nee.0),
            )?;
            ctx.upload_buffer(&self.buffers.pc_grid, 0, bytemuck::cast_slice(&cur.pc))?;
            ctx.upload_image(
                &self.images[IMAGE_DENSITY_PREV],
                bytemuck::cast_slice(&prev.density.data),
            )?;
            ctx.upload_image(
                &self.images[IMAGE_MARCH_REUSE_PREV],
                bytemuck::cast_slice(&prev.march_reuse.0),
            )?;
            self.loaded.set(want);
        }
        Ok(())
    }

    /// Number of analytic lights per set.
    pub fn light_count(&self, scene: &Scene) -> u32 {
        scene
            .lights
            .iter()
            .filter(|l| !matches!(l, nimbus_scene::Light::Environment { .. }))
            .count() as u32
    }

    /// Loads and derives every density grid of the animation (checked to have the base
    /// grid's dims), so frames only upload.
    pub fn load_frames(&mut self) -> Result<()> {
        let dims = self.volumes[&0].density.dims;
        for (i, frame) in self.grid.frames.clone().iter().enumerate() {
            let what = format!(
                "{} > [[medium.frame]] #{} (frame {})",
                self.grid_label,
                i + 1,
                frame.frame
            );
            let grid = nimbus_scene::load_grid(&frame.density, 1, &what)?;
            if grid.dims != dims {
                bail!(
                    "{what}: field `density`: dims {:?} differ from the medium's density {:?}; every frame must have the same resolution",
                    grid.dims,
                    dims
                );
            }
            let derived = DerivedVolume::build(grid, self.grid.density_scale, &self.plan);
            self.volumes.insert(i + 1, derived);
        }
        Ok(())
    }

    fn dispatch(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        index: usize,
        uniforms: &FrameUniforms,
        push: RestirPush,
    ) -> Result<()> {
        let groups = image_groups(uniforms);
        self.pipelines[index].dispatch(
            ctx,
            cmd,
            &self.sets[index],
            bytemuck::bytes_of(&push),
            groups,
        )
    }

    /// The passes this frame runs, with their reservoir slots.
    pub fn schedule(&self, frame: u32) -> Vec<(usize, RestirPush)> {
        let prev = self.prev_slot.get().filter(|_| frame > 0);
        let free: Vec<u32> = (0..3).filter(|s| Some(*s) != prev).collect();
        let mut passes = Vec::new();
        let cur = free[0];
        passes.push((
            0,
            RestirPush {
                frame,
                src: cur,
                dst: cur,
                aux: 0,
            },
        ));
        if let (true, Some(p)) = (self.plan.temporal, prev) {
            passes.push((
                1,
                RestirPush {
                    frame,
                    src: cur,
                    dst: cur,
                    aux: p,
                },
            ));
        }
        let mut at = cur;
        if self.plan.spatial_neighbors > 0 {
            for round in 0..self.plan.spatial_rounds {
                let other = if at == free[0] { free[1] } else { free[0] };
                passes.push((
                    2,
                    RestirPush {
                        frame,
                        src: at,
                        dst: other,
                        aux: round,
                    },
                ));
                at = other;
            }
        }
        passes.push((
            3,
            RestirPush {
                frame,
                src: at,
                dst: at,
                aux: 0,
            },
        ));
        passes
    }

    /// Records the frame's passes, each in its own profiler scope, with a barrier between
    /// consecutive dispatches; the last output becomes the next frame's previous slot.
    pub fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        uniforms: &FrameUniforms,
        frame: u32,
        mut profiler: Option<&mut Profiler>,
    ) -> Result<()> {
        let passes = self.schedule(frame);
        let mut last = 0;
        let mut open: Option<usize> = None;
        for (n, (index, push)) in passes.iter().enumerate() {
            if n > 0 {
                compute_barrier(ctx, cmd);
            }
            // Spatial rounds share one scope.
            if open != Some(*index) {
                if let (Some(p), Some(_)) = (profiler.as_deref_mut(), open) {
                    p.end_scope(ctx, cmd)?;
                }
                if let Some(p) = profiler.as_deref_mut() {
                    p.begin_scope(ctx, cmd, PASS_NAMES[*index])?;
                }
                open = Some(*index);
            }
            self.dispatch(ctx, cmd, *index, uniforms, *push)?;
            last = push.src;
        }
        if let (Some(p), Some(_)) = (profiler, open) {
            p.end_scope(ctx, cmd)?;
        }
        self.prev_slot.set(Some(last));
        Ok(())
    }

    pub fn destroy(self, ctx: &Context) {
        let b = self.buffers;
        Partial {
            buffers: vec![
                b.lights,
                b.super_voxels,
                b.env_texels,
                b.env_cdf,
                b.base_uniforms,
                b.restir_uniforms,
                b.prev_frame,
                b.pc_grid,
                b.reservoirs,
            ],
            images: self.images,
            samplers: vec![self.nearest, self.linear],
            pipelines: self.pipelines,
            sets: self.sets,
        }
        .destroy(ctx);
    }
}
