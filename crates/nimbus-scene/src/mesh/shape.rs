//! A mesh as a scene shape (`[[shape]] type = "mesh"`): the file it came from, its
//! placement, the world-space triangles and their BVH. The scene loader builds one per
//! mesh shape when the scene loads, so a bad file fails there, and shares it (`Arc`)
//! among the copies of the scene.

use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{anyhow, Result};
use glam::Vec3;

use super::{load_mesh, Bvh, ToWorld, TriangleMesh};

/// A loaded, placed and validated mesh with its BVH. Two are equal when their file,
/// placement and triangles are (the BVH follows from the triangles; the build time
/// does not count).
#[derive(Clone)]
pub struct MeshShape {
    /// The mesh file (resolved against the scene's directory).
    pub file: PathBuf,
    pub to_world: ToWorld,
    /// World-space triangles (degenerate ones dropped).
    pub mesh: TriangleMesh,
    /// The BVH over `mesh`; its leaf triangles are what the GPU uploads.
    pub bvh: Bvh,
    /// Degenerate triangles (zero area, repeated vertex) the loader dropped.
    pub dropped_degenerate: u64,
    /// Seconds [`Bvh::build`] took.
    pub bvh_build_seconds: f64,
}

impl MeshShape {
    /// Loads `file` (`.obj` or `.ply`), places it by `to_world` and builds its BVH.
    /// Errors start with the file's name.
    pub fn load(file: &Path, to_world: ToWorld) -> Result<Self> {
        let loaded = load_mesh(file, &to_world)?;
        let mut shape = Self::from_mesh(file.to_path_buf(), to_world, loaded.mesh)?;
        shape.dropped_degenerate = loaded.dropped_degenerate;
        Ok(shape)
    }

    /// A mesh already in world space (made in code, or loaded); `file` names it in
    /// messages. Builds the BVH; errors start with `file`.
    pub fn from_mesh(file: PathBuf, to_world: ToWorld, mesh: TriangleMesh) -> Result<Self> {
        let start = Instant::now();
        let bvh = Bvh::build(&mesh).map_err(|e| anyhow!("{}: {e:#}", file.display()))?;
        Ok(Self {
            file,
            to_world,
            mesh,
            bvh,
            dropped_degenerate: 0,
            bvh_build_seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.mesh.triangle_count()
    }

    /// The world-space bounds of its triangles.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.bvh
            .nodes()
            .first()
            .map(|root| (Vec3::from(root.min), Vec3::from(root.max)))
            .unwrap_or((Vec3::ZERO, Vec3::ZERO))
    }
}

impl PartialEq for MeshShape {
    fn eq(&self, other: &Self) -> bool {
        self.file == other.file
            && self.to_world == other.to_world
            && self.mesh == other.mesh
            && self.dropped_degenerate == other.dropped_degenerate
    }
}

/// A summary: the vertex and triangle lists of a large mesh would flood any message.
impl fmt::Debug for MeshShape {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("MeshShape")
            .field("file", &self.file)
            .field("to_world", &self.to_world)
            .field("triangles", &self.mesh.triangle_count())
            .field("vertices", &self.mesh.positions.len())
            .field("bvh_nodes", &self.bvh.nodes().len())
            .field("bvh_depth", &self.bvh.depth())
            .field("dropped_degenerate", &self.dropped_degenerate)
            .finish()
    }
}
