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
        plan: &RestirPlan,
        format: MarchFormat,
    ) -> DerivedVolume {
        let (pc, pc_primary_dims, pc_indirect_dims, pc_indirect_offset) = {
            let conservative = density.conservative_piecewise_constant();
            let primary = conservative.mip_level(plan.mip_candidates);
            let indirect = conservative.mip_level(plan.mip_indirect);
            let mut pc: Vec<f32> = primary.data.iter().map(|v| v * scale).collect();
            let offset = pc.len() as u32;
            pc.extend(indirect.data.iter().map(|v| v * scale));
            (pc, primary.dims, indirect.dims, offset)
        };
        let march_reuse = MarchLevel::of(&density.mip_level(plan.mip_reuse), format);
        let march_nee = MarchLevel::of(&density.mip_level(plan.mip_indirect), format);
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
        let by_index = grids
            .into_iter()
            .enumerate()
            .map(|(i, g)| (i, DerivedVolume::build(g, grid.density_scale, plan, format)))
            .collect();
        Ok(Volumes { by_index, format })
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
