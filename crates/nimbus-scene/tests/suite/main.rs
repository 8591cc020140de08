//! The nimbus-scene crate's integration tests, one binary of modules.

// Test code: a panic is how a test reports a failure.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

mod animation;
mod assets;
mod bad_scenes;
mod conventions;
mod envmap;
mod fuzz;
mod good_scenes;
mod hostile;
mod mesh_bvh;
mod mesh_load;
mod mesh_scenes;
mod vdb;
mod vdb_scenes;
mod volume;
