//! Scene files that must be rejected, each with a message naming the file, the table
//! and the field.

use crate::common::*;
use nimbus_scene::{load, parse_str};

const BOX: &str = "[[medium]]\ntype = \"box\"\ncenter = [0, 0, 0]\nsize = [1, 1, 1]\n";
const GRID: &str = "[[medium]]\ntype = \"grid\"\nbounds_min = [0, 0, 0]\nbounds_max = [1, 1, 1]\n";
const DIRECTIONAL: &str =
    "[[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1\n";

mod geometry;
mod media;

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
        &[
            SCENE,
            "[integrator.restir]",
            "field `temporal`",
            "boolean or \"auto\"",
        ],
    );
    let error = parse_err("[integrator.restir]\ntemporal = \"yes\"\n");
    assert_contains(
        &error,
        &[
            SCENE,
            "[integrator.restir]",
            "field `temporal`",
            "\"yes\"",
            "\"auto\"",
        ],
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
    let error = parse_err("[integrator.restir]\ncandidate_tracking = \"ratio\"\n");
    assert_contains(
        &error,
        &[
            SCENE,
            "[integrator.restir]",
            "field `candidate_tracking`",
            "\"ratio\"",
            "\"auto\"",
            "\"delta\"",
            "\"regular\"",
        ],
    );
    let error = parse_err("[integrator.restir]\ntarget = \"rgb\"\n");
    assert_contains(
        &error,
        &[
            SCENE,
            "[integrator.restir]",
            "field `target`",
            "\"rgb\"",
            "\"luminance\"",
            "\"sum\"",
            "\"max\"",
        ],
    );
    let error = parse_err("[integrator.restir]\ncamera_emission = \"marched\"\n");
    assert_contains(
        &error,
        &[
            "field `camera_emission`",
            "\"marched\"",
            "\"reservoir\"",
            "\"stratified\"",
        ],
    );
    let error = parse_err("[integrator.restir]\ntemporal_reprojection = \"motion\"\n");
    assert_contains(
        &error,
        &[
            "field `temporal_reprojection`",
            "\"motion\"",
            "\"path\"",
            "\"aligned\"",
        ],
    );
    let error = parse_err("[integrator.restir]\nspatial_when = \"density\"\n");
    assert_contains(
        &error,
        &[
            "field `spatial_when`",
            "\"always\"",
            "\"camera_moves\"",
            "\"camera_or_density\"",
        ],
    );
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
