//! Helpers shared by the scene-file tests.

#![allow(dead_code)]

pub mod contract;

use std::path::{Path, PathBuf};

use nimbus_scene::{parse_str, Scene};

/// The name every in-memory test scene is parsed under.
pub const SCENE: &str = "scenes/test.toml";

/// A camera table every test scene can start from.
pub const CAMERA: &str = "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n";

pub fn parse(text: &str) -> anyhow::Result<Scene> {
    parse_str(text, Path::new(SCENE))
}

/// Parses `CAMERA` + `text`, which must succeed.
pub fn parse_ok(text: &str) -> Scene {
    match parse(&format!("{CAMERA}{text}")) {
        Ok(scene) => scene,
        Err(e) => panic!("scene should parse, got: {e:#}"),
    }
}

/// Parses `CAMERA` + `text`, which must fail, and returns the message.
pub fn parse_err(text: &str) -> String {
    match parse(&format!("{CAMERA}{text}")) {
        Ok(scene) => panic!("scene should be rejected, parsed as {scene:#?}"),
        Err(e) => format!("{e:#}"),
    }
}

/// Asserts that `message` contains every one of `needles`.
#[track_caller]
pub fn assert_contains(message: &str, needles: &[&str]) {
    for needle in needles {
        assert!(
            message.contains(needle),
            "error message lacks {needle:?}:\n{message}"
        );
    }
}

/// A fresh, empty directory under the system temp dir, removed on drop.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(name: &str) -> Self {
        let unique = format!(
            "nimbus-scene-{name}-{}-{:?}",
            std::process::id(),
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap_or_default()
                .as_nanos()
        );
        let dir = std::env::temp_dir().join(unique);
        std::fs::create_dir_all(&dir).expect("create temp dir");
        Self(dir)
    }

    /// Writes `bytes` to `relative` inside the directory (creating parents).
    pub fn write(&self, relative: &str, bytes: &[u8]) -> PathBuf {
        let path = self.0.join(relative);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).expect("create parent dir");
        }
        std::fs::write(&path, bytes).expect("write temp file");
        path
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// `n` float32 zeros as raw bytes.
pub fn raw_floats(n: usize) -> Vec<u8> {
    vec![0u8; n * 4]
}

/// A Mitsuba `.vol` file: header with `dims` and `channels`, then zeroed float32 data.
pub fn vol_file(dims: [i32; 3], channels: i32) -> Vec<u8> {
    let mut bytes = b"VOL".to_vec();
    bytes.push(3);
    for value in [1, dims[0], dims[1], dims[2], channels] {
        bytes.extend_from_slice(&value.to_le_bytes());
    }
    for value in [0.0f32, 0.0, 0.0, 1.0, 1.0, 1.0] {
        bytes.extend_from_slice(&value.to_le_bytes());
    }
    let n = dims.iter().map(|&d| d.max(0) as usize).product::<usize>() * channels.max(0) as usize;
    bytes.extend(raw_floats(n));
    bytes
}

/// A regular dodecahedron of inradius `r` centred at `center` as `[[medium]] type =
/// "convex"` planes (face normals along the icosahedron's vertices, not normalized, so
/// the loader's normalization is exercised), with extinction `sigma_t`.
pub fn dodecahedron(center: [f64; 3], r: f64, sigma_t: f64) -> String {
    let phi = (1.0 + 5f64.sqrt()) / 2.0;
    let mut normals = Vec::new();
    for a in [-1.0, 1.0] {
        for b in [-phi, phi] {
            normals.push([0.0, a, b]);
            normals.push([a, b, 0.0]);
            normals.push([b, 0.0, a]);
        }
    }
    let planes: Vec<String> = normals
        .iter()
        .map(|n| {
            let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let d = r * length + n[0] * center[0] + n[1] * center[1] + n[2] * center[2];
            format!("[{}, {}, {}, {d}]", n[0], n[1], n[2])
        })
        .collect();
    format!(
        "[[medium]]\ntype = \"convex\"\nplanes = [{}]\nsigma_t = {sigma_t}\n",
        planes.join(", ")
    )
}
