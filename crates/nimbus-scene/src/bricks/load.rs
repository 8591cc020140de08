//! Loading any grid source of a scene into bricks, streamed: raw and `.vol` files 8
//! layers at a time, the procedural cloud brick by brick, OpenVDB files leaf by leaf.
//! No dense copy of a grid is ever made.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};

use super::{BrickGrid, BrickTopology};
use crate::files::{file_size, read_vol_header, VOL_HEADER_BYTES};
use crate::types::GridSource;
use crate::vdb::{read_vdb_grid, read_vdb_topology, VdbGridKind};
use crate::volume::check_grid_memory;

/// A reader of z-slabs of a float32 grid file whose data starts at byte `offset`.
struct SlabReader {
    reader: BufReader<File>,
    offset: u64,
    /// Bytes per z-layer.
    layer: u64,
    bytes: Vec<u8>,
    path: std::path::PathBuf,
}

impl SlabReader {
    fn open(path: &Path, offset: u64, dims: [u32; 3], channels: u32) -> Result<SlabReader> {
        let file = File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
        Ok(SlabReader {
            reader: BufReader::with_capacity(1 << 20, file),
            offset,
            layer: u64::from(dims[0]) * u64::from(dims[1]) * u64::from(channels) * 4,
            bytes: Vec::new(),
            path: path.to_path_buf(),
        })
    }

    fn fill(&mut self, z0: u32, layers: u32, out: &mut [f32]) -> Result<()> {
        let start = self.offset + u64::from(z0) * self.layer;
        self.reader
            .seek(SeekFrom::Start(start))
            .with_context(|| format!("cannot seek in {}", self.path.display()))?;
        self.bytes.resize(out.len() * 4, 0);
        self.reader.read_exact(&mut self.bytes).with_context(|| {
            format!(
                "{}: file ended within z layers {z0}..{}",
                self.path.display(),
                z0 + layers
            )
        })?;
        for (v, b) in out.iter_mut().zip(self.bytes.chunks_exact(4)) {
            *v = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        }
        Ok(())
    }
}

/// The dims, data offset and file of a raw or `.vol` source, checked against the file.
fn dense_file(
    source: &GridSource,
    channels: u32,
    what: &str,
) -> Result<Option<(std::path::PathBuf, [u32; 3], u64)>> {
    Ok(match source {
        GridSource::Raw { file, dims } => {
            let values = check_grid_memory(*dims, channels, what)?;
            let size = file_size(file).map_err(|m| anyhow!("{what}: {m}"))?;
            let expected = values as u64 * 4;
            if size != expected {
                bail!(
                    "{what}: {}: expected {expected} bytes ({} x {} x {} voxels x {channels} \
                     channel(s) x 4 bytes of float32), found {size} bytes",
                    file.display(),
                    dims[0],
                    dims[1],
                    dims[2]
                );
            }
            Some((file.clone(), *dims, 0))
        }
        GridSource::MitsubaVol { file } => {
            let header = read_vol_header(file).with_context(|| what.to_string())?;
            if header.channels != channels {
                bail!(
                    "{what}: {}: .vol file has {} channel(s), expected {channels}",
                    file.display(),
                    header.channels
                );
            }
            check_grid_memory(header.dims, channels, what)
                .with_context(|| format!("{what}: {}", file.display()))?;
            Some((file.clone(), header.dims, VOL_HEADER_BYTES))
        }
        _ => None,
    })
}

/// The OpenVDB grid kind a use with `channels` reads (0: scalar or vec3).
fn vdb_kind(channels: u32) -> VdbGridKind {
    match channels {
        1 => VdbGridKind::Scalar,
        3 => VdbGridKind::Vec3,
        _ => VdbGridKind::Any,
    }
}

impl BrickGrid {
    /// Loads a grid into bricks. `channels` says what it holds: 1 for a scalar grid
    /// (density or emission: every value finite and ≥ 0), 3 for a velocity grid (finite,
    /// any sign), 0 for an emission grid that may be scalar or vec3 (OpenVDB only; other
    /// sources are scalar). `what` names the grid in messages, e.g.
    /// `"scenes/a.toml: [[medium]] #2 > density"`; errors name the file and the voxel
    /// (and for OpenVDB the grid). The memory guard of dense files
    /// ([`check_grid_memory`]) runs before anything is read.
    pub fn load(source: &GridSource, channels: u32, what: &str) -> Result<BrickGrid> {
        let scalar = channels != 3;
        if let Some((file, dims, offset)) = dense_file(source, channels.max(1), what)? {
            let ch = channels.max(1);
            let mut reader =
                SlabReader::open(&file, offset, dims, ch).with_context(|| what.to_string())?;
            let name = file.display().to_string();
            return BrickGrid::from_slabs(dims, ch, &name, scalar, |z0, layers, out| {
                reader.fill(z0, layers, out)
            })
            .with_context(|| what.to_string());
        }
        match source {
            GridSource::ProceduralCloud { dims, noise_seed } => {
                if channels == 3 {
                    bail!("{what}: a procedural cloud has 1 channel, 3 were expected");
                }
                check_grid_memory(*dims, 1, what)?;
                BrickGrid::procedural_cloud(*dims, *noise_seed).with_context(|| what.to_string())
            }
            GridSource::Vdb { file, grid, .. } => {
                let sparse = read_vdb_grid(file, grid.as_deref(), vdb_kind(channels), what)?;
                BrickGrid::from_vdb(sparse, what, scalar)
            }
            GridSource::Raw { .. } | GridSource::MitsubaVol { .. } => {
                bail!("internal: {what}: dense file not handled")
            }
        }
    }
}

impl BrickTopology {
    /// The bricks [`BrickGrid::load`] will store for `source` (an upper bound for the
    /// procedural cloud: the bricks its envelope may reach), without keeping any values:
    /// dense files are scanned slab by slab, OpenVDB files read up to their topology.
    pub fn of(source: &GridSource, channels: u32, what: &str) -> Result<BrickTopology> {
        if let Some((file, dims, offset)) = dense_file(source, channels.max(1), what)? {
            let ch = channels.max(1);
            let mut reader =
                SlabReader::open(&file, offset, dims, ch).with_context(|| what.to_string())?;
            return BrickTopology::scan_slabs(dims, ch, |z0, layers, out| {
                reader.fill(z0, layers, out)
            })
            .with_context(|| what.to_string());
        }
        match source {
            GridSource::ProceduralCloud { dims, .. } => Ok(BrickTopology::procedural_cloud(*dims)),
            GridSource::Vdb { file, grid, .. } => {
                let header = read_vdb_topology(file, grid.as_deref(), vdb_kind(channels), what)?;
                let name = format!("{what}: {}: grid \"{}\"", file.display(), header.name);
                let Some((bmin, bmax)) = header.topology.active_bbox else {
                    bail!("{name}: the grid has no active voxels");
                };
                let ch = header.value_type.channels() as u32;
                let topo = BrickTopology::vdb(bmin, bmax, ch, Vec::new());
                let mut bricks: Vec<glam::IVec3> = header
                    .topology
                    .leaf_origins
                    .iter()
                    .map(|o| super::shr(*o - topo.origin, 3))
                    .collect();
                for t in &header.topology.tiles {
                    let n = (t.edge / 8) as i32;
                    let first = super::shr(t.origin - topo.origin, 3);
                    for z in 0..n {
                        for y in 0..n {
                            for x in 0..n {
                                bricks.push(first + glam::IVec3::new(x, y, z));
                            }
                        }
                    }
                }
                Ok(BrickTopology { bricks, ..topo })
            }
            GridSource::Raw { .. } | GridSource::MitsubaVol { .. } => {
                bail!("internal: {what}: dense file not handled")
            }
        }
    }
}
