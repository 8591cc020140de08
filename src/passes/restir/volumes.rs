//! The densities ReSTIR derives from each density grid, brick by brick: the conservative
//! piecewise-constant levels for regular tracking and the averaged mips for ray marching,
//! for the base grid and every `[[medium.frame]]`, and their atlas layouts (one atlas
//! size over all frames, so frames only upload).

use std::collections::HashMap;

use anyhow::{bail, Result};
use glam::IVec3;
use nimbus_scene::bricks::{march_errors, MARCH_ERROR_SEGMENTS};
use nimbus_scene::precision::PositionScale;
use nimbus_scene::{BrickGrid, GridMedium};

use crate::gpu::sparse::{atlas_slots, SparseLayout, TexelFormat};
use crate::gpu::GridLevelGpu;
use crate::plan::RestirPlan;

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

/// The largest error in optical depth, RMS over segments weighted by their transmittance
/// ([`march_errors`]), that a level chosen from the content (`"auto"`) may have: T~
/// within about 5 % of T. Calibrated on two clouds whose targets were measured with
/// both levels (tests/suite and docs/restir.md): the 64³ study cloud (noise at voxel
/// scale) loses 0.043 at mip 0 and 0.245 at mip 1, and per-frame error fell 2-3.6x
/// with mip 0; the 256x160x256 benchmark cloud loses 0.030 at mip 1 and 0.101 at mip 2,
/// and its per-frame error was the same at mips 0 and 1 (1 % apart) for 10 % less time.
pub const MAX_MARCH_ERROR: f64 = 0.05;
/// The coarsest level `"auto"` considers.
pub const MAX_AUTO_LEVEL: u32 = 3;
/// The finest level `"auto"` gives the candidates' scattered segments: their
/// transmittance only weighs candidates (the reuse targets replace it), so mip 1 serves
/// where the reuse targets need mip 0 (measured on the 64³ study cloud: mip_indirect 1
/// with mip_reuse 0 cut per-frame MSE 2-3.6x), and the level-0 conservative grid it would
/// add costs a full-resolution copy of the density.
pub const MIN_AUTO_INDIRECT: u32 = 1;

/// The levels the passes use and, when some were chosen from the content, the measured
/// optical-depth errors of mips 0..=[`MAX_AUTO_LEVEL`] that chose them.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelChoice {
    pub levels: Levels,
    pub march_errors: Option<Vec<f64>>,
}

impl Levels {
    /// The plan's levels (`auto` ones: the coarsest of mips 0..=[`MAX_AUTO_LEVEL`] whose
    /// marched optical depth stays within [`MAX_MARCH_ERROR`] on the first grid, `voxel`
    /// its world voxel size), each lowered to the coarsest level at or below it whose
    /// blocks stay within [`MAX_LEVEL_EXCESS_TAU`] in every grid of the animation.
    pub fn choose(
        plan: &RestirPlan,
        grids: &[&BrickGrid],
        scale: f32,
        voxel: [f64; 3],
    ) -> Result<LevelChoice> {
        let voxel_diagonal =
            (voxel[0] * voxel[0] + voxel[1] * voxel[1] + voxel[2] * voxel[2]).sqrt() as f32;
        let auto = plan.mip_indirect.is_none() || plan.mip_reuse.is_none();
        let (auto_level, march_errors) = match (auto, grids.first()) {
            (true, Some(g)) => {
                let errors = march_errors(
                    g,
                    voxel,
                    f64::from(scale),
                    MAX_AUTO_LEVEL,
                    MARCH_ERROR_SEGMENTS,
                    1,
                )?;
                let level = errors
                    .iter()
                    .take_while(|&&e| e <= MAX_MARCH_ERROR)
                    .count()
                    .saturating_sub(1) as u32;
                (level, Some(errors))
            }
            _ => (0, None),
        };
        let indirect = plan
            .mip_indirect
            .unwrap_or(auto_level.max(MIN_AUTO_INDIRECT));
        let reuse = plan.mip_reuse.unwrap_or(auto_level);
        let requested = plan.mip_candidates.max(indirect).max(reuse);
        let mut allowed = requested;
        for g in grids {
            allowed = allowed.min(allowed_level(g, scale, voxel_diagonal, requested)?);
        }
        Ok(LevelChoice {
            levels: Levels {
                candidates: plan.mip_candidates.min(allowed),
                indirect: indirect.min(allowed),
                reuse: reuse.min(allowed),
            },
            march_errors,
        })
    }
}

/// Whether a level's lattice is a single point (the 1×1×1 level of a dense grid).
fn is_last(g: &BrickGrid) -> bool {
    g.lattice_min == g.lattice_max
}

/// The coarsest level ≤ `requested` whose 2^L blocks all keep
/// (mean − min) · scale · (voxel diagonal · 2^L) ≤ [`MAX_LEVEL_EXCESS_TAU`].
fn allowed_level(grid: &BrickGrid, scale: f32, voxel_diagonal: f32, requested: u32) -> Result<u32> {
    if requested == 0 || is_last(grid) {
        return Ok(requested);
    }
    let mut mean = grid.mip()?;
    let mut min = grid.min_mip()?;
    for level in 1..=requested {
        if level > 1 {
            if is_last(&mean) {
                return Ok(requested);
            }
            mean = mean.mip()?;
            min = min.min_mip()?;
        }
        let diagonal = f64::from(voxel_diagonal) * f64::from(1u32 << level.min(31));
        let excess = mean.max_excess_over(&min) * f64::from(scale) * diagonal;
        if excess > MAX_LEVEL_EXCESS_TAU {
            return Ok(level - 1);
        }
    }
    Ok(requested)
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
            pc_primary_layout: SparseLayout::new_at(
                &g.pc_primary,
                g.pc_primary.bricks.clone(),
                0,
                sizes.pc,
            )?,
            pc_indirect_layout: SparseLayout::new_at(
                &g.pc_indirect,
                g.pc_indirect.bricks.clone(),
                primary_count,
                sizes.pc,
            )?,
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
    /// The optical-depth errors of mips 0..=MAX_AUTO_LEVEL that chose the `auto` levels.
    pub march_errors: Option<Vec<f64>>,
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
        for (i, frame) in grid.frames.iter().enumerate() {
            let what = format!(
                "{label} > [[medium.frame]] #{} (frame {})",
                i + 1,
                frame.frame
            );
            let density = BrickGrid::load(&frame.density, 1, &what)?;
            grid.check_density_bricks(&density, scale, &what)?;
            let first = &loaded[0].0;
            if (
                density.origin + density.lattice_min,
                density.origin + density.lattice_max,
            ) != (
                first.origin + first.lattice_min,
                first.origin + first.lattice_max,
            ) {
                bail!(
                    "{what}: field `density`: its lattice {} ..= {} differs from the medium's \
                     density {} ..= {}; every frame must have the same resolution and extent",
                    density.origin + density.lattice_min,
                    density.origin + density.lattice_max,
                    first.origin + first.lattice_min,
                    first.origin + first.lattice_max
                );
            }
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
        let dims = (loaded[0].0.lattice_max + 1)
            .to_array()
            .map(|d| d.max(1) as u32);
        let voxel = grid.voxel_size(dims);
        let grids: Vec<&BrickGrid> = loaded.iter().map(|(g, _, _)| g).collect();
        let LevelChoice {
            levels,
            march_errors,
        } = Levels::choose(plan, &grids, s, voxel)?;
        let derived: Vec<DerivedGrids> = loaded
            .into_iter()
            .map(|(g, b, r)| DerivedGrids::build(g, b, r, &levels, plan.sigma_star_floor))
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
            march_errors,
            sizes,
            sigma_t_max,
        })
    }

    /// The base grid's derived volume.
    /// Whether residual ratio tracking with `majorant_scale` x the tight residual majorant
    /// can meet a hot super-voxel span in any density frame.
    pub fn needs_exact_spans(&self, p_to_world: &glam::DMat4, majorant_scale: f32) -> bool {
        self.by_index.values().any(|v| {
            crate::gpu::scene::needs_exact_spans(&v.grids.super_voxels, p_to_world, majorant_scale)
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
    use nimbus_scene::VoxelGrid;

    #[test]
    fn densities_beyond_f16_use_f32_texels() {
        assert_eq!(march_format(65504.0), TexelFormat::R16);
        assert_eq!(march_format(65505.0), TexelFormat::R32);
    }

    fn plan(level: u32) -> RestirPlan {
        RestirPlan {
            max_bounces: 1,
            has_emission: false,
            has_blackbody: false,
            has_albedo_grid: false,
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
            spatial_camera_moves: false,
            spatial_rounds: 1,
            vertex_reuse: false,
            final_ratio_tracking: false,
            mip_candidates: level,
            mip_indirect: Some(level),
            mip_reuse: Some(level),
            pairwise_mis: false,
            spatial_tau_shift: false,
            fold_emission: false,
            spatial_max_history: 0.0,
            nee_split: false,
            direct_each_walk: true,
            history_before_spatial: false,
            sigma_star_floor: 0.0,
            has_shapes: false,
            has_meshes: false,
            has_boxes: false,
            has_convex: false,
            has_area_lights: false,
            has_gobos: false,
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
        let bricks = |g: &VoxelGrid| BrickGrid::from_dense(g).unwrap();
        // Voxels whose diagonal is 0.1.
        let voxel = [0.1 / 3f64.sqrt(); 3];
        let smooth = Levels::choose(&plan(2), &[&bricks(&grid)], 1.0, voxel).unwrap();
        assert_eq!(smooth.march_errors, None);
        assert_eq!(
            smooth.levels,
            Levels {
                candidates: 2,
                indirect: 2,
                reuse: 2
            }
        );
        grid.data[(8 + n * (8 + n * 8)) as usize] = 1e6;
        let hot = Levels::choose(&plan(2), &[&bricks(&grid)], 1.0, voxel).unwrap();
        assert_eq!(
            hot.levels,
            Levels {
                candidates: 0,
                indirect: 0,
                reuse: 0
            }
        );
    }

    /// `auto` keeps the coarsest level that marches the content's transmittance within
    /// MAX_MARCH_ERROR: every allowed level for a smooth ramp, mip 0 for noise at voxel
    /// scale; fixed levels stay as asked.
    #[test]
    fn auto_levels_follow_the_content() {
        let n = 32u32;
        let cells = (n * n * n) as usize;
        let ramp = VoxelGrid {
            dims: [n; 3],
            channels: 1,
            data: (0..cells)
                .map(|i| 0.2 + (i % n as usize) as f32 / n as f32)
                .collect(),
        };
        let mut state = 7u32;
        let noise = VoxelGrid {
            dims: [n; 3],
            channels: 1,
            data: (0..cells)
                .map(|_| {
                    state = state.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
                    (state >> 8) as f32 / (1u32 << 24) as f32
                })
                .collect(),
        };
        let mut auto = plan(1);
        auto.mip_indirect = None;
        auto.mip_reuse = None;
        // Optical depth about 0.1-0.3 per voxel in the noise, half that in the ramp (whose
        // coarsest mips still lose a little at the clamped border).
        let (scale, voxel) = (8.0, [0.03; 3]);
        let smooth = Levels::choose(
            &auto,
            &[&BrickGrid::from_dense(&ramp).unwrap()],
            scale / 2.0,
            voxel,
        )
        .unwrap();
        let errors = smooth.march_errors.clone().unwrap();
        assert_eq!(errors.len() as u32, MAX_AUTO_LEVEL + 1);
        assert!(errors.iter().all(|&e| e <= MAX_MARCH_ERROR), "{errors:?}");
        assert_eq!(
            (smooth.levels.indirect, smooth.levels.reuse),
            (MAX_AUTO_LEVEL, MAX_AUTO_LEVEL)
        );
        let rough = Levels::choose(
            &auto,
            &[&BrickGrid::from_dense(&noise).unwrap()],
            scale,
            voxel,
        )
        .unwrap();
        let errors = rough.march_errors.clone().unwrap();
        assert!(errors[1] > MAX_MARCH_ERROR, "{errors:?}");
        assert_eq!(
            (rough.levels.indirect, rough.levels.reuse),
            (MIN_AUTO_INDIRECT, 0)
        );
        // A fixed level is kept, the other chosen.
        let mut half = auto.clone();
        half.mip_reuse = Some(2);
        let mixed = Levels::choose(
            &half,
            &[&BrickGrid::from_dense(&noise).unwrap()],
            scale,
            voxel,
        )
        .unwrap();
        assert_eq!(
            (mixed.levels.indirect, mixed.levels.reuse),
            (MIN_AUTO_INDIRECT, 2)
        );
    }
}
