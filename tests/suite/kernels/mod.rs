//! GPU unit tests: shader functions run through small test kernels (`shaders/tests/`)
//! against CPU references: sampling families, environment maps, the BVH, grid lookups and
//! the box-medium analytics.

mod box_analytic;
mod envmap_gpu;
mod grid_volume;
mod mesh_bvh_gpu;
mod pipelines;
mod sampling_gpu;
mod settle;
