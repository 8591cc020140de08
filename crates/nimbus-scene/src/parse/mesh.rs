//! `[[shape]] type = "mesh"`: a triangle mesh from an `.obj` or `.ply` file, placed by
//! an optional `to_world` (as for vdb media), loaded and given its BVH when the scene
//! loads.

use std::sync::Arc;

use anyhow::Result;
use glam::Vec3;

use super::vdb::to_world_parts;
use super::*;
use crate::mesh::{MeshShape, ToWorld};

/// The fields of a mesh shape.
pub(super) const MESH_KEYS: &[&str] = &["type", "file", "to_world", "albedo", "emission"];

/// A mesh shape: its file read, validated and placed, its BVH built. Every error names
/// the scene file, the shape, the field and (for the file's contents) the mesh file.
pub(super) fn parse_mesh_shape(f: &Fields, albedo: Vec3, emission: Vec3) -> Result<Shape> {
    let name = f
        .opt_str("file")?
        .ok_or_else(|| f.error("file", "missing required field (an .obj or .ply file)"))?;
    let lower = name.to_ascii_lowercase();
    if !(lower.ends_with(".obj") || lower.ends_with(".ply")) {
        return Err(f.error("file", format!("\"{name}\" must be an .obj or .ply file")));
    }
    let path = existing_file(f, "file", name, None)?;
    let to_world = match f.opt_table("to_world")? {
        Some(table) => {
            let (scale, rotate, translate) = to_world_parts(f, table)?;
            ToWorld {
                scale: scale.as_vec3(),
                rotate_deg: rotate.as_vec3(),
                translate: translate.as_vec3(),
            }
        }
        None => ToWorld::IDENTITY,
    };
    // The loader's messages start with the mesh file's path.
    let mesh = MeshShape::load(&path, to_world).map_err(|e| f.error("file", format!("{e:#}")))?;
    Ok(Shape::Mesh {
        mesh: Arc::new(mesh),
        albedo,
        emission,
    })
}
