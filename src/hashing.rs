//! Content hashes (FNV-1a, 64 bit): of files, and of a scene together with every file it
//! reads. A render's `nimbus/scene_hash` ([`scene_hash`]) is what `nimbus merge` and
//! `nimbus render --resume` compare, so that parts rendered from different data never
//! mix; the study's reference cache keys on the same inputs.

use std::io::Read as _;
use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result};
use nimbus_scene::{GridSource, Light, Medium, Scene, Shape};

/// FNV-1a, 64 bit, over `bytes`, continuing from `hash` (start with [`FNV_OFFSET`]).
pub fn fnv1a64(mut hash: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        hash ^= u64::from(b);
        hash = hash.wrapping_mul(0x0000_0100_0000_01B3);
    }
    hash
}

/// The FNV-1a 64 offset basis.
pub const FNV_OFFSET: u64 = 0xCBF2_9CE4_8422_2325;

/// The FNV-1a 64 hash of the contents of the file at `path`, read in pieces (grid files
/// can be large).
pub fn hash_file(path: &Path) -> Result<u64> {
    let mut file = std::fs::File::open(path)
        .with_context(|| format!("{}: cannot open to hash it", path.display()))?;
    let mut buffer = vec![0u8; 1 << 20];
    let mut hash = FNV_OFFSET;
    loop {
        let n = file
            .read(&mut buffer)
            .with_context(|| format!("{}: cannot read to hash it", path.display()))?;
        if n == 0 {
            return Ok(hash);
        }
        hash = fnv1a64(hash, &buffer[..n]);
    }
}

/// A file the scene reads besides itself, with the hash of its contents.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InputFile {
    /// Where the scene names it, e.g. `[[medium]] #1 density`.
    pub role: String,
    pub path: PathBuf,
    /// FNV-1a 64 of its bytes.
    pub hash: u64,
}

/// Every file `scene` reads besides the scene file, with where it names it: the grid
/// files of each `[[medium]]` (density, emission, velocity, each `[[medium.frame]]`'s
/// density) and environment maps. Procedural grids read no file.
///
/// The patterns below name every field and variant on purpose: a new one that can
/// name a file does not compile until it is considered here.
pub fn scene_files(scene: &Scene) -> Vec<(String, &Path)> {
    let Scene {
        source: _,
        render: _,
        camera: _,
        lights,
        light_keyframes: _,
        // Names only.
        light_groups: _,
        media,
        // Follows from the media.
        overlaps: _,
        shapes,
        integrator: _,
    } = scene;
    fn grid_file(source: &GridSource) -> Option<&Path> {
        match source {
            GridSource::Raw { file, dims: _ }
            | GridSource::MitsubaVol { file }
            | GridSource::Vdb {
                file,
                grid: _,
                window: _,
            } => Some(file.as_path()),
            GridSource::ProceduralCloud { .. } => None,
        }
    }
    let mut out: Vec<(String, &Path)> = Vec::new();
    for (i, medium) in media.iter().enumerate() {
        let grid = match medium {
            Medium::Grid(grid) => grid,
            Medium::Box(_) | Medium::Convex(_) => continue,
        };
        let nimbus_scene::GridMedium {
            bounds_min: _,
            bounds_max: _,
            density,
            density_scale: _,
            albedo: _,
            albedo_grid,
            g: _,
            emission,
            emission_scale: _,
            temperature,
            velocity,
            velocity_scale: _,
            frames,
            // Where its files' grids sit, read from the files hashed below.
            vdb: _,
        } = grid;
        let table = format!("[[medium]] #{}", i + 1);
        let mut sources: Vec<(String, &GridSource)> = vec![(format!("{table} density"), density)];
        sources.extend(emission.iter().map(|e| (format!("{table} emission"), e)));
        sources.extend(albedo_grid.iter().map(|a| (format!("{table} albedo"), a)));
        sources.extend(
            temperature
                .iter()
                .map(|t| (format!("{table} temperature"), &t.source)),
        );
        sources.extend(velocity.iter().map(|v| (format!("{table} velocity"), v)));
        for (j, frame) in frames.iter().enumerate() {
            sources.push((
                format!("{table} [[medium.frame]] #{} density", j + 1),
                &frame.density,
            ));
            for (key, grid) in [
                ("temperature", &frame.temperature),
                ("albedo", &frame.albedo),
                ("emission", &frame.emission),
            ] {
                sources.extend(
                    grid.iter()
                        .map(|g| (format!("{table} [[medium.frame]] #{} {key}", j + 1), g)),
                );
            }
        }
        out.extend(
            sources
                .into_iter()
                .filter_map(|(what, source)| grid_file(source).map(|p| (what, p))),
        );
    }
    for (i, light) in lights.iter().enumerate() {
        match light {
            Light::Environment {
                file: Some(file), ..
            } => out.push((format!("[[light]] #{} file", i + 1), file.as_path())),
            Light::Environment { file: None, .. }
            | Light::Directional { .. }
            | Light::Point { .. }
            | Light::Sphere { .. } => {}
        }
    }
    for (i, shape) in shapes.iter().enumerate() {
        match shape {
            Shape::Quad { .. } | Shape::Box { .. } | Shape::Sphere { .. } => {}
            Shape::Mesh { mesh, .. } => {
                out.push((format!("[[shape]] #{} file", i + 1), mesh.file.as_path()));
            }
        }
    }
    out
}

/// Every file `scene` reads besides the scene file ([`scene_files`]), each hashed.
pub fn scene_inputs(scene: &Scene) -> Result<Vec<InputFile>> {
    scene_files(scene)
        .into_iter()
        .map(|(role, path)| {
            Ok(InputFile {
                hash: hash_file(path).with_context(|| role.clone())?,
                role,
                path: path.to_path_buf(),
            })
        })
        .collect()
}

/// The hash of a scene as renders record it (`nimbus/scene_hash`, 16 hex digits): the
/// scene file's bytes, then the role and contents of every file the scene reads
/// ([`scene_inputs`]), so that a density or environment map changed under an unchanged
/// scene file changes it too. Errors name the file and where the scene names it.
pub fn scene_hash(scene_bytes: &[u8], scene: &Scene) -> Result<String> {
    let mut hash = fnv1a64(FNV_OFFSET, scene_bytes);
    for input in scene_inputs(scene)? {
        hash = fnv1a64(
            hash,
            format!("\nfile {}={:016x}", input.role, input.hash).as_bytes(),
        );
    }
    Ok(format!("{hash:016x}"))
}
