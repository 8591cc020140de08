//! Scene files that must be rejected, each with a message naming the file, the table
//! and the field.

use crate::common::*;
use nimbus_scene::{load, parse_str};

const BOX: &str = "[[medium]]\ntype = \"box\"\ncenter = [0, 0, 0]\nsize = [1, 1, 1]\n";
const GRID: &str = "[[medium]]\ntype = \"grid\"\nbounds_min = [0, 0, 0]\nbounds_max = [1, 1, 1]\n";
const DIRECTIONAL: &str =
    "[[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1\n";

#[test]
fn missing_scene_file_names_the_path() {
    let path = std::env::temp_dir().join("nimbus-scene-does-not-exist/scene.toml");
    let error = format!("{:#}", load(&path).unwrap_err());
    assert_contains(
        &error,
        &["nimbus-scene-does-not-exist/scene.toml", "cannot read"],
    );
}

#[test]
fn toml_syntax_error_names_file_and_line() {
    let error = format!(
        "{:#}",
        parse_str("[camera]\nposition = [0, 0,\n", std::path::Path::new(SCENE)).unwrap_err()
    );
    assert_contains(&error, &[SCENE, "TOML syntax error", "line 2"]);
}

#[test]
fn missing_camera_is_rejected() {
    let error = format!("{:#}", parse("[render]\nwidth = 4\n").unwrap_err());
    assert_contains(&error, &[SCENE, "[camera]", "missing"]);
}

#[test]
fn unknown_fields_are_named_with_the_valid_ones() {
    let error = parse_err("[render]\nwidht = 5\n");
    assert_contains(
        &error,
        &[
            SCENE,
            "[render]",
            "field `widht`",
            "unknown field",
            "width, height, frames, spp, seed",
        ],
    );
    let error = parse_err(&format!("{DIRECTIONAL}colour = 1\n"));
    assert_contains(
        &error,
        &[
            SCENE,
            "[[light]] #1 (type = \"directional\")",
            "field `colour`",
            "direction, irradiance, gobo, gobo_origin",
        ],
    );
    let error = parse_err("[integrator.restir]\ncandidate = 3\n");
    assert_contains(
        &error,
        &[
            SCENE,
            "[integrator.restir]",
            "field `candidate`",
            "candidates",
        ],
    );
    let error = parse_err("[[lights]]\ntype = \"point\"\n");
    assert_contains(
        &error,
        &[SCENE, "top level", "field `lights`", "light, medium"],
    );
    let error = parse_err(&format!(
        "{GRID}density = {{ procedural = \"cloud\", dims = [1, 1, 1], seed = 3 }}\n"
    ));
    assert_contains(
        &error,
        &[
            SCENE,
            "[[medium]] #1 (type = \"grid\") > density",
            "field `seed`",
            "noise_seed",
        ],
    );
    // Grid-only fields are unknown on a box medium.
    let error = parse_err(&format!("{BOX}sigma_t = 1\ndensity_scale = 2\n"));
    assert_contains(
        &error,
        &[
            SCENE,
            "[[medium]] #1 (type = \"box\")",
            "field `density_scale`",
        ],
    );
}

#[test]
fn wrong_types_say_what_was_expected() {
    let error = parse_err("[render]\nwidth = \"wide\"\n");
    assert_contains(
        &error,
        &[
            SCENE,
            "[render]",
            "field `width`",
            "expected an integer",
            "found a string",
        ],
    );
    let error = parse_err("[render]\nwidth = 256.0\n");
    assert_contains(
        &error,
        &["field `width`", "expected an integer", "found a float"],
    );
    let error = parse_err("[[light]]\ntype = \"directional\"\ndirection = 3\nirradiance = 1\n");
    assert_contains(
        &error,
        &[
            SCENE,
            "[[light]] #1 (type = \"directional\")",
            "field `direction`",
            "array of 3 numbers",
        ],
    );
    let error = parse_err("[[light]]\ntype = \"point\"\nposition = [0, 0]\nintensity = 1\n");
    assert_contains(
        &error,
        &["field `position`", "3 numbers", "found 2 elements"],
    );
    let error =
        parse_err("[[light]]\ntype = \"point\"\nposition = [0, 0, 0]\nintensity = \"red\"\n");
    assert_contains(
        &error,
        &[
            SCENE,
            "[[light]] #1 (type = \"point\")",
            "field `intensity`",
            "colour",
        ],
    );
    let error = parse_err("[integrator.restir]\ntemporal = 1\n");
    assert_contains(
        &error,
        &[SCENE, "[integrator.restir]", "field `temporal`", "boolean"],
    );
    let error = parse_err("[light]\ntype = \"point\"\n");
    assert_contains(
        &error,
        &[SCENE, "top level", "field `light`", "array of tables"],
    );
    let error = parse_err("[[light]]\ntype = 4\n");
    assert_contains(
        &error,
        &[SCENE, "[[light]] #1", "field `type`", "expected a string"],
    );
}

#[test]
fn missing_required_fields_are_named() {
    let error = parse("[camera]\nposition = [0, 0, 1]\n").unwrap_err();
    assert_contains(
        &format!("{error:#}"),
        &[
            SCENE,
            "[camera]",
            "field `look_at`",
            "missing required field",
        ],
    );
    let error = parse_err("[[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\n");
    assert_contains(
        &error,
        &[
            SCENE,
            "[[light]] #1 (type = \"directional\")",
            "field `irradiance`",
            "missing",
        ],
    );
    let error = parse_err(BOX);
    assert_contains(
        &error,
        &[
            SCENE,
            "[[medium]] #1 (type = \"box\")",
            "field `sigma_t`",
            "missing",
        ],
    );
    let error = parse_err("[[shape]]\ncenter = [0, 0, 0]\n");
    assert_contains(
        &error,
        &[
            SCENE,
            "[[shape]] #1",
            "field `type`",
            "missing",
            "\"quad\", \"box\", \"sphere\"",
        ],
    );
    let error = parse_err(GRID);
    assert_contains(
        &error,
        &[
            SCENE,
            "[[medium]] #1 (type = \"grid\")",
            "field `density`",
            "missing",
        ],
    );
    let error = parse_err("[[light]]\ntype = \"environment\"\nscale = 2\n");
    assert_contains(
        &error,
        &[
            SCENE,
            "[[light]] #1 (type = \"environment\")",
            "field `radiance`",
            "`file`",
        ],
    );
    let error = parse_err(&format!("{GRID}density = {{ procedural = \"cloud\" }}\n"));
    assert_contains(&error, &[SCENE, "> density", "field `dims`", "missing"]);
}

#[test]
fn unknown_type_strings_list_the_valid_ones() {
    let error = parse_err("[[light]]\ntype = \"spot\"\n");
    assert_contains(
        &error,
        &[
            SCENE,
            "[[light]] #1",
            "field `type`",
            "\"spot\"",
            "\"directional\", \"environment\", \"point\", \"sphere\"",
        ],
    );
    let error = parse_err("[[medium]]\ntype = \"fog\"\n");
    assert_contains(
        &error,
        &[
            SCENE,
            "[[medium]] #1",
            "field `type`",
            "\"box\", \"convex\", \"grid\"",
        ],
    );
    let error = parse_err("[integrator]\nbox_estimator = \"best\"\n");
    assert_contains(
        &error,
        &[
            SCENE,
            "[integrator]",
            "field `box_estimator`",
            "\"mcwvds\", \"reds\", \"rees\", \"rm\", \"mcds\", \"me\"",
        ],
    );
    let error = parse_err("[integrator]\nvolume = \"fast\"\n");
    assert_contains(&error, &["field `volume`", "\"restir\", \"baseline\""]);
    let error = parse_err("[integrator.restir]\nreuse = \"path\"\n");
    assert_contains(
        &error,
        &[
            "[integrator.restir]",
            "field `reuse`",
            "\"direction\", \"vertex\"",
        ],
    );
    let error = parse_err(&format!(
        "{GRID}density = {{ procedural = \"smoke\", dims = [2, 2, 2] }}\n"
    ));
    assert_contains(&error, &["> density", "field `procedural`", "\"cloud\""]);
}

#[test]
fn zero_directions_are_rejected() {
    let error =
        parse_err("[[light]]\ntype = \"directional\"\ndirection = [0, 0, 0]\nirradiance = 1\n");
    assert_contains(
        &error,
        &[
            SCENE,
            "[[light]] #1 (type = \"directional\")",
            "field `direction`",
            "must not be the zero vector",
        ],
    );
    let error =
        parse("[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\nup = [0, 0, 0]\n").unwrap_err();
    assert_contains(
        &format!("{error:#}"),
        &[SCENE, "[camera]", "field `up`", "zero vector"],
    );
}

#[test]
fn nan_and_infinity_are_rejected() {
    let error = parse_err(&format!("{BOX}sigma_t = nan\n"));
    assert_contains(
        &error,
        &[
            SCENE,
            "[[medium]] #1 (type = \"box\")",
            "field `sigma_t`",
            "finite",
        ],
    );
    let error = parse_err(&format!("{BOX}sigma_t = inf\n"));
    assert_contains(&error, &["field `sigma_t`", "finite"]);
    let error = parse_err(&format!("{BOX}sigma_t = 1\nalbedo = [0.5, nan, 0.5]\n"));
    assert_contains(&error, &["field `albedo`", "element 1", "finite"]);
    let error = parse_err("[[light]]\ntype = \"point\"\nposition = [0, -inf, 0]\nintensity = 1\n");
    assert_contains(
        &error,
        &[
            "[[light]] #1 (type = \"point\")",
            "field `position`",
            "finite",
        ],
    );
    let error = parse_err("[[light]]\ntype = \"point\"\nposition = [0, 1e300, 0]\nintensity = 1\n");
    assert_contains(&error, &["field `position`", "too large"]);
}

#[test]
fn out_of_range_values_are_rejected() {
    for g in ["1", "1.0", "-1", "1.5"] {
        let error = parse_err(&format!("{BOX}sigma_t = 1\ng = {g}\n"));
        assert_contains(
            &error,
            &[
                SCENE,
                "[[medium]] #1 (type = \"box\")",
                "field `g`",
                "(-1, 1)",
            ],
        );
    }
    let error = parse_err(&format!("{BOX}sigma_t = 1\nalbedo = [0.5, 1.5, 0.5]\n"));
    assert_contains(
        &error,
        &[
            SCENE,
            "[[medium]] #1 (type = \"box\")",
            "field `albedo`",
            "component 1",
            "[0, 1]",
        ],
    );
    let error = parse_err(&format!("{BOX}sigma_t = 1\nalbedo = -0.1\n"));
    assert_contains(&error, &["field `albedo`", "[0, 1]"]);
    let error =
        parse_err("[[shape]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nalbedo = 2\n");
    assert_contains(
        &error,
        &[SCENE, "[[shape]] #1 (type = \"sphere\")", "field `albedo`"],
    );
    for fov in ["0", "180", "-10", "200"] {
        let error = parse(&format!("{CAMERA}horizontal_fov_deg = {fov}\n")).unwrap_err();
        assert_contains(
            &format!("{error:#}"),
            &[SCENE, "[camera]", "field `horizontal_fov_deg`", "(0, 180)"],
        );
    }
    let error = parse_err(&format!("{BOX}sigma_t = -1\n"));
    assert_contains(&error, &["field `sigma_t`", "out of range"]);
    let error = parse_err("[render]\nwidth = 0\n");
    assert_contains(&error, &[SCENE, "[render]", "field `width`", "[1, 16384]"]);
    let error = parse_err("[render]\nwidth = 16384\nheight = 16384\n");
    assert_contains(&error, &[SCENE, "[render]", "field `height`", "pixels"]);
    let error = parse_err("[render]\nspp = 0\n");
    assert_contains(&error, &["field `spp`"]);
    let error = parse_err("[render]\nseed = -1\n");
    assert_contains(&error, &["field `seed`"]);
    let error = parse_err("[integrator]\nmax_bounces = 0\n");
    assert_contains(&error, &[SCENE, "[integrator]", "field `max_bounces`"]);
    let error = parse_err("[integrator.restir]\ncandidates = 0\n");
    assert_contains(&error, &["[integrator.restir]", "field `candidates`"]);
    let error = parse_err("[integrator.restir]\nspatial_radius_px = -1\n");
    assert_contains(&error, &["field `spatial_radius_px`"]);
    let error = parse_err("[integrator.restir]\nmip_indirect = 17\n");
    assert_contains(&error, &["field `mip_indirect`"]);
    let error = parse_err("[integrator.restir]\nmip_reuse = \"coarse\"\n");
    assert_contains(&error, &["field `mip_reuse`", "\"coarse\" is not \"auto\""]);
    let error = parse_err("[integrator.restir]\nmip_reuse = 1.5\n");
    assert_contains(&error, &["field `mip_reuse`", "an integer or \"auto\""]);
    let error =
        parse_err("[[light]]\ntype = \"point\"\nposition = [0, 0, 0]\nintensity = [1, -1, 1]\n");
    assert_contains(&error, &["field `intensity`", ">= 0"]);
    let error =
        parse_err("[[light]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0\nradiance = 1\n");
    assert_contains(
        &error,
        &["[[light]] #1 (type = \"sphere\")", "field `radius`", "> 0"],
    );
    let error = parse_err(
        "[[medium]]\ntype = \"box\"\ncenter = [0, 0, 0]\nsize = [1, 0, 1]\nsigma_t = 1\n",
    );
    assert_contains(&error, &["field `size`", "component 1"]);
}

#[test]
fn grid_bounds_and_dims_are_checked() {
    let error = parse_err(
        "[[medium]]\ntype = \"grid\"\nbounds_min = [0, 1, 0]\nbounds_max = [1, 1, 1]\n\
         density = { procedural = \"cloud\", dims = [2, 2, 2] }\n",
    );
    assert_contains(
        &error,
        &[
            SCENE,
            "[[medium]] #1 (type = \"grid\")",
            "field `bounds_max`",
            "component 1",
        ],
    );
    let error = parse_err(&format!(
        "{GRID}density = {{ procedural = \"cloud\", dims = [2, 0, 2] }}\n"
    ));
    assert_contains(&error, &["> density", "field `dims`", "component 1"]);
    let error = parse_err(&format!(
        "{GRID}density = {{ procedural = \"cloud\", dims = [4096, 4096, 4096] }}\n"
    ));
    assert_contains(&error, &["field `dims`", "voxels"]);
    let error = parse_err(&format!(
        "{GRID}density = {{ procedural = \"cloud\", dims = [2, 2.5, 2] }}\n"
    ));
    assert_contains(&error, &["field `dims`", "integers"]);
    let error = parse_err(&format!(
        "{GRID}density = {{ procedural = \"cloud\", dims = [2, 2, 2] }}\nvelocity = {{ procedural = \"cloud\", dims = [2, 2, 2] }}\n"
    ));
    assert_contains(&error, &["> velocity", "field `procedural`", "file"]);
}

#[test]
fn grid_files_are_checked() {
    let dir = TempDir::new("grid-files");
    dir.write("small.raw", &raw_floats(7));
    dir.write("vel.raw", &raw_floats(8));
    dir.write("bad-magic.vol", &{
        let mut bytes = vol_file([2, 2, 2], 1);
        bytes[0..3].copy_from_slice(b"VOX");
        bytes
    });
    dir.write("short.vol", &vol_file([2, 2, 2], 1)[..60]);
    dir.write("scalar.vol", &vol_file([2, 2, 2], 1));
    let scene_file = dir.0.join("scene.toml");
    let check = |density: &str, extra: &str, needles: &[&str]| {
        let text = format!("{CAMERA}{GRID}density = {density}\n{extra}");
        let error = format!("{:#}", parse_str(&text, &scene_file).unwrap_err());
        assert_contains(&error, &["scene.toml", "[[medium]] #1 (type = \"grid\")"]);
        assert_contains(&error, needles);
    };
    check(
        "{ file = \"missing.raw\", dims = [2, 2, 2] }",
        "",
        &[
            "> density",
            "field `file`",
            "file not found",
            &dir.0.join("missing.raw").display().to_string(),
        ],
    );
    check(
        "{ file = \"small.raw\", dims = [2, 2, 2] }",
        "",
        &[
            "> density",
            "field `file`",
            "expected 32 bytes",
            "found 28 bytes",
        ],
    );
    check(
        "{ file = \"small.raw\" }",
        "",
        &["> density", "field `dims`", "missing"],
    );
    check(
        "{ file = \"scalar.vol\" }",
        "velocity = { file = \"vel.raw\", dims = [2, 2, 2] }\n",
        &[
            "> velocity",
            "field `file`",
            "expected 96 bytes",
            "3 channel",
            "found 32 bytes",
        ],
    );
    check(
        "{ file = \"scalar.vol\" }",
        "velocity = { file = \"scalar.vol\" }\n",
        &["> velocity", "field `file`", "1 channels, expected 3"],
    );
    check(
        "{ file = \"bad-magic.vol\" }",
        "",
        &["> density", "field `file`", "bad-magic.vol", "magic"],
    );
    check(
        "{ file = \"short.vol\" }",
        "",
        &[
            "> density",
            "field `file`",
            "expected 80 bytes",
            "found 60 bytes",
        ],
    );
    check(
        "{ file = \"missing.vol\" }",
        "",
        &["> density", "field `file`", "missing.vol"],
    );
    check(
        "{ file = \"scalar.vol\", dims = [2, 2, 3] }",
        "",
        &["> density", "field `dims`", "header"],
    );
    check(
        "{ file = \"scalar.vol\", procedural = \"cloud\" }",
        "",
        &["> density", "field `procedural`", "not both"],
    );
    check(
        "{ file = \"scalar.vol\" }",
        "[[medium.frame]]\nframe = 1\ndensity = { file = \"gone.raw\", dims = [1, 1, 1] }\n",
        &["[[medium.frame]] #1 > density", "field `file`", "gone.raw"],
    );
}

#[test]
fn environment_file_must_be_an_existing_exr() {
    let dir = TempDir::new("env-bad");
    dir.write("sky.hdr", b"x");
    let scene_file = dir.0.join("scene.toml");
    for (file, needle) in [("sky.hdr", ".exr"), ("nowhere.exr", "file not found")] {
        let text = format!("{CAMERA}[[light]]\ntype = \"environment\"\nfile = \"{file}\"\n");
        let error = format!("{:#}", parse_str(&text, &scene_file).unwrap_err());
        assert_contains(
            &error,
            &[
                "scene.toml",
                "[[light]] #1 (type = \"environment\")",
                "field `file`",
                file,
                needle,
            ],
        );
    }
}

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

/// Media may share volume: the loader lists the pairs that do ([`Scene::overlaps`]) by
/// an exact test, and touching or merely nearby media are no pair.
#[test]
fn overlapping_media_are_found_exactly() {
    let overlaps = |text: &str| parse_ok(text).overlaps;
    let boxes = |second_center: &str, rotation: &str| {
        format!(
            "{BOX}sigma_t = 1\n[[medium]]\ntype = \"box\"\ncenter = {second_center}\nsize = [1, 1, 1]\n\
             rotation_deg = {rotation}\nsigma_t = 1\n"
        )
    };
    assert_eq!(overlaps(&boxes("[0.5, 0.5, 0]", "[0, 0, 0]")), [(0, 1)]);
    // A 45° cube reaches √0.5 ≈ 0.707 along X: at x = 1.2 it overlaps the unit cube,
    // at x = 1.25 it does not.
    assert_eq!(overlaps(&boxes("[1.2, 0, 0]", "[0, 0, 45]")), [(0, 1)]);
    assert!(overlaps(&boxes("[1.25, 0, 0]", "[0, 0, 45]")).is_empty());
    // Edge-on cubes, rotated about different axes: only the edge-edge axis of SAT
    // separates them, and pushing them 1 cm closer makes them overlap.
    let edge_on = |y: f64| {
        format!(
            "{BOX}sigma_t = 1\nrotation_deg = [45, 0, 0]\n[[medium]]\ntype = \"box\"\n\
             center = [0, {y}, 0]\nsize = [1, 1, 1]\nrotation_deg = [0, 0, 45]\nsigma_t = 1\n"
        )
    };
    assert!(overlaps(&edge_on(std::f64::consts::SQRT_2 + 0.01)).is_empty());
    assert_eq!(
        overlaps(&edge_on(std::f64::consts::SQRT_2 - 0.01)),
        [(0, 1)]
    );

    let grid = |min: &str, max: &str| {
        format!(
            "[[medium]]\ntype = \"grid\"\nbounds_min = {min}\nbounds_max = {max}\n\
             density = {{ procedural = \"cloud\", dims = [2, 2, 2] }}\n"
        )
    };
    assert_eq!(
        overlaps(&format!(
            "{}{}",
            grid("[0, 0, 0]", "[2, 2, 2]"),
            grid("[1, 1, 1]", "[3, 3, 3]")
        )),
        [(0, 1)]
    );
    assert!(overlaps(&format!(
        "{}{}",
        grid("[0, 0, 0]", "[2, 2, 2]"),
        grid("[2, 0, 0]", "[3, 3, 3]")
    ))
    .is_empty());
    // Three media: the grid overlaps both boxes, the boxes are apart.
    assert_eq!(
        overlaps(&format!(
            "{}{BOX}sigma_t = 1\n[[medium]]\ntype = \"box\"\ncenter = [1.5, 1.5, 1.5]\n\
             size = [0.5, 0.5, 0.5]\nsigma_t = 2\n",
            grid("[0.4, 0.4, 0.4]", "[2, 2, 2]")
        )),
        [(0, 1), (0, 2)]
    );
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

#[test]
fn fields_without_effect_are_rejected() {
    let error = parse_err(&format!(
        "{GRID}density = {{ procedural = \"cloud\", dims = [2, 2, 2] }}\nemission_scale = 3\n"
    ));
    assert_contains(
        &error,
        &[
            SCENE,
            "[[medium]] #1 (type = \"grid\")",
            "field `emission_scale`",
        ],
    );
    let error = parse_err(&format!(
        "{GRID}density = {{ file = \"x.raw\", dims = [2, 2, 2], noise_seed = 3 }}\n"
    ));
    assert_contains(&error, &["> density", "field `noise_seed`"]);
}

#[test]
fn no_panic_on_odd_inputs() {
    let inputs = [
        "",
        "camera = 3",
        "[camera]\nposition = []\n",
        "[camera]\nposition = [[0, 0, 0]]\nlook_at = [0, 0, 0]\n",
        "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\nkeyframe = 3\n",
        "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\n[[camera.keyframe]]\nframe = -1\n",
        "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\n[[camera.keyframe]]\nframe = 99999999999\n",
        "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\nup = [1e-30, 1e-30, 0]\n",
        "[camera]\nposition = [0, 0, 1e-30]\nlook_at = [0, 0, 0]\n",
        "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\nlight = [1, 2]\n",
        "light = [1, 2]\n[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\n",
        "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\n[[medium]]\ntype = \"grid\"\ndensity = 3\n",
        "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\n[[medium]]\ntype = \"grid\"\nbounds_min = [0,0,0]\nbounds_max = [1,1,1]\ndensity = { dims = 1 }\n",
        "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\n[[medium]]\ntype = \"grid\"\nbounds_min = [0,0,0]\nbounds_max = [1,1,1]\ndensity = { dims = [9999999999, 1, 1], procedural = \"cloud\" }\n",
        "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\n[[light]]\ntype = \"directional\"\ndirection = [1e-200, 0, 0]\nirradiance = 1\n",
        "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\n[[light]]\ntype = \"directional\"\ndirection = [0, 1, 0]\nirradiance = 1\ngobo = [[1e30, 0], [0, 1e30], [-1e30, 0]]\n",
    ];
    for input in inputs {
        let _ = parse(input);
    }
}

#[test]
fn convex_media_that_are_not_bounded_polyhedra_are_rejected() {
    let convex =
        |planes: &str| format!("[[medium]]\ntype = \"convex\"\nplanes = {planes}\nsigma_t = 1\n");
    let table = "[[medium]] #1 (type = \"convex\")";
    let cube = "[1, 0, 0, 1], [-1, 0, 0, 1], [0, 1, 0, 1], [0, -1, 0, 1], [0, 0, 1, 1]";
    let check = |planes: String, needles: &[&str]| {
        let error = parse_err(&convex(&planes));
        assert_contains(&error, &[SCENE, table, "field `planes`"]);
        assert_contains(&error, needles);
    };
    check(format!("[{cube}]"), &["bounded"]);
    check(
        "[[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1]]".into(),
        &["3 planes", "4 to 64"],
    );
    let many: Vec<String> = (0..65)
        .map(|i| {
            let a = f64::from(i) * 0.7;
            format!("[{}, {}, {}, 1]", a.cos(), a.sin(), (a * 1.3).sin())
        })
        .collect();
    check(format!("[{}]", many.join(", ")), &["65 planes"]);
    check(
        format!("[{cube}, [0, 0, 0, 1]]"),
        &["plane 5", "no direction"],
    );
    check(format!("[{cube}, [0, 0, -1, -2]]"), &["empty"]);
    check(format!("[{cube}, [0, 0, -1, -1]]"), &["interior"]);
    check(format!("[{cube}, [0, 0, -1]]"), &["plane 5"]);
    check(format!("[{cube}, [0, 0, -1, nan]]"), &["plane 5", "finite"]);
    check("[0, 1, 2, 3]".into(), &["plane 0"]);
    check("\"cube\"".into(), &["expected an array"]);
    let error = parse_err("[[medium]]\ntype = \"convex\"\nsigma_t = 1\n");
    assert_contains(&error, &[table, "field `planes`", "missing"]);
    // A sliver 20 nm thick at 1 m from the origin is below what f32 positions resolve.
    let error = parse_err(&convex(
        "[[1, 0, 0, 1e-8], [-1, 0, 0, 1e-8], [0, 1, 0, 1], [0, -1, 0, 1], [0, 0, 1, 1], [0, 0, -1, 1]]",
    ));
    assert_contains(
        &error,
        &[table, "field `planes`", "width across a face", "32-bit"],
    );
    // A dodecahedron overlapping a box is a pair, one beside it is not (it reaches
    // 1.176 r below its centre, the box 0.5 above the origin).
    let scene = parse_ok(&format!(
        "{}{BOX}sigma_t = 1\n",
        dodecahedron([0.0, 1.0, 0.0], 1.0, 1.0)
    ));
    assert_eq!(scene.overlaps, [(0, 1)]);
    let scene = parse_ok(&format!(
        "{}{BOX}sigma_t = 1\n",
        dodecahedron([0.0, 1.7, 0.0], 1.0, 1.0)
    ));
    assert!(scene.overlaps.is_empty());
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
