//! The scene parser never panics: property-based fuzzing with a bounded number of cases
//! (`NIMBUS_FUZZ_CASES`, default 5000 per property) so it runs in CI.
//!
//! Three generators: random TOML documents built from the format's own table and field
//! names with values of every kind (numbers at and beyond every limit, NaN and
//! infinities, wrong types, nested tables); valid scenes with one field replaced by such
//! a value; and valid scene texts with random bytes changed. Every input must give
//! `Ok` or an `Err` whose message names the scene file. Accepted scenes are also asked
//! for their position scale and every light at several frames, which must not panic.

use std::path::Path;

use std::sync::atomic::{AtomicU32, Ordering};

use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};

const FILE: &str = "fuzz/scene.toml";

fn cases() -> u32 {
    std::env::var("NIMBUS_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5000)
}

/// Tables and fields of the format (a sample of each kind, valid and not).
const TABLES: &[&str] = &["render", "camera", "integrator", "integrator.restir"];
const ARRAYS: &[&str] = &["light", "medium", "shape", "camera.keyframe"];
const FIELDS: &[&str] = &[
    "type",
    "width",
    "height",
    "frames",
    "spp",
    "seed",
    "pixel_jitter",
    "position",
    "look_at",
    "up",
    "horizontal_fov_deg",
    "direction",
    "irradiance",
    "radiance",
    "intensity",
    "scale",
    "file",
    "center",
    "radius",
    "size",
    "rotation_deg",
    "sigma_t",
    "albedo",
    "g",
    "bounds_min",
    "bounds_max",
    "density",
    "density_scale",
    "emission",
    "emission_scale",
    "velocity",
    "frame",
    "corner",
    "edge_u",
    "edge_v",
    "gobo",
    "gobo_origin",
    "max_bounces",
    "volume",
    "box_estimator",
    "box_samples",
    "candidates",
    "candidates_settled",
    "temporal",
    "temporal_limit",
    "spatial_neighbors",
    "spatial_radius_px",
    "spatial_rounds",
    "reuse",
    "mip_candidates",
    "mip_indirect",
    "mip_reuse",
    "final_transmittance",
    "nee",
    "direct",
    "keyframe",
    "dims",
    "procedural",
    "noise_seed",
    "unknown_field",
];
const TYPES: &[&str] = &[
    "box",
    "grid",
    "quad",
    "sphere",
    "directional",
    "point",
    "environment",
    "cloud",
    "cumulus",
    "restir",
    "baseline",
    "mcwvds",
    "rm",
    "vertex",
    "ratio",
    "nope",
];

/// A number at or beyond a limit, or an ordinary one.
fn number() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("0".to_string()),
        Just("-0.0".to_string()),
        Just("nan".to_string()),
        Just("inf".to_string()),
        Just("-inf".to_string()),
        Just("1e-46".to_string()),
        Just("1e-300".to_string()),
        Just("3.4e38".to_string()),
        Just("1e39".to_string()),
        Just("1e300".to_string()),
        Just("179.999999999".to_string()),
        Just("0.99999999".to_string()),
        Just("-0.99999999".to_string()),
        Just("16384".to_string()),
        Just("16385".to_string()),
        Just("4294967296".to_string()),
        Just("9223372036854775807".to_string()),
        Just("-9223372036854775808".to_string()),
        (-1e9f64..1e9).prop_map(|x| format!("{x:e}")),
        (-5i64..70000).prop_map(|x| x.to_string()),
        (0.0f64..1.0).prop_map(|x| x.to_string()),
    ]
}

/// A TOML value of any kind.
fn value() -> impl Strategy<Value = String> {
    let leaf = prop_oneof![
        number(),
        prop::sample::select(TYPES).prop_map(|t| format!("\"{t}\"")),
        Just("true".to_string()),
        Just("\"missing.raw\"".to_string()),
        Just("\"\"".to_string()),
    ];
    leaf.prop_recursive(2, 12, 4, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..5).prop_map(|v| format!("[{}]", v.join(", "))),
            prop::collection::vec((prop::sample::select(FIELDS), inner), 0..4).prop_map(|kv| {
                let items: Vec<String> = kv.iter().map(|(k, v)| format!("{k} = {v}")).collect();
                format!("{{ {} }}", items.join(", "))
            }),
        ]
    })
}

/// `key = value` lines.
fn fields() -> impl Strategy<Value = String> {
    prop::collection::vec((prop::sample::select(FIELDS), value()), 0..8).prop_map(|kv| {
        let mut seen = std::collections::HashSet::new();
        kv.into_iter()
            .filter(|(k, _)| seen.insert(*k))
            .map(|(k, v)| format!("{k} = {v}\n"))
            .collect()
    })
}

/// A whole document of tables and arrays of tables.
fn document() -> impl Strategy<Value = String> {
    let table = (prop::sample::select(TABLES), fields()).prop_map(|(t, f)| format!("[{t}]\n{f}"));
    let array = (
        prop::sample::select(ARRAYS),
        fields(),
        prop::sample::select(TYPES),
    )
        .prop_map(|(t, f, ty)| {
            let f = if f.contains("type =") {
                f
            } else {
                format!("type = \"{ty}\"\n{f}")
            };
            format!("[[{t}]]\n{f}")
        });
    prop::collection::vec(prop_oneof![table, array], 0..7).prop_map(|parts| {
        // TOML forbids a table twice; keep the first of each plain table.
        let mut seen = std::collections::HashSet::new();
        parts
            .into_iter()
            .filter(|p| {
                !p.starts_with("[")
                    || p.starts_with("[[")
                    || seen.insert(p.lines().next().map(str::to_owned))
            })
            .collect::<Vec<_>>()
            .join("\n")
    })
}

/// A valid scene that every generator starts from.
const VALID: &str = r#"
[render]
width = 16
height = 12
frames = 3
[camera]
position = [0, 1, 4]
look_at = [0, 0, 0]
[[camera.keyframe]]
frame = 0
position = [0, 1, 4]
look_at = [0, 0, 0]
[[camera.keyframe]]
frame = 2
position = [1, 1, 4]
look_at = [0, 0, 0]
[[light]]
type = "directional"
direction = [0.3, -1, 0.2]
irradiance = 3
gobo = [[0, 0], [1, 0], [0, 1]]
[[light]]
type = "point"
position = [0, 2, 0]
intensity = 1
[[light.keyframe]]
frame = 2
position = [0, 3, 0]
[[medium]]
type = "box"
center = [0, 0, 0]
size = [1, 1, 1]
sigma_t = 2
g = 0.5
[[medium]]
type = "grid"
bounds_min = [2, 0, 0]
bounds_max = [3, 1, 1]
density = { procedural = "cloud", dims = [4, 4, 4] }
[[shape]]
type = "quad"
corner = [-2, -1, -2]
edge_u = [4, 0, 0]
edge_v = [0, 0, 4]
[integrator]
max_bounces = 2
[integrator.restir]
candidates = 4
"#;

/// Parses `text`; the outcome must be `Ok` or an error naming the file, and an accepted
/// scene must answer the questions renderers ask of it.
fn check(text: &str, accepted: &AtomicU32) -> Result<(), TestCaseError> {
    match nimbus_scene::parse_str(text, Path::new(FILE)) {
        Ok(scene) => {
            accepted.fetch_add(1, Ordering::Relaxed);
            let scale = scene.position_scale();
            prop_assert!(scale.extent.is_finite() && scale.extent > 0.0);
            for frame in [0, 1, scene.render.frames.saturating_sub(1)] {
                let _ = scene.lights_at(frame);
                let c = scene.camera.frame_at(frame);
                prop_assert!(c.forward.is_finite() && c.tan_half_fov_x.is_finite());
            }
        }
        Err(e) => {
            let message = format!("{e:#}");
            prop_assert!(
                message.contains(FILE) || message.starts_with("--set"),
                "error does not name the file: {message}"
            );
        }
    }
    Ok(())
}

/// Runs `strategy` through [`check`]; returns how many inputs were accepted.
fn run(name: &str, strategy: impl Strategy<Value = String>) -> u32 {
    let mut runner = TestRunner::new(Config {
        cases: cases(),
        failure_persistence: None,
        ..Config::default()
    });
    let accepted = AtomicU32::new(0);
    if let Err(e) = runner.run(&strategy, |text| check(&text, &accepted)) {
        panic!("{name}: {e}");
    }
    let accepted = accepted.load(Ordering::Relaxed);
    eprintln!("{name}: {} inputs, {accepted} accepted", cases());
    accepted
}

#[test]
fn random_documents_never_panic() {
    run("random documents", document());
}

#[test]
fn valid_scenes_with_one_field_replaced_never_panic() {
    let lines: Vec<&'static str> = VALID.lines().collect();
    let strategy = (0..lines.len(), value()).prop_map(move |(i, v)| {
        let mut out: Vec<String> = lines.iter().map(|l| (*l).to_string()).collect();
        if let Some((key, _)) = out[i].split_once(" = ") {
            out[i] = format!("{key} = {v}");
        }
        out.join("\n")
    });
    let accepted = run("one field replaced", strategy);
    // The generator reaches past the parser's refusals into accepted scenes too.
    assert!(accepted > cases() / 20, "only {accepted} accepted");
}

#[test]
fn valid_scenes_with_bytes_changed_never_panic() {
    let bytes = VALID.as_bytes().to_vec();
    let strategy =
        prop::collection::vec((0..bytes.len(), any::<u8>()), 1..6).prop_map(move |edits| {
            let mut b = bytes.clone();
            for (i, x) in edits {
                b[i] = x;
            }
            String::from_utf8_lossy(&b).into_owned()
        });
    run("bytes changed", strategy);
}

#[test]
fn the_starting_scene_is_valid() {
    nimbus_scene::parse_str(VALID, Path::new(FILE)).unwrap();
}
