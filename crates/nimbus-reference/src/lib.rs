//! CPU oracles for Nimbus: slow, plain f64 computations of what the GPU passes
//! estimate, for the root package's tests to check the renderer against.
//!
//! - [`quadrature`]: single scattering in homogeneous box media by adaptive
//!   Gauss–Kronrod quadrature along each camera ray, to a requested relative error.
//!   Deterministic; the reference for the box pass at K = 1 and for the paper's
//!   unoccluded T_box integral ([`quadrature::unoccluded_single_scatter`]).
//! - [`mc`]: multiple scattering in homogeneous box media by an analog path tracer
//!   with next-event estimation of the suns, and the environment (constant or a map)
//!   wherever an analog path escapes; a mean and a standard error per pixel or ray.
//! - [`grid`]: multiple scattering in voxel-grid (and box) media by delta tracking and
//!   ratio tracking with one global majorant, with point, sphere and environment
//!   lights and emission; a mean and a standard error per pixel or ray.
//!
//! # Independence
//!
//! An oracle is only worth something if it does not share the mistakes of what it
//! checks. This crate depends on `nimbus-scene` (the scene description) and nothing
//! of the renderer, and the root package takes it as a dev-dependency only, so Cargo
//! keeps the two apart: the oracles cannot call into the GPU code and the renderer
//! cannot call into the oracles. Their algorithms are deliberately not the GPU's (no
//! closed-form transmittance integrals, ratio estimators over whole volumes,
//! super-voxel majorants or reservoirs).
//!
//! Within the crate, `common` holds the small f64 routines written once for all
//! oracles (random numbers, sampling, the HG phase function, oriented boxes, gobos,
//! camera rays, moments, threading). The quadrature keeps its own ray–shape
//! intersections, so that comparing it with the Monte Carlo oracles also checks
//! their geometry.

mod common;
pub mod grid;
pub mod mc;
pub mod quadrature;
