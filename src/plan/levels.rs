//! The mip levels ReSTIR tracks and marches a grid on, chosen from the grid's content:
//! the conservative piecewise-constant levels of candidate generation and the ray-march
//! mips of the target functions.

use std::collections::HashMap;
use std::sync::{Mutex, OnceLock};

use anyhow::{bail, Result};
use nimbus_scene::bricks::{march_errors, MARCH_ERROR_SEGMENTS};
use nimbus_scene::precision::PositionScale;
use nimbus_scene::{BrickGrid, BrickTopology, GridMedium, GridSource, Scene};

use crate::budget::{brick_bytes, host_budget};

/// The mip levels the passes use for a grid: the conservative piecewise-constant levels
/// of candidate generation (camera and scattered rays) and the ray-march mips of the
/// target functions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Levels {
    pub candidates: u32,
    pub indirect: u32,
    pub reuse: u32,
}

/// The levels a scene asks for (`[integrator.restir] mip_candidates`, `mip_indirect`,
/// `mip_reuse`; `None`: `"auto"`, chosen from the content).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AskedLevels {
    pub candidates: u32,
    pub indirect: Option<u32>,
    pub reuse: Option<u32>,
    /// The march errors are wanted whatever the levels (`candidate_tracking = "auto"`
    /// reads the candidates' level's: [`CANDIDATE_DELTA_MARCH_ERROR`]).
    pub errors: bool,
}

/// `candidate_tracking = "auto"` takes delta tracking where the candidates' level
/// (`mip_candidates`) marches the optical depth with a larger error than this
/// ([`march_errors`]): there regular tracking through that coarse level weighs its
/// candidates by a heavy-tailed (σ_s/σ*)(T/T*). Measured on lavapipe (docs/restir.md,
/// "Candidates by delta tracking"): perf-cloud (0.187 at mip 1) gained 1.09-1.17x in
/// efficiency with delta tracking; the benchmark cumulus and the explosions (0.030-0.037)
/// lost 6-15 % under temporal reuse.
pub const CANDIDATE_DELTA_MARCH_ERROR: f64 = 0.1;

impl AskedLevels {
    /// The levels `settings` ask for.
    pub fn of(settings: &nimbus_scene::RestirSettings) -> AskedLevels {
        AskedLevels {
            candidates: settings.mip_candidates,
            indirect: settings.mip_indirect,
            reuse: settings.mip_reuse,
            errors: settings.candidate_tracking == nimbus_scene::CandidateTracking::Auto,
        }
    }
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

/// The level choices this process made, by a hash of the grid medium (with its files'
/// sizes and modification times), the asked levels and the position scale.
static CHOSEN: OnceLock<Mutex<HashMap<u64, LevelChoice>>> = OnceLock::new();

/// The densities the last level choice loaded, for the pass that renders the plan to take
/// instead of reading them again ([`take_density`], [`take_frames`]); the renderer
/// drops what is left once its passes exist ([`forget_loaded`]), so nothing outlives
/// the render it was loaded for.
static LOADED: Mutex<Option<Loaded>> = Mutex::new(None);

struct Loaded {
    /// [`loaded_key`] of the grid medium they are.
    key: u64,
    density: Option<BrickGrid>,
    frames: Option<Vec<BrickGrid>>,
}

/// What identifies a medium's loaded densities: its sources and the position scale they
/// were checked against.
fn loaded_key(grid: &GridMedium, scale: &PositionScale) -> u64 {
    let key = format!("{:?}", (grid, scale, file_stamps(grid)));
    crate::hashing::fnv1a64(crate::hashing::FNV_OFFSET, key.as_bytes())
}

/// The size and modification time of every density file of `grid` (base and frames),
/// so that a file rewritten between two plans in one process is read again.
fn file_stamps(grid: &GridMedium) -> Vec<Option<(u64, std::time::SystemTime)>> {
    std::iter::once(&grid.density)
        .chain(grid.frames.iter().map(|f| &f.density))
        .map(|source| match source {
            GridSource::Raw { file, .. }
            | GridSource::MitsubaVol { file }
            | GridSource::Vdb { file, .. } => std::fs::metadata(file)
                .ok()
                .and_then(|m| Some((m.len(), m.modified().ok()?))),
            GridSource::ProceduralCloud { .. } => None,
        })
        .collect()
}

/// `grid`'s base density as the plan loaded and checked it (`BrickGrid::load` of its
/// `density` with one channel, then `check_density_bricks` at `scale`), if the plan
/// loaded this medium and nothing took it yet.
pub fn take_density(grid: &GridMedium, scale: &PositionScale) -> Option<BrickGrid> {
    let key = loaded_key(grid, scale);
    let mut slot = LOADED.lock().ok()?;
    slot.as_mut()
        .filter(|l| l.key == key)
        .and_then(|l| l.density.take())
}

/// `grid`'s `[[medium.frame]]` densities as [`load_frames`] gave them to the plan, if
/// the plan loaded this medium and nothing took them yet.
pub fn take_frames(grid: &GridMedium, scale: &PositionScale) -> Option<Vec<BrickGrid>> {
    let key = loaded_key(grid, scale);
    let mut slot = LOADED.lock().ok()?;
    slot.as_mut()
        .filter(|l| l.key == key)
        .and_then(|l| l.frames.take())
}

/// Drops the densities no pass took.
pub fn forget_loaded() {
    if let Ok(mut slot) = LOADED.lock() {
        *slot = None;
    }
}

/// Refuses, before any of it is read, a density whose bricks (every frame's, all held at
/// once while the levels are chosen) exceed the host memory budget: the renderer checks
/// the whole render's footprint only after the plan is built.
fn check_host_memory(grid: &GridMedium, what: &str) -> Result<()> {
    let mut bytes = brick_bytes(&BrickTopology::of(&grid.density, 1, what)?);
    for (i, frame) in grid.frames.iter().enumerate() {
        let what = format!("{what} > [[medium.frame]] #{}", i + 1);
        bytes = bytes.saturating_add(brick_bytes(&BrickTopology::of(&frame.density, 1, &what)?));
    }
    let budget = host_budget()?;
    if bytes > budget {
        bail!(
            "{what}: choosing ReSTIR's mip levels holds the density's bricks (every frame's) \
             in host memory, about {:.1} MiB; the host memory budget is {:.1} MiB (set \
             NIMBUS_HOST_MEMORY_BUDGET in MiB to change it)",
            bytes as f64 / 1048576.0,
            budget as f64 / 1048576.0
        );
    }
    Ok(())
}

/// The levels the passes use and, when some were chosen from the content, the measured
/// optical-depth errors of mips 0..=[`MAX_AUTO_LEVEL`] that chose them.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelChoice {
    pub levels: Levels,
    pub march_errors: Option<Vec<f64>>,
}

impl Levels {
    /// The `asked` levels (`auto` ones: the coarsest of mips 0..=[`MAX_AUTO_LEVEL`] whose
    /// marched optical depth stays within [`MAX_MARCH_ERROR`] on the first grid, `voxel`
    /// its world voxel size), each lowered to the coarsest level at or below it whose
    /// blocks stay within [`MAX_LEVEL_EXCESS_TAU`] in every grid of the animation.
    pub fn choose(
        asked: AskedLevels,
        grids: &[&BrickGrid],
        scale: f32,
        voxel: [f64; 3],
    ) -> Result<LevelChoice> {
        let voxel_diagonal =
            (voxel[0] * voxel[0] + voxel[1] * voxel[1] + voxel[2] * voxel[2]).sqrt() as f32;
        let auto = asked.indirect.is_none() || asked.reuse.is_none() || asked.errors;
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
        let indirect = asked.indirect.unwrap_or(auto_level.max(MIN_AUTO_INDIRECT));
        let reuse = asked.reuse.unwrap_or(auto_level);
        let requested = asked.candidates.max(indirect).max(reuse);
        let mut allowed = requested;
        for g in grids {
            allowed = allowed.min(allowed_level(g, scale, voxel_diagonal, requested)?);
        }
        Ok(LevelChoice {
            levels: Levels {
                candidates: asked.candidates.min(allowed),
                indirect: indirect.min(allowed),
                reuse: reuse.min(allowed),
            },
            march_errors,
        })
    }
}

impl LevelChoice {
    /// The levels ReSTIR uses for the grid medium `grid` (`[[medium]]` #`index` of
    /// `scene`): every density grid of its animation loaded into bricks (checked as the
    /// passes check them) and the `asked` levels [`Levels::choose`]n on them.
    pub fn of(
        scene: &Scene,
        index: usize,
        grid: &GridMedium,
        asked: AskedLevels,
    ) -> Result<LevelChoice> {
        // The same grid, frames and asks choose the same levels: a study plans every
        // configuration, and each would otherwise load every density frame again.
        let key = format!(
            "{:?}",
            (grid, asked, scene.position_scale(), file_stamps(grid))
        );
        let key = crate::hashing::fnv1a64(crate::hashing::FNV_OFFSET, key.as_bytes());
        let chosen = CHOSEN.get_or_init(Default::default);
        if let Some(choice) = chosen.lock().ok().and_then(|c| c.get(&key).cloned()) {
            return Ok(choice);
        }
        let label = format!("{}: [[medium]] #{}", scene.source.display(), index + 1);
        let what = format!("{label} > density");
        let scale = scene.position_scale();
        check_host_memory(grid, &what)?;
        let density = BrickGrid::load(&grid.density, 1, &what)?;
        grid.check_density_bricks(&density, &scale, &what)?;
        let frames = load_frames(grid, &density, &scale, &label)?;
        let dims = (density.lattice_max + 1)
            .to_array()
            .map(|d| d.max(1) as u32);
        let voxel = grid.voxel_size(dims);
        let grids: Vec<&BrickGrid> = std::iter::once(&density).chain(&frames).collect();
        let choice = Levels::choose(asked, &grids, grid.density_scale, voxel)?;
        if let Ok(mut c) = chosen.lock() {
            c.insert(key, choice.clone());
        }
        if let Ok(mut slot) = LOADED.lock() {
            *slot = Some(Loaded {
                key: loaded_key(grid, &scale),
                density: Some(density),
                frames: Some(frames),
            });
        }
        Ok(choice)
    }

    /// What `--explain` says of how the levels were chosen: the measured errors that
    /// chose the `auto` ones, and the levels refined below what was `asked`.
    pub fn reasons(&self, asked: AskedLevels) -> Vec<String> {
        let l = self.levels;
        let mut reasons = Vec::new();
        let chose = asked.indirect.is_none() || asked.reuse.is_none();
        if let (Some(errors), true) = (&self.march_errors, chose) {
            let list: Vec<String> = errors.iter().map(|e| format!("{e:.3}")).collect();
            reasons.push(format!(
                "ReSTIR chose mip {} (scattered segments) and {} (reuse targets) from the \
                 volume's content: marched optical depth errors {} at mips 0..{} \
                 (transmittance-weighted RMS), the coarsest within {}",
                l.indirect,
                l.reuse,
                list.join(" / "),
                errors.len().saturating_sub(1),
                MAX_MARCH_ERROR
            ));
        }
        let asked = (
            asked.candidates,
            asked.indirect.unwrap_or(l.indirect),
            asked.reuse.unwrap_or(l.reuse),
        );
        if (l.candidates, l.indirect, l.reuse) != asked {
            reasons.push(format!(
                "ReSTIR used mip levels {}/{}/{} (candidates/indirect/reuse) instead of {}/{}/{}: \
                 coarser levels would spread the grid's sharpest density steps over more than \
                 {} optical depths and stop sampling paths that contribute",
                l.candidates, l.indirect, l.reuse, asked.0, asked.1, asked.2, MAX_LEVEL_EXCESS_TAU
            ));
        }
        reasons
    }
}

/// The densities of `grid`'s `[[medium.frame]]`s loaded into bricks, each checked and
/// checked to share the lattice of `first`, the base density. `label` names the medium.
pub fn load_frames(
    grid: &GridMedium,
    first: &BrickGrid,
    scale: &PositionScale,
    label: &str,
) -> Result<Vec<BrickGrid>> {
    let mut frames = Vec::with_capacity(grid.frames.len());
    for (i, frame) in grid.frames.iter().enumerate() {
        let what = format!(
            "{label} > [[medium.frame]] #{} (frame {})",
            i + 1,
            frame.frame
        );
        let density = BrickGrid::load(&frame.density, 1, &what)?;
        grid.check_density_bricks(&density, scale, &what)?;
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
        frames.push(density);
    }
    Ok(frames)
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

#[cfg(test)]
mod tests {
    use super::*;
    use nimbus_scene::VoxelGrid;

    /// Every level fixed at `level`.
    fn asked(level: u32) -> AskedLevels {
        AskedLevels {
            candidates: level,
            indirect: Some(level),
            reuse: Some(level),
            errors: false,
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
        let smooth = Levels::choose(asked(2), &[&bricks(&grid)], 1.0, voxel).unwrap();
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
        let hot = Levels::choose(asked(2), &[&bricks(&grid)], 1.0, voxel).unwrap();
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
        let auto = AskedLevels {
            indirect: None,
            reuse: None,
            ..asked(1)
        };
        // Optical depth about 0.1-0.3 per voxel in the noise, half that in the ramp (whose
        // coarsest mips still lose a little at the clamped border).
        let (scale, voxel) = (8.0, [0.03; 3]);
        let smooth = Levels::choose(
            auto,
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
            auto,
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
        let half = AskedLevels {
            reuse: Some(2),
            ..auto
        };
        let mixed = Levels::choose(
            half,
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
