//! The data the shaders read: what passes upload and how the shaders see it (the
//! Vulkan runtime itself is the `nimbus_gpu` crate; this module was called `gpu` before it
//! was named apart from it).
//!
//! - [`contract`]: how the records, binding numbers and specialization-constant IDs are
//!   declared once, for the crate and (through `build.rs`) for the shaders;
//! - [`records`]: every `#[repr(C)]` record shared with the shaders (records, uniforms,
//!   push constants);
//! - [`bindings`]: descriptor binding numbers;
//! - [`features`]: specialization-constant IDs and the limits the shaders hard-code;
//! - [`scene`]: turning a [`nimbus_scene::Scene`] into those records (box media, shapes,
//!   lights with their selection CDF, grids with their super-voxels, environment maps);
//! - [`meshes`]: the BVH node and triangle buffers of the scene's meshes;
//! - [`emitters`]: the emitting shapes' primitives with their power CDF (area lights).
//! - [`counters`]: the deterministic work counters passes report (`nimbus profile --counters`).

// First: its table macros are used by the modules below.
#[macro_use]
pub mod contract;

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
