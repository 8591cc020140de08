//! Nimbus scene files: parsing and validation into [`Scene`] and the types it holds
//! (pure CPU, no Vulkan).
//!
//! The format is the contract in `docs/scene-format.md`. [`load`] reads a file,
//! [`parse_str`] parses text; both return a fully validated [`Scene`] or an error
//! that names the file, the table and the field, e.g.
//!
//! ```text
//! scenes/room.toml: [[light]] #2 (type = "directional"): field `direction`: must not be the zero vector
//! ```
//!
//! Array entries are numbered from 1 in messages (`#2` is the second `[[light]]`).
//! Unknown fields, unknown `type` strings, wrong value types, missing required fields,
//! missing files and out-of-range values are all errors; nothing here panics on user
//! input.
//!
//! # Values
//! - Numbers: integers are accepted wherever a float is expected. Every number must be
//!   finite (TOML's `nan` and `inf` are rejected) and representable as f32. Integer
//!   fields reject floats.
//! - Vectors: arrays of exactly 3 numbers. Directions are normalized; a zero direction
//!   is an error.
//! - Colours: a number `x` means `[x, x, x]`, otherwise an array of exactly 3 numbers.
//! - Files: resolved against the scene file's directory (absolute paths are kept) and
//!   checked to exist when the scene is loaded; contents are read later, except the
//!   48-byte header of `.vol` files.
//!
//! # Defaults (beyond those in docs/scene-format.md)
//! - `[camera]` is required, with `position` and `look_at`; when `[[camera.keyframe]]`
//!   entries exist, `position` / `look_at` may be left out and default to the first
//!   keyframe's. Each keyframe needs `frame`, `position` and `look_at`.
//! - `[[light.keyframe]]` (a Nimbus addition) animates a directional light without a
//!   gobo (`direction`, `irradiance`), a point light (`position`, `intensity`), a
//!   sphere light (`center`, `radiance`) or an environment light (`rotation_deg`, its
//!   map's turn about +Y, interpolated unwrapped and then reduced to one turn); each
//!   keyframe needs `frame` and may give any of its light's animatable fields. A field a keyframe leaves out holds the
//!   light's static value at that keyframe. The static field may itself be left out
//!   when the first keyframe (lowest `frame`) gives it, and defaults to that value.
//!   [`Scene::lights_at`] interpolates linearly by frame (directions by normalized
//!   lerp) and clamps outside the keyed range, like the camera.
//! - Media: `albedo` 1 (no absorption), `g` 0, `rotation_deg` [0, 0, 0]; grid
//!   `density_scale` 1, `emission_scale` 1, `temperature_offset` 0, `temperature_scale` 1,
//!   `blackbody_scale` 1. Shapes: `albedo` 0, `emission` 0 (no area
//!   light).
//! - Directional light: `gobo_origin` [0, 0, 0] (an error without `gobo`).
//! - Environment light: `scale` 1, `rotation_deg` 0 (any finite angle, reduced modulo
//!   360 exactly past one turn); `radiance` 1 when `file` is given (the two multiply);
//!   one of `radiance` / `file` is required.
//! - Procedural grids: `noise_seed` 0.
//!
//! # Validated ranges
//! | what | range |
//! |---|---|
//! | `width`, `height` | 1..=16384, width·height <= 64 Mi pixels |
//! | `frames` | 1..=1 000 000 |
//! | `spp` | 1..=65536 |
//! | `seed`, `noise_seed` | 0..=2^63−1 (TOML integers are signed) |
//! | `horizontal_fov_deg` | (0, 180) exclusive |
//! | camera | `position` ≠ `look_at` (relative 1e-6), `up` not within ~0.006° of the view direction, also for every keyframe and every interpolated pose in `0..frames` |
//! | keyframe / medium `frame` | u32, unique within their list (lists are sorted) |
//! | light keyframes | not on directional lights with a `gobo`; keyframe directions non-zero; consecutive keyframe directions (after filling in the light's static one) not nearly opposite: dot >= −0.999 |
//! | `sigma_t`, `density_scale` | [0, 1e9] 1/m |
//! | `albedo` (media and shapes) | each component in [0, 1]; a grid or vdb medium's `albedo` grid (1 or 3 channels): every value in [0, 1], checked when it loads |
//! | `g` | (−1, 1) exclusive |
//! | `size`, `radius`, quad edge lengths, grid extents | (0, 1e7] m |
//! | `irradiance`, `radiance`, `intensity`, `scale`, `emission_scale` | components >= 0 |
//! | shape `emission` | each component finite, in [0, 1e12] W/(m²·sr) ([`MAX_RADIOMETRIC`]) |
//! | `temperature_offset`, `temperature_scale`, `blackbody_scale` | [−1e6, 1e6] K, [0, 1e6] K per unit, [0, 1e12]; each an error without `temperature`; the hottest voxel's blackbody radiance at most 1e12 W/(m²·sr) (checked when the grid loads: [`blackbody`]) |
//! | `bounds_min` < `bounds_max` | componentwise |
//! | grid `dims` | each 1..=4096, product <= 2^31 voxels |
//! | raw grid files | exactly nx·ny·nz·4 bytes (·3 channels for `velocity`) |
//! | `.vol` files | magic `VOL`, version 3, encoding 1 (float32), 2 (float16) or 3 (uint8, read as value / 255), 1 channel (1 or 3 for `emission`, 3 for `velocity`), dims as above, size 48 + n·channels·bytes per value; `dims`, if given, must match the header |
//! | environment `file` | ends in `.exr` (any case) and exists |
//! | gobo | 3..=64 `[u, v]` points, each coordinate within ±1e7 m, convex, non-zero area, no repeated consecutive point; clockwise input is reversed to counter-clockwise |
//! | quad | `edge_u`, `edge_v` non-zero and not parallel (sin angle > 1e-6) |
//! | convex `planes` | 4..=64 `[nx, ny, nz, d]`, no zero normal; their intersection bounded (within 1e3·max|d| + 1e8 m), with a non-empty interior, spanning at most 1e7 m (see [`convex`]) |
//! | media | may share volume: the pairs that do are found by an exact separating-axis test on (rotated) boxes, convex polyhedra and grid extents (touching within 1e-6 × the scene scale is not sharing) and listed in [`Scene::overlaps`]; integrators that take disjoint media refuse them when the render is planned |
//! | `max_bounces` | 1..=1024 |
//! | `volume` | `"restir"`, `"baseline"` |
//! | `box_estimator` | `"mcwvds"`, `"reds"`, `"rees"`, `"rm"`, `"mcds"`, `"me"` |
//! | `moment_map_size` | a power of two in 16..=4096 |
//! | restir `candidates` | 1..=4096 |
//! | restir `candidates_settled` | 1..=4096 (at most `candidates` takes effect) |
//! | restir `temporal` | `true`, `false`, or `"auto"` (off for a still of a static scene) |
//! | restir `temporal_limit` | 1..=1024 or `"auto"` (60 where nothing moves, 20 in an animation; turn temporal reuse off with `temporal = false`) |
//! | restir `temporal_limit_moving` | 1..=1024 (Q where the camera or the density moved: the smaller of it and `temporal_limit`) |
//! | restir `spatial_neighbors` | 0..=16 ([`MAX_SPATIAL_NEIGHBORS`]) |
//! | restir `spatial_radius_px` | [0, 16384], or `"auto"` |
//! | restir `spatial_when` | `"always"`, `"camera_moves"`, `"camera_or_density"` |
//! | restir `spatial_rounds` | 0..=16 |
//! | restir `mip_candidates` | 0..=16 |
//! | restir `mip_indirect`, `mip_reuse` | 0..=16, or `"auto"` |
//! | restir `mis` | `"talbot"`, `"pairwise"` |
//! | restir `temporal_history` | `"spatial"`, `"temporal"` |
//! | restir `sigma_star_floor` | [0, 1] |
//! | restir `spatial_shift` | `"distance"`, `"optical_depth"`, `"optical_depth_exact"` (the distance where box or convex media are beside the grid) |
//! | restir `env_reuse` | `"map"`, `"world"` |
//! | restir `emission` | `"separate"`, `"folded"` (folded only takes effect with split NEE) |
//! | restir `spatial_max_history` | [0, 1025] (0: spatial reuse on every pixel) |
//! | restir `spatial_feature_tolerance` | [0, 1] (0: every neighbour is combined) |
//! | restir `nee` | `"auto"`, `"one"`, `"split"` (only with delta lights and an environment alone besides) |
//! | restir `direct` | `"each_walk"`, `"escape"` |
//! | restir `candidate_tracking` | `"auto"`, `"delta"`, `"regular"` |
//! | restir `target` | `"luminance"`, `"sum"`, `"max"` |
//! | restir `camera_emission` | `"reservoir"`, `"stratified"` |
//! | restir `temporal_reprojection` | `"path"`, `"aligned"` |
//! | restir `temporal_shift` | `"anchor"`, `"optical_depth"` (the anchors where box or convex media are beside the grid) |
//! | restir `pc_fetch` | `"auto"`, `"image"`, `"buffer"` (refused where the buffer exceeds the device's storage-buffer range) |
//! | restir `density_fetch` | `"auto"`, `"image"`, `"buffer"` (refused where the buffer exceeds the device's storage-buffer range) |
//! | baseline `nee` | `"auto"`, `"one"`, `"split"` |
//! | baseline `density_fetch` | `"auto"`, `"image"`, `"buffer"` |
//! | grid `procedural` | `"cloud"`, `"cumulus"` (not allowed for `velocity`) |
//! | mesh `file` | ends in `.obj` or `.ply` (any case), exists, and loads (see [`mesh`]: finite vertices, also after `to_world`; indices in range; fannable faces; at most 2^26 triangles) |
//! | `to_world` `scale` | each component non-zero, magnitude at most 1e7; `translate` within ±1e7 m |
//!
//! # Voxel grids
//! Grid contents are read by [`load_grid`] (not by [`load`]) into a [`VoxelGrid`]
//! (x fastest, then y, then z, channels interleaved). It refuses grids over
//! [`MAX_GRID_VALUES`] (2^31 voxels·channels, 8 GiB of f32) before allocating, and
//! rejects NaN / infinite values anywhere and negative density or emission, naming
//! the file, the voxel (i, j, k) and the value. `procedural = "cloud"` grids come from
//! [`procedural_cloud`], `"cumulus"` ones from [`procedural_cumulus`], bit-identical for a
//! `(dims, noise_seed)` on every platform.
//!
//! # Animated grids
//! [`GridMedium::density_index_at`] / [`GridMedium::density_at`] give the density grid
//! in effect at a frame (the latest `[[medium.frame]]` at or before it, else the base
//! `density`), indexing [`GridMedium::density_sources`]. The format lets frame grids
//! and the velocity grid have dims other than the density's; the loader does not
//! compare them. A renderer that needs them equal calls
//! [`GridMedium::animation_dims`] (reads `.vol` headers only) and compares the grids
//! it loads with [`check_same_dims`]. Velocity grids load with `load_grid(source, 3,
//! what)`.
//!
//! Derived structures, all in voxel-index space (voxel centres at i + 0.5):
//! - [`VoxelGrid::sample_trilinear`]: trilinear between centres, clamped to the
//!   outermost centre within half a voxel of a face.
//! - [`VoxelGrid::mip_chain`]: halving (rounding up) by averaging 2×2×2 children, down
//!   to 1×1×1.
//! - [`VoxelGrid::conservative_piecewise_constant`]: nearest density, zero voxels
//!   replaced by the average of their 26 neighbours (Volumetric ReSTIR sec. 4.1), so
//!   σ* > 0 wherever the trilinear σ > 0 anywhere in the voxel.
//! - [`VoxelGrid::super_voxels`]: per 8³ block, min / max bounding the trilinear
//!   density over the block (one-voxel apron) and its exact mean.
//!
//! # OpenVDB files
//! [`read_vdb_grid`] reads one grid of a `.vdb` file into a [`SparseGrid`]: the
//! tree's 8³ leaf nodes as bricks plus constant tiles, the index-to-world transform
//! as an affine matrix, the background and the active bounding box, so memory follows
//! the active voxels. [`list_grids`] names a file's grids for messages. [`vdb`] lists
//! what of the format is supported. `[[medium]] type = "vdb"` reads each grid's header
//! and topology ([`read_vdb_topology`]) when the scene loads, and its values into the
//! dense window around the active voxels ([`VdbWindow`]) when the grid loads
//! ([`load_grid`]).
//!
//! # Triangle meshes
//! The [`mesh`] module (re-exported here) loads `.obj` / `.ply` files into a
//! [`TriangleMesh`] ([`load_mesh`], placed by a [`ToWorld`]), builds a [`Bvh`] of
//! 32-byte [`BvhNode`]s for the GPU, and answers rays on the CPU
//! ([`Bvh::closest_hit`], [`Bvh::any_hit`]) as the reference for the GPU traversal.
//! `[[shape]] type = "mesh"` (`file`, optional `to_world` as for vdb media, `albedo`)
//! loads its file and builds its BVH when the scene loads, into a [`MeshShape`] that
//! [`Shape::Mesh`] shares (`Arc`); errors name the scene file, the shape, the field
//! and the mesh file.

mod animation;
pub mod blackbody;
pub mod bricks;
pub mod cie1931;
pub mod convex;
mod cumulus;
mod envmap;
mod fields;
mod files;
mod geometry;
pub mod mesh;
mod overrides;
mod parse;
pub mod precision;
mod procedural;
mod types;
pub mod vdb;
mod vol_write;
mod volume;

use std::path::Path;

use anyhow::{anyhow, Result};

pub use bricks::{BrickGrid, BrickTopology};
pub use cumulus::procedural_cumulus;
pub use envmap::{
    direction_to_uv, environment_rotation, luminance, uv_to_direction, EnvMap, EnvRotation,
    EnvSampler, MAX_ENVMAP_HEIGHT, MAX_ENVMAP_WIDTH,
};
pub use fields::MAX_RADIOMETRIC;
pub use files::{
    check_grid_dims, read_vol_header, VolEncoding, VolHeader, MAX_GRID_DIM, MAX_GRID_VOXELS,
    VOL_HEADER_BYTES,
};
pub use geometry::MAX_GOBO_POINTS;
pub use mesh::{
    intersect_triangle, load_mesh, read_mesh, Bvh, BvhNode, Hit, LoadedMesh, MeshFormat, MeshShape,
    Ray, ToWorld, TriangleMesh, BVH_MAX_DEPTH, BVH_MAX_LEAF_TRIANGLES, BVH_STACK_SIZE,
    MAX_FACE_NONPLANARITY, MAX_FACE_VERTICES, MAX_LINE_BYTES, MAX_MESH_TRIANGLES,
    MAX_MESH_VERTICES,
};
pub use overrides::FieldOverride;
pub use parse::{
    scene_tables, TableFields, BASELINE_KEYS, MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE, MAX_LENGTH_M,
    MAX_SIGMA_T, MAX_SPATIAL_NEIGHBORS, RESTIR_KEYS,
};
pub use procedural::{daylight_sky, fbm_noise, procedural_cloud, sun_direction};
pub use types::*;
pub use vdb::{
    list_grids, read_vdb_grid, read_vdb_topology, GridClass, SparseGrid, ValueType, VdbGridHeader,
    VdbGridInfo, VdbGridKind, VdbTile, VdbTopology, BRICK_VOXELS, LEAF_DIM, MAX_ACTIVE_VOXELS,
};
pub use vol_write::{write_vol, write_vol_encoded};
pub use volume::{
    check_grid_memory, check_same_dims, load_grid, SuperVoxels, VoxelGrid, MAX_GRID_VALUES,
    SUPER_VOXEL_FACTOR,
};

/// Reads and validates the scene file at `path`.
pub fn load(path: &Path) -> Result<Scene> {
    load_with(path, &[])
}

/// The largest scene file read: a scene is a page of TOML (the files it names hold the
/// data), so anything larger is not one.
pub const MAX_SCENE_FILE_BYTES: u64 = 16 << 20;

/// Reads the scene file at `path` once: a regular file (a FIFO, a terminal or a device
/// such as /dev/zero would hang or never end) of at most [`MAX_SCENE_FILE_BYTES`], in
/// UTF-8. Callers that also hash the scene hash these bytes, so the render and its
/// metadata describe the same file contents.
pub fn read_scene_file(path: &Path) -> Result<String> {
    use std::io::Read as _;
    let fail = |what: String| anyhow!("{}: cannot read scene file: {what}", path.display());
    let meta = std::fs::metadata(path).map_err(|e| fail(e.to_string()))?;
    if !meta.is_file() {
        return Err(fail(
            "not a regular file (a pipe, terminal or device is refused: write the scene to a \
             file)"
                .into(),
        ));
    }
    if meta.len() > MAX_SCENE_FILE_BYTES {
        return Err(fail(format!(
            "{} bytes, more than a scene file's {} MiB",
            meta.len(),
            MAX_SCENE_FILE_BYTES >> 20
        )));
    }
    let file = std::fs::File::open(path).map_err(|e| fail(e.to_string()))?;
    let mut bytes = Vec::new();
    file.take(MAX_SCENE_FILE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| fail(e.to_string()))?;
    if bytes.len() as u64 > MAX_SCENE_FILE_BYTES {
        return Err(fail(format!(
            "it grew past a scene file's {} MiB while being read",
            MAX_SCENE_FILE_BYTES >> 20
        )));
    }
    String::from_utf8(bytes).map_err(|e| fail(format!("not UTF-8 text ({e})")))
}

/// Reads the scene file at `path` ([`read_scene_file`]), applies `overrides` to its
/// tables, and validates the result (an overridden field is checked like one written in
/// the file).
pub fn load_with(path: &Path, overrides: &[FieldOverride]) -> Result<Scene> {
    let text = read_scene_file(path)?;
    parse_str_with(&text, path, overrides)
}

/// Parses and validates a scene from `text`. `source` names the scene in error
/// messages, and relative file paths resolve against `source.parent()`.
pub fn parse_str(text: &str, source: &Path) -> Result<Scene> {
    parse_str_with(text, source, &[])
}

/// [`parse_str`] with `overrides` applied to the tables before validation.
/// A value refused only because of an override says so, naming the overrides (issue 24:
/// `--set render.width=abc` was reported as if the scene file held "abc").
pub fn parse_str_with(text: &str, source: &Path, overrides: &[FieldOverride]) -> Result<Scene> {
    let result = parse::parse_scene(text, source, overrides);
    match result {
        Err(e) if !overrides.is_empty() && parse::parse_scene(text, source, &[]).is_ok() => {
            let given: Vec<String> = overrides.iter().map(FieldOverride::describe).collect();
            Err(anyhow::anyhow!(
                "{e:#} (the scene file itself is valid: the value comes from {})",
                given.join(", ")
            ))
        }
        other => other,
    }
}
