//! Nimbus's integration tests: one binary of modules, sharing one harness (`common`:
//! golden images, the validated lavapipe context, the command-line runner, a PCG32 and
//! the compute-kernel scaffold of the GPU unit tests).
//!
//! Run one module with `cargo test --test suite restir::`, one test by its full name.

// Test code: a panic is how a test reports a failure.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

mod commands;
mod contracts;
mod golden;
mod hard;
mod kernels;
mod oracle;
