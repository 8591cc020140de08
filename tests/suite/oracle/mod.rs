//! Renders against an independent answer: the CPU oracles of `nimbus-reference`
//! (quadrature, Monte Carlo), another unbiased estimator (ReSTIR against the baseline), or
//! an invariant every integrator must keep.

mod alpha;
mod aovs;
mod baseline;
mod box_env;
mod box_estimators;
mod box_me;
mod emitters;
mod env_rotation;
mod grid_gobos;
mod grid_sparse;
mod invariants;
mod light_keys;
mod meshes;
mod overlap;
mod pyro;
mod render_convex;
mod restir;
mod restir_aovs;
mod restir_history;
mod vdb_render;
