//! A grid of a `.vdb` file into the dense window of a `type = "vdb"` medium
//! ([`VdbWindow`]): bricks and tiles scattered into a zeroed [`VoxelGrid`], inactive
//! voxels 0 (the background, which the scene parser requires to be 0).

use std::path::Path;

use anyhow::{bail, Result};
use glam::{DVec3, IVec3};

use super::{read_vdb_grid, VdbGridKind, LEAF_DIM};
use crate::types::VdbWindow;
use crate::volume::VoxelGrid;

/// Reads grid `grid` of `file` (as the scene chose it) and cuts `window` out of it with
/// `channels` channels (1: a scalar grid, 3: a vec3 grid). The caller checks the
/// window's size against the memory guard first. Values outside the window are dropped
/// (the window holds the density's active voxels; emission or velocity beyond them
/// meets no density).
pub(crate) fn load_window(
    file: &Path,
    grid: Option<&str>,
    window: &VdbWindow,
    channels: u32,
    what: &str,
) -> Result<VoxelGrid> {
    let kind = match channels {
        1 => VdbGridKind::Scalar,
        3 => VdbGridKind::Vec3,
        _ => bail!("{what}: OpenVDB grids load with 1 or 3 channels, not {channels}"),
    };
    let sparse = read_vdb_grid(file, grid, kind, what)?;
    let ch = channels as usize;
    if sparse.channels() != ch {
        bail!(
            "{what}: {}: grid \"{}\" has {} channel(s), {ch} expected",
            file.display(),
            sparse.name,
            sparse.channels()
        );
    }
    let dims = window.dims.map(|d| d as usize);
    let mut data = vec![0f32; dims[0] * dims[1] * dims[2] * ch];
    let mut put = |ijk: IVec3, value: &[f32]| {
        let Some(at) = window_index(window, ijk) else {
            return;
        };
        let out = &mut data[at * ch..(at + 1) * ch];
        if ch == 3 {
            let v = window.vector_map
                * DVec3::new(
                    f64::from(value[0]),
                    f64::from(value[1]),
                    f64::from(value[2]),
                );
            out.copy_from_slice(&v.as_vec3().to_array());
        } else {
            out[0] = value[0];
        }
    };
    for (b, origin) in sparse.brick_origins.iter().enumerate() {
        let values = sparse.brick(b);
        for z in 0..LEAF_DIM {
            for y in 0..LEAF_DIM {
                for x in 0..LEAF_DIM {
                    if !sparse.brick_voxel_active(b, x, y, z) {
                        continue;
                    }
                    let at = super::SparseGrid::brick_voxel_index(x, y, z) * ch;
                    put(*origin + IVec3::new(x, y, z), &values[at..at + ch]);
                }
            }
        }
    }
    // Tiles: only the part inside the window (a root tile is 4096³ voxels).
    let lo = window.origin;
    let hi = lo + IVec3::from_array(window.dims.map(|d| d as i32)) - 1;
    for tile in &sparse.tiles {
        let t_lo = tile.origin.max(lo);
        let t_hi = (tile.origin + IVec3::splat(tile.edge as i32 - 1)).min(hi);
        for k in t_lo.z..=t_hi.z {
            for j in t_lo.y..=t_hi.y {
                for i in t_lo.x..=t_hi.x {
                    put(IVec3::new(i, j, k), &tile.value[..ch]);
                }
            }
        }
    }
    Ok(VoxelGrid {
        dims: window.dims,
        channels,
        data,
    })
}

/// The dense voxel (x fastest) holding the grid's voxel `ijk`, if the window has it.
fn window_index(window: &VdbWindow, ijk: IVec3) -> Option<usize> {
    let mut d = [0usize; 3];
    for a in 0..3 {
        let n = i64::from(window.dims[a]);
        let mut offset = i64::from(ijk[a]) - i64::from(window.origin[a]);
        if !(0..n).contains(&offset) {
            return None;
        }
        if window.flip[a] {
            offset = n - 1 - offset;
        }
        d[a] = offset as usize;
    }
    let [nx, ny, _] = window.dims.map(|d| d as usize);
    Some((d[2] * ny + d[1]) * nx + d[0])
}
