//! The heterogeneous grid-medium core (`shaders/include/grid.glsl`, `grid_dual.glsl` and
//! `grid_blocks.glsl`) run on the GPU through `shaders/tests/grid_volume.comp`, with
//! validation layers on, against independent f64 computations on the CPU:
//!
//! - closed-form optical depth (regular tracking, exact per-cell integration) against
//!   5-point Gauss–Legendre quadrature of [`VoxelGrid::sample_trilinear`] between every
//!   crossing of a voxel-centre or voxel-face plane (the density is a polynomial of degree
//!   <= 3 there, so the quadrature is exact up to f64 rounding): relative error < 1e-4,
//!   or absolute < 1e-6 where the depth is tiny;
//! - `grid_sigma_t` at voxel centres equals the voxel value × scale, and 0 outside;
//! - ratio tracking and residual ratio tracking are unbiased: the mean of 8192 estimates per
//!   ray is within **4 standard errors** of the reference transmittance on every one of
//!   50 rays (4σ rather than "3σ with one failure allowed": a two-sided 4σ miss has
//!   probability 6e-5, so 100 checks all pass with probability 0.994 under the null, and
//!   the seeds are fixed, so the outcome is deterministic);
//! - decomposition tracking: the fraction of 20 000 collisions beyond s equals T(t0 → s)
//!   for several s, and the passing fraction equals T(t0 → t1), within 4 standard errors;
//! - no NaN or infinity anywhere in the shader (its non-finite counter stays 0), also on
//!   degenerate rays (zero-length and reversed intervals, misses, rays in face planes,
//!   along voxel edges, parallel to voxel planes).
//!
//! The closed-form tests are in [`closed_form`], the estimators' in [`estimators`]; this
//! module holds the GPU side and the random media and rays they share.

use crate::common::kernel::{records, Arg, Kernel};
use crate::common::rng::Pcg32;
use bytemuck::{Pod, Zeroable};
use glam::{DMat4, DVec3, Vec3};
use nimbus::shader_data::sparse::{grid_space, SparseLayout, TexelFormat};
use nimbus::shader_data::GridParamsGpu;
use nimbus_gpu::{vk, BindingDesc, SamplerDesc};
use nimbus_scene::{procedural_cloud, BrickGrid, VoxelGrid};

mod closed_form;
mod estimators;

/// Relative tolerance on the closed-form optical depth.
const DEPTH_REL_TOL: f64 = 1e-4;
/// Absolute tolerance where the optical depth is tiny.
const DEPTH_ABS_TOL: f64 = 1e-6;
/// Standard errors allowed for the Monte Carlo checks.
const Z: f64 = 4.0;
/// `FAR` of constants.glsl.
const FAR: f32 = 1.0e30;

const MODE_CLOSED_FORM: u32 = 0;
const MODE_ESTIMATORS: u32 = 1;
const MODE_COLLISION: u32 = 2;
const LOCAL_SIZE: u32 = 64;

// ---------------------------------------------------------------------------------------
// GPU side: records mirrored from the test shader (its `GridParams` is the renderer's,
// mirrored by nimbus::shader_data::GridParamsGpu).

/// The push constants of grid_volume.comp (its `GridParams` is a storage buffer).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuPush {
    query_count: u32,
    pad: [u32; 3],
}

/// `Query` of grid_volume.comp.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuQuery {
    o_t0: [f32; 4],
    d_t1: [f32; 4],
    mode: u32,
    samples: u32,
    seed: u32,
    pad: u32,
}

/// `Result` of grid_volume.comp.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct GpuResult {
    r0: [f32; 4],
    r1: [f32; 4],
    non_finite: u32,
    pad: [u32; 3],
}

const _: () = assert!(std::mem::size_of::<GpuPush>() == 16);
const _: () = assert!(std::mem::size_of::<GpuQuery>() == 48);
const _: () = assert!(std::mem::size_of::<GpuResult>() == 48);

/// A grid medium as the test sees it: the grid, its f32 bounds and density scale.
struct Medium {
    name: &'static str,
    grid: VoxelGrid,
    bounds_min: [f32; 3],
    bounds_max: [f32; 3],
    scale: f32,
}

impl Medium {
    /// The grid as the renderer stores it: 8³ bricks (those whose super-voxel holds
    /// density) in a 3D atlas of 9³-texel slots behind an indirection grid, with one
    /// super-voxel record per slot; the all-zero corner block of [`random_grid`] gets no
    /// slot, so the walks must skip it.
    fn sparse(&self) -> GpuMedium {
        let bricks = BrickGrid::from_dense(&self.grid).expect("bricks of a test grid");
        let (slots, super_voxels): (Vec<_>, Vec<_>) = bricks
            .super_voxels()
            .into_iter()
            .map(|(b, v)| (b, [v[0], v[1], v[2], 0.0].map(|x| x * self.scale)))
            .unzip();
        let layout = SparseLayout::new(&bricks, slots, 1).expect("atlas layout");
        let lo = Vec3::from_array(self.bounds_min);
        let hi = Vec3::from_array(self.bounds_max);
        let dims = DVec3::from_array(self.grid.dims.map(f64::from));
        let p_to_world =
            DMat4::from_translation(lo.as_dvec3()) * DMat4::from_scale((hi - lo).as_dvec3() / dims);
        let space = grid_space(&bricks, &layout, 0, p_to_world, Some((lo, hi)));
        let max = self.grid.data.iter().fold(0f32, |m, &v| m.max(v));
        let mut super_voxels = super_voxels;
        if super_voxels.is_empty() {
            super_voxels.push([0.0; 4]);
        }
        GpuMedium {
            params: GridParamsGpu {
                bounds_min: self.bounds_min,
                density_scale: self.scale,
                bounds_max: self.bounds_max,
                sigma_t_max: max * self.scale,
                space,
            },
            atlas_dims: layout.atlas_dims(),
            atlas: layout.atlas_texels(&bricks, 1.0, TexelFormat::R32),
            bricks: layout.indirection.entries.clone(),
            super_voxels,
        }
    }

    fn size(&self) -> [f64; 3] {
        [0, 1, 2].map(|a| f64::from(self.bounds_max[a]) - f64::from(self.bounds_min[a]))
    }

    /// World position of voxel (i, j, k)'s centre, in f64.
    fn centre(&self, v: [u32; 3]) -> [f64; 3] {
        let size = self.size();
        [0, 1, 2].map(|a| {
            f64::from(self.bounds_min[a])
                + (f64::from(v[a]) + 0.5) / f64::from(self.grid.dims[a]) * size[a]
        })
    }

    /// sigma_t at world x (f64): scale × sample_trilinear in index space, 0 outside.
    fn sigma_t(&self, x: [f64; 3]) -> f64 {
        let size = self.size();
        let mut p = [0f64; 3];
        for a in 0..3 {
            if x[a] < f64::from(self.bounds_min[a]) || x[a] > f64::from(self.bounds_max[a]) {
                return 0.0;
            }
            p[a] = (x[a] - f64::from(self.bounds_min[a])) / size[a] * f64::from(self.grid.dims[a]);
        }
        f64::from(self.scale) * self.grid.sample_trilinear(p)
    }

    /// (t_in, t_out) of the closed bounds along o + t d in f64; t_in > t_out on a miss.
    fn span(&self, o: [f64; 3], d: [f64; 3]) -> (f64, f64) {
        let (mut t_in, mut t_out) = (f64::NEG_INFINITY, f64::INFINITY);
        for a in 0..3 {
            let (lo, hi) = (f64::from(self.bounds_min[a]), f64::from(self.bounds_max[a]));
            if d[a] == 0.0 {
                if o[a] < lo || o[a] > hi {
                    return (1.0, -1.0);
                }
                continue;
            }
            let (ta, tb) = ((lo - o[a]) / d[a], (hi - o[a]) / d[a]);
            t_in = t_in.max(ta.min(tb));
            t_out = t_out.min(ta.max(tb));
        }
        (t_in, t_out)
    }

    /// Reference ∫ sigma_t(o + t d) dt over [t0, t1] (f64): the interval is clipped to the
    /// bounds and cut at every crossing of a plane p_a = m/2 (voxel faces and centres) in
    /// index space; each piece gets 5-point Gauss–Legendre (exact for the cubic there).
    fn optical_depth(&self, ray: &Ray) -> f64 {
        let o = ray.o.map(f64::from);
        let d = ray.d.map(f64::from);
        let (t_in, t_out) = self.span(o, d);
        let (ta, tb) = (f64::from(ray.t0).max(t_in), f64::from(ray.t1).min(t_out));
        if ta >= tb {
            return 0.0;
        }
        let size = self.size();
        let mut cuts = vec![ta, tb];
        for a in 0..3 {
            if d[a] == 0.0 {
                continue;
            }
            let n = self.grid.dims[a];
            for m in 0..=2 * n {
                let x = f64::from(self.bounds_min[a]) + f64::from(m) * 0.5 / f64::from(n) * size[a];
                let t = (x - o[a]) / d[a];
                if t > ta && t < tb {
                    cuts.push(t);
                }
            }
        }
        cuts.sort_by(f64::total_cmp);
        const NODES: [f64; 5] = [
            0.0,
            -0.538_469_310_105_683_1,
            0.538_469_310_105_683_1,
            -0.906_179_845_938_664,
            0.906_179_845_938_664,
        ];
        const WEIGHTS: [f64; 5] = [
            0.568_888_888_888_888_9,
            0.478_628_670_499_366_5,
            0.478_628_670_499_366_5,
            0.236_926_885_056_189_1,
            0.236_926_885_056_189_1,
        ];
        let mut tau = 0.0;
        for w in cuts.windows(2) {
            let (mid, half) = (0.5 * (w[0] + w[1]), 0.5 * (w[1] - w[0]));
            for (x, wt) in NODES.iter().zip(WEIGHTS) {
                let t = mid + half * x;
                tau += half * wt * self.sigma_t([0, 1, 2].map(|a| o[a] + t * d[a]));
            }
        }
        tau
    }
}

/// A ray segment exactly as the GPU sees it.
#[derive(Clone, Copy, Debug)]
struct Ray {
    o: [f32; 3],
    d: [f32; 3],
    t0: f32,
    t1: f32,
    kind: &'static str,
}

impl Ray {
    fn query(&self, mode: u32, samples: u32, seed: u32) -> GpuQuery {
        GpuQuery {
            o_t0: [self.o[0], self.o[1], self.o[2], self.t0],
            d_t1: [self.d[0], self.d[1], self.d[2], self.t1],
            mode,
            samples,
            seed,
            pad: 0,
        }
    }
}

/// The test kernel `shaders/tests/grid_volume.comp`.
struct Gpu {
    kernel: Kernel,
}

/// What a run binds for a medium: its parameters, density atlas, indirection and
/// super-voxel records.
struct GpuMedium {
    params: GridParamsGpu,
    atlas_dims: [u32; 3],
    atlas: Vec<u8>,
    bricks: Vec<u32>,
    super_voxels: Vec<[f32; 4]>,
}

impl Gpu {
    fn new() -> Self {
        let layout = [
            BindingDesc::sampled_image(0),
            BindingDesc::storage_buffer(1),
            BindingDesc::storage_buffer(2),
            BindingDesc::storage_buffer(3),
            BindingDesc::storage_buffer(4),
            BindingDesc::storage_buffer(5),
        ];
        Self {
            kernel: Kernel::new(
                nimbus::shaders::TESTS_GRID_VOLUME,
                &layout,
                std::mem::size_of::<GpuPush>() as u32,
                // Both branches compiled in: exact spans for hot super-voxels, and the
                // two-level tag read (one-level sections carry no tag, so they read alike).
                &[
                    (
                        nimbus::shader_data::features::SC_ID_EXACT_SPANS,
                        nimbus_gpu::SpecValue::Bool(true),
                    ),
                    (
                        nimbus::shader_data::features::SC_ID_TWO_LEVEL_BRICKS,
                        nimbus_gpu::SpecValue::Bool(true),
                    ),
                ],
                "grid volume test",
            ),
        }
    }

    fn upload(&self, medium: &Medium) -> GpuMedium {
        medium.sparse()
    }

    /// Runs every query against `medium`; one result per query.
    fn run(&self, medium: &GpuMedium, queries: &[GpuQuery]) -> Vec<GpuResult> {
        let count = u32::try_from(queries.len()).expect("query count fits u32");
        let push = GpuPush {
            query_count: count,
            pad: [0; 3],
        };
        let out = self.kernel.run(
            &[
                Arg::Image3d {
                    binding: 0,
                    dims: medium.atlas_dims,
                    format: vk::Format::R32_SFLOAT,
                    data: &medium.atlas,
                    sampler: SamplerDesc::nearest(),
                },
                Arg::Storage(1, bytemuck::cast_slice(&medium.super_voxels)),
                Arg::Storage(2, bytemuck::cast_slice(queries)),
                Arg::Zeroed(3, queries.len() * std::mem::size_of::<GpuResult>()),
                Arg::Storage(4, bytemuck::cast_slice(&medium.bricks)),
                Arg::Storage(5, bytemuck::bytes_of(&medium.params)),
            ],
            bytemuck::bytes_of(&push),
            [count.div_ceil(LOCAL_SIZE), 1, 1],
        );
        let results: Vec<GpuResult> = records(&out[3], queries.len());
        let non_finite: u32 = results.iter().map(|r| r.non_finite).sum();
        assert_eq!(non_finite, 0, "non-finite values in the grid shader");
        results
    }

    /// Fails on any validation error so far.
    fn finish(self) {
        self.kernel.finish();
    }
}

// ---------------------------------------------------------------------------------------
// Random media and rays.

/// A random grid: uniform values with ~30 % zeros, and an all-zero corner block of
/// 8×8×8 voxels (an empty super-voxel).
fn random_grid(dims: [u32; 3], rng: &mut Pcg32) -> VoxelGrid {
    random_grid_above(dims, 0.0, rng)
}

/// With `floor` = 0 as [`random_grid`]; with `floor` > 0 a dense grid, uniform in
/// [floor, 1), no zeros.
fn random_grid_above(dims: [u32; 3], floor: f64, rng: &mut Pcg32) -> VoxelGrid {
    let mut data = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let empty_block = i < 8 && j < 8 && k < 8 && dims.iter().all(|&n| n > 9);
                let v = if floor > 0.0 {
                    (floor + (1.0 - floor) * rng.uniform32()) as f32
                } else if empty_block || rng.uniform32() < 0.3 {
                    0.0
                } else {
                    rng.uniform32() as f32
                };
                data.push(v);
            }
        }
    }
    VoxelGrid {
        dims,
        channels: 1,
        data,
    }
}

fn media() -> Vec<Medium> {
    let mut rng = Pcg32::new(0x6a1d_0001);
    let cloud = procedural_cloud([32, 32, 32], 7);
    let cloud_max = cloud.data.iter().fold(0f32, |m, &v| m.max(v));
    vec![
        Medium {
            name: "random 13x17x19",
            grid: random_grid([13, 17, 19], &mut rng),
            bounds_min: [-1.2, 0.3, 2.0],
            bounds_max: [0.8, 1.5, 4.5],
            scale: 2.5,
        },
        Medium {
            name: "random 1x5x20 (single-voxel axis)",
            grid: random_grid([1, 5, 20], &mut rng),
            bounds_min: [0.0, 0.0, 0.0],
            bounds_max: [0.5, 2.0, 3.0],
            scale: 0.7,
        },
        Medium {
            name: "procedural cloud 32^3",
            grid: cloud,
            bounds_min: [-1.0, -1.0, -1.0],
            bounds_max: [1.0, 1.0, 1.0],
            // sigma_max · side = 6: optical depths of a few units through dense parts.
            scale: 3.0 / cloud_max.max(1e-6),
        },
        Medium {
            name: "dense random 24x20x16 (min > 0)",
            grid: random_grid_above([24, 20, 16], 0.6, &mut rng),
            bounds_min: [2.0, -3.0, 0.5],
            bounds_max: [3.2, -2.0, 1.3],
            scale: 1.5,
        },
    ]
}

fn to_f32(v: [f64; 3]) -> [f32; 3] {
    v.map(|x| x as f32)
}

/// A unit f32 direction.
fn unit_f32(v: [f64; 3]) -> [f32; 3] {
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    to_f32(v.map(|x| x / len))
}

/// Random rays of every kind for a medium.
fn random_rays(m: &Medium, count: usize, rng: &mut Pcg32) -> Vec<Ray> {
    let lo = m.bounds_min.map(f64::from);
    let size = m.size();
    let diag = (size[0] * size[0] + size[1] * size[1] + size[2] * size[2]).sqrt();
    let inside = |rng: &mut Pcg32| [0, 1, 2].map(|a| lo[a] + rng.uniform32() * size[a]);
    let mut rays = Vec::with_capacity(count);
    while rays.len() < count {
        let ray = match rays.len() % 8 {
            // Inside start, random interval (sometimes starting behind the origin).
            0 => {
                let t0 = if rng.uniform32() < 0.3 {
                    rng.range32(-diag, 0.0)
                } else {
                    0.0
                };
                Ray {
                    o: to_f32(inside(rng)),
                    d: unit_f32(rng.unit_vector_f64()),
                    t0: t0 as f32,
                    t1: (t0 + rng.range32(0.0, 1.5 * diag)) as f32,
                    kind: "inside",
                }
            }
            // Outside start aimed at a point inside, to infinity.
            1 | 2 => {
                let target = inside(rng);
                let dir = rng.unit_vector_f64();
                let o = [0, 1, 2].map(|a| target[a] - dir[a] * rng.range32(0.5, 1.5) * diag);
                Ray {
                    o: to_f32(o),
                    d: unit_f32(dir),
                    t0: 0.0,
                    t1: FAR,
                    kind: "outside",
                }
            }
            // Axis-aligned, on voxel-centre or voxel-face planes (along voxel edges).
            3 | 4 => {
                let axis = rng.below(3) as usize;
                let mut o = inside(rng);
                for a in 0..3 {
                    if a != axis {
                        let n = m.grid.dims[a];
                        let half_steps = rng.below(2 * n + 1);
                        o[a] = lo[a] + f64::from(half_steps) * 0.5 / f64::from(n) * size[a];
                    }
                }
                let mut d = [0.0; 3];
                d[axis] = if rng.uniform32() < 0.5 { 1.0 } else { -1.0 };
                if rng.uniform32() < 0.5 {
                    // Start outside, looking in.
                    o[axis] = if d[axis] > 0.0 {
                        lo[axis] - 0.3 * size[axis]
                    } else {
                        lo[axis] + 1.3 * size[axis]
                    };
                }
                Ray {
                    o: to_f32(o),
                    d: to_f32(d),
                    t0: 0.0,
                    t1: FAR,
                    kind: "axis-aligned",
                }
            }
            // Grazing: in a face plane, direction within it.
            5 => {
                let axis = rng.below(3) as usize;
                let mut o = inside(rng);
                o[axis] = if rng.uniform32() < 0.5 {
                    lo[axis]
                } else {
                    f64::from(m.bounds_max[axis])
                };
                let mut dir = rng.unit_vector_f64();
                dir[axis] = 0.0;
                Ray {
                    o: to_f32(o),
                    d: unit_f32(dir),
                    t0: -FAR,
                    t1: FAR,
                    kind: "grazing",
                }
            }
            // Parallel to one axis's planes, random otherwise.
            6 => {
                let mut dir = rng.unit_vector_f64();
                dir[rng.below(3) as usize] = 0.0;
                Ray {
                    o: to_f32(inside(rng)),
                    d: unit_f32(dir),
                    t0: 0.0,
                    t1: FAR,
                    kind: "parallel to a plane",
                }
            }
            // Degenerate intervals and misses.
            _ => {
                let o = to_f32(inside(rng));
                let d = unit_f32(rng.unit_vector_f64());
                match rng.below(3) {
                    0 => Ray {
                        o,
                        d,
                        t0: 0.1,
                        t1: 0.1,
                        kind: "zero-length",
                    },
                    1 => Ray {
                        o,
                        d,
                        t0: 0.5,
                        t1: -0.5,
                        kind: "reversed",
                    },
                    _ => {
                        // Beside the box, parallel to its nearest face.
                        let mut o = o;
                        o[0] = (f64::from(m.bounds_max[0]) + 0.1 * size[0]) as f32;
                        let mut d = rng.unit_vector_f64();
                        d[0] = 0.0;
                        Ray {
                            o,
                            d: unit_f32(d),
                            t0: -FAR,
                            t1: FAR,
                            kind: "miss",
                        }
                    }
                }
            }
        };
        rays.push(ray);
    }
    rays
}
