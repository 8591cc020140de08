//! Every `#[repr(C)]` record the passes share with their shaders: GPU records,
//! parameter blocks and push constants, with the type tags of the tagged ones.
//!
//! They are declared once, in `src/shader_data/contract/records.rs`, which `build.rs` also turns
//! into the GLSL structs the shaders include (see [`crate::shader_data::contract`]): each struct
//! here has its GLSL struct's members, in order and by the same names (`r#type` is
//! `type`), and a compile-time check holds its offsets and size to GLSL's std430 rules.

use bytemuck::{Pod, Zeroable};

include!("contract/records.rs");

/// Bytes per pixel of one reservoir slot for K = `max_bounces` (`Reservoir` in
/// reservoir.glsl): a 32-byte header (w_sum, M, p_hat, packed info, light point,
/// octahedral light direction) and per vertex z (f32) plus an octahedral direction
/// (2 × 16 bits).
pub fn reservoir_bytes(max_bounces: u32) -> u64 {
    use super::features::{RESERVOIR_HEADER_UINTS, RESERVOIR_VERTEX_UINTS};
    4 * u64::from(RESERVOIR_HEADER_UINTS + RESERVOIR_VERTEX_UINTS * max_bounces)
}
