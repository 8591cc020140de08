//! `[[medium]] type = "vdb"`: OpenVDB grids placed by their own index-to-world
//! transform and an optional `to_world`. Loading the scene reads each grid's header and
//! topology (not its values): the transform, the active bounding box that sets the
//! medium's extent, and the checks a bad file fails early (wrong grid type, point data,
//! unknown compression, a transform that is not affine, a non-zero background, a level
//! set, grids that do not share the density's transform).
//!
//! The density and emission load sparsely (bricks of their active voxels) and render in
//! their own index space, so any invertible affine index-to-world transform places them:
//! rotated, mirrored or sheared. The velocity loads as the dense [`VdbWindow`] around the
//! density's active voxels, sampled through the same transform.

use anyhow::Result;
use std::path::PathBuf;

use glam::{DMat3, DMat4, DVec3, IVec3, Vec3};

use super::*;
use crate::convex::Solid;
use crate::fields::{radiometric, Fields};
use crate::geometry::rotation_xyz_deg_f64;
use crate::vdb::{read_vdb_topology, GridClass, VdbGridHeader, VdbGridKind};

pub(super) const VDB_KEYS: &[&str] = &[
    "type",
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
    "to_world",
];
const VDB_GRID_KEYS: &[&str] = &["file", "grid"];
const VDB_FRAME_KEYS: &[&str] = &["frame", "density"];
const TO_WORLD_KEYS: &[&str] = &["scale", "rotate_deg", "translate"];

/// `to_world = { scale, rotate_deg, translate }`: scale, then rotate about X, Y, Z, then
/// translate.
fn parse_to_world(parent: &Fields, table: &toml::Table) -> Result<DMat4> {
    let (scale, rotate, translate) = to_world_parts(parent, table)?;
    Ok(DMat4::from_translation(translate)
        * DMat4::from_mat3(rotation_xyz_deg_f64(rotate))
        * DMat4::from_scale(scale))
}

/// The checked parts of `to_world = { scale, rotate_deg, translate }` (field `to_world`
/// of `parent`): each scale non-zero with magnitude at most [`MAX_LENGTH_M`], translations
/// within ±[`MAX_LENGTH_M`].
pub(super) fn to_world_parts(
    parent: &Fields,
    table: &toml::Table,
) -> Result<(DVec3, DVec3, DVec3)> {
    let f = Fields::new(
        parent.source,
        format!("{} > to_world", parent.name),
        table,
        TO_WORLD_KEYS,
    )?;
    let scale = match f.value("scale") {
        None => DVec3::ONE,
        Some(Value::Array(_)) => f.vec3_f64("scale", None)?,
        Some(_) => {
            let s = f.opt_f64("scale")?.unwrap_or(1.0);
            DVec3::splat(s)
        }
    };
    for axis in 0..3 {
        let s = scale[axis].abs();
        if !(s > 0.0 && s <= MAX_LENGTH_M && (s as f32) > 0.0) {
            return Err(f.error(
                "scale",
                format!(
                    "component {axis} is {}: each scale must be non-zero with magnitude at \
                     most {MAX_LENGTH_M:e}",
                    scale[axis]
                ),
            ));
        }
    }
    let rotate = f.angles_deg("rotate_deg", Some(DVec3::ZERO))?;
    let translate = f.vec3_f64("translate", Some(DVec3::ZERO))?;
    if translate.abs().max_element() > MAX_LENGTH_M {
        return Err(f.error(
            "translate",
            format!("components must be within ±{MAX_LENGTH_M:e} m"),
        ));
    }
    Ok((scale, rotate, translate))
}

/// A grid table `{ file, grid }` (field `key` of `parent`): its file, the grid's name
/// if given, and the grid's header, read with `kind`. Errors name the scene file, the
/// table, the field, the `.vdb` file and, once chosen, the grid.
fn parse_vdb_source(
    parent: &Fields,
    key: &str,
    table: &toml::Table,
    kind: VdbGridKind,
) -> Result<VdbSource> {
    let f = Fields::new(
        parent.source,
        format!("{} > {key}", parent.name),
        table,
        VDB_GRID_KEYS,
    )?;
    let name = f
        .opt_str("file")?
        .ok_or_else(|| f.error("file", "missing required field (an OpenVDB .vdb file)"))?;
    let grid = f.opt_str("grid")?.map(str::to_string);
    let path = existing_file(&f, "file", name, None)?;
    let header = read_vdb_topology(&path, grid.as_deref(), kind, "").map_err(|e| {
        // The field to change: `grid` when one is named in a file whose grids can be
        // listed (no such grid, or one of the wrong kind), else the `file` itself.
        let blame = if grid.is_some() && crate::vdb::list_grids(&path).is_ok() {
            "grid"
        } else {
            "file"
        };
        f.error(blame, format!("{e:#}"))
    })?;
    let source = VdbSource {
        file: path,
        grid,
        header,
    };
    if source.header.grid_class == GridClass::LevelSet && kind == VdbGridKind::Scalar {
        return Err(source.error(
            parent,
            key,
            "it is a level set (signed distances, not densities); convert it to a fog \
             volume first",
        ));
    }
    let ch = source.header.value_type.channels();
    if source.header.topology.background[..ch]
        .iter()
        .any(|v| *v != 0.0)
    {
        return Err(source.error(
            parent,
            key,
            format!(
                "its background (the value of inactive voxels) is {:?}; Nimbus reads \
                 inactive voxels as empty, so it must be 0",
                &source.header.topology.background[..ch]
            ),
        ));
    }
    if source.header.topology.active_bbox.is_none() {
        return Err(source.error(parent, key, "the grid has no active voxels"));
    }
    Ok(source)
}

/// A grid of a `.vdb` file named by the scene, with its header.
struct VdbSource {
    file: PathBuf,
    grid: Option<String>,
    header: VdbGridHeader,
}

impl VdbSource {
    /// An error on field `key` of `parent` naming the file and the grid.
    fn error(&self, parent: &Fields, key: &str, problem: impl std::fmt::Display) -> anyhow::Error {
        parent.error(
            key,
            format!(
                "{}: grid \"{}\": {problem}",
                self.file.display(),
                self.header.name
            ),
        )
    }

    /// Refuses a grid whose transform is not the density's (`density`): the grids of a
    /// medium share one lattice.
    fn check_same_transform(&self, parent: &Fields, key: &str, density: &DMat4) -> Result<()> {
        if same_transform(&self.header.index_to_world, density) {
            return Ok(());
        }
        Err(self.error(
            parent,
            key,
            format!(
                "its index-to-world transform {:?} is not the medium's density's {:?}; \
                 every grid of a medium must share it",
                self.header.index_to_world.to_cols_array_2d(),
                density.to_cols_array_2d()
            ),
        ))
    }

    fn into_source(self, window: &VdbWindow) -> GridSource {
        GridSource::Vdb {
            file: self.file,
            grid: self.grid,
            window: Box::new(window.clone()),
        }
    }
}

/// Whether two transforms agree to 1e-9 of their largest entry.
fn same_transform(a: &DMat4, b: &DMat4) -> bool {
    let scale = a
        .to_cols_array()
        .iter()
        .chain(b.to_cols_array().iter())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    a.to_cols_array()
        .iter()
        .zip(b.to_cols_array().iter())
        .all(|(x, y)| (x - y).abs() <= 1e-9 * scale)
}

/// The diagonal of `m`'s linear part when its off-diagonal entries are within 1e-9 of
/// its largest (the grid's axes along the world's), else `None`.
fn axis_aligned_scale(m: &DMat4) -> Option<DVec3> {
    let l = DMat3::from_mat4(*m);
    let cols = [l.x_axis, l.y_axis, l.z_axis];
    let largest = cols
        .iter()
        .fold(0.0f64, |a, c| a.max(c.abs().max_element()));
    let off = (0..3)
        .flat_map(|c| (0..3).filter(move |r| *r != c).map(move |r| (c, r)))
        .fold(0.0f64, |a, (c, r)| a.max(cols[c][r].abs()));
    (off <= 1e-9 * largest).then(|| DVec3::new(cols[0].x, cols[1].y, cols[2].z))
}

pub(super) fn parse_vdb_medium(
    f: &Fields,
    albedo_table: Option<&toml::Table>,
    g: f32,
) -> Result<(Medium, String, Solid)> {
    let to_world = match f.opt_table("to_world")? {
        Some(table) => parse_to_world(f, table)?,
        None => DMat4::IDENTITY,
    };
    let density_table = f
        .opt_table("density")?
        .ok_or_else(|| f.error("density", "missing required field"))?;
    let density = parse_vdb_source(f, "density", density_table, VdbGridKind::Scalar)?;
    let file_transform = density.header.index_to_world;
    let index_to_world = to_world * file_transform;
    // The file's own transform is checked when its header is read; `to_world` may still
    // flatten it.
    let linear = DMat3::from_mat4(index_to_world);
    let largest = [linear.x_axis, linear.y_axis, linear.z_axis]
        .iter()
        .fold(0.0f64, |a, c| a.max(c.length()));
    let det = linear.determinant();
    if det.is_nan() || det.abs() <= 1e-12 * largest.powi(3) {
        let field = if f.has("to_world") {
            "to_world"
        } else {
            "density"
        };
        return Err(density.error(
            f,
            field,
            format!(
                "its index-to-world transform{} {:?} is degenerate (determinant {:e}): it \
                 flattens the grid",
                if f.has("to_world") {
                    " with `to_world`"
                } else {
                    ""
                },
                index_to_world.to_cols_array_2d(),
                linear.determinant()
            ),
        ));
    }
    // A mirror along an index axis flips the dense velocity window there (the axis-aligned
    // case, as before); a rotated or sheared grid's window stays in index order.
    let scale = axis_aligned_scale(&index_to_world).unwrap_or(DVec3::ONE);
    let Some(mut bbox) = density.header.topology.active_bbox else {
        return Err(f.error("density", "the grid has no active voxels"));
    };

    let mut frames: Vec<(u32, VdbSource, String)> = Vec::new();
    for (i, frame_table) in f.tables("frame")?.into_iter().enumerate() {
        let name = format!("{} > [[medium.frame]] #{}", f.name, i + 1);
        let ff = Fields::new(f.source, name.clone(), frame_table, VDB_FRAME_KEYS)?;
        let frame = ff.u32_in("frame", None, 0..=u32::MAX)?;
        let table = ff
            .opt_table("density")?
            .ok_or_else(|| ff.error("density", "missing required field"))?;
        let source = parse_vdb_source(&ff, "density", table, VdbGridKind::Scalar)?;
        source.check_same_transform(&ff, "density", &file_transform)?;
        if let Some((lo, hi)) = source.header.topology.active_bbox {
            bbox = (bbox.0.min(lo), bbox.1.max(hi));
        }
        frames.push((frame, source, name));
    }
    frames.sort_by_key(|(frame, ..)| *frame);
    for pair in frames.windows(2) {
        if pair[0].0 == pair[1].0 {
            return Err(f.source.error(format!(
                "{} and {}: field `frame`: both are frame {}; medium frames must be unique",
                pair[0].2, pair[1].2, pair[0].0
            )));
        }
    }

    let emission = match f.opt_table("emission")? {
        Some(table) => {
            // A scalar grid, or a vec3 grid of rgb radiance (its values are colours, not
            // vectors: `to_world` does not rotate them).
            let source = parse_vdb_source(f, "emission", table, VdbGridKind::Any)?;
            source.check_same_transform(f, "emission", &file_transform)?;
            Some(source)
        }
        None if f.has("emission_scale") => {
            return Err(f.error("emission_scale", "has no effect without `emission`"));
        }
        None => None,
    };
    let albedo_grid = match albedo_table {
        Some(table) => {
            // A float grid, or a vec3 grid of rgb albedos (Houdini's `Cd`): colours,
            // which `to_world` does not turn.
            let source = parse_vdb_source(f, "albedo", table, VdbGridKind::Any)?;
            source.check_same_transform(f, "albedo", &file_transform)?;
            Some(source)
        }
        None => None,
    };
    let albedo = match albedo_grid {
        Some(_) => Vec3::ONE,
        None => f.color("albedo", Some(Vec3::ONE), crate::fields::unit_interval)?,
    };
    let temperature = match f.opt_table("temperature")? {
        Some(table) => {
            let source = parse_vdb_source(f, "temperature", table, VdbGridKind::Scalar)?;
            source.check_same_transform(f, "temperature", &file_transform)?;
            Some(source)
        }
        None => None,
    };
    let velocity = match f.opt_table("velocity")? {
        Some(table) => {
            let source = parse_vdb_source(f, "velocity", table, VdbGridKind::Vec3)?;
            source.check_same_transform(f, "velocity", &file_transform)?;
            Some(source)
        }
        None if f.has("velocity_scale") => {
            return Err(f.error("velocity_scale", "has no effect without `velocity`"));
        }
        None => None,
    };

    // The window: the active box grown by one voxel, where trilinear filtering reaches.
    let (lo, hi) = (bbox.0 - IVec3::ONE, bbox.1 + IVec3::ONE);
    let span = (hi.as_i64vec3() - lo.as_i64vec3() + 1).to_array();
    let Ok(dims) = span
        .map(u32::try_from)
        .into_iter()
        .collect::<Result<Vec<u32>, _>>()
    else {
        return Err(density.error(f, "density", "its active voxels span more than 2^32 voxels"));
    };
    let window = VdbWindow {
        origin: lo,
        dims: [dims[0], dims[1], dims[2]],
        flip: [0, 1, 2].map(|a| scale[a] < 0.0),
        vector_map: DMat3::from_mat4(to_world),
    };
    let world = |ijk: DVec3| (index_to_world * ijk.extend(1.0)).truncate();
    // The extent (lattice points lo ..= hi), a parallelepiped, and the world box around
    // the window's cell-centred voxels, half a voxel wider, where the grid is 0.
    let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
    let corner = |a: DVec3, b: DVec3, c: u32| {
        world(DVec3::new(
            if c & 1 != 0 { b.x } else { a.x },
            if c & 2 != 0 { b.y } else { a.y },
            if c & 4 != 0 { b.z } else { a.z },
        ))
    };
    let (wmin, wmax) = (0..8)
        .map(|c| corner(lo - 0.5, hi + 0.5, c))
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), p| {
            (a.min(p), b.max(p))
        });
    if !(wmin.is_finite() && wmax.is_finite())
        || wmin.abs().max_element() > MAX_LENGTH_M
        || wmax.abs().max_element() > MAX_LENGTH_M
    {
        return Err(density.error(
            f,
            "density",
            format!(
                "the grid's extent {wmin:?} .. {wmax:?} (its transform{} applied to its \
                 active voxels) reaches beyond ±{MAX_LENGTH_M:e} m",
                if f.has("to_world") {
                    " and `to_world`"
                } else {
                    ""
                }
            ),
        ));
    }
    let bounds = parallelepiped((0..8).map(|c| corner(lo, hi, c)).collect(), &linear);

    let medium = GridMedium {
        bounds_min: wmin.as_vec3(),
        bounds_max: wmax.as_vec3(),
        density: density.into_source(&window),
        density_scale: f.f32_in("density_scale", Some(1.0), 0.0..=MAX_SIGMA_T)?,
        albedo,
        albedo_grid: albedo_grid.map(|s| {
            s.into_source(&VdbWindow {
                vector_map: DMat3::IDENTITY,
                ..window.clone()
            })
        }),
        g,
        emission: emission.map(|s| {
            s.into_source(&VdbWindow {
                vector_map: DMat3::IDENTITY,
                ..window.clone()
            })
        }),
        emission_scale: f.color("emission_scale", Some(Vec3::ONE), radiometric)?,
        temperature: super::media::temperature_fields(
            f,
            temperature.map(|s| s.into_source(&window)),
        )?,
        velocity: velocity.map(|s| s.into_source(&window)),
        velocity_scale: f.f32_in("velocity_scale", Some(1.0), 1e-6..=1e6)?,
        frames: frames
            .into_iter()
            .map(|(frame, source, _)| GridFrame {
                temperature: None,
                albedo: None,
                emission: None,
                frame,
                density: source.into_source(&window),
            })
            .collect(),
        vdb: Some(Box::new(VdbPlacement {
            to_world,
            index_to_world,
            active_bbox: bbox,
        })),
    };
    Ok((Medium::Grid(medium), f.name.clone(), bounds))
}

/// The solid of a parallelepiped with corners `vertices` whose edges run along the
/// columns of `linear` (invertible), for the media's overlap test.
fn parallelepiped(vertices: Vec<DVec3>, linear: &DMat3) -> Solid {
    let edges = [linear.x_axis, linear.y_axis, linear.z_axis].map(DVec3::normalize);
    Solid {
        vertices,
        normals: vec![
            edges[1].cross(edges[2]).normalize(),
            edges[2].cross(edges[0]).normalize(),
            edges[0].cross(edges[1]).normalize(),
        ],
        edges: edges.to_vec(),
    }
}
