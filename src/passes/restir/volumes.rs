//! The densities ReSTIR derives from each density grid, brick by brick: the conservative
//! piecewise-constant levels for regular tracking and the averaged mips for ray marching,
//! for the base grid and every `[[medium.frame]]`, and their atlas layouts (one atlas
//! size over all frames, so frames only upload).

use std::collections::HashMap;

use anyhow::{bail, Result};
use glam::IVec3;
use nimbus_scene::precision::PositionScale;
use nimbus_scene::{BrickGrid, GridMedium};

use crate::plan::{Levels, RestirPlan};
use crate::shader_data::sparse::{atlas_slots, SparseLayout, TexelFormat};
use crate::shader_data::GridLevelGpu;

/// The texel format of the ray-march mips: half floats where every density of the
/// animation fits f16 (the paper's choice, half the bandwidth), f32 otherwise. An f16
/// texel above 65504 reads as infinity, which makes the target function 0 where the path
/// contribution is not: a biased image (one voxel of 1e6 darkened half a cloud).
pub fn march_format(max_density: f32) -> TexelFormat {
    if max_density <= f32::from(half::f16::MAX) {
        TexelFormat::R16
    } else {
        TexelFormat::R32
    }
}

/// The mip `level` of `grid` (a copy at level 0), clamped at its single-point level.
fn level_of(grid: &BrickGrid, level: u32) -> Result<BrickGrid> {
    let mut g = grid.clone();
    for _ in 0..level.min(grid.last_level()) {
        g = g.mip()?;
    }
    Ok(g)
}

/// Level `level` of the conservative piecewise-constant grid (`mean`), raised to `floor`
/// times the largest density that can reach each block (the maximum of the voxels' 3×3×3
/// neighbourhoods over the block) when `floor` > 0: then σ_t / σ* ≤ 1 / floor everywhere
/// in the block, which bounds the candidates' weights.
fn floored(mean: BrickGrid, density: &BrickGrid, level: u32, floor: f32) -> Result<BrickGrid> {
    if floor.is_nan() || floor <= 0.0 {
        return Ok(mean);
    }
    let mut reach = density.neighbourhood_max()?;
    for _ in 0..level.min(density.last_level()) {
        reach = reach.max_mip()?;
    }
    mean.max_with_scaled(&reach, floor)
}

/// The levels derived from one density grid, and which bricks of each get a slot.
pub struct DerivedGrids {
    pub density: BrickGrid,
    /// The density's slots (its super-voxels with density) and their records.
    pub density_bricks: Vec<IVec3>,
    pub super_voxels: Vec<[f32; 4]>,
    /// σ_t* (scaled at upload) of the primary and the indirect level.
    pub pc_primary: BrickGrid,
    pub pc_indirect: BrickGrid,
    /// Unscaled density at mip_reuse and mip_indirect, and their slots.
    pub march_reuse: BrickGrid,
    pub march_reuse_bricks: Vec<IVec3>,
    pub march_nee: BrickGrid,
    pub march_nee_bricks: Vec<IVec3>,
}

impl DerivedGrids {
    /// Derives the levels of `density` (moved in, not copied), whose super-voxels are
    /// `density_bricks` / `super_voxels` (sigma_t, scaled); peak memory is the grid, its
    /// conservative copy and two mip levels.
    pub fn build(
        density: BrickGrid,
        density_bricks: Vec<IVec3>,
        super_voxels: Vec<[f32; 4]>,
        levels: &Levels,
        floor: f32,
    ) -> Result<DerivedGrids> {
        let (pc_primary, pc_indirect) = {
            let conservative = density.conservative()?;
            let mut g = conservative;
            let mut primary = None;
            let mut indirect = None;
            let top = levels.candidates.max(levels.indirect);
            let last = g.last_level();
            for level in 0..=top {
                if level > 0 && level <= last {
                    g = g.mip()?;
                }
                if level == levels.candidates {
                    primary = Some(g.clone());
                }
                if level == levels.indirect {
                    indirect = Some(g.clone());
                }
            }
            match (primary, indirect) {
                (Some(p), Some(i)) => (
                    floored(p, &density, levels.candidates, floor)?,
                    floored(i, &density, levels.indirect, floor)?,
                ),
                _ => bail!("internal: piecewise-constant levels not built"),
            }
        };
        let march_reuse = level_of(&density, levels.reuse)?;
        let march_nee = level_of(&density, levels.indirect)?;
        Ok(DerivedGrids {
            march_reuse_bricks: march_reuse.slot_bricks(),
            march_nee_bricks: march_nee.slot_bricks(),
            density,
            density_bricks,
            super_voxels,
            pc_primary,
            pc_indirect,
            march_reuse,
            march_nee,
        })
    }
}

/// What the passes read for one density grid: its levels laid out in atlases whose sizes
/// all frames share.
pub struct DerivedVolume {
    pub grids: DerivedGrids,
    pub density_layout: SparseLayout,
    /// The piecewise-constant levels share one atlas: primary slots first.
    pub pc_primary_layout: SparseLayout,
    pub pc_indirect_layout: SparseLayout,
    pub march_reuse_layout: SparseLayout,
    pub march_nee_layout: SparseLayout,
}

/// Slots per axis of each atlas, shared by every frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AtlasSizes {
    pub density: [u32; 3],
    pub pc: [u32; 3],
    pub march_reuse: [u32; 3],
    pub march_nee: [u32; 3],
}

impl AtlasSizes {
    fn of(all: &[DerivedGrids]) -> Result<AtlasSizes> {
        let max = |f: &dyn Fn(&DerivedGrids) -> usize| all.iter().map(f).max().unwrap_or(0) as u64;
        Ok(AtlasSizes {
            density: atlas_slots(max(&|g| g.density_bricks.len()))?,
            pc: atlas_slots(max(&|g| {
                g.pc_primary.brick_count() + g.pc_indirect.brick_count()
            }))?,
            march_reuse: atlas_slots(max(&|g| g.march_reuse_bricks.len()))?,
            march_nee: atlas_slots(max(&|g| g.march_nee_bricks.len()))?,
        })
    }
}

impl DerivedVolume {
    fn layout(grids: DerivedGrids, sizes: &AtlasSizes) -> Result<DerivedVolume> {
        let g = &grids;
        let primary_count = g.pc_primary.brick_count() as u32;
        Ok(DerivedVolume {
            density_layout: SparseLayout::new_at(
                &g.density,
                g.density_bricks.clone(),
                0,
                sizes.density,
            )?,
            // Regular tracking skips their empty blocks (pc_track).
            pc_primary_layout: SparseLayout::new_at(
                &g.pc_primary,
                g.pc_primary.bricks.clone(),
                0,
                sizes.pc,
            )?
            .with_occupancy(&g.pc_primary)?,
            pc_indirect_layout: SparseLayout::new_at(
                &g.pc_indirect,
                g.pc_indirect.bricks.clone(),
                primary_count,
                sizes.pc,
            )?
            .with_occupancy(&g.pc_indirect)?,
            march_reuse_layout: SparseLayout::new_at(
                &g.march_reuse,
                g.march_reuse_bricks.clone(),
                0,
                sizes.march_reuse,
            )?,
            march_nee_layout: SparseLayout::new_at(
                &g.march_nee,
                g.march_nee_bricks.clone(),
                0,
                sizes.march_nee,
            )?,
            grids,
        })
    }
}

/// The [`GridLevelGpu`] of a derived level at mip `level` of `density` (clamped at its
/// last level), its indirection at `offset`.
pub fn grid_level(
    density: &BrickGrid,
    grid: &BrickGrid,
    layout: &SparseLayout,
    level: u32,
    offset: u32,
) -> GridLevelGpu {
    GridLevelGpu {
        lattice_min: grid.lattice_min.to_array(),
        bricks_offset: offset,
        lattice_max: grid.lattice_max.to_array(),
        factor: 1 << level.min(density.last_level()).min(31),
        brick_dims: layout.brick_dims,
        slots_x: layout.slots[0],
        slots_y: layout.slots[1],
        ..GridLevelGpu::default()
    }
}

/// The derived volumes of every density grid of the animation, by density index
/// (0 = the medium's `density`, i + 1 = `[[medium.frame]]` i).
pub struct Volumes {
    by_index: HashMap<usize, DerivedVolume>,
    pub format: TexelFormat,
    pub levels: Levels,
    pub sizes: AtlasSizes,
    /// The largest sigma_t of every frame.
    pub sigma_t_max: f32,
}

impl Volumes {
    /// Loads every `[[medium.frame]]` into bricks (checked to share the base grid's
    /// lattice and to have resolvable densities), picks the march format all of them fit,
    /// and derives each, so frames only upload. `base` is the base density with its
    /// super-voxels (`bricks`, `records`). `label` names the medium in errors.
    pub fn load(
        base: (BrickGrid, Vec<IVec3>, Vec<[f32; 4]>),
        grid: &GridMedium,
        plan: &RestirPlan,
        scale: &PositionScale,
        label: &str,
    ) -> Result<Volumes> {
        let s = grid.density_scale;
        let mut loaded = vec![base];
        // The plan loaded them to choose the levels: the same loads and checks.
        let frames = match crate::plan::levels::take_frames(grid, scale) {
            Some(frames) => frames,
            None => crate::plan::load_frames(grid, &loaded[0].0, scale, label)?,
        };
        for density in frames {
            let (bricks, records): (Vec<_>, Vec<_>) = density
                .super_voxels()
                .into_iter()
                .map(|(b, v)| (b, [v[0] * s, v[1] * s, v[2] * s, 0.0]))
                .unzip();
            loaded.push((density, bricks, records));
        }
        let max = loaded
            .iter()
            .map(|(g, _, _)| g.max_value().0)
            .fold(0.0f32, f32::max);
        let format = march_format(max);
        let sigma_t_max = loaded
            .iter()
            .flat_map(|(_, _, r)| r.iter().map(|v| v[1]))
            .fold(0.0f32, f32::max);
        let levels = plan.levels.levels;
        let derived: Vec<DerivedGrids> = loaded
            .into_iter()
            .map(|(g, b, r)| DerivedGrids::build(g, b, r, &levels, plan.settings.sigma_star_floor))
            .collect::<Result<_>>()?;
        let sizes = AtlasSizes::of(&derived)?;
        let by_index = derived
            .into_iter()
            .enumerate()
            .map(|(i, g)| Ok((i, DerivedVolume::layout(g, &sizes)?)))
            .collect::<Result<_>>()?;
        Ok(Volumes {
            by_index,
            format,
            levels,
            sizes,
            sigma_t_max,
        })
    }

    /// The base grid's derived volume.
    /// Whether residual ratio tracking with `majorant_scale` x the tight residual majorant
    /// can meet a hot super-voxel span in any density frame.
    pub fn needs_exact_spans(&self, p_to_world: &glam::DMat4, majorant_scale: f32) -> bool {
        self.by_index.values().any(|v| {
            crate::shader_data::scene::needs_exact_spans(
                &v.grids.super_voxels,
                p_to_world,
                majorant_scale,
            )
        })
    }

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
pub fn march_step(grid: &GridMedium, density: &BrickGrid, level: u32) -> f32 {
    let dims = (density.lattice_max + 1)
        .to_array()
        .map(|d| d.max(1) as u32);
    let factor = 1u64 << level.min(density.last_level()).min(31);
    if grid.vdb.is_none() {
        // In f32, as the dense renderer always computed it.
        let size = grid.bounds_max - grid.bounds_min;
        let voxel = glam::Vec3::new(
            size.x / dims[0] as f32,
            size.y / dims[1] as f32,
            size.z / dims[2] as f32,
        ) * factor as f32;
        return voxel.length();
    }
    let v = grid.voxel_size(dims);
    ((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() * factor as f64) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn densities_beyond_f16_use_f32_texels() {
        assert_eq!(march_format(65504.0), TexelFormat::R16);
        assert_eq!(march_format(65505.0), TexelFormat::R32);
    }
}
