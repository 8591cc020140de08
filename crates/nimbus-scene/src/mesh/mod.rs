//! Triangle meshes on the CPU: loading `.obj` / `.ply` files into a [`TriangleMesh`],
//! validation, placement by a [`ToWorld`] transform, a binned-SAH [`Bvh`] with a flat,
//! GPU-friendly node array, and the CPU ray queries that are the reference for the
//! GPU traversal.
//!
//! # Loading
//! [`load_mesh`] reads a file (the format from its extension, any case: `.obj` or
//! `.ply`); [`read_mesh`] reads from any [`BufRead`]. Both return a [`LoadedMesh`]:
//! the world-space [`TriangleMesh`] and how many degenerate triangles were dropped.
//!
//! - OBJ: `v x y z` (extra values such as `w` or vertex colours are ignored) and
//!   `f a b c ...` with 1-based or negative (relative) indices, `a/t/n` forms allowed;
//!   every other statement (`vt`, `vn`, `l`, `p`, `o`, `g`, `usemtl`, `mtllib`, ...)
//!   is ignored. A line ending in `\` continues on the next.
//! - PLY: `ascii 1.0`, `binary_little_endian 1.0`, `binary_big_endian 1.0`; a
//!   `vertex` element with scalar `x`, `y`, `z` of any PLY type and a `face` element
//!   with a list `vertex_indices` (or `vertex_index`) of any integer type; other
//!   elements and properties are read and skipped.
//!
//! Faces with more than three vertices are split into fans (v0, vi, vi+1). A face
//! that a fan would not cover correctly is an error naming it: a *concave* corner, a
//! *non-planar* face (a vertex farther than [`MAX_FACE_NONPLANARITY`] × the face's
//! bounding-box diagonal from its mean plane) or a *self-intersecting* outline (the
//! boundary turns around more than once, e.g. a pentagram).
//!
//! # Errors and what is dropped
//! Every error starts with the file's name. Faces are numbered from 1 in messages
//! (`face #3` is the third face in the file; OBJ messages add the line); vertices are
//! named by the index the file itself uses (1-based in OBJ, 0-based in PLY). Errors:
//! missing or unreadable file, unknown extension, malformed lines or headers,
//! truncated data, NaN or infinite coordinates (also after `to_world`), indices out
//! of range, faces with fewer than 3 vertices, faces that cannot be fanned, a file
//! with no faces, and sizes over the limits below (refused before the memory is
//! allocated).
//!
//! **Degenerate triangles are dropped, not refused**: a triangle that repeats a
//! vertex index or whose three world-space corners are exactly collinear (zero
//! area, tested in f64) can never be hit, and exports from modelling tools often
//! carry a few. [`LoadedMesh::dropped_degenerate`] counts them so the caller can
//! warn. A mesh whose triangles are *all* degenerate is an error. Vertices that no
//! kept triangle uses are removed.
//!
//! # Placement and winding
//! [`ToWorld`]: world = translate + R · (scale ⊙ p), R = [`rotation_xyz_deg`]
//! (about X, then Y, then Z: the convention of box shapes and media). A transform
//! with a negative scale determinant mirrors the mesh; the loader then swaps two
//! indices of every triangle so that a triangle's counter-clockwise side (the side
//! it emits on, see docs/scene-format.md) stays the side the file's normal pointed to,
//! as pbrt does.
//!
//! # Limits
//! | what | limit |
//! |---|---|
//! | triangles (after fanning) | [`MAX_MESH_TRIANGLES`] = 2^26 |
//! | vertices | [`MAX_MESH_VERTICES`] = 2^26 |
//! | vertices in one face | [`MAX_FACE_VERTICES`] = 4096 |
//! | one text line (OBJ, PLY header / ascii) | [`MAX_LINE_BYTES`] = 1 MiB |
//!
//! The final mesh takes 12 bytes per vertex and 12 per triangle; the PLY and OBJ
//! readers keep one polygon list of at most the same size while fanning, and
//! [`Bvh::build`] needs about 100 bytes per triangle while it runs.
//!
//! # BVH and ray queries
//! See [`Bvh`] for the node layout and the depth guarantee ([`BVH_MAX_DEPTH`]), and
//! [`Ray`] / [`intersect_triangle`] for the watertight ray–triangle test shared by
//! [`Bvh::closest_hit`], [`Bvh::any_hit`] and the brute-force references
//! [`TriangleMesh::closest_hit_brute_force`] / [`TriangleMesh::any_hit_brute_force`].
//!
//! # In a scene
//! `[[shape]] type = "mesh"` loads its file into a [`MeshShape`] (triangles and BVH)
//! when the scene loads; the renderer uploads the BVHs of all of a scene's meshes
//! into one node buffer and one triangle buffer.

mod bvh;
mod generate;
mod lines;
mod obj;
mod ply;
mod polygon;
mod shape;
mod traverse;

use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::Path;

use anyhow::{anyhow, bail, Result};
use glam::{DVec3, Vec3};

use crate::types::rotation_xyz_deg;

pub use bvh::{Bvh, BvhNode, BVH_MAX_DEPTH, BVH_MAX_LEAF_TRIANGLES, BVH_STACK_SIZE};
pub use lines::MAX_LINE_BYTES;
pub use polygon::MAX_FACE_NONPLANARITY;
pub use shape::MeshShape;
pub use traverse::{intersect_triangle, Hit, Ray};

/// Most triangles in one mesh (after fanning polygons): 2^26.
pub const MAX_MESH_TRIANGLES: u64 = 1 << 26;

/// Most vertices in one mesh file: 2^26.
pub const MAX_MESH_VERTICES: u64 = 1 << 26;

/// Most vertices in one face (polygon).
pub const MAX_FACE_VERTICES: u64 = 4096;

/// An indexed triangle mesh. Triangle `i` has corners `positions[indices[i][k]]`,
/// counter-clockwise seen from the side its normal
/// `(p1 − p0) × (p2 − p0)` points to.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    pub positions: Vec<Vec3>,
    pub indices: Vec<[u32; 3]>,
}

/// A mesh as [`load_mesh`] returns it.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadedMesh {
    /// World-space triangles, degenerate ones removed.
    pub mesh: TriangleMesh,
    /// Degenerate triangles (repeated vertex, zero area) that were dropped.
    pub dropped_degenerate: u64,
}

/// Places a mesh in the world: world = `translate` + R · (`scale` ⊙ p) with R =
/// [`rotation_xyz_deg`]`(rotate_deg)` (about X, then Y, then Z).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToWorld {
    pub scale: Vec3,
    pub rotate_deg: Vec3,
    pub translate: Vec3,
}

impl Default for ToWorld {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl ToWorld {
    /// No scaling, rotation or translation.
    pub const IDENTITY: Self = Self {
        scale: Vec3::ONE,
        rotate_deg: Vec3::ZERO,
        translate: Vec3::ZERO,
    };

    /// Every component finite and no scale component zero.
    pub fn validate(&self) -> Result<()> {
        let all = [self.scale, self.rotate_deg, self.translate];
        if !all.iter().all(|v| v.is_finite()) {
            bail!("to_world: every value must be finite, got {self:?}");
        }
        if self.scale.cmpeq(Vec3::ZERO).any() {
            bail!(
                "to_world: scale components must be non-zero, got {}",
                self.scale
            );
        }
        Ok(())
    }

    /// The transformed point: scale, then rotate (X, Y, Z), then translate.
    pub fn transform_point(&self, p: Vec3) -> Vec3 {
        rotation_xyz_deg(self.rotate_deg) * (self.scale * p) + self.translate
    }

    /// True when the transform mirrors (an odd number of negative scale components),
    /// so triangle windings must be swapped to keep their facing.
    pub fn flips_handedness(&self) -> bool {
        self.scale.x * self.scale.y * self.scale.z < 0.0
    }
}

/// A mesh file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    Obj,
    Ply,
}

impl MeshFormat {
    /// The format named by `path`'s extension (`.obj` or `.ply`, any case).
    pub fn from_path(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("obj") => Ok(Self::Obj),
            Some("ply") => Ok(Self::Ply),
            _ => bail!(
                "{}: unknown mesh file extension (expected .obj or .ply)",
                path.display()
            ),
        }
    }
}

/// Reads the mesh file at `path` (format from its extension) and places it with
/// `to_world`. See the module documentation for what is checked.
pub fn load_mesh(path: &Path, to_world: &ToWorld) -> Result<LoadedMesh> {
    let format = MeshFormat::from_path(path)?;
    let name = path.display().to_string();
    let file = match File::open(path) {
        Ok(file) => file,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            bail!("{name}: mesh file not found")
        }
        Err(e) => bail!("{name}: cannot open mesh file: {e}"),
    };
    if file.metadata().map(|m| m.is_dir()).unwrap_or(false) {
        bail!("{name}: is a directory, not a mesh file");
    }
    read_mesh(&mut BufReader::new(file), format, &name, to_world)
}

/// Reads a mesh in `format` from `reader`; `name` starts every error message.
pub fn read_mesh(
    reader: &mut dyn BufRead,
    format: MeshFormat,
    name: &str,
    to_world: &ToWorld,
) -> Result<LoadedMesh> {
    to_world.validate().map_err(|e| anyhow!("{name}: {e}"))?;
    let polygons = match format {
        MeshFormat::Obj => obj::read_obj(reader, name)?,
        MeshFormat::Ply => ply::read_ply(reader, name)?,
    };
    polygons.into_triangles(name, to_world)
}

/// Faces as a file gives them, before fanning: the common output of the readers.
#[derive(Debug, Default)]
pub(crate) struct Polygons {
    /// Object-space positions, in file order (all finite).
    pub positions: Vec<Vec3>,
    /// The vertex indices of all faces, concatenated (0-based).
    pub corners: Vec<u32>,
    /// Corners per face (each >= 3).
    pub arities: Vec<u32>,
    /// OBJ: the line each face starts on; empty for PLY.
    pub lines: Vec<u64>,
    /// What the file adds to a 0-based index when it writes one (1 for OBJ).
    pub index_base: u64,
    /// Triangles the faces will fan into.
    pub triangle_count: u64,
}

impl Polygons {
    /// "face #3 (line 10)" for messages; `face` is 0-based.
    pub fn face_name(&self, face: usize) -> String {
        match self.lines.get(face) {
            Some(line) => format!("face #{} (line {line})", face + 1),
            None => format!("face #{}", face + 1),
        }
    }

    /// Fans, places, drops degenerate triangles and unused vertices.
    fn into_triangles(self, name: &str, to_world: &ToWorld) -> Result<LoadedMesh> {
        if self.arities.is_empty() {
            bail!("{name}: the mesh has no faces");
        }
        let vertex_count = self.positions.len() as u64;
        let mut indices = Vec::with_capacity(self.triangle_count as usize);
        let mut start = 0usize;
        for (face, &arity) in self.arities.iter().enumerate() {
            let end = start + arity as usize;
            let corners = self.corners.get(start..end).unwrap_or(&[]);
            if let Some(&bad) = corners.iter().find(|&&i| u64::from(i) >= vertex_count) {
                bail!(
                    "{name}: {}: vertex index {} is out of range (the file has {vertex_count} vertices)",
                    self.face_name(face),
                    u64::from(bad) + self.index_base
                );
            }
            polygon::fan(&self.positions, corners, &mut indices)
                .map_err(|e| anyhow!("{name}: {}: {e}", self.face_name(face)))?;
            start = end;
        }

        let mut positions = self.positions;
        for (i, p) in positions.iter_mut().enumerate() {
            let world = to_world.transform_point(*p);
            if !world.is_finite() {
                bail!(
                    "{name}: vertex {} ({p}) is not finite after to_world ({world})",
                    i as u64 + self.index_base
                );
            }
            *p = world;
        }
        if to_world.flips_handedness() {
            for t in &mut indices {
                t.swap(1, 2);
            }
        }

        let total = indices.len() as u64;
        indices.retain(|&t| !is_degenerate(&positions, t));
        let dropped_degenerate = total - indices.len() as u64;
        if indices.is_empty() {
            bail!("{name}: all {total} triangles are degenerate (zero area or a repeated vertex)");
        }
        let mesh = TriangleMesh { positions, indices }.without_unused_vertices();
        Ok(LoadedMesh {
            mesh,
            dropped_degenerate,
        })
    }
}

/// The axis of `v`'s largest component (pbrt's `MaxComponentIndex`: ties go to the
/// later axis).
pub(crate) fn max_axis(v: Vec3) -> usize {
    if v.x > v.y {
        if v.x > v.z {
            0
        } else {
            2
        }
    } else if v.y > v.z {
        1
    } else {
        2
    }
}

/// A repeated index or three exactly collinear corners (cross product zero in f64,
/// where the products of f32 coordinates are exact).
fn is_degenerate(positions: &[Vec3], t: [u32; 3]) -> bool {
    if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
        return true;
    }
    let [a, b, c] = t.map(|i| {
        positions
            .get(i as usize)
            .map_or(DVec3::ZERO, |p| p.as_dvec3())
    });
    (b - a).cross(c - a) == DVec3::ZERO
}

impl TriangleMesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }

    /// The corners of triangle `i`, or `None` when `i` or one of its indices is out of
    /// range.
    pub fn triangle(&self, i: usize) -> Option<[Vec3; 3]> {
        let t = self.indices.get(i)?;
        Some([
            *self.positions.get(t[0] as usize)?,
            *self.positions.get(t[1] as usize)?,
            *self.positions.get(t[2] as usize)?,
        ])
    }

    /// The axis-aligned bounds of the vertices (`None` for no vertices).
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p))),
        )
    }

    /// Checks what [`Bvh::build`] and the GPU rely on: at least one triangle, at most
    /// [`MAX_MESH_TRIANGLES`] triangles and [`MAX_MESH_VERTICES`] vertices, indices in
    /// range, finite positions. Degenerate triangles are allowed (never hit).
    pub fn validate(&self) -> Result<()> {
        if self.indices.is_empty() {
            bail!("the mesh has no triangles");
        }
        if self.indices.len() as u64 > MAX_MESH_TRIANGLES {
            bail!(
                "the mesh has {} triangles, more than the limit of {MAX_MESH_TRIANGLES}",
                self.indices.len()
            );
        }
        if self.positions.len() as u64 > MAX_MESH_VERTICES {
            bail!(
                "the mesh has {} vertices, more than the limit of {MAX_MESH_VERTICES}",
                self.positions.len()
            );
        }
        if let Some((i, p)) = self
            .positions
            .iter()
            .enumerate()
            .find(|(_, p)| !p.is_finite())
        {
            bail!("vertex {i} is not finite: {p}");
        }
        let n = self.positions.len();
        if let Some((i, t)) = self
            .indices
            .iter()
            .enumerate()
            .find(|(_, t)| t.iter().any(|&k| k as usize >= n))
        {
            bail!("triangle {i} {t:?}: vertex index out of range ({n} vertices)");
        }
        Ok(())
    }

    /// The same triangles with vertices that no triangle uses removed (order kept).
    pub fn without_unused_vertices(self) -> Self {
        let mut remap = vec![u32::MAX; self.positions.len()];
        for t in &self.indices {
            for &k in t {
                if let Some(slot) = remap.get_mut(k as usize) {
                    *slot = 0;
                }
            }
        }
        let mut positions = Vec::new();
        for (slot, &p) in remap.iter_mut().zip(&self.positions) {
            if *slot == 0 {
                *slot = positions.len() as u32;
                positions.push(p);
            }
        }
        let indices = self
            .indices
            .iter()
            .map(|t| t.map(|k| remap.get(k as usize).copied().unwrap_or(k)))
            .collect();
        Self { positions, indices }
    }
}
