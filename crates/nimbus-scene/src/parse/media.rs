//! `[[medium]]` tables and the grid sources they name.

use anyhow::Result;
use glam::Vec3;
use toml::Value;

use super::*;
use crate::convex::Solid;
use crate::fields::{
    open_interval, positive_up_to, radiometric, type_name, unit_interval, Fields, Source,
};
use crate::files::{check_grid_dims, file_size, read_vol_header};
use crate::geometry::OrientedBox;

pub(super) const MEDIUM_TYPES: &[(&str, &[&str])] = &[
    (
        "box",
        &[
            "type",
            "center",
            "size",
            "rotation_deg",
            "sigma_t",
            "albedo",
            "g",
        ],
    ),
    ("convex", &["type", "planes", "sigma_t", "albedo", "g"]),
    (
        "grid",
        &[
            "type",
            "bounds_min",
            "bounds_max",
            "density",
            "density_scale",
            "albedo",
            "g",
            "emission",
            "emission_scale",
            "temperature",
            "temperature_offset",
            "temperature_scale",
            "blackbody_scale",
            "velocity",
            "velocity_scale",
            "frame",
        ],
    ),
    ("vdb", super::vdb::VDB_KEYS),
];
pub(super) const GRID_KEYS: &[&str] = &["file", "dims", "procedural", "noise_seed"];
pub(super) const GRID_FRAME_KEYS: &[&str] =
    &["frame", "density", "temperature", "albedo", "emission"];

pub(super) fn parse_medium(
    source: &Source,
    index: usize,
    table: &toml::Table,
) -> Result<(Medium, String, Solid)> {
    let (kind, f) = typed_fields(source, "medium", index, table, MEDIUM_TYPES)?;
    // Grid and vdb media may give `albedo` as a grid (then the colour is 1).
    let albedo_table = match kind {
        "grid" | "vdb" if f.is_table("albedo") => f.opt_table("albedo")?,
        _ => None,
    };
    let albedo = match albedo_table {
        Some(_) => Vec3::ONE,
        None => f.color("albedo", Some(Vec3::ONE), unit_interval)?,
    };
    let g = f.f32_with("g", Some(0.0), open_interval(-1.0, 1.0))?;
    if kind == "box" {
        let medium = BoxMedium {
            center: f.vec3("center", None)?,
            size: size3(&f, "size")?,
            rotation_deg: f
                .angles_deg("rotation_deg", Some(glam::DVec3::ZERO))?
                .as_vec3(),
            sigma_t: f.f32_in("sigma_t", None, 0.0..=MAX_SIGMA_T)?,
            albedo,
            g,
        };
        let bounds = OrientedBox::new(
            medium.center.as_dvec3(),
            medium.size.as_dvec3(),
            medium.rotation_deg.as_dvec3(),
        );
        return Ok((Medium::Box(medium), f.name, Solid::from(&bounds)));
    }
    if kind == "convex" {
        let planes = parse_planes(&f)?;
        let sigma_t = f.f32_in("sigma_t", None, 0.0..=MAX_SIGMA_T)?;
        let medium = ConvexMedium::new(&planes, sigma_t, albedo, g)
            .map_err(|message| f.error("planes", message))?;
        let extent = {
            let (lo, hi) = medium.polyhedron.bounds();
            (hi - lo).max_element()
        };
        if extent > MAX_LENGTH_M {
            return Err(f.error(
                "planes",
                format!("the polyhedron spans {extent:e} m, more than {MAX_LENGTH_M:e} m"),
            ));
        }
        let bounds = Solid::from(&medium.polyhedron);
        return Ok((Medium::Convex(medium), f.name, bounds));
    }
    if kind == "vdb" {
        return super::vdb::parse_vdb_medium(&f, albedo_table, g);
    }

    let density_table = f
        .opt_table("density")?
        .ok_or_else(|| f.error("density", "missing required field"))?;
    let density = parse_grid_source(&f, "density", density_table, GridChannels::Scalar)?;
    // The box: the scene's bounds, else (both left out) a .vol density's header box.
    let (bounds_min, bounds_max) = match (f.has("bounds_min"), f.has("bounds_max"), &density) {
        (false, false, GridSource::MitsubaVol { file }) => {
            let header = read_vol_header(file).map_err(|e| f.error("density", e))?;
            let finite = header.bbox_min.is_finite() && header.bbox_max.is_finite();
            if !finite {
                return Err(f.error(
                    "bounds_min",
                    format!(
                        "missing, and the .vol header of {} holds no finite bounding box \
                         ({:?} .. {:?}): give bounds_min and bounds_max",
                        file.display(),
                        header.bbox_min.to_array(),
                        header.bbox_max.to_array()
                    ),
                ));
            }
            (header.bbox_min, header.bbox_max)
        }
        (false, true, _) => {
            return Err(f.error(
                "bounds_min",
                "missing: give both bounds or neither (a .vol density's header box)",
            ));
        }
        (true, false, _) => {
            return Err(f.error(
                "bounds_max",
                "missing: give both bounds or neither (a .vol density's header box)",
            ));
        }
        _ => (f.vec3("bounds_min", None)?, f.vec3("bounds_max", None)?),
    };
    for axis in 0..3 {
        let extent = f64::from(bounds_max[axis]) - f64::from(bounds_min[axis]);
        if let Some(message) = positive_up_to(MAX_LENGTH_M)(extent) {
            return Err(f.error(
                "bounds_max",
                format!(
                    "component {axis}: bounds_max - bounds_min = {extent}, {message} \
                     (`bounds_min` must be < `bounds_max` componentwise)"
                ),
            ));
        }
    }
    let emission = match f.opt_table("emission")? {
        Some(table) => Some(parse_grid_source(
            &f,
            "emission",
            table,
            GridChannels::ScalarOrRgb,
        )?),
        None if f.has("emission_scale") => {
            return Err(f.error("emission_scale", "has no effect without `emission`"));
        }
        None => None,
    };
    let temperature = match f.opt_table("temperature")? {
        Some(table) => Some(parse_grid_source(
            &f,
            "temperature",
            table,
            GridChannels::Scalar,
        )?),
        None => None,
    };
    let temperature = temperature_fields(&f, temperature)?;
    let albedo_grid = match albedo_table {
        Some(table) => Some(parse_grid_source(
            &f,
            "albedo",
            table,
            GridChannels::ScalarOrRgb,
        )?),
        None => None,
    };
    let velocity = match f.opt_table("velocity")? {
        Some(table) => Some(parse_grid_source(
            &f,
            "velocity",
            table,
            GridChannels::Vector,
        )?),
        None if f.has("velocity_scale") => {
            return Err(f.error("velocity_scale", "has no effect without `velocity`"));
        }
        None => None,
    };
    let velocity_scale = f.f32_in("velocity_scale", Some(1.0), 1e-6..=1e6)?;

    let mut frames: Vec<(GridFrame, String)> = Vec::new();
    for (i, frame_table) in f.tables("frame")?.into_iter().enumerate() {
        let name = format!("{} > [[medium.frame]] #{}", f.name, i + 1);
        let frame_fields = Fields::new(source, name.clone(), frame_table, GRID_FRAME_KEYS)?;
        let frame = frame_fields.u32_in("frame", None, 0..=u32::MAX)?;
        let density_table = frame_fields
            .opt_table("density")?
            .ok_or_else(|| frame_fields.error("density", "missing required field"))?;
        let density = parse_grid_source(
            &frame_fields,
            "density",
            density_table,
            GridChannels::Scalar,
        )?;
        // A frame's grid of `key`, which the medium must have as a grid too (its scale
        // and mapping apply to every frame's).
        let frame_grid =
            |key: &str, medium_has: bool, channels: GridChannels, why: &str| match frame_fields
                .opt_table(key)?
            {
                Some(_) if !medium_has => Err(frame_fields.error(
                    key,
                    format!("the medium has no `{key}` grid: give it one ({why})"),
                )),
                Some(table) => parse_grid_source(&frame_fields, key, table, channels).map(Some),
                None => Ok(None),
            };
        let frame_temperature = frame_grid(
            "temperature",
            temperature.is_some(),
            GridChannels::Scalar,
            "its `temperature_offset`, `temperature_scale` and `blackbody_scale` map every \
             frame's grid to kelvin and radiance",
        )?;
        let frame_albedo = frame_grid(
            "albedo",
            albedo_grid.is_some(),
            GridChannels::ScalarOrRgb,
            "a constant albedo has no grid for a frame to replace",
        )?;
        let frame_emission = frame_grid(
            "emission",
            emission.is_some(),
            GridChannels::ScalarOrRgb,
            "its `emission_scale` applies to every frame's grid",
        )?;
        frames.push((
            GridFrame {
                frame,
                density,
                temperature: frame_temperature,
                albedo: frame_albedo,
                emission: frame_emission,
            },
            name,
        ));
    }
    frames.sort_by_key(|(frame, _)| frame.frame);
    for pair in frames.windows(2) {
        if pair[0].0.frame == pair[1].0.frame {
            return Err(source.error(format!(
                "{} and {}: field `frame`: both are frame {}; medium frames must be unique",
                pair[0].1, pair[1].1, pair[0].0.frame
            )));
        }
    }

    let medium = GridMedium {
        bounds_min,
        bounds_max,
        density,
        density_scale: f.f32_in("density_scale", Some(1.0), 0.0..=MAX_SIGMA_T)?,
        albedo,
        albedo_grid,
        g,
        emission,
        emission_scale: f.color("emission_scale", Some(Vec3::ONE), radiometric)?,
        temperature,
        velocity,
        velocity_scale,
        frames: frames.into_iter().map(|(frame, _)| frame).collect(),
        vdb: None,
    };
    let bounds = OrientedBox::aabb(bounds_min.as_dvec3(), bounds_max.as_dvec3());
    Ok((Medium::Grid(medium), f.name, Solid::from(&bounds)))
}

/// `planes = [[nx, ny, nz, d], ...]`.
fn parse_planes(f: &Fields) -> Result<Vec<[f64; 4]>> {
    let value = f
        .value("planes")
        .ok_or_else(|| f.error("planes", "missing required field"))?;
    let Value::Array(items) = value else {
        return Err(f.error(
            "planes",
            format!(
                "expected an array of [nx, ny, nz, d] planes, found {}",
                type_name(value)
            ),
        ));
    };
    items
        .iter()
        .enumerate()
        .map(|(i, item)| {
            crate::fields::parse_numbers::<4>(item)
                .map_err(|message| f.error("planes", format!("plane {i}: {message}")))
        })
        .collect()
}

/// What a grid holds per voxel.
#[derive(Clone, Copy, PartialEq, Eq)]
enum GridChannels {
    /// One float (density); procedural grids allowed.
    Scalar,
    /// One float, or (a `.vol` file) three: rgb emission; procedural grids allowed.
    ScalarOrRgb,
    /// Three floats (velocity); files only.
    Vector,
}

impl GridChannels {
    /// Whether a `.vol` file of `n` channels fits.
    fn takes(self, n: u32) -> bool {
        match self {
            Self::Scalar => n == 1,
            Self::ScalarOrRgb => n == 1 || n == 3,
            Self::Vector => n == 3,
        }
    }

    /// Channels of a raw float32 file (raw emission is scalar).
    fn raw_count(self) -> u32 {
        match self {
            Self::Scalar | Self::ScalarOrRgb => 1,
            Self::Vector => 3,
        }
    }

    fn expected(self) -> &'static str {
        match self {
            Self::Scalar => {
                "1 (a density has one channel; 3-channel .vol files are read as \
                             rgb `emission` or as `velocity`)"
            }
            Self::ScalarOrRgb => "1 or 3 (rgb)",
            Self::Vector => "3",
        }
    }
}

/// A grid table (`density`, `emission`, `velocity`) found as field `key` of `parent`.
fn parse_grid_source(
    parent: &Fields,
    key: &str,
    table: &toml::Table,
    channels: GridChannels,
) -> Result<GridSource> {
    let f = Fields::new(
        parent.source,
        format!("{} > {key}", parent.name),
        table,
        GRID_KEYS,
    )?;
    let dims = match f.value("dims") {
        Some(value) => Some(parse_dims(&f, value)?),
        None => None,
    };
    let file = f.opt_str("file")?;
    let procedural = f.opt_str("procedural")?;
    match (file, procedural) {
        (Some(_), Some(_)) => {
            Err(f.error("procedural", "give either `file` or `procedural`, not both"))
        }
        (None, None) => Err(f.error(
            "file",
            "missing: a grid needs `file` (raw float32 with `dims`, or .vol) or `procedural`",
        )),
        (None, Some(_)) => {
            if channels == GridChannels::Vector {
                return Err(f.error(
                    "procedural",
                    "a velocity grid must come from a file (3 float32 channels)",
                ));
            }
            let kind = f.choice(
                "procedural",
                None,
                &[
                    ("cloud", ProceduralKind::Cloud),
                    ("cumulus", ProceduralKind::Cumulus),
                ],
            )?;
            let dims = dims.ok_or_else(|| {
                f.error(
                    "dims",
                    "missing required field (procedural grids need `dims`)",
                )
            })?;
            let noise_seed = f.int_in("noise_seed", Some(0), 0..=i64::MAX)? as u64;
            Ok(GridSource::ProceduralCloud {
                dims,
                noise_seed,
                kind,
            })
        }
        (Some(name), None) => {
            if f.has("noise_seed") {
                return Err(f.error("noise_seed", "only procedural grids take a `noise_seed`"));
            }
            let path = f.source.resolve(name);
            if name.to_ascii_lowercase().ends_with(".vdb") {
                return Err(f.error(
                    "file",
                    format!(
                        "\"{name}\" is an OpenVDB file: use a [[medium]] of type = \"vdb\" \
                         (placed by the file's own transform) instead of type = \"grid\""
                    ),
                ));
            }
            if name.to_ascii_lowercase().ends_with(".vol") {
                let header = read_vol_header(&path).map_err(|e| f.error("file", e))?;
                if !channels.takes(header.channels) {
                    return Err(f.error(
                        "file",
                        format!(
                            "{}: .vol file has {} channels, expected {}",
                            path.display(),
                            header.channels,
                            channels.expected()
                        ),
                    ));
                }
                if let Some(dims) = dims {
                    if dims != header.dims {
                        return Err(f.error(
                            "dims",
                            format!(
                                "{dims:?} differs from the .vol header's {:?} (dims may be left out for .vol files)",
                                header.dims
                            ),
                        ));
                    }
                }
                return Ok(GridSource::MitsubaVol { file: path });
            }
            let dims = dims.ok_or_else(|| {
                f.error(
                    "dims",
                    "missing required field (raw float32 grid files need `dims`)",
                )
            })?;
            let size = file_size(&path).map_err(|message| f.error("file", message))?;
            let voxels: u64 = dims.iter().map(|&d| u64::from(d)).product();
            let expected = voxels * u64::from(channels.raw_count()) * 4;
            if size != expected {
                return Err(f.error(
                    "file",
                    format!(
                        "{}: expected {expected} bytes ({} x {} x {} voxels x {} channel(s) x 4 \
                         bytes of float32), found {size} bytes",
                        path.display(),
                        dims[0],
                        dims[1],
                        dims[2],
                        channels.raw_count()
                    ),
                ));
            }
            Ok(GridSource::Raw { file: path, dims })
        }
    }
}

/// `dims = [nx, ny, nz]`.
fn parse_dims(f: &Fields, value: &Value) -> Result<[u32; 3]> {
    let expected = "expected an array of 3 integers [nx, ny, nz]";
    let items = match value {
        Value::Array(items) if items.len() == 3 => items,
        Value::Array(items) => {
            return Err(f.error(
                "dims",
                format!("{expected}, found {} elements", items.len()),
            ))
        }
        other => return Err(f.error("dims", format!("{expected}, found {}", type_name(other)))),
    };
    let mut dims = [0i64; 3];
    for (axis, item) in items.iter().enumerate() {
        dims[axis] = match item {
            Value::Integer(i) => *i,
            other => {
                return Err(f.error(
                    "dims",
                    format!("{expected}, element {axis} is {}", type_name(other)),
                ))
            }
        };
    }
    check_grid_dims(dims).map_err(|message| f.error("dims", message))
}

/// The blackbody settings of a grid medium whose `temperature` grid is `source` (`None`:
/// none, and then none of its settings may be given).
pub(super) fn temperature_fields(
    f: &Fields,
    source: Option<GridSource>,
) -> Result<Option<Box<Temperature>>> {
    let Some(source) = source else {
        for key in ["temperature_offset", "temperature_scale", "blackbody_scale"] {
            if f.has(key) {
                return Err(f.error(key, "has no effect without `temperature`"));
            }
        }
        return Ok(None);
    };
    Ok(Some(Box::new(Temperature {
        source,
        offset: f.f32_in("temperature_offset", Some(0.0), -MAX_KELVIN..=MAX_KELVIN)?,
        scale: f.f32_in("temperature_scale", Some(1.0), 0.0..=MAX_KELVIN)?,
        blackbody_scale: f.f32_with("blackbody_scale", Some(1.0), radiometric)?,
    })))
}

/// The largest |`temperature_offset`| and `temperature_scale`, in kelvin (per grid unit).
pub const MAX_KELVIN: f64 = 1e6;
