//! The plan: `nimbus render --explain` names the four passes and what switches them off,
//! and scenes ReSTIR cannot render are errors naming the file and table.

use super::*;

/// Writes `cloud`'s scene text into a scratch directory and returns its path.
fn scene_file(name: &str, cloud: &Cloud) -> std::path::PathBuf {
    let path = scratch("restir", name).join("scene.toml");
    std::fs::write(&path, cloud.text()).expect("write scene");
    path
}

/// `nimbus render --explain FILE ARGS`: stdout, after checking that it succeeded.
fn explain(path: &std::path::Path, args: &[&str]) -> String {
    let mut all = vec!["render", "--explain", path.to_str().unwrap()];
    all.extend_from_slice(args);
    let out = nimbus(&all);
    assert!(out.status.success(), "{}", text(&out.stderr));
    text(&out.stdout)
}

/// `--explain` lists the four ReSTIR passes; temporal reuse is off with `temporal =
/// false`, with a single frame and, under `temporal = "auto"` (the default), for the
/// still of a static scene; SC_HAS_EMISSION follows the medium.
#[test]
fn explain_lists_the_restir_passes() {
    // The defaults: no spatial reuse, split NEE under a sun and a sky, and the static
    // scene's still made of independent frames.
    let defaults = scene_file("explain-default", &Cloud::default());
    let out = explain(&defaults, &[]);
    for line in [
        "[on ] pass restir initial",
        "[off] pass restir temporal",
        "temporal = \"auto\": this static scene renders a still",
        "[off] pass restir spatial",
        "[on ] pass restir shade",
        "[off]   SC_HAS_EMISSION",
        "[on ]   SC_NEE_SPLIT",
        "[off] pass baseline path tracer",
    ] {
        assert!(out.contains(line), "missing {line:?} in:\n{out}");
    }

    let spatial = scene_file(
        "explain-spatial",
        &Cloud {
            restir: "spatial_neighbors = 3\nspatial_when = \"always\"\nnee = \"one\"",
            ..Cloud::default()
        },
    );
    let out = explain(&spatial, &[]);
    assert!(out.contains("[on ] pass restir spatial"), "{out}");
    assert!(out.contains("[off]   SC_NEE_SPLIT"), "{out}");
    let one_frame = explain(&spatial, &["--frames", "1"]);
    assert!(
        one_frame.contains("[off] pass restir temporal"),
        "{one_frame}"
    );
    assert!(
        one_frame.contains("[on ] pass restir spatial"),
        "{one_frame}"
    );

    let temporal = scene_file(
        "explain-temporal",
        &Cloud {
            restir: "temporal = true",
            ..Cloud::default()
        },
    );
    let out = explain(&temporal, &[]);
    assert!(out.contains("[on ] pass restir temporal"), "{out}");
    assert!(
        out.contains("temporal reuse (temporal = true) makes"),
        "{out}"
    );

    let no_temporal = scene_file(
        "explain-no-temporal",
        &Cloud {
            restir: "temporal = false",
            ..Cloud::default()
        },
    );
    let out = explain(&no_temporal, &[]);
    assert!(out.contains("[off] pass restir temporal"), "{out}");
    assert!(out.contains("[on ] pass restir initial"), "{out}");
    assert!(out.contains("[on ] pass restir shade"), "{out}");

    let emitting = scene_file(
        "explain-emission",
        &Cloud {
            medium_extra: "emission = { procedural = \"cloud\", dims = [4, 4, 4], noise_seed = 5 }",
            ..Cloud::default()
        },
    );
    let out = explain(&emitting, &[]);
    assert!(out.contains("[on ]   SC_HAS_EMISSION"), "{out}");
}

/// The plan error for `cloud` (named `name`).
fn plan_error(cloud: &Cloud, name: &str) -> String {
    match nimbus::plan::build(&cloud.scene(name), None) {
        Ok(_) => panic!("{name}: the plan was accepted"),
        Err(e) => e.to_string(),
    }
}

/// Scenes ReSTIR cannot render are errors naming the file, the table and the field:
/// vertex reuse with a shape (a surface x2 has no volume-measure geometry term), K above
/// 16 (plan errors), more than 16 spatial neighbours (a scene error). The limits
/// themselves (16) are accepted, and so are shapes with direction reuse.
#[test]
fn unsupported_scenes_are_plan_errors() {
    let sphere = "[[shape]]\ntype = \"sphere\"\ncenter = [0.0, -2.0, 0.0]\nradius = 0.5";
    let with_shape = Cloud {
        shapes: sphere,
        restir: "reuse = \"vertex\"",
        ..Cloud::default()
    };
    let e = plan_error(&with_shape, "restir-shape.toml");
    for needle in [
        "restir-shape.toml",
        "[integrator.restir] field `reuse`",
        "[[shape]] #1",
        "reuse = \"direction\"",
    ] {
        assert!(e.contains(needle), "{needle:?} missing from: {e}");
    }
    let direction = Cloud {
        shapes: sphere,
        ..Cloud::default()
    };
    nimbus::plan::build(&direction.scene("restir-shape-direction.toml"), None)
        .expect("shapes with direction reuse");

    // Split NEE needs the environment alone besides the delta lights.
    let sphere_light = Cloud {
        lights:
            "[[light]]\ntype = \"sphere\"\ncenter = [0.0, 2.0, 0.0]\nradius = 0.2\nradiance = 5.0\n\
                 [[light]]\ntype = \"environment\"\nradiance = 0.2",
        restir: "nee = \"split\"",
        ..Cloud::default()
    };
    let e = plan_error(&sphere_light, "restir-split.toml");
    assert!(
        e.contains("restir-split.toml") && e.contains("field `nee`") && e.contains("nee = \"one\""),
        "{e}"
    );

    let e = plan_error(
        &Cloud {
            bounces: 17,
            ..Cloud::default()
        },
        "restir-k17.toml",
    );
    assert!(
        e.contains("restir-k17.toml") && e.contains("[integrator]") && e.contains("`max_bounces`"),
        "{e}"
    );

    // More than 16 spatial neighbours is refused by the scene loader itself, so the
    // loader's documented range and what the plan accepts are one.
    let text = Cloud {
        restir: "spatial_neighbors = 17",
        ..Cloud::default()
    }
    .text();
    let e = nimbus_scene::parse_str(&text, std::path::Path::new("restir-n17.toml"))
        .expect_err("17 neighbours are refused")
        .to_string();
    assert!(
        e.contains("restir-n17.toml")
            && e.contains("[integrator.restir]")
            && e.contains("`spatial_neighbors`"),
        "{e}"
    );

    let at_limits = Cloud {
        bounces: 16,
        restir: "spatial_neighbors = 16\nspatial_when = \"always\"",
        ..Cloud::default()
    };
    let plan = nimbus::plan::build(&at_limits.scene("restir-limits.toml"), None).expect("plan");
    let restir = plan.restir().cloned().expect("a ReSTIR plan");
    assert_eq!((restir.max_bounces, restir.spatial_neighbors), (16, 16));
}
