//! The GPU side of the scene: what passes upload and how the shaders see it.
//!
//! - [`records`]: every `#[repr(C)]` mirror of a GLSL struct (records, uniforms, push
//!   constants), checked against the GLSL by `tests/suite/layout.rs`;
//! - [`bindings`]: descriptor binding numbers, mirrored from `bindings.glsl`;
//! - [`scene`]: turning a [`nimbus_scene::Scene`] into those records (box media, shapes,
//!   lights with their selection CDF, grids with their super-voxels, environment maps);
//! - [`meshes`]: the BVH node and triangle buffers of the scene's meshes;
//! - [`emitters`]: the emitting shapes' primitives with their power CDF (area lights).
//! - [`counters`]: the deterministic work counters passes report (`nimbus profile --counters`).

pub mod bindings;
pub mod counters;
pub mod emitters;
pub mod features;
pub mod meshes;
pub mod records;
pub mod scene;
pub mod sparse;

pub use emitters::EmitterTable;
pub use meshes::MeshBuffers;
pub use records::*;
pub use scene::{
    box_records, frame_uniforms, gobo_half_planes, non_empty, shape_records, GpuEnvMap, GpuGrid,
    GpuScene, LightSet, RecordCounts,
};
