//! Every `#[repr(C)]` mirror of a GLSL struct the passes share with their shaders.
//!
//! All records are made of 16-byte vectors (or groups of four 32-bit scalars) so that
//! std140 / std430 and `repr(C)` agree; `tests/layout.rs` parses the GLSL declarations
//! (`shaders/include/scene.glsl`, `grid_types.glsl`, `restir.glsl`) and checks every size.

use bytemuck::{Pod, Zeroable};

/// `BoxMedium` in scene.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct BoxMediumGpu {
    pub world_to_local: [[f32; 4]; 3],
    pub center_sigma_t: [f32; 4],
    pub half_size_g: [f32; 4],
    pub sigma_s: [f32; 4],
}

pub const SHAPE_QUAD: u32 = 0;
pub const SHAPE_BOX: u32 = 1;
pub const SHAPE_SPHERE: u32 = 2;

/// `Shape` in scene.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct ShapeGpu {
    pub p: [[f32; 4]; 5],
    pub albedo_type: [f32; 4],
}

pub const LIGHT_DIRECTIONAL: u32 = 0;

/// `Light` in scene.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct LightGpu {
    pub direction_type: [f32; 4],
    pub irradiance: [f32; 4],
    pub gobo_origin: [f32; 4],
    pub gobo_u: [f32; 4],
    pub gobo_v: [f32; 4],
}

/// `FrameUniforms` in scene.glsl (std140).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FrameUniforms {
    pub cam_position: [f32; 4],
    pub cam_forward: [f32; 4],
    pub cam_right: [f32; 4],
    pub cam_up: [f32; 4],
    pub env_radiance: [f32; 4],
    pub image: [u32; 4],
    pub counts: [u32; 4],
    pub reserved: [f32; 4],
}

/// `PassPush` in scene.glsl: the push constants of every dispatch.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct PassPush {
    pub frame: u32,
    pub sample_base: u32,
    pub pad0: u32,
    pub pad1: u32,
}

/// `GridParams` in grid_types.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GridParamsGpu {
    pub bounds_min: [f32; 4],
    pub bounds_max: [f32; 4],
    pub dims: [u32; 4],
    pub super_dims: [u32; 4],
}

/// `BaselineUniforms` in grid_types.glsl (std140).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct BaselineUniformsGpu {
    pub grid: GridParamsGpu,
    /// rgb single-scattering albedo, w HG g.
    pub albedo_g: [f32; 4],
    /// Probability that next-event estimation picks the environment, in x.
    pub env_select: [f32; 4],
    /// rgb emission_scale (Le = scale · trilinear emission grid), w unused.
    pub emission_scale: [f32; 4],
    /// Emission grid dims xyz (its own resolution), w unused.
    pub emission_dims: [u32; 4],
    /// Environment map width and height in xy (1 x 1 without a map).
    pub env_size: [u32; 4],
}

pub const LIGHT_POINT: u32 = 1;
pub const LIGHT_SPHERE: u32 = 2;

/// `RestirUniforms` in restir/resources.glsl (std140).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
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

/// `RestirPush` in restir/resources.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct RestirPush {
    pub frame: u32,
    pub src: u32,
    pub dst: u32,
    pub aux: u32,
}

/// Bytes per pixel of one reservoir slot for K = `max_bounces` (`Reservoir` in
/// reservoir.glsl): a 32-byte header (w_sum, M, p_hat, packed info, light point,
/// octahedral light direction) and per vertex z (f32) plus an octahedral direction
/// (2 × 16 bits).
pub fn reservoir_bytes(max_bounces: u32) -> u64 {
    use super::features::{RESERVOIR_HEADER_UINTS, RESERVOIR_VERTEX_UINTS};
    4 * u64::from(RESERVOIR_HEADER_UINTS + RESERVOIR_VERTEX_UINTS * max_bounces)
}
