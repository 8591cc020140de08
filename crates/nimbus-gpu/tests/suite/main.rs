//! The nimbus-gpu crate's integration tests, one binary of modules.

// Test code: a panic is how a test reports a failure.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

mod buffers;
mod compute;
mod context;
mod images;
mod profiler;
mod profiler_math;
mod specialize;
