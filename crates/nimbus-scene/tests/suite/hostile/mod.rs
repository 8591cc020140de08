//! The hostile suite of the scene format, by class (issue 24): every table and every
//! field of the contract, `docs/scene-format.md`, gets every hostile value of every
//! class (numbers at and past every limit, NaN and infinities; vectors of the wrong
//! length, with NaN, infinite, zero or huge components; empty, long and wrong-typed
//! strings; files that are missing, a directory, empty or a device; wrong-typed tables).
//!
//! The tables and their fields are read from the page's `### ...` sections and their
//! field tables, so a field added to the contract is covered here without a word of
//! this file changing, and a section added without a minimal scene here fails the test.
//! Each value is written into a minimal valid scene holding that table, which must then
//! either parse to a sane scene (finite, answering the questions renderers ask of it) or
//! be refused with a message naming the scene file, the field, and the table where the
//! contract has one. Unlike `fuzz.rs` (random, "never panics, names the file"), this is
//! exhaustive over tables x fields x values and checks the field and the table.

use std::collections::BTreeMap;
use std::path::Path;

use nimbus_scene::{Light, Medium, Scene, Shape};
use toml::Value;

mod templates;

use templates::{
    inline_templates, templates, Files, Index, Key, Step, Template, CAMERA, EXTENSIONS, RENDER,
};

/// The `### ...` sections under "## Tables" of docs/scene-format.md with the fields in
/// the first column of their tables.
fn contract() -> BTreeMap<String, Vec<String>> {
    let page = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/scene-format.md"),
    )
    .expect("docs/scene-format.md");
    crate::common::contract::documented_tables(&page)
}

/// The class of a hostile value, for the tally.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Class {
    Number,
    Vector,
    String,
    File,
    Other,
}

/// Every hostile value, with its class and how it is shown.
fn hostile_values() -> Vec<(Class, String, Value)> {
    use Value::{Array, Boolean, Float, Integer, String as Str};
    let f = |x: f64| Float(x);
    let v = |xs: &[f64]| Array(xs.iter().map(|&x| Float(x)).collect());
    let mut out: Vec<(Class, Value)> = vec![
        // Numbers at and past every limit.
        (Class::Number, Integer(0)),
        (Class::Number, Integer(-1)),
        (Class::Number, f(-0.0)),
        (Class::Number, f(1e-300)),
        (Class::Number, f(1e-46)),
        (Class::Number, f(1e300)),
        (Class::Number, f(3.4e38)),
        (Class::Number, f(1e39)),
        (Class::Number, Integer(i64::MAX)),
        (Class::Number, Integer(i64::MIN)),
        (Class::Number, Integer(1 << 32)),
        (Class::Number, f(f64::NAN)),
        (Class::Number, f(f64::INFINITY)),
        (Class::Number, f(f64::NEG_INFINITY)),
        // Vectors: wrong length, non-finite, zero, huge, tiny, wrong element types.
        (Class::Vector, Array(vec![])),
        (Class::Vector, v(&[1.0, 2.0])),
        (Class::Vector, v(&[1.0, 2.0, 3.0, 4.0])),
        (Class::Vector, v(&[f64::NAN, 0.0, 1.0])),
        (Class::Vector, v(&[0.0, f64::INFINITY, 1.0])),
        (Class::Vector, v(&[0.0, 1.0, f64::NEG_INFINITY])),
        (Class::Vector, v(&[0.0, 0.0, 0.0])),
        (Class::Vector, v(&[-0.0, -0.0, -0.0])),
        (Class::Vector, v(&[-1.0, -1.0, -1.0])),
        (Class::Vector, v(&[1e-300, 1e-300, 1e-300])),
        (Class::Vector, v(&[1e30, 1e30, 1e30])),
        (Class::Vector, v(&[-1e30, 1.0, 1.0])),
        (Class::Vector, v(&[3.4e38, -3.4e38, 3.4e38])),
        (Class::Vector, v(&[1e39, 0.0, 0.0])),
        (
            Class::Vector,
            Array(vec![Integer(i64::MAX), Integer(0), Integer(1)]),
        ),
        (
            Class::Vector,
            Array(vec![Str("a".into()), Str("b".into()), Str("c".into())]),
        ),
        (Class::Vector, Array(vec![v(&[0.0, 0.0]); 3])),
        (
            Class::Vector,
            Array(vec![v(&[1e30, 0.0]), v(&[0.0, 1e30]), v(&[-1e30, -1e30])]),
        ),
        (
            Class::Vector,
            Array(vec![
                v(&[1e-30, 0.0]),
                v(&[0.0, 1e-30]),
                v(&[-1e-30, -1e-30]),
            ]),
        ),
        (Class::Vector, Array(vec![v(&[0.0, 0.0, 0.0, 1.0]); 6])),
        (Class::Vector, Array(vec![v(&[1.0, 0.0, 0.0, 1e30]); 6])),
        // Strings: empty, long, unknown, and the format's own words in the wrong place.
        (Class::String, Str(String::new())),
        (Class::String, Str("x".repeat(100_000))),
        (Class::String, Str("nope".into())),
        (Class::String, Str("auto".into())),
        (Class::String, Str("cloud".into())),
        (Class::String, Str("1.5".into())),
        // Other types.
        (Class::Other, Boolean(true)),
        (Class::Other, Value::Table(toml::Table::new())),
        (Class::Other, Array(vec![Value::Table(toml::Table::new())])),
        (
            Class::Other,
            Value::Table(
                [("file".to_string(), Str("empty.raw".into()))]
                    .into_iter()
                    .collect(),
            ),
        ),
        (
            Class::Other,
            Value::Table([("scale".to_string(), f(1e-30))].into_iter().collect()),
        ),
        (
            Class::Other,
            Array(vec![Value::Table(
                [("frame".to_string(), Integer(i64::MAX))]
                    .into_iter()
                    .collect(),
            )]),
        ),
    ];
    // Files: missing, a directory, empty, a device (through a link with the right
    // extension), and an absolute device path.
    for ext in EXTENSIONS {
        for stem in ["missing", "dir", "empty", "zero"] {
            out.push((Class::File, Str(format!("{stem}{ext}"))));
        }
    }
    out.push((Class::File, Str("/dev/zero".into())));
    out.push((Class::File, Str("/".into())));
    out.into_iter()
        .map(|(class, value)| {
            let mut shown = value.to_string();
            if shown.len() > 40 {
                shown = format!("{}... ({} chars)", &shown[..20], shown.len());
            }
            (class, shown, value)
        })
        .collect()
}

/// The table at `path` under `root`.
fn table_at<'a>(root: &'a mut toml::Table, path: &[Step]) -> &'a mut toml::Table {
    let mut table = root;
    let mut steps = path.iter().peekable();
    while let Some(step) = steps.next() {
        let Key(key) = step else {
            panic!("a path starts each step with a key: {path:?}")
        };
        let value = table.get_mut(*key).expect("the template has the table");
        table = match (value, steps.peek()) {
            (Value::Array(items), Some(Index(i))) => {
                steps.next();
                items[*i].as_table_mut().expect("an array of tables")
            }
            (Value::Table(t), _) => t,
            (other, _) => panic!("{key} is no table: {other:?}"),
        };
    }
    table
}

/// Whether `message` names `field` (as `field`, as a sub-table `> field`, or as the
/// array of tables it is).
fn names_field(message: &str, field: &str) -> bool {
    message.contains(&format!("`{field}`"))
        || message.contains(&format!("> {field}"))
        || message.contains(&format!(".{field}]"))
        || message.contains(&format!("[{field}]"))
}

/// Whether `message` names `table`, or the sub-table `field` of it (`[camera]` with
/// field `keyframe`: `[[camera.keyframe]] #1`).
fn names_table(message: &str, table: &str, field: &str) -> bool {
    let sub = format!("{}.{field}]", table.trim_end_matches(']'));
    message.contains(table) || message.contains(&sub)
}

/// `message` cut to a readable length (a 100 000-character value repeats in it).
fn shorten(message: &str) -> String {
    let chars: Vec<char> = message.chars().collect();
    if chars.len() <= 400 {
        return message.to_string();
    }
    let head: String = chars[..300].iter().collect();
    let tail: String = chars[chars.len() - 100..].iter().collect();
    format!("{head}[...]{tail}")
}

/// Why an accepted scene is not sane, if it is not: every number finite, and the
/// questions renderers ask of a scene answered with finite values at several frames.
fn insane(scene: &Scene) -> Option<String> {
    let debug = format!("{scene:?}");
    for bad in [
        "NaN", ": inf", "-inf", "[inf", "(inf", " inf,", " inf)", " inf]",
    ] {
        if debug.contains(bad) {
            return Some(format!("the parsed scene holds {bad:?}"));
        }
    }
    let scale = scene.position_scale();
    if !(scale.extent.is_finite() && scale.extent > 0.0) {
        return Some(format!("position scale {}", scale.extent));
    }
    let last = scene.render.frames.saturating_sub(1);
    for frame in [0, 1, last / 2, last] {
        let c = scene.camera.frame_at(frame);
        let finite = c.position.is_finite()
            && c.forward.is_finite()
            && c.right.is_finite()
            && c.up.is_finite()
            && c.tan_half_fov_x.is_finite()
            && c.tan_half_fov_x > 0.0;
        if !finite {
            return Some(format!("camera at frame {frame}: {c:?}"));
        }
        for light in scene.lights_at(frame) {
            let finite = match &light {
                Light::Directional {
                    direction,
                    irradiance,
                    ..
                } => direction.is_normalized() && irradiance.is_finite(),
                Light::Environment {
                    radiance,
                    scale,
                    rotation_deg,
                    ..
                } => {
                    // Within one turn, as a box's rotation (see below).
                    (*radiance * *scale).is_finite() && rotation_deg.abs() <= 360.0
                }
                Light::Point {
                    position,
                    intensity,
                } => position.is_finite() && intensity.is_finite(),
                Light::Sphere {
                    center,
                    radius,
                    radiance,
                } => center.is_finite() && radius.is_finite() && radiance.is_finite(),
            };
            if !finite {
                return Some(format!("light at frame {frame}: {light:?}"));
            }
        }
    }
    // Rotations within one turn: the renderer rotates in f32, the overlap test in f64,
    // and their sines of a huge angle disagree.
    let within_a_turn = |r: glam::Vec3| r.abs().max_element() <= 360.0;
    for medium in &scene.media {
        match medium {
            Medium::Grid(g) => {
                let extent = g.bounds_max - g.bounds_min;
                if !(extent.is_finite() && extent.min_element() > 0.0) {
                    return Some(format!(
                        "grid bounds {:?} .. {:?}",
                        g.bounds_min, g.bounds_max
                    ));
                }
            }
            Medium::Box(b) if !within_a_turn(b.rotation_deg) => {
                return Some(format!("box rotation {:?}", b.rotation_deg));
            }
            _ => {}
        }
    }
    for shape in &scene.shapes {
        match shape {
            Shape::Box { rotation_deg, .. } if !within_a_turn(*rotation_deg) => {
                return Some(format!("box rotation {rotation_deg:?}"));
            }
            Shape::Mesh { mesh, .. } if !within_a_turn(mesh.to_world.rotate_deg) => {
                return Some(format!("mesh rotation {:?}", mesh.to_world.rotate_deg));
            }
            _ => {}
        }
    }
    for light in &scene.lights {
        if let Light::Directional {
            gobo: Some(gobo), ..
        } = light
        {
            // The renderer's f32 inside test multiplies two coordinates.
            let far = gobo
                .polygon
                .iter()
                .map(|p| p.abs().max_element())
                .fold(0.0, f32::max);
            if far > 1e7 {
                return Some(format!("a gobo point {far:e} m out"));
            }
        }
    }
    None
}

#[derive(Default)]
struct Tally {
    cases: usize,
    accepted: BTreeMap<Class, usize>,
    refused: BTreeMap<Class, usize>,
    /// (table, field, value) of the numbers and vectors accepted.
    accepted_extremes: Vec<String>,
    failures: Vec<String>,
}

/// Writes every hostile value into `field` of the table of `template`, and checks the
/// outcome.
fn run_field(files: &Files, template: &Template, field: &str, tally: &mut Tally) {
    let text = format!("{CAMERA}{}", template.text);
    let base: toml::Table = text.parse().expect("the template is TOML");
    // The template itself is valid.
    if let Err(e) = nimbus_scene::parse_str(&text, &files.scene) {
        panic!("template of {} is invalid: {e:#}\n{text}", template.section);
    }
    for (class, shown, value) in hostile_values() {
        let mut root = base.clone();
        table_at(&mut root, &template.path).insert(field.to_string(), value);
        let Ok(text) = toml::to_string(&root) else {
            continue; // Not representable as a document (e.g. a table inside a value).
        };
        tally.cases += 1;
        let case = format!("{} `{field}` = {shown}", template.section);
        match nimbus_scene::parse_str(&text, &files.scene) {
            Ok(scene) => {
                *tally.accepted.entry(class).or_default() += 1;
                if let Some(problem) = insane(&scene) {
                    tally
                        .failures
                        .push(format!("{case}: accepted, but {problem}"));
                }
                if matches!(class, Class::Number | Class::Vector) {
                    tally.accepted_extremes.push(case);
                }
            }
            Err(e) => {
                *tally.refused.entry(class).or_default() += 1;
                let message = format!("{e:#}");
                let scene = files.scene.display().to_string();
                let mut lacks = Vec::new();
                if !message.contains(&scene) {
                    lacks.push("the scene file".to_string());
                }
                if !names_field(&message, field) {
                    lacks.push(format!("the field `{field}`"));
                }
                if let Some(table) = template.table {
                    if !names_table(&message, table, field) {
                        lacks.push(format!("the table {table}"));
                    }
                }
                if !lacks.is_empty() {
                    tally.failures.push(format!(
                        "{case}: the refusal lacks {}: {}",
                        lacks.join(", "),
                        shorten(&message)
                    ));
                }
            }
        }
    }
}

#[test]
fn every_field_of_every_table_takes_every_hostile_value_or_names_it() {
    let start = std::time::Instant::now();
    let files = Files::new();
    let contract = contract();
    assert!(contract.len() > 20, "read {} sections", contract.len());
    let templates = templates();
    let mut tally = Tally::default();
    for (section, fields) in &contract {
        let mine: Vec<&Template> = templates.iter().filter(|t| t.section == section).collect();
        assert!(
            !mine.is_empty(),
            "docs/scene-format.md section `### {section}` has no minimal scene in hostile/templates.rs: add one"
        );
        assert!(
            !fields.is_empty(),
            "section `### {section}` lists no fields"
        );
        for template in mine {
            for field in fields {
                run_field(&files, template, field, &mut tally);
            }
        }
    }
    for template in &templates {
        assert!(
            contract.contains_key(template.section),
            "hostile/templates.rs covers `### {}`, which docs/scene-format.md no longer has",
            template.section
        );
    }
    for (template, fields) in inline_templates() {
        for field in fields {
            run_field(&files, &template, field, &mut tally);
        }
    }
    eprintln!(
        "{} cases in {:.1} s",
        tally.cases,
        start.elapsed().as_secs_f64()
    );
    for class in [
        Class::Number,
        Class::Vector,
        Class::String,
        Class::File,
        Class::Other,
    ] {
        eprintln!(
            "{class:?}: {} accepted, {} refused",
            tally.accepted.get(&class).copied().unwrap_or(0),
            tally.refused.get(&class).copied().unwrap_or(0)
        );
    }
    eprintln!(
        "accepted extremes:\n  {}",
        tally.accepted_extremes.join("\n  ")
    );
    assert!(
        tally.failures.is_empty(),
        "{} of {} hostile cases failed:\n{}",
        tally.failures.len(),
        tally.cases,
        tally.failures.join("\n")
    );
}

/// Keyframes at opposite ends of the f32 range: the interpolated poses between them
/// (whose differences overflow f32) are finite, or the scene is refused naming the
/// keyframes.
#[test]
fn keyframes_at_opposite_extremes_interpolate_finitely_or_are_refused() {
    let files = Files::new();
    let far = "3.4e38";
    let cases = [
        (
            "[[camera.keyframe]]",
            format!(
                "{RENDER}{CAMERA}[[camera.keyframe]]\nframe = 0\nposition = [{far}, 0, 0]\nlook_at = [0, 0, 0]\n\
                 [[camera.keyframe]]\nframe = 2\nposition = [-{far}, 0, 1]\nlook_at = [0, 0, 0]\n"
            ),
        ),
        (
            "[[camera.keyframe]]",
            format!(
                "{RENDER}{CAMERA}[[camera.keyframe]]\nframe = 0\nposition = [0, 0, 5]\nlook_at = [{far}, {far}, 0]\n\
                 [[camera.keyframe]]\nframe = 2\nposition = [0, 0, 5]\nlook_at = [-{far}, -{far}, 1]\n"
            ),
        ),
        (
            "[[light.keyframe]]",
            format!(
                "{RENDER}{CAMERA}[[light]]\ntype = \"point\"\nposition = [0, 3, 0]\nintensity = 1\n\
                 [[light.keyframe]]\nframe = 0\nposition = [{far}, 0, 0]\n\
                 [[light.keyframe]]\nframe = 2\nposition = [-{far}, 0, 0]\n"
            ),
        ),
        (
            "[[light.keyframe]]",
            format!(
                "{RENDER}{CAMERA}[[light]]\ntype = \"sphere\"\ncenter = [0, 30, 0]\nradius = 1\nradiance = 1\n\
                 [[light.keyframe]]\nframe = 0\ncenter = [{far}, 0, 0]\n\
                 [[light.keyframe]]\nframe = 2\ncenter = [-{far}, 0, 0]\n"
            ),
        ),
    ];
    for (table, text) in cases {
        match nimbus_scene::parse_str(&text, &files.scene) {
            Ok(scene) => {
                if let Some(problem) = insane(&scene) {
                    panic!("accepted, but {problem}:\n{text}");
                }
            }
            Err(e) => {
                let message = format!("{e:#}");
                let scene = files.scene.display().to_string();
                assert!(
                    message.contains(&scene) && message.contains(table),
                    "{message}"
                );
            }
        }
    }
}
