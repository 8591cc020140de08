//! Geometry that must be rejected: gobos, cameras and their keyframes, quads, and a
//! camera inside a sphere light.

use super::*;

#[test]
fn bad_gobos_are_rejected() {
    let check = |gobo: &str, needles: &[&str]| {
        let error = parse_err(&format!("{DIRECTIONAL}gobo = {gobo}\n"));
        assert_contains(
            &error,
            &[
                SCENE,
                "[[light]] #1 (type = \"directional\")",
                "field `gobo`",
            ],
        );
        assert_contains(&error, needles);
    };
    check("[[0, 0], [2, 1], [0, 2], [0.5, 1]]", &["not convex"]);
    check("[[0, 0], [1, 0]]", &["at least 3 points"]);
    check("[[0, 0], [1, 0], [2, 0]]", &["zero area"]);
    check("[[0, 0], [1, 0], [0, nan]]", &["point 2", "finite"]);
    check("[[0, 0], [1, 0], [0, 1, 2]]", &["point 2"]);
    check("[0, 1, 2]", &["point 0"]);
    let error = parse_err(&format!("{DIRECTIONAL}gobo_origin = [0, 1, 0]\n"));
    assert_contains(&error, &["field `gobo_origin`", "without `gobo`"]);
}

#[test]
fn degenerate_cameras_are_rejected() {
    let error = parse("[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 5]\n").unwrap_err();
    assert_contains(
        &format!("{error:#}"),
        &[SCENE, "[camera]", "field `look_at`", "coincide"],
    );
    let error = parse("[camera]\nposition = [0, 5, 0]\nlook_at = [0, 0, 0]\n").unwrap_err();
    assert_contains(
        &format!("{error:#}"),
        &[SCENE, "[camera]", "field `up`", "parallel"],
    );
    let error = parse("[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, -1]\nup = [0, 0, 3]\n")
        .unwrap_err();
    assert_contains(&format!("{error:#}"), &["field `up`", "parallel"]);
    let error = parse(&format!(
        "{CAMERA}[[camera.keyframe]]\nframe = 3\nposition = [0, 2, 0]\nlook_at = [0, 0, 0]\n"
    ))
    .unwrap_err();
    assert_contains(
        &format!("{error:#}"),
        &[
            SCENE,
            "[[camera.keyframe]] #1",
            "field `look_at`",
            "parallel",
        ],
    );
}

#[test]
fn interpolated_camera_poses_are_checked() {
    // Position and look_at swap places between frames 0 and 10 and meet at frame 5.
    let text = "[render]\nframes = 11\n[camera]\n\
                [[camera.keyframe]]\nframe = 0\nposition = [0, 0, 1]\nlook_at = [0, 0, -1]\n\
                [[camera.keyframe]]\nframe = 10\nposition = [0, 0, -1]\nlook_at = [0, 0, 1]\n";
    let error = format!("{:#}", parse(text).unwrap_err());
    assert_contains(
        &error,
        &[SCENE, "[camera]", "field `keyframe`", "frame 5", "coincide"],
    );
    // Rendering only frames 0..5 never reaches the degenerate pose.
    assert!(parse(&text.replace("frames = 11", "frames = 5")).is_ok());
}

#[test]
fn duplicate_frames_are_rejected() {
    let error = parse(&format!(
        "{CAMERA}[[camera.keyframe]]\nframe = 2\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\n\
         [[camera.keyframe]]\nframe = 2\nposition = [0, 0, 2]\nlook_at = [0, 0, 0]\n"
    ))
    .unwrap_err();
    assert_contains(
        &format!("{error:#}"),
        &[
            SCENE,
            "[[camera.keyframe]] #1",
            "[[camera.keyframe]] #2",
            "field `frame`",
            "unique",
        ],
    );
    let error = parse_err(&format!(
        "{GRID}density = {{ procedural = \"cloud\", dims = [2, 2, 2] }}\n\
         [[medium.frame]]\nframe = 4\ndensity = {{ procedural = \"cloud\", dims = [2, 2, 2] }}\n\
         [[medium.frame]]\nframe = 4\ndensity = {{ procedural = \"cloud\", dims = [2, 2, 2], noise_seed = 1 }}\n"
    ));
    assert_contains(
        &error,
        &[
            SCENE,
            "[[medium.frame]] #1",
            "[[medium.frame]] #2",
            "field `frame`",
            "unique",
        ],
    );
}

#[test]
fn degenerate_quads_are_rejected() {
    let quad = |u: &str, v: &str| {
        parse_err(&format!(
            "[[shape]]\ntype = \"quad\"\ncorner = [0, 0, 0]\nedge_u = {u}\nedge_v = {v}\n"
        ))
    };
    assert_contains(
        &quad("[1, 0, 0]", "[-2, 0, 0]"),
        &[
            SCENE,
            "[[shape]] #1 (type = \"quad\")",
            "field `edge_v`",
            "parallel",
        ],
    );
    assert_contains(
        &quad("[0, 0, 0]", "[0, 1, 0]"),
        &["field `edge_u`", "zero vector"],
    );
}

/// A sphere light around the camera (issue 24: the camera saw its inside at radiance 4
/// while it lit nothing inside it) is refused, naming the light and the frame; outside
/// it, or around the medium only, it is fine.
#[test]
fn a_camera_inside_a_sphere_light_is_refused() {
    let sphere = |center: &str, radius: f32| {
        format!(
            "[[light]]\ntype = \"sphere\"\ncenter = {center}\nradius = {radius}\nradiance = 4\n"
        )
    };
    let error = parse_err(&format!("{DIRECTIONAL}{}", sphere("[0, 0, 0]", 50.0)));
    assert_contains(
        &error,
        &[
            SCENE,
            "[[light]] #2 (type = \"sphere\")",
            "camera is inside it at frame 0",
            "type = \"environment\"",
        ],
    );
    parse_ok(&sphere("[0, 30, 0]", 1.0));
    // A light that moves over the camera at frame 2 of 3.
    let keyed = format!(
        "[render]\nframes = 3\n{}[[light.keyframe]]\nframe = 0\ncenter = [0, 30, 0]\n\
         [[light.keyframe]]\nframe = 2\ncenter = [0, 0, 0]\n",
        sphere("[0, 30, 0]", 20.0)
    );
    let error = parse_err(&keyed);
    assert_contains(&error, &["[[light]] #1", "inside it at frame 1"]);
}
