//! Loading any grid source of a scene into bricks, streamed: raw and `.vol` files 8
//! layers at a time, the procedural cloud brick by brick, OpenVDB files leaf by leaf.
//! No dense copy of a grid is ever made.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};

use anyhow::{bail, Context, Result};

use super::{BrickGrid, BrickTopology};
use crate::files::{read_vol_header, VolEncoding, VOL_HEADER_BYTES};
use crate::types::GridSource;
use crate::vdb::{read_vdb_grid, read_vdb_topology, VdbGridKind};
use crate::volume::{check_grid_memory, check_raw_file};

/// A dense grid file: raw float32, or a `.vol` file's values after its header.
struct DenseFile {
    path: std::path::PathBuf,
    dims: [u32; 3],
    /// Values per voxel in the file.
    channels: u32,
    /// Byte where the values start.
    offset: u64,
    encoding: VolEncoding,
}

/// A reader of z-slabs of a dense grid file.
struct SlabReader {
    reader: BufReader<File>,
    offset: u64,
    /// Bytes per z-layer.
    layer: u64,
    encoding: VolEncoding,
    bytes: Vec<u8>,
    path: std::path::PathBuf,
}

impl SlabReader {
    fn open(f: &DenseFile) -> Result<SlabReader> {
        let file =
            File::open(&f.path).with_context(|| format!("cannot open {}", f.path.display()))?;
        Ok(SlabReader {
            reader: BufReader::with_capacity(1 << 20, file),
            offset: f.offset,
            layer: u64::from(f.dims[0])
                * u64::from(f.dims[1])
                * u64::from(f.channels)
                * f.encoding.bytes(),
            encoding: f.encoding,
            bytes: Vec::new(),
            path: f.path.clone(),
        })
    }

    fn fill(&mut self, z0: u32, layers: u32, out: &mut [f32]) -> Result<()> {
        let start = self.offset + u64::from(z0) * self.layer;
        self.reader
            .seek(SeekFrom::Start(start))
            .with_context(|| format!("cannot seek in {}", self.path.display()))?;
        self.bytes
            .resize(out.len() * self.encoding.bytes() as usize, 0);
        self.reader.read_exact(&mut self.bytes).with_context(|| {
            format!(
                "{}: file ended within z layers {z0}..{}",
                self.path.display(),
                z0 + layers
            )
        })?;
        self.encoding.decode(&self.bytes, out);
        Ok(())
    }
}

/// The dims, channels, data offset and encoding of a raw or `.vol` source, checked
/// against the file. `channels` as for [`BrickGrid::load`]: 0 takes a `.vol` file of 1 or
/// 3 channels (raw files are then scalar).
fn dense_file(source: &GridSource, channels: u32, what: &str) -> Result<Option<DenseFile>> {
    Ok(match source {
        GridSource::Raw { file, dims } => {
            let channels = channels.max(1);
            check_raw_file(file, *dims, channels, what)?;
            Some(DenseFile {
                path: file.clone(),
                dims: *dims,
                channels,
                offset: 0,
                encoding: VolEncoding::F32,
            })
        }
        GridSource::MitsubaVol { file } => {
            let header = read_vol_header(file).with_context(|| what.to_string())?;
            let fits = match channels {
                0 => header.channels == 1 || header.channels == 3,
                c => header.channels == c,
            };
            if !fits {
                let expected = match channels {
                    0 => "1 or 3".to_string(),
                    c => c.to_string(),
                };
                bail!(
                    "{what}: {}: .vol file has {} channel(s), expected {expected}",
                    file.display(),
                    header.channels
                );
            }
            check_grid_memory(header.dims, header.channels, what)
                .with_context(|| format!("{what}: {}", file.display()))?;
            Some(DenseFile {
                path: file.clone(),
                dims: header.dims,
                channels: header.channels,
                offset: VOL_HEADER_BYTES,
                encoding: header.encoding,
            })
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
    /// any sign), 0 for an emission grid that may be scalar or rgb (OpenVDB vec3 grids and
    /// 3-channel `.vol` files; raw files and procedural clouds are scalar). `what` names the grid in messages, e.g.
    /// `"scenes/a.toml: [[medium]] #2 > density"`; errors name the file and the voxel
    /// (and for OpenVDB the grid). The memory guard of dense files
    /// ([`check_grid_memory`]) runs before anything is read.
    pub fn load(source: &GridSource, channels: u32, what: &str) -> Result<BrickGrid> {
        let scalar = channels != 3;
        if let Some(f) = dense_file(source, channels, what)? {
            let mut reader = SlabReader::open(&f).with_context(|| what.to_string())?;
            let name = f.path.display().to_string();
            return BrickGrid::from_slabs(f.dims, f.channels, &name, scalar, |z0, layers, out| {
                reader.fill(z0, layers, out)
            })
            .with_context(|| what.to_string());
        }
        match source {
            GridSource::ProceduralCloud {
                dims,
                noise_seed,
                kind,
            } => {
                if channels == 3 {
                    bail!("{what}: a procedural cloud has 1 channel, 3 were expected");
                }
                check_grid_memory(*dims, 1, what)?;
                BrickGrid::procedural(*dims, *noise_seed, *kind).with_context(|| what.to_string())
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
        if let Some(f) = dense_file(source, channels, what)? {
            let mut reader = SlabReader::open(&f).with_context(|| what.to_string())?;
            return BrickTopology::scan_slabs(f.dims, f.channels, |z0, layers, out| {
                reader.fill(z0, layers, out)
            })
            .with_context(|| what.to_string());
        }
        match source {
            GridSource::ProceduralCloud {
                dims,
                noise_seed,
                kind,
            } => Ok(BrickTopology::procedural(*dims, *noise_seed, *kind)),
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
