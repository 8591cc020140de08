//! The EXR of a render carries the standard attributes compositors read (issue 28, item
//! 3), checked with OpenEXR's own `exrheader` (Debian's `openexr`, installed by
//! tools/install-deps.sh): Rec. 709 / D65 chromaticities, the camera's `worldToCamera`
//! and `worldToNDC`, the screen window, and the frame of an animation's frame.

use std::process::Command;

use crate::common::cli::{nimbus, scratch, text};

/// A box under a sun, seen by a camera that moves over four frames.
const ANIMATED: &str = r#"
[render]
width = 8
height = 6
frames = 4
[camera]
horizontal_fov_deg = 60
[[camera.keyframe]]
frame = 0
position = [0.3, 0.8, 4.0]
look_at = [0.0, 0.0, 0.0]
[[camera.keyframe]]
frame = 3
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
[[light]]
type = "directional"
direction = [0.4, -1.0, -0.3]
irradiance = 2.0
[[medium]]
type = "box"
center = [0.0, 0.0, 0.0]
size = [1.0, 1.0, 1.0]
sigma_t = 1.0
albedo = 0.8
"#;

#[test]
fn exrheader_shows_the_standard_attributes() {
    let dir = scratch("exr_header", "animated");
    let scene = dir.join("anim.toml");
    std::fs::write(&scene, ANIMATED).unwrap();
    let exr = dir.join("frame3.exr");
    let out = nimbus(&[
        "render",
        scene.to_str().unwrap(),
        "--frame",
        "3",
        "--out",
        exr.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let header = Command::new("exrheader")
        .arg(&exr)
        .output()
        .expect("exrheader runs (Debian's openexr: tools/install-deps.sh installs it)");
    assert!(header.status.success(), "{}", text(&header.stderr));
    let header = text(&header.stdout);
    for line in [
        "chromaticities (type chromaticities):",
        "red   (0.64 0.33)",
        "green (0.3 0.6)",
        "blue  (0.15 0.06)",
        "white (0.3127 0.329)",
        "frame (type int): 3",
        "screenWindowCenter (type v2f): (0 0)",
        // 2 tan(30°).
        "screenWindowWidth (type float): 1.1547",
        "worldToCamera (type m44f):",
        "worldToNDC (type m44f):",
        // Frame 3's camera looks down -Z from (0, 0, 4): camera x = world x, camera z =
        // -world z, 4 m to the origin.
        "(1 0 0 0",
        "0 0 -1 0",
        "-0 -0 4 1)",
    ] {
        assert!(header.contains(line), "no {line:?} in:\n{header}");
    }
}
