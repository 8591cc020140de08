//! Media that must be rejected: grid bounds, dims and files, environment maps, media
//! that share volume and convex media that are not bounded polyhedra.

use super::*;

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
