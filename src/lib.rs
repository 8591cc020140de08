//! Nimbus: a raw-Vulkan compute renderer for participating media.
//!
//! The root package turns a scene into a render plan ([`plan`]) and runs it
//! ([`renderer`]), one compute pass per module under [`passes`]: scene → plan → passes →
//! renderer → output (the README's "Layout" lists where each lives).

pub mod bench;
pub mod budget;
pub mod denoise;
pub mod hashing;
pub mod merge;
pub mod output;
pub mod passes;
pub mod plan;
pub mod profile;
pub mod renderer;
pub mod shader_data;

use std::path::{Path, PathBuf};

use anyhow::Result;
use nimbus_scene::{FieldOverride, Scene};

/// SPIR-V of every shader, compiled by `build.rs`.
pub mod shaders {
    include!(concat!(env!("OUT_DIR"), "/shaders.rs"));
}

/// The default scene (`assets/scenes/window.toml`), embedded in the binary.
pub const DEFAULT_SCENE: &str = include_str!("../assets/scenes/window.toml");

/// Load `path`, or the embedded default scene when there is none, with `overrides`
/// applied to its fields before validation.
pub fn load_scene(path: Option<&Path>, overrides: &[FieldOverride]) -> Result<Scene> {
    load_scene_text(path, overrides).map(|(scene, _)| scene)
}

/// [`load_scene`], also returning the scene file's text exactly as it was read and
/// parsed (one read: a render hashes what it rendered, even if the file changes).
pub fn load_scene_text(
    path: Option<&Path>,
    overrides: &[FieldOverride],
) -> Result<(Scene, String)> {
    match path {
        Some(path) => {
            let text = nimbus_scene::read_scene_file(path)?;
            let scene = nimbus_scene::parse_str_with(&text, path, overrides)?;
            Ok((scene, text))
        }
        None => {
            let scene = nimbus_scene::parse_str_with(
                DEFAULT_SCENE,
                &PathBuf::from("assets/scenes/window.toml (embedded default)"),
                overrides,
            )?;
            Ok((scene, DEFAULT_SCENE.to_string()))
        }
    }
}
