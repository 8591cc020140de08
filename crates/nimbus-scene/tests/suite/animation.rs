//! Animation: `[[light.keyframe]]` (parsing, interpolation, errors), the density frame
//! in effect at a frame, and the dims checks for animated grids.

use std::path::PathBuf;

use crate::common::*;
use glam::Vec3;
use nimbus_scene::*;

#[track_caller]
fn assert_close(a: Vec3, b: Vec3) {
    assert!((a - b).length() < 1e-6, "{a} != {b}");
}

fn directional(light: &Light) -> (Vec3, Vec3) {
    match light {
        Light::Directional {
            direction,
            irradiance,
            ..
        } => (*direction, *irradiance),
        other => panic!("expected a directional light, got {other:?}"),
    }
}

const ANIMATED: &str = r#"
[[light]]
type = "directional"
direction = [0, -1, 0]
irradiance = 2

[[light.keyframe]]
frame = 12
direction = [1, -1, 0]
irradiance = [4, 6, 8]

[[light.keyframe]]
frame = 2
direction = [0, -3, 0]
irradiance = [0, 2, 4]

[[light]]
type = "environment"
radiance = 0.5

[[light]]
type = "point"
position = [1, 2, 3]
intensity = 10

[[light.keyframe]]
frame = 0
position = [0, 0, 0]

[[light.keyframe]]
frame = 10
intensity = 20

[[light]]
type = "sphere"
center = [0, 5, 0]
radius = 0.5
radiance = 1

[[light.keyframe]]
frame = 4
center = [2, 5, 0]
radiance = [3, 3, 3]
"#;

#[test]
fn keyframed_lights_interpolate_by_frame_and_clamp_outside() {
    let scene = parse_ok(ANIMATED);
    assert!(scene.lights_animated());
    assert_eq!(scene.light_keyframes.len(), scene.lights.len());
    // Sorted by frame; directions normalized.
    let frames: Vec<u32> = scene.light_keyframes[0].iter().map(|k| k.frame).collect();
    assert_eq!(frames, [2, 12]);
    assert!(scene.light_keyframes[1].is_empty());

    let a = Vec3::NEG_Y;
    let b = Vec3::new(1.0, -1.0, 0.0).normalize();
    // Before the first keyframe and at it: the first keyframe (not the static value).
    for frame in [0, 1, 2] {
        let (direction, irradiance) = directional(&scene.lights_at(frame)[0]);
        assert_eq!(direction, a, "frame {frame}");
        assert_eq!(irradiance, Vec3::new(0.0, 2.0, 4.0), "frame {frame}");
    }
    // Midpoint: normalized lerp of the directions, linear irradiance.
    let (direction, irradiance) = directional(&scene.lights_at(7)[0]);
    assert_close(direction, (a + b).normalize());
    assert_close(irradiance, Vec3::new(2.0, 4.0, 6.0));
    // A quarter of the way: normalized lerp, not slerp.
    let (direction, _) = directional(&scene.lights_at(4)[0]);
    assert_close(direction, a.lerp(b, 0.2).normalize());
    // At and after the last keyframe: exactly the last keyframe.
    for frame in [12, 13, 1000, u32::MAX] {
        let (direction, irradiance) = directional(&scene.lights_at(frame)[0]);
        assert_eq!(direction, b, "frame {frame}");
        assert_eq!(irradiance, Vec3::new(4.0, 6.0, 8.0), "frame {frame}");
    }

    // An environment light without keyframes is not animated.
    assert_eq!(scene.lights_at(7)[1], scene.lights[1]);

    // Fields a keyframe leaves out hold the light's static value at that keyframe.
    let point = |frame| match scene.lights_at(frame)[2] {
        Light::Point {
            position,
            intensity,
        } => (position, intensity),
        ref other => panic!("expected a point light, got {other:?}"),
    };
    assert_eq!(point(0), (Vec3::ZERO, Vec3::splat(10.0)));
    assert_close(point(5).0, Vec3::new(0.5, 1.0, 1.5));
    assert_close(point(5).1, Vec3::splat(15.0));
    assert_eq!(point(10), (Vec3::new(1.0, 2.0, 3.0), Vec3::splat(20.0)));
    assert_eq!(point(99), point(10));

    // One keyframe: constant (clamped on both sides); the radius is kept.
    for frame in [0, 4, 50] {
        assert_eq!(
            scene.lights_at(frame)[3],
            Light::Sphere {
                center: Vec3::new(2.0, 5.0, 0.0),
                radius: 0.5,
                radiance: Vec3::splat(3.0),
            }
        );
    }
}

#[test]
fn static_lights_are_unchanged_at_every_frame() {
    let scene = parse_ok(
        "[[light]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = 3\n\
         [[light]]\ntype = \"environment\"\nradiance = 1\n",
    );
    assert!(!scene.lights_animated());
    assert_eq!(scene.light_keyframes, vec![Vec::new(), Vec::new()]);
    for frame in [0, 1, 77] {
        assert_eq!(scene.lights_at(frame), scene.lights);
    }
    // A scene built in code may leave `light_keyframes` empty.
    let mut built = scene.clone();
    built.light_keyframes.clear();
    assert!(!built.lights_animated());
    assert_eq!(built.lights_at(3), scene.lights);
}

#[test]
fn animated_fields_default_to_the_first_keyframe() {
    let scene = parse_ok(
        r#"
[[light]]
type = "directional"
irradiance = 1
[[light.keyframe]]
frame = 8
direction = [0, 0, -2]
[[light.keyframe]]
frame = 3
direction = [0, -2, 0]
"#,
    );
    // The first keyframe by frame, not in file order.
    assert_eq!(directional(&scene.lights[0]).0, Vec3::NEG_Y);
    let error = parse_err(
        "[[light]]\ntype = \"point\"\nintensity = 1\n\
         [[light.keyframe]]\nframe = 0\nintensity = 2\n",
    );
    assert_contains(
        &error,
        &[
            SCENE,
            "[[light]] #1 (type = \"point\")",
            "field `position`",
            "missing",
        ],
    );
}

#[test]
fn bad_light_keyframes_name_the_file_table_and_field() {
    let sun = "[[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1\n";
    let key = |frame: u32, extra: &str| format!("[[light.keyframe]]\nframe = {frame}\n{extra}");
    let keyframe_1 = "[[light]] #1 (type = \"directional\") > [[light.keyframe]] #1";
    let keyframe_2 = "[[light]] #1 (type = \"directional\") > [[light.keyframe]] #2";

    // Duplicate frames name both keyframes.
    let error = parse_err(&format!(
        "{sun}{}{}",
        key(3, "direction = [1, -1, 0]\n"),
        key(3, "irradiance = 2\n")
    ));
    assert_contains(
        &error,
        &[SCENE, keyframe_1, keyframe_2, "field `frame`", "unique"],
    );

    // A zero direction.
    let error = parse_err(&format!("{sun}{}", key(0, "direction = [0, 0, 0]\n")));
    assert_contains(
        &error,
        &[SCENE, keyframe_1, "field `direction`", "zero vector"],
    );

    // Nearly opposite consecutive directions name both keyframes.
    let error = parse_err(&format!(
        "{sun}{}{}",
        key(0, "direction = [0, -1, 0]\n"),
        key(5, "direction = [0.001, 1, 0]\n")
    ));
    assert_contains(
        &error,
        &[
            SCENE,
            keyframe_1,
            keyframe_2,
            "field `direction`",
            "nearly opposite",
        ],
    );
    // Also when one of them is the light's static direction.
    let error = parse_err(&format!(
        "{sun}{}{}",
        key(0, "irradiance = 3\n"),
        key(5, "direction = [0, 1, 0]\n")
    ));
    assert_contains(
        &error,
        &[keyframe_1, keyframe_2, "nearly opposite", "leaves out"],
    );
    // A third keyframe in between makes the turn well defined.
    let scene = parse_ok(&format!(
        "{sun}{}{}{}",
        key(0, "direction = [0, -1, 0]\n"),
        key(2, "direction = [1, 0, 0]\n"),
        key(5, "direction = [0, 1, 0]\n")
    ));
    assert_close(directional(&scene.lights_at(5)[0]).0, Vec3::Y);

    // An environment light's keyframes animate its rotation only.
    let error = parse_err(&format!(
        "[[light]]\ntype = \"environment\"\nradiance = 1\n{}",
        key(0, "radiance = 2\n")
    ));
    assert_contains(
        &error,
        &[
            SCENE,
            "[[light]] #1 (type = \"environment\") > [[light.keyframe]] #1",
            "field `radiance`",
            "unknown field",
            "frame, rotation_deg",
        ],
    );

    // Keyframes on a directional light with a gobo.
    let error = parse_err(&format!(
        "{sun}gobo = [[-1, -1], [1, -1], [0, 1]]\n{}",
        key(0, "irradiance = 2\n")
    ));
    assert_contains(
        &error,
        &[
            SCENE,
            "[[light]] #1 (type = \"directional\")",
            "field `keyframe`",
            "gobo",
            "cannot be animated",
        ],
    );

    // Unknown fields: another type's animatable field, or a static-only one.
    let error = parse_err(&format!("{sun}{}", key(0, "position = [0, 1, 0]\n")));
    assert_contains(
        &error,
        &[
            SCENE,
            keyframe_1,
            "field `position`",
            "unknown field",
            "frame, direction, irradiance",
        ],
    );
    let error = parse_err(&format!(
        "[[light]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nradiance = 1\n{}",
        key(1, "radius = 2\n")
    ));
    assert_contains(
        &error,
        &[
            SCENE,
            "[[light]] #1 (type = \"sphere\") > [[light.keyframe]] #1",
            "field `radius`",
            "unknown field",
            "frame, center, radiance",
        ],
    );

    // Missing or negative frame, negative colour, wrong table type.
    let error = parse_err(&format!("{sun}[[light.keyframe]]\nirradiance = 1\n"));
    assert_contains(&error, &[SCENE, keyframe_1, "field `frame`", "missing"]);
    let error = parse_err(&format!("{sun}[[light.keyframe]]\nframe = -1\n"));
    assert_contains(
        &error,
        &[SCENE, keyframe_1, "field `frame`", "out of range"],
    );
    let error = parse_err(&format!("{sun}{}", key(0, "irradiance = -1\n")));
    assert_contains(&error, &[SCENE, keyframe_1, "field `irradiance`", ">= 0"]);
    let error = parse_err(&format!("{sun}keyframe = 3\n"));
    assert_contains(
        &error,
        &[SCENE, "[[light]] #1", "field `keyframe`", "array of tables"],
    );
}

fn grid_medium(frames: &[u32]) -> GridMedium {
    let source = |seed| GridSource::ProceduralCloud {
        dims: [4, 4, 4],
        noise_seed: seed,
        kind: Default::default(),
    };
    GridMedium {
        bounds_min: Vec3::ZERO,
        bounds_max: Vec3::ONE,
        density: source(100),
        density_scale: 1.0,
        albedo: Vec3::ONE,
        g: 0.0,
        emission: None,
        emission_scale: Vec3::ONE,
        temperature: None,
        albedo_grid: None,
        velocity: None,
        velocity_scale: 1.0,
        frames: frames
            .iter()
            .map(|&frame| GridFrame {
                frame,
                density: source(u64::from(frame)),
                temperature: None,
                albedo: None,
                emission: None,
            })
            .collect(),
        vdb: None,
    }
}

#[test]
fn density_index_at_picks_the_latest_frame_entry() {
    let still = grid_medium(&[]);
    for frame in [0, 1, u32::MAX] {
        assert_eq!(still.density_index_at(frame), 0);
        assert_eq!(still.density_at(frame), &still.density);
    }

    let medium = grid_medium(&[2, 5, 9]);
    let expected = [
        (0, 0),
        (1, 0),
        (2, 1),
        (4, 1),
        (5, 2),
        (8, 2),
        (9, 3),
        (1000, 3),
        (u32::MAX, 3),
    ];
    let sources: Vec<&GridSource> = medium.density_sources().collect();
    assert_eq!(sources.len(), 4);
    for (frame, index) in expected {
        assert_eq!(medium.density_index_at(frame), index, "frame {frame}");
        assert_eq!(medium.density_at(frame), sources[index], "frame {frame}");
    }
    assert_eq!(medium.density_at(3), &medium.frames[0].density);

    // A frame entry at 0 replaces the base density from the start.
    let from_zero = grid_medium(&[0, 3]);
    assert_eq!(from_zero.density_index_at(0), 1);
    assert_eq!(from_zero.density_index_at(3), 2);

    // Parsed frames are sorted whatever their order in the file.
    let scene = parse_ok(
        r#"
[[medium]]
type = "grid"
bounds_min = [0, 0, 0]
bounds_max = [1, 1, 1]
density = { procedural = "cloud", dims = [2, 2, 2] }
[[medium.frame]]
frame = 6
density = { procedural = "cloud", dims = [2, 2, 2], noise_seed = 6 }
[[medium.frame]]
frame = 3
density = { procedural = "cloud", dims = [2, 2, 2], noise_seed = 3 }
"#,
    );
    let Medium::Grid(grid) = &scene.media[0] else {
        panic!("expected a grid");
    };
    let seed_at = |frame| match grid.density_at(frame) {
        GridSource::ProceduralCloud { noise_seed, .. } => *noise_seed,
        other => panic!("unexpected {other:?}"),
    };
    assert_eq!([0, 2, 3, 5, 6, 7].map(seed_at), [0, 0, 3, 3, 6, 6]);
}

/// `[[medium.frame]]` may swap the temperature (and the albedo and emission grids) too:
/// the latest frame at or before a density frame that gives one holds (else the
/// medium's own); a frame's grid the medium lacks is refused, naming the frame and the
/// field.
#[test]
fn medium_frames_swap_the_temperature_and_hold_it() {
    let grid =
        |seed| format!("{{ procedural = \"cloud\", dims = [2, 2, 2], noise_seed = {seed} }}");
    let scene = parse_ok(&format!(
        r#"
[[medium]]
type = "grid"
bounds_min = [0, 0, 0]
bounds_max = [1, 1, 1]
density = {d0}
temperature = {t0}
temperature_offset = 1000.0
albedo = {a0}
emission = {e0}
[[medium.frame]]
frame = 2
density = {d2}
temperature = {t2}
[[medium.frame]]
frame = 4
density = {d4}
albedo = {a4}
emission = {e4}
[[medium.frame]]
frame = 6
density = {d6}
temperature = {t6}
"#,
        d0 = grid(0),
        t0 = grid(100),
        d2 = grid(2),
        t2 = grid(102),
        d4 = grid(4),
        d6 = grid(6),
        t6 = grid(106),
        a0 = grid(200),
        a4 = grid(204),
        e0 = grid(300),
        e4 = grid(304),
    ));
    let Medium::Grid(g) = &scene.media[0] else {
        panic!("expected a grid");
    };
    assert!(g.has_shading_frames());
    let seed = |s: Option<&GridSource>| match s {
        Some(GridSource::ProceduralCloud { noise_seed, .. }) => *noise_seed,
        other => panic!("unexpected {other:?}"),
    };
    // Density grids 0 (base), 1 (frame 2), 2 (frame 4: no temperature), 3 (frame 6).
    let temps: Vec<u64> = (0..4)
        .map(|i| seed(g.temperature_source_at_index(i)))
        .collect();
    assert_eq!(temps, [100, 102, 102, 106]);
    let albedos: Vec<u64> = (0..4).map(|i| seed(g.albedo_source_at_index(i))).collect();
    assert_eq!(albedos, [200, 200, 204, 204]);
    let emissions: Vec<u64> = (0..4)
        .map(|i| seed(g.emission_source_at_index(i)))
        .collect();
    assert_eq!(emissions, [300, 300, 304, 304]);

    // A frame's grid the medium lacks (a constant albedo or emission is no grid).
    let tiny = "{ procedural = \"cloud\", dims = [2, 2, 2] }";
    for (medium_line, field, message) in [
        ("", "temperature", "the medium has no `temperature`"),
        ("albedo = 0.5", "albedo", "the medium has no `albedo` grid"),
        ("", "emission", "the medium has no `emission`"),
    ] {
        let e = parse_err(&format!(
            "[[medium]]\ntype = \"grid\"\nbounds_min = [0, 0, 0]\nbounds_max = [1, 1, 1]\n\
             density = {tiny}\n{medium_line}\n[[medium.frame]]\nframe = 1\ndensity = {tiny}\n\
             {field} = {tiny}\n"
        ));
        for part in ["[[medium.frame]] #1", field, message] {
            assert!(e.contains(part), "{part:?} missing from {e}");
        }
    }
}

#[test]
fn animation_dims_finds_grids_that_differ() {
    let dir = TempDir::new("animation-dims");
    dir.write("d.vol", &vol_file([4, 3, 2], 1));
    dir.write("f.raw", &raw_floats(4 * 3 * 2));
    dir.write("small.vol", &vol_file([2, 3, 2], 1));
    dir.write("v.vol", &vol_file([4, 3, 2], 3));
    dir.write("v-small.raw", &raw_floats(2 * 2 * 2 * 3));
    let scene_text = |frame_file: &str, velocity: &str| {
        format!(
            r#"{CAMERA}
[[medium]]
type = "grid"
bounds_min = [0, 0, 0]
bounds_max = [1, 1, 1]
density = {{ file = "d.vol" }}
velocity = {velocity}
[[medium.frame]]
frame = 1
density = {{ file = "f.raw", dims = [4, 3, 2] }}
[[medium.frame]]
frame = 2
density = {{ {frame_file} }}
"#
        )
    };
    let grid = |text: String| -> GridMedium {
        let scene = parse_str(&text, &dir.0.join("scene.toml")).expect("scene parses");
        match &scene.media[0] {
            Medium::Grid(grid) => grid.clone(),
            other => panic!("expected a grid, got {other:?}"),
        }
    };

    let good = grid(scene_text(
        "procedural = \"cloud\", dims = [4, 3, 2]",
        "{ file = \"v.vol\" }",
    ));
    assert_eq!(good.animation_dims("m").unwrap(), [4, 3, 2]);
    assert_eq!(good.velocity.as_ref().unwrap().dims().unwrap(), [4, 3, 2]);

    // The format allows frames of other dims; the check names the one that differs.
    let small_frame = grid(scene_text("file = \"small.vol\"", "{ file = \"v.vol\" }"));
    let error = format!(
        "{:#}",
        small_frame
            .animation_dims("scene.toml: [[medium]] #1")
            .unwrap_err()
    );
    assert_contains(
        &error,
        &[
            "scene.toml: [[medium]] #1 > [[medium.frame]] (frame 2) > density",
            "2 x 3 x 2",
            "4 x 3 x 2",
            "same dims",
        ],
    );
    let small_velocity = grid(scene_text(
        "file = \"f.raw\", dims = [4, 3, 2]",
        "{ file = \"v-small.raw\", dims = [2, 2, 2] }",
    ));
    let error = format!("{:#}", small_velocity.animation_dims("m").unwrap_err());
    assert_contains(&error, &["m > velocity", "2 x 2 x 2", "m > density"]);

    // The same check for grids already loaded.
    check_same_dims(&[]).unwrap();
    check_same_dims(&[("a", [1, 2, 3]), ("b", [1, 2, 3])]).unwrap();
    let error = format!(
        "{:#}",
        check_same_dims(&[("a", [1, 2, 3]), ("b", [1, 2, 3]), ("c", [3, 2, 1])]).unwrap_err()
    );
    assert_contains(&error, &["c: 3 x 2 x 1", "a's 1 x 2 x 3"]);

    // A .vol file that has gone missing since the scene was loaded.
    let gone = GridSource::MitsubaVol {
        file: PathBuf::from("/nonexistent/nimbus/grid.vol"),
    };
    assert!(format!("{:#}", gone.dims().unwrap_err()).contains("grid.vol"));
}

/// The rotation of environment light `i` of `lights`.
fn env_rotation(lights: &[Light], i: usize) -> f32 {
    match &lights[i] {
        Light::Environment { rotation_deg, .. } => *rotation_deg,
        other => panic!("expected an environment light, got {other:?}"),
    }
}

/// `rotation_deg` on an environment light: default 0, any finite angle reduced to one
/// turn exactly (as a box's), NaN and infinities refused naming the file and field.
#[test]
fn environment_rotation_is_parsed_and_reduced_to_one_turn() {
    let env = |extra: &str| format!("[[light]]\ntype = \"environment\"\nradiance = 1\n{extra}");
    assert_eq!(env_rotation(&parse_ok(&env("")).lights, 0), 0.0);
    assert_eq!(
        env_rotation(&parse_ok(&env("rotation_deg = 90\n")).lights, 0),
        90.0
    );
    // Within one turn: kept bit for bit, the sign too.
    for a in [-360.0f64, -12.5, 0.1, 359.75, 360.0] {
        let scene = parse_ok(&env(&format!("rotation_deg = {a:?}\n")));
        let r = env_rotation(&scene.lights, 0);
        assert_eq!(r, a as f32, "{a}");
        assert_eq!(r.is_sign_negative(), a.is_sign_negative(), "{a}");
    }
    // Past one turn: f64 `%`, exactly.
    for (a, want) in [
        (725.0, 5.0),
        (-450.0, -90.0),
        (1e30, 1e30 % 360.0),
        (3.4e38, 3.4e38 % 360.0),
    ] {
        let scene = parse_ok(&env(&format!("rotation_deg = {a:e}\n")));
        assert_eq!(env_rotation(&scene.lights, 0), want as f32, "{a}");
    }
    for bad in ["nan", "inf", "-inf"] {
        let error = parse_err(&env(&format!("rotation_deg = {bad}\n")));
        assert_contains(
            &error,
            &[
                SCENE,
                "[[light]] #1 (type = \"environment\")",
                "field `rotation_deg`",
                "finite",
            ],
        );
    }
    let error = parse_err(&env("rotation_deg = \"90\"\n"));
    assert_contains(&error, &[SCENE, "field `rotation_deg`", "a number"]);
    // On a key too.
    let error = parse_err(&env(
        "[[light.keyframe]]\nframe = 0\nrotation_deg = 0\n[[light.keyframe]]\nframe = 4\nrotation_deg = nan\n",
    ));
    assert_contains(
        &error,
        &[
            SCENE,
            "[[light]] #1 (type = \"environment\") > [[light.keyframe]] #2",
            "field `rotation_deg`",
            "finite",
        ],
    );
}

/// `[[light.keyframe]]` on an environment light: its rotation, linear by frame in the
/// unwrapped angle (350 to 370 turns by 20°, not back by 340°), clamped outside the
/// keyed range, the static value where a key leaves it out, frames unique.
#[test]
fn environment_keyframes_interpolate_the_unwrapped_angle() {
    let scene = parse_ok(
        r#"
[[light]]
type = "environment"
radiance = 0.5
[[light.keyframe]]
frame = 12
rotation_deg = 370
[[light.keyframe]]
frame = 2
rotation_deg = 350
"#,
    );
    assert!(scene.lights_animated());
    assert!(scene.is_animated());
    // The static value defaults to the first keyframe's (by frame).
    assert_eq!(env_rotation(&scene.lights, 0), 350.0);
    let at = |frame| env_rotation(&scene.lights_at(frame), 0);
    for frame in [0, 1, 2] {
        assert_eq!(at(frame), 350.0, "frame {frame}");
    }
    // Two degrees a frame through 360 (reduced past it).
    assert_eq!(at(3), 352.0);
    assert_eq!(at(7), 360.0);
    assert_eq!(at(8), 2.0);
    assert_eq!(at(11), 8.0);
    for frame in [12, 13, u32::MAX] {
        assert_eq!(at(frame), 10.0, "frame {frame}");
    }
    // Many turns: 10 turns over 100 frames is 36 degrees a frame.
    let scene = parse_ok(
        "[[light]]\ntype = \"environment\"\nradiance = 1\nrotation_deg = 0\n\
         [[light.keyframe]]\nframe = 0\n[[light.keyframe]]\nframe = 100\nrotation_deg = -3600\n",
    );
    // The first key leaves the angle out: the static 0 holds there.
    assert_eq!(env_rotation(&scene.lights_at(0), 0), 0.0);
    assert_eq!(env_rotation(&scene.lights_at(1), 0), -36.0);
    assert_eq!(env_rotation(&scene.lights_at(15), 0), -180.0);
    assert_eq!(env_rotation(&scene.lights_at(100), 0), 0.0);
    // Huge keyed angles stay finite and within a turn at every frame.
    let scene = parse_ok(
        "[[light]]\ntype = \"environment\"\nradiance = 1\n\
         [[light.keyframe]]\nframe = 0\nrotation_deg = -3.4e38\n\
         [[light.keyframe]]\nframe = 9\nrotation_deg = 3.4e38\n",
    );
    for frame in 0..12 {
        let r = env_rotation(&scene.lights_at(frame), 0);
        assert!(r.is_finite() && r.abs() <= 360.0, "frame {frame}: {r}");
    }
    // Duplicate frames name both keyframes.
    let error = parse_err(
        "[[light]]\ntype = \"environment\"\nradiance = 1\n\
         [[light.keyframe]]\nframe = 3\nrotation_deg = 1\n\
         [[light.keyframe]]\nframe = 3\nrotation_deg = 2\n",
    );
    assert_contains(
        &error,
        &[
            SCENE,
            "[[light.keyframe]] #1",
            "[[light.keyframe]] #2",
            "field `frame`",
            "unique",
        ],
    );
    // A negative frame.
    let error = parse_err(
        "[[light]]\ntype = \"environment\"\nradiance = 1\n\
         [[light.keyframe]]\nframe = -1\nrotation_deg = 1\n",
    );
    assert_contains(&error, &[SCENE, "[[light.keyframe]] #1", "field `frame`"]);
}
