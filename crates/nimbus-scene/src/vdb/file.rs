//! The parts of a `.vdb` file around the trees: the header, metadata maps, grid
//! descriptors, grid value types and transforms (OpenVDB `io/Archive.cc`,
//! `io/GridDescriptor.cc`, `MetaMap.cc`, `math/Maps.h`).

use std::io::{Read, Seek};

use anyhow::{bail, Result};
use glam::{DMat4, DVec3, DVec4};

use super::input::Input;
use super::{GridClass, ValueType};

/// `OPENVDB_MAGIC` (0x56444220, " BDV") as the first 8 bytes, little-endian.
const MAGIC: i64 = 0x5644_4220;
/// `OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION`: per-grid compression flags and
/// per-node mask-compression metadata (OpenVDB 3.0, 2014).
pub const MIN_FILE_VERSION: u32 = 222;
/// `OPENVDB_FILE_VERSION_HALF_GRID` (OpenVDB 13; 10 to 12 write 224): the newest this
/// reader knows.
pub const MAX_FILE_VERSION: u32 = 225;
const HALF_FLOAT_SUFFIX: &str = "_HalfFloat";
/// OpenVDB's separator between a grid name and the `[N]` suffix that makes
/// duplicate names unique (`GridDescriptor::stringAsUniqueName`).
const UNIQUE_NAME_SEP: char = '\x1e';

pub struct Header {
    pub file_version: u32,
    pub library: (u32, u32),
}

pub fn read_header<R: Read + Seek>(input: &mut Input<R>) -> Result<Header> {
    let magic = match input.i64("the magic number") {
        Ok(m) => m,
        Err(_) => bail!("not a VDB file: shorter than the 8-byte magic number"),
    };
    if magic != MAGIC {
        bail!("not a VDB file (its first 8 bytes are not OpenVDB's magic number)");
    }
    let file_version = input.u32("the file format version")?;
    if file_version < MIN_FILE_VERSION {
        bail!(
            "VDB file format version {file_version} is older than {MIN_FILE_VERSION} \
             (OpenVDB 3.0) and not supported; re-save it with a current OpenVDB"
        );
    }
    if file_version > MAX_FILE_VERSION {
        bail!(
            "VDB file format version {file_version} is newer than this reader knows \
             ({MIN_FILE_VERSION}..={MAX_FILE_VERSION}, up to OpenVDB 13)"
        );
    }
    let major = input.u32("the library version")?;
    let minor = input.u32("the library version")?;
    let has_offsets = input.u8("the grid-offsets flag")?;
    if has_offsets == 0 {
        bail!(
            "this VDB stream has no grid offsets (written to a pipe, not a file); \
             re-save it as a file"
        );
    }
    input.skip(36, "the file UUID")?;
    Ok(Header {
        file_version,
        library: (major, minor),
    })
}

/// Metadata entries this reader uses; everything else is skipped by its size.
#[derive(Default)]
pub struct Meta {
    pub class: Option<String>,
}

/// Reads a `MetaMap`: a u32 count, then per entry a name, a type name, a u32 byte count
/// and the value.
pub fn read_meta<R: Read + Seek>(input: &mut Input<R>) -> Result<Meta> {
    let count = input.u32("the metadata count")?;
    let mut meta = Meta::default();
    for _ in 0..count {
        let name = input.string("a metadata name")?;
        let type_name = input.string("a metadata type")?;
        let size = input.u32("a metadata size")?;
        if name == "class" && type_name == "string" && size <= 256 {
            let bytes = input.bytes(u64::from(size), "the grid class")?;
            meta.class = Some(String::from_utf8_lossy(&bytes).into_owned());
        } else {
            input.skip(u64::from(size), "a metadata value")?;
        }
    }
    Ok(meta)
}

pub fn grid_class(meta: &Meta) -> GridClass {
    match meta.class.as_deref() {
        Some("fog volume") => GridClass::FogVolume,
        Some("level set") => GridClass::LevelSet,
        Some("staggered") => GridClass::Staggered,
        _ => GridClass::Unknown,
    }
}

/// One grid descriptor: names, type and the byte ranges of the grid.
#[derive(Clone, Debug)]
pub struct Descriptor {
    /// The grid name, without the `\x1e[N]` suffix of duplicate names.
    pub name: String,
    pub unique_name: String,
    /// The tree's value type name, e.g. `float` in `Tree_float_5_4_3`, or the whole
    /// type name when it is not a `Tree_*_5_4_3` tree.
    pub type_name: String,
    pub tree_543: bool,
    pub save_half: bool,
    pub instance_parent: String,
    pub grid_pos: u64,
    pub end_pos: u64,
}

impl Descriptor {
    pub fn value_type(&self) -> Option<ValueType> {
        if !self.tree_543 {
            return None;
        }
        match self.type_name.as_str() {
            "float" => Some(ValueType::Float),
            "half" => Some(ValueType::Half),
            "double" => Some(ValueType::Double),
            "vec3s" => Some(ValueType::Vec3Float),
            "vec3d" => Some(ValueType::Vec3Double),
            _ => None,
        }
    }
}

pub fn read_descriptors<R: Read + Seek>(input: &mut Input<R>) -> Result<Vec<Descriptor>> {
    let count = input.i32("the grid count")?;
    if count < 0 {
        bail!("corrupt file: grid count {count}");
    }
    let mut out = Vec::new();
    for n in 0..count {
        let unique_name = input.string("a grid name")?;
        let mut full_type = input.string("a grid type")?;
        let save_half = full_type.ends_with(HALF_FLOAT_SUFFIX);
        if save_half {
            full_type.truncate(full_type.len() - HALF_FLOAT_SUFFIX.len());
        }
        let instance_parent = input.string("a grid's instance parent")?;
        let grid_pos = input.i64("a grid offset")?;
        let block_pos = input.i64("a grid offset")?;
        let end_pos = input.i64("a grid offset")?;
        let here = input.pos() as i64;
        // An instance has no blocks of its own: block_pos 0.
        let blocks_ok = block_pos == 0 || (grid_pos <= block_pos && block_pos <= end_pos);
        if !(here <= grid_pos && grid_pos <= end_pos && blocks_ok) || end_pos as u64 > input.len() {
            bail!(
                "corrupt file: grid #{} (\"{unique_name}\") has offsets {grid_pos}, \
                 {block_pos}, {end_pos} outside {here}..={} ",
                n + 1,
                input.len()
            );
        }
        let name = match unique_name.find(UNIQUE_NAME_SEP) {
            Some(i) => unique_name[..i].to_string(),
            None => unique_name.clone(),
        };
        let (type_name, tree_543) = match full_type
            .strip_prefix("Tree_")
            .and_then(|t| t.strip_suffix("_5_4_3"))
        {
            Some(t) => (t.to_string(), true),
            None => (full_type.clone(), false),
        };
        out.push(Descriptor {
            name,
            unique_name,
            type_name,
            tree_543,
            save_half,
            instance_parent,
            grid_pos: grid_pos as u64,
            end_pos: end_pos as u64,
        });
        input.seek(end_pos as u64)?;
    }
    Ok(out)
}

/// Reads a transform (`Transform::read`): the map's type name, then its data, and
/// returns it as an index-to-world matrix acting on column vectors.
///
/// OpenVDB stores a `Mat4d` row-major for row vectors (`world = index · M`, the
/// translation in the last row); read in order as columns, those 16 doubles are the
/// column-vector matrix glam uses.
pub fn read_transform<R: Read + Seek>(input: &mut Input<R>) -> Result<(String, DMat4)> {
    let map = input.string("the transform's map type")?;
    let vec3 = |input: &mut Input<R>| -> Result<DVec3> {
        Ok(DVec3::new(
            input.f64("a map")?,
            input.f64("a map")?,
            input.f64("a map")?,
        ))
    };
    let matrix = match map.as_str() {
        "AffineMap" | "UnitaryMap" => {
            let mut m = [0.0f64; 16];
            for v in &mut m {
                *v = input.f64("an affine map")?;
            }
            let m = DMat4::from_cols_array(&m);
            let last_row = m.row(3);
            if last_row != DVec4::W {
                bail!(
                    "the {map} is not affine: its projective part (the last column of \
                     OpenVDB's row-vector matrix) is {:?}, not [0, 0, 0, 1]",
                    last_row.to_array()
                );
            }
            m
        }
        "ScaleMap" | "UniformScaleMap" => {
            // scale, voxel size, inverse scale, 1/scale², 1/(2·scale)
            let scale = vec3(input)?;
            input.skip(4 * 24, "a scale map")?;
            DMat4::from_scale(scale)
        }
        "ScaleTranslateMap" | "UniformScaleTranslateMap" => {
            let translation = vec3(input)?;
            let scale = vec3(input)?;
            input.skip(4 * 24, "a scale-translate map")?;
            DMat4::from_translation(translation) * DMat4::from_scale(scale)
        }
        "TranslationMap" => DMat4::from_translation(vec3(input)?),
        "NonlinearFrustumMap" => bail!(
            "the transform is a NonlinearFrustumMap (a frustum, not affine); \
             resample the grid to a linear transform"
        ),
        other => bail!("the transform's map type \"{other}\" is not supported"),
    };
    let finite = matrix.to_cols_array().iter().all(|v| v.is_finite());
    let det = matrix.determinant();
    if !finite || !det.is_finite() || det.abs() < 1e-300 {
        bail!(
            "the {map} index-to-world transform is degenerate (determinant {det:e}): {:?}",
            matrix.to_cols_array_2d()
        );
    }
    Ok((map, matrix))
}
