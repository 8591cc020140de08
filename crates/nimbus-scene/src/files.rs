//! Checks on the files a scene names: existence, raw grid sizes, Mitsuba `.vol`
//! headers.

use std::fs::File;
use std::io::Read;
use std::path::Path;

use anyhow::{bail, Context, Result};
use glam::Vec3;

/// Bytes in a Mitsuba `.vol` header.
pub const VOL_HEADER_BYTES: u64 = 48;

/// Most voxels along one axis of a grid.
pub const MAX_GRID_DIM: u32 = 4096;

/// Most voxels in one grid (2^31).
pub const MAX_GRID_VOXELS: u64 = 1 << 31;

/// How a Mitsuba `.vol` file stores its values (the header's encoding identifier, as
/// Mitsuba 0.6's `gridvolume` defines it; Mitsuba 3 writes float32).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VolEncoding {
    /// 1: little-endian float32.
    F32,
    /// 2: little-endian IEEE half floats.
    F16,
    /// 3: bytes, 0..255 mapped to 0..1.
    U8,
}

impl VolEncoding {
    /// Bytes per value.
    pub fn bytes(self) -> u64 {
        match self {
            VolEncoding::F32 => 4,
            VolEncoding::F16 => 2,
            VolEncoding::U8 => 1,
        }
    }

    /// Decodes `bytes` (`out.len()` values of this encoding) into `out`.
    pub fn decode(self, bytes: &[u8], out: &mut [f32]) {
        match self {
            VolEncoding::F32 => {
                for (v, b) in out.iter_mut().zip(bytes.chunks_exact(4)) {
                    *v = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                }
            }
            VolEncoding::F16 => {
                for (v, b) in out.iter_mut().zip(bytes.chunks_exact(2)) {
                    *v = half::f16::from_le_bytes([b[0], b[1]]).to_f32();
                }
            }
            VolEncoding::U8 => {
                for (v, &b) in out.iter_mut().zip(bytes) {
                    *v = f32::from(b) / 255.0;
                }
            }
        }
    }

    /// The name a message gives the encoding.
    pub fn name(self) -> &'static str {
        match self {
            VolEncoding::F32 => "float32",
            VolEncoding::F16 => "float16",
            VolEncoding::U8 => "uint8",
        }
    }
}

/// The header of a Mitsuba `.vol` grid file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolHeader {
    /// Voxels along x, y, z.
    pub dims: [u32; 3],
    /// Values per voxel.
    pub channels: u32,
    /// How the values are stored.
    pub encoding: VolEncoding,
    /// The bounding box stored in the file (the scene's `bounds_min` / `bounds_max`
    /// take precedence).
    pub bbox_min: Vec3,
    pub bbox_max: Vec3,
}

impl VolHeader {
    /// Number of voxels.
    pub fn voxel_count(&self) -> u64 {
        self.dims.iter().map(|&d| u64::from(d)).product()
    }

    /// The file size this header implies: header plus the values.
    pub fn expected_file_bytes(&self) -> u64 {
        VOL_HEADER_BYTES + self.voxel_count() * u64::from(self.channels) * self.encoding.bytes()
    }
}

/// Checks grid dimensions: each in 1..=[`MAX_GRID_DIM`], product <= [`MAX_GRID_VOXELS`].
pub fn check_grid_dims(dims: [i64; 3]) -> std::result::Result<[u32; 3], String> {
    let mut out = [0u32; 3];
    for (axis, &d) in dims.iter().enumerate() {
        if !(1..=i64::from(MAX_GRID_DIM)).contains(&d) {
            return Err(format!(
                "component {axis} is {d}, each dimension must be in [1, {MAX_GRID_DIM}]"
            ));
        }
        out[axis] = d as u32;
    }
    let voxels: u64 = out.iter().map(|&d| u64::from(d)).product();
    if voxels > MAX_GRID_VOXELS {
        return Err(format!(
            "{} x {} x {} = {voxels} voxels, at most {MAX_GRID_VOXELS} are allowed",
            out[0], out[1], out[2]
        ));
    }
    Ok(out)
}

/// The size of the regular file at `path`, or an error saying it is missing.
pub fn file_size(path: &Path) -> std::result::Result<u64, String> {
    match std::fs::metadata(path) {
        Ok(meta) if meta.is_file() => Ok(meta.len()),
        Ok(_) => Err(format!("{} is not a regular file", path.display())),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            Err(format!("file not found: {}", path.display()))
        }
        Err(e) => Err(format!("cannot access {}: {e}", path.display())),
    }
}

/// Reads and checks the header of the Mitsuba `.vol` file at `path`: magic `VOL`,
/// version 3, float32 encoding, sane dims, and a file size matching the header.
pub fn read_vol_header(path: &Path) -> Result<VolHeader> {
    let size = file_size(path).map_err(anyhow::Error::msg)?;
    if size < VOL_HEADER_BYTES {
        bail!(
            "{}: {size} bytes is too short for a .vol header ({VOL_HEADER_BYTES} bytes)",
            path.display()
        );
    }
    let mut bytes = [0u8; VOL_HEADER_BYTES as usize];
    File::open(path)
        .and_then(|mut f| f.read_exact(&mut bytes))
        .with_context(|| format!("cannot read {}", path.display()))?;
    if &bytes[0..3] != b"VOL" {
        bail!(
            "{}: bad magic {:?}, a .vol file starts with \"VOL\"",
            path.display(),
            String::from_utf8_lossy(&bytes[0..3])
        );
    }
    if bytes[3] != 3 {
        bail!(
            "{}: .vol version {} is not supported (only 3)",
            path.display(),
            bytes[3]
        );
    }
    let int_at = |offset: usize| {
        i32::from_le_bytes([
            bytes[offset],
            bytes[offset + 1],
            bytes[offset + 2],
            bytes[offset + 3],
        ])
    };
    let float_at = |offset: usize| f32::from_bits(int_at(offset) as u32);
    let encoding = match int_at(4) {
        1 => VolEncoding::F32,
        2 => VolEncoding::F16,
        3 => VolEncoding::U8,
        4 => bail!(
            "{}: .vol encoding 4 (quantized directions) is not a grid of values: \
             1 (float32), 2 (float16) or 3 (uint8) are read",
            path.display()
        ),
        other => bail!(
            "{}: .vol encoding {other} is not supported: 1 (float32), 2 (float16) or \
             3 (uint8) are read",
            path.display()
        ),
    };
    let dims = check_grid_dims([8, 12, 16].map(|offset| i64::from(int_at(offset))))
        .map_err(|message| anyhow::anyhow!("{}: .vol header dims: {message}", path.display()))?;
    let channels = int_at(20);
    let channels = u32::try_from(channels)
        .ok()
        .filter(|&c| c >= 1)
        .ok_or_else(|| {
            anyhow::anyhow!("{}: .vol header has {channels} channels", path.display())
        })?;
    let header = VolHeader {
        dims,
        channels,
        encoding,
        bbox_min: Vec3::new(float_at(24), float_at(28), float_at(32)),
        bbox_max: Vec3::new(float_at(36), float_at(40), float_at(44)),
    };
    let expected = header.expected_file_bytes();
    if size != expected {
        bail!(
            "{}: expected {expected} bytes (48-byte header + {} x {} x {} voxels x {channels} \
             channels x {} bytes of {}), found {size} bytes",
            path.display(),
            dims[0],
            dims[1],
            dims[2],
            encoding.bytes(),
            encoding.name()
        );
    }
    Ok(header)
}
