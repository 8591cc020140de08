//! The densities ReSTIR derives from each density grid: the conservative
//! piecewise-constant levels for regular tracking and the averaged mip textures for
//! ray marching, for the base grid and every `[[medium.frame]]`.

use std::collections::HashMap;

use anyhow::{bail, Result};
use nimbus_gpu::vk;
use nimbus_scene::precision::PositionScale;
use nimbus_scene::{GridMedium, VoxelGrid};

use crate::plan::RestirPlan;

/// The texel format of the ray-march mips: half floats where every density of the
/// animation fits f16 (the paper's choice, half the bandwidth), f32 otherwise. An f16
/// texel above 65504 reads as infinity, which makes the target function 0 where the path
/// contribution is not: a biased image (one voxel of 1e6 darkened half a cloud).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MarchFormat {
    Half,
    Float,
}

impl MarchFormat {
    /// The format that holds densities up to `max_density` (unscaled).
    pub fn for_max(max_density: f32) -> MarchFormat {
        if max_density <= f32::from(half::f16::MAX) {
            MarchFormat::Half
        } else {
            MarchFormat::Float
        }
    }

    pub fn vk(self) -> vk::Format {
        match self {
            MarchFormat::Half => vk::Format::R16_SFLOAT,
            MarchFormat::Float => vk::Format::R32_SFLOAT,
        }
    }

    /// `grid`'s texels in this format.
    fn texels(self, grid: &VoxelGrid) -> Vec<u8> {
        match self {
            MarchFormat::Half => grid
                .data
                .iter()
                .flat_map(|v| half::f16::from_f32(*v).to_bits().to_le_bytes())
                .collect(),
            MarchFormat::Float => bytemuck::cast_slice(&grid.data).to_vec(),
        }
    }
}

/// A ray-march mip level as uploaded.
pub struct MarchLevel {
    pub texels: Vec<u8>,
    pub dims: [u32; 3],
}

impl MarchLevel {
    fn of(grid: &VoxelGrid, format: MarchFormat) -> MarchLevel {
        MarchLevel {
            texels: format.texels(grid),
            dims: grid.dims,
        }
    }
}

/// The mip levels the passes use for a grid: the conservative piecewise-constant levels
/// of candidate generation (camera and scattered rays) and the ray-march mips of the
/// target functions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Levels {
    pub candidates: u32,
    pub indirect: u32,
    pub reuse: u32,
}

/// The largest optical depth a coarse level may put across one of its blocks beyond what
/// the block's thinnest voxel allows (`(mean − min) · σ scale · block diagonal`). A block
/// that averages a hot voxel with clear neighbours claims opacity where light really
/// passes: its T~ or T* becomes 0 (or too small to sample) for paths that contribute,
/// which biases ReSTIR (one 1e6 voxel darkened a cloud by 1.4 % at mip 2). Past this the
/// level is refined, whatever the scene asks. Below it, T~ is at worst e^8 too small
/// across a block: RIS stays unbiased (T~ > 0) at a bounded cost in variance. A cloud
/// with voxel-scale detail stays below it (the study cloud: about 5 at mip 2), so this
/// guards correctness; which levels pay best is a separate, measured choice.
pub const MAX_LEVEL_EXCESS_TAU: f64 = 8.0;

impl Levels {
    /// The plan's levels, each lowered to the coarsest level at or below it whose blocks
    /// stay within [`MAX_LEVEL_EXCESS_TAU`] in every grid of the animation.
    pub fn choose(
        plan: &RestirPlan,
        grids: &[VoxelGrid],
        scale: f32,
        voxel_diagonal: f32,
    ) -> Levels {
        let requested = plan
            .mip_candidates
            .max(plan.mip_indirect)
            .max(plan.mip_reuse);
        let allowed = grids
            .iter()
            .map(|g| allowed_level(g, scale, voxel_diagonal, requested))
            .min()
            .unwrap_or(0);
        Levels {
            candidates: plan.mip_candidates.min(allowed),
            indirect: plan.mip_indirect.min(allowed),
            reuse: plan.mip_reuse.min(allowed),
        }
    }
}

/// The coarsest level ≤ `requested` whose 2^L blocks all keep
/// (mean − min) · scale · (voxel diagonal · 2^L) ≤ [`MAX_LEVEL_EXCESS_TAU`].
fn allowed_level(grid: &VoxelGrid, scale: f32, voxel_diagonal: f32, requested: u32) -> u32 {
    let mut mean = std::borrow::Cow::Borrowed(grid);
    let mut min = std::borrow::Cow::Borrowed(grid);
    for level in 1..=requested {
        if mean.dims == [1, 1, 1] {
            return requested;
        }
        mean = std::borrow::Cow::Owned(mean.mip_level(1).into_owned());
        min = std::borrow::Cow::Owned(min.min_downsample());
        let diagonal = f64::from(voxel_diagonal) * f64::from(1u32 << level.min(31));
        let excess = mean
            .data
            .iter()
            .zip(&min.data)
            .map(|(m, lo)| f64::from(m - lo))
            .fold(0.0, f64::max)
            * f64::from(scale)
            * diagonal;
        if excess > MAX_LEVEL_EXCESS_TAU {
            return level - 1;
        }
    }
    requested
}

/// Level `level` of the conservative piecewise-constant grid (the mean of its children),
/// raised to `floor` times the largest density that can reach each block (the maximum of
/// the voxels' 3×3×3 neighbourhoods over the block) when `floor` > 0: then σ_t / σ* ≤
/// 1 / floor everywhere in the block, which bounds the candidates' weights.
fn floored_level(
    conservative: &VoxelGrid,
    density: &VoxelGrid,
    level: u32,
    floor: f32,
) -> VoxelGrid {
    let mean = conservative.mip_level(level).into_owned();
    if floor.is_nan() || floor <= 0.0 {
        return mean;
    }
    let mut reach = density.neighbourhood_max();
    for _ in 0..level {
        if reach.dims == [1, 1, 1] {
            break;
        }
        reach = reach.max_downsample();
    }
    let data = mean
        .data
        .iter()
        .zip(&reach.data)
        .map(|(m, r)| m.max(floor * r))
        .collect();
    VoxelGrid { data, ..mean }
}

/// What the passes read for one density grid.
pub struct DerivedVolume {
    /// σ_t* (scaled) of the primary level, then of the indirect level.
    pub pc: Vec<f32>,
    /// Dims of the primary level (its values start at 0), of the indirect level and
    /// where its values start.
    pub pc_primary_dims: [u32; 3],
    pub pc_indirect_dims: [u32; 3],
    pub pc_indirect_offset: u32,
    /// Unscaled density at mip_reuse and mip_indirect.
    pub march_reuse: MarchLevel,
    pub march_nee: MarchLevel,
    pub density: VoxelGrid,
}

impl DerivedVolume {
    /// Derives the levels of `density` (moved in, not copied); peak memory is the grid,
    /// its conservative copy and two mip levels.
    pub fn build(
        density: VoxelGrid,
        scale: f32,
        levels: &Levels,
        format: MarchFormat,
        floor: f32,
    ) -> DerivedVolume {
        let (pc, pc_primary_dims, pc_indirect_dims, pc_indirect_offset) = {
            let conservative = density.conservative_piecewise_constant();
            let primary = floored_level(&conservative, &density, levels.candidates, floor);
            let indirect = floored_level(&conservative, &density, levels.indirect, floor);
            let mut pc: Vec<f32> = primary.data.iter().map(|v| v * scale).collect();
            let offset = pc.len() as u32;
            pc.extend(indirect.data.iter().map(|v| v * scale));
            (pc, primary.dims, indirect.dims, offset)
        };
        let march_reuse = MarchLevel::of(&density.mip_level(levels.reuse), format);
        let march_nee = MarchLevel::of(&density.mip_level(levels.indirect), format);
        DerivedVolume {
            pc,
            pc_primary_dims,
            pc_indirect_dims,
            pc_indirect_offset,
            march_reuse,
            march_nee,
            density,
        }
    }
}

/// The derived volumes of every density grid of the animation, by density index
/// (0 = the medium's `density`, i + 1 = `[[medium.frame]]` i).
pub struct Volumes {
    by_index: HashMap<usize, DerivedVolume>,
    pub format: MarchFormat,
    pub levels: Levels,
}

impl Volumes {
    /// Loads every `[[medium.frame]]` (checked to have the base grid's dims and
    /// resolvable densities), picks the march format all of them fit, and derives each,
    /// so frames only upload. `label` names the medium in errors.
    pub fn load(
        base: VoxelGrid,
        grid: &GridMedium,
        plan: &RestirPlan,
        scale: &PositionScale,
        label: &str,
    ) -> Result<Volumes> {
        let dims = base.dims;
        let mut grids = vec![base];
        for (i, frame) in grid.frames.iter().enumerate() {
            let what = format!(
                "{label} > [[medium.frame]] #{} (frame {})",
                i + 1,
                frame.frame
            );
            let density = nimbus_scene::load_grid(&frame.density, 1, &what)?;
            grid.check_density(&density, scale, &what)?;
            if density.dims != dims {
                bail!(
                    "{what}: field `density`: dims {:?} differ from the medium's density {:?}; every frame must have the same resolution",
                    density.dims,
                    dims
                );
            }
            grids.push(density);
        }
        let max = grids
            .iter()
            .flat_map(|g| g.data.iter())
            .fold(0.0f32, |m, v| m.max(*v));
        let format = MarchFormat::for_max(max);
        let size = grid.bounds_max - grid.bounds_min;
        let voxel = size / glam::Vec3::from(dims.map(|d| d as f32));
        let levels = Levels::choose(plan, &grids, grid.density_scale, voxel.length());
        let by_index = grids
            .into_iter()
            .enumerate()
            .map(|(i, g)| {
                (
                    i,
                    DerivedVolume::build(
                        g,
                        grid.density_scale,
                        &levels,
                        format,
                        plan.sigma_star_floor,
                    ),
                )
            })
            .collect();
        Ok(Volumes {
            by_index,
            format,
            levels,
        })
    }

    /// The base grid's derived volume.
    pub fn base(&self) -> Result<&DerivedVolume> {
        self.get(0)
    }

    pub fn get(&self, index: usize) -> Result<&DerivedVolume> {
        match self.by_index.get(&index) {
            Some(v) => Ok(v),
            None => bail!("internal: density frame {index} was not loaded before rendering"),
        }
    }
}

/// The ray-marching step at mip `level`: the diagonal of one of its voxels, in metres
/// (sec. 5.1: "our step size for ray marching is the diagonal of a Mip 1 voxel").
pub fn march_step(grid: &GridMedium, dims: [u32; 3], level: u32) -> f32 {
    let factor = (1u64 << level.min(last_level(dims))) as f32;
    let size = grid.bounds_max - grid.bounds_min;
    let voxel = glam::Vec3::new(
        size.x / dims[0] as f32,
        size.y / dims[1] as f32,
        size.z / dims[2] as f32,
    ) * factor;
    voxel.length()
}

/// ceil(log2(largest dim)): the index of the 1×1×1 level of a mip chain.
pub fn last_level(dims: [u32; 3]) -> u32 {
    let max = dims.iter().copied().max().unwrap_or(1).max(1);
    32 - (max - 1).leading_zeros()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn last_level_is_the_one_by_one_level() {
        assert_eq!(last_level([1, 1, 1]), 0);
        assert_eq!(last_level([2, 1, 1]), 1);
        assert_eq!(last_level([64, 48, 64]), 6);
        assert_eq!(last_level([65, 1, 1]), 7);
    }
}

#[cfg(test)]
mod format_tests {
    use super::*;

    #[test]
    fn densities_beyond_f16_use_f32_texels() {
        assert_eq!(MarchFormat::for_max(65504.0), MarchFormat::Half);
        assert_eq!(MarchFormat::for_max(65505.0), MarchFormat::Float);
        let grid = VoxelGrid {
            dims: [2, 1, 1],
            channels: 1,
            data: vec![0.5, 1e6],
        };
        assert_eq!(MarchFormat::Half.texels(&grid).len(), 4);
        let f32_texels = MarchFormat::Float.texels(&grid);
        assert_eq!(bytemuck::cast_slice::<u8, f32>(&f32_texels), &[0.5, 1e6]);
    }
}

#[cfg(test)]
mod level_tests {
    use super::*;

    fn plan(level: u32) -> RestirPlan {
        RestirPlan {
            max_bounces: 1,
            has_emission: false,
            has_env: false,
            has_env_map: false,
            pixel_jitter: true,
            has_velocity: false,
            animated_density: false,
            candidates: 4,
            temporal: true,
            temporal_limit: 4,
            spatial_neighbors: 3,
            spatial_radius_px: 10.0,
            spatial_rounds: 1,
            vertex_reuse: false,
            final_ratio_tracking: false,
            mip_candidates: level,
            mip_indirect: level,
            mip_reuse: level,
            pairwise_mis: false,
            history_before_spatial: false,
            sigma_star_floor: 0.0,
        }
    }

    #[test]
    fn a_hot_voxel_refines_the_levels_and_smooth_media_keep_them() {
        let n = 16u32;
        let mut grid = VoxelGrid {
            dims: [n; 3],
            channels: 1,
            data: vec![0.5; (n * n * n) as usize],
        };
        let smooth = Levels::choose(&plan(2), std::slice::from_ref(&grid), 1.0, 0.1);
        assert_eq!(
            smooth,
            Levels {
                candidates: 2,
                indirect: 2,
                reuse: 2
            }
        );
        grid.data[(8 + n * (8 + n * 8)) as usize] = 1e6;
        let hot = Levels::choose(&plan(2), &[grid], 1.0, 0.1);
        assert_eq!(
            hot,
            Levels {
                candidates: 0,
                indirect: 0,
                reuse: 0
            }
        );
    }
}
