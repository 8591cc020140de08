//! f64 building blocks shared by the oracles.
//!
//! Random numbers, direction sampling and the phase function, oriented boxes, gobos,
//! directional lights, the scene's shapes (with the Monte Carlo oracles' ray test),
//! camera rays, running moments and the threading over rows and paths. Nothing here
//! comes from the GPU code: these are the oracles' own small routines, written once
//! for all of them. What each oracle computes with them (quadrature along a ray, analog
//! tracking, delta and ratio tracking) stays in its own module.

pub(crate) mod camera;
pub(crate) mod estimate;
pub(crate) mod geometry;
pub(crate) mod lights;
pub(crate) mod parallel;
pub(crate) mod rng;
pub(crate) mod sampling;
pub(crate) mod surface;
#[cfg(test)]
pub(crate) mod testing;
