//! Nimbus's integration tests: one binary of modules, sharing one harness (`common`:
//! golden images, the validated lavapipe context, the command-line runner, a PCG32 and
//! the compute-kernel scaffold of the GPU unit tests).
//!
//! Run one module with `cargo test --test suite restir::`, one test by its full name.

// Test code: a panic is how a test reports a failure.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

mod alpha;
mod baseline;
mod bench_scenes;
mod box_analytic;
mod box_env;
mod box_estimators;
mod box_me;
mod budget;
mod cli;
mod cli_hostile;
mod contract;
mod counters;
mod docs;
mod emitters;
mod env_rotation;
mod envmap_gpu;
mod exr_header;
mod generators;
mod grid_gobos;
mod grid_sparse;
mod grid_volume;
mod hard_cases;
mod hard_extremes;
mod image_harness;
mod invariants;
mod layout;
mod light_keys;
mod mesh_bvh_gpu;
mod meshes;
mod overlap;
mod pipeline;
mod pyro;
mod render_box;
mod render_convex;
mod restir;
mod restir_golden;
mod restir_history;
mod sampling_gpu;
mod slurm;
mod vdb_render;
