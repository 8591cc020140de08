//! The densities ReSTIR derives from each density grid: the conservative
//! piecewise-constant levels for regular tracking and the averaged mip textures for
//! ray marching, for the base grid and every `[[medium.frame]]`.

use std::collections::HashMap;

use anyhow::{bail, Result};
use nimbus_scene::precision::PositionScale;
use nimbus_scene::{GridMedium, VoxelGrid};

use crate::plan::RestirPlan;

/// What the passes read for one density grid.
pub struct DerivedVolume {
    /// σ_t* (scaled) of the primary level, then of the indirect level.
    pub pc: Vec<f32>,
    /// Dims of the primary level (its values start at 0), of the indirect level and
    /// where its values start.
    pub pc_primary_dims: [u32; 3],
    pub pc_indirect_dims: [u32; 3],
    pub pc_indirect_offset: u32,
    /// Unscaled density, half floats, at mip_reuse and mip_indirect.
    pub march_reuse: (Vec<u16>, [u32; 3]),
    pub march_nee: (Vec<u16>, [u32; 3]),
    pub density: VoxelGrid,
}

/// Mip level `level` of a chain, clamped to the last (1×1×1) one.
fn level_of(chain: &[VoxelGrid], level: u32) -> &VoxelGrid {
    let l = (level as usize).min(chain.len().saturating_sub(1));
    &chain[l]
}

fn to_half(grid: &VoxelGrid) -> (Vec<u16>, [u32; 3]) {
    (
        grid.data
            .iter()
            .map(|v| half::f16::from_f32(*v).to_bits())
            .collect(),
        grid.dims,
    )
}

impl DerivedVolume {
    pub fn build(density: VoxelGrid, scale: f32, plan: &RestirPlan) -> DerivedVolume {
        let conservative = density.conservative_piecewise_constant().mip_chain();
        let primary = level_of(&conservative, plan.mip_candidates);
        let indirect = level_of(&conservative, plan.mip_indirect);
        let mut pc: Vec<f32> = primary.data.iter().map(|v| v * scale).collect();
        let offset = pc.len() as u32;
        pc.extend(indirect.data.iter().map(|v| v * scale));
        let mips = density.mip_chain();
        let march_reuse = to_half(level_of(&mips, plan.mip_reuse));
        let march_nee = to_half(level_of(&mips, plan.mip_indirect));
        DerivedVolume {
            pc,
            pc_primary_dims: primary.dims,
            pc_indirect_dims: indirect.dims,
            pc_indirect_offset: offset,
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
}

impl Volumes {
    /// Derives the base grid, then loads and derives every `[[medium.frame]]` (checked
    /// to have the base grid's dims), so frames only upload. `label` names the medium
    /// in errors.
    pub fn load(
        base: VoxelGrid,
        grid: &GridMedium,
        plan: &RestirPlan,
        scale: &PositionScale,
        label: &str,
    ) -> Result<Volumes> {
        let dims = base.dims;
        let mut by_index = HashMap::new();
        by_index.insert(0, DerivedVolume::build(base, grid.density_scale, plan));
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
            by_index.insert(
                i + 1,
                DerivedVolume::build(density, grid.density_scale, plan),
            );
        }
        Ok(Volumes { by_index })
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
