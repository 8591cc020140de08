//! Writing Mitsuba `.vol` grid files (the format `load_grid` reads), for asset tools.

use std::io::Write;
use std::path::Path;

use anyhow::{Context, Result};
use glam::Vec3;

use crate::{VolEncoding, VoxelGrid};

/// Write `grid` as a Mitsuba `.vol` file: magic `VOL`, version 3, encoding 1 (float32),
/// dims, channels, the bounding box `bbox_min..bbox_max`, then the float32 values in
/// the grid's order (x fastest, channels interleaved), all little-endian.
pub fn write_vol(path: &Path, grid: &VoxelGrid, bbox_min: Vec3, bbox_max: Vec3) -> Result<()> {
    write_vol_encoded(path, grid, bbox_min, bbox_max, VolEncoding::F32)
}

/// [`write_vol`] with the values in `encoding` (float16 rounds to nearest; uint8 stores
/// round(255 · v) clamped to 0..255).
pub fn write_vol_encoded(
    path: &Path,
    grid: &VoxelGrid,
    bbox_min: Vec3,
    bbox_max: Vec3,
    encoding: VolEncoding,
) -> Result<()> {
    let mut bytes = Vec::with_capacity(48 + grid.data.len() * encoding.bytes() as usize);
    bytes.extend_from_slice(b"VOL");
    bytes.push(3);
    let id: i32 = match encoding {
        VolEncoding::F32 => 1,
        VolEncoding::F16 => 2,
        VolEncoding::U8 => 3,
    };
    bytes.extend_from_slice(&id.to_le_bytes());
    for n in grid.dims {
        bytes.extend_from_slice(&(n as i32).to_le_bytes());
    }
    bytes.extend_from_slice(&(grid.channels as i32).to_le_bytes());
    for v in [
        bbox_min.x, bbox_min.y, bbox_min.z, bbox_max.x, bbox_max.y, bbox_max.z,
    ] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    for &v in &grid.data {
        match encoding {
            VolEncoding::F32 => bytes.extend_from_slice(&v.to_le_bytes()),
            VolEncoding::F16 => bytes.extend_from_slice(&half::f16::from_f32(v).to_le_bytes()),
            VolEncoding::U8 => bytes.push((v * 255.0).round().clamp(0.0, 255.0) as u8),
        }
    }
    std::fs::File::create(path)
        .and_then(|mut f| f.write_all(&bytes))
        .with_context(|| format!("cannot write {}", path.display()))
}
