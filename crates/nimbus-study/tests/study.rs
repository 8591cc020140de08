//! `nimbus study` (`nimbus-study`) end to end: the real binary on a tiny box scene with validation layers
//! on (NIMBUS_VALIDATION=1), its files, the reference cache, and clear errors.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

use std::path::PathBuf;
use std::process::{Command, Output};

/// A 16x16 unoccluded box under one directional light, rendered by ray marching.
const TINY_BOX: &str = r#"
[render]
width = 16
height = 16
frames = 1
spp = 1
seed = 3

[camera]
position = [0.3, 0.8, 4.0]
look_at = [0.0, 0.0, 0.0]
horizontal_fov_deg = 45

[[light]]
type = "directional"
direction = [0.4, -1.0, -0.3]
irradiance = [3.0, 2.0, 1.0]

[[medium]]
type = "box"
center = [0.0, 0.0, 0.0]
size = [2.0, 1.2, 1.6]
rotation_deg = [10.0, 30.0, -5.0]
sigma_t = 1.5
albedo = [0.9, 0.7, 0.5]
g = 0.6

[integrator]
box_estimator = "rm"
box_samples = 8
"#;

/// Run `nimbus-study ARGS` with validation layers on (any validation error fails it).
fn study(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_nimbus-study"))
        .args(args)
        .env("NIMBUS_VALIDATION", "1")
        .output()
        .expect("run nimbus-study")
}

/// Lossy UTF-8 of a command's output.
fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// A fresh, empty directory `<target tmp>/study/<name>` for one test's files.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("study")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

/// The CSV as (header, rows).
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let body = std::fs::read_to_string(path).expect("study.csv");
    let mut lines = body
        .lines()
        .map(|l| l.split(',').map(str::to_owned).collect());
    let header: Vec<String> = lines.next().expect("CSV header");
    (header, lines.collect())
}

fn column(header: &[String], rows: &[Vec<String>], name: &str) -> Vec<f64> {
    let i = header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name} in {header:?}"));
    rows.iter()
        .map(|r| {
            r[i].parse()
                .unwrap_or_else(|_| panic!("{name}: {:?}", r[i]))
        })
        .collect()
}

#[test]
fn study_measures_error_against_time_and_caches_the_reference() {
    let dir = scratch("spp");
    let scene = dir.join("tiny.toml");
    std::fs::write(&scene, TINY_BOX).unwrap();
    let (cache, out) = (dir.join("cache"), dir.join("out"));
    let args = [
        scene.to_str().unwrap(),
        "--vary",
        "spp=1,4",
        "--reference-frames",
        "16",
        "--cache-dir",
        cache.to_str().unwrap(),
        "--out-dir",
        out.to_str().unwrap(),
    ];

    let first = study(&args);
    let stderr = text(&first.stderr);
    assert!(first.status.success(), "{stderr}");
    assert!(stderr.contains("rendering reference"), "{stderr}");
    assert!(
        stderr.contains("[1/2] spp=1") && stderr.contains("[2/2] spp=4"),
        "{stderr}"
    );
    for name in ["study.csv", "study.md", "study.png"] {
        assert!(out.join(name).is_file(), "{name} missing");
    }
    let png = image::open(out.join("study.png")).expect("study.png decodes");
    assert!(png.width() >= 640 && png.height() >= 480);
    let md = std::fs::read_to_string(out.join("study.md")).unwrap();
    assert!(md.contains("| spp |"), "{md}");
    assert!(md.contains("reference: 16 frame(s) x 16 spp"), "{md}");
    assert!(text(&first.stdout).contains("gpu_ms_total"));

    let (header, rows) = read_csv(&out.join("study.csv"));
    assert_eq!(rows.len(), 2, "{header:?} {rows:?}");
    assert_eq!(column(&header, &rows, "spp"), [1.0, 4.0]);
    for name in ["gpu_ms_per_frame", "gpu_ms_total", "rmse", "rel_mse"] {
        for v in column(&header, &rows, name) {
            assert!(v.is_finite() && v > 0.0, "{name} = {v}");
        }
    }
    // Four times the samples: the RMSE should halve; demand a clear drop.
    let rmse = column(&header, &rows, "rmse");
    assert!(
        rmse[1] < 0.75 * rmse[0],
        "RMSE {rmse:?} does not fall with spp"
    );

    // One EXR and its sidecar in the cache; the second run uses them.
    let cached: Vec<_> = std::fs::read_dir(&cache)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(cached.len(), 2, "{cached:?}");
    assert!(cached
        .iter()
        .any(|n| n.starts_with("tiny-") && n.ends_with(".exr")));
    let second = study(&args);
    let stderr = text(&second.stderr);
    assert!(second.status.success(), "{stderr}");
    assert!(stderr.contains("using cached reference"), "{stderr}");
    assert!(!stderr.contains("rendering reference"), "{stderr}");
    let (_, again) = read_csv(&out.join("study.csv"));
    assert_eq!(
        column(&header, &again, "rmse"),
        rmse,
        "same seeds, same errors"
    );

    // Other reference settings are another cache entry.
    let mut other = args.to_vec();
    other.extend(["--reference-spp", "4"]);
    let third = study(&other);
    assert!(third.status.success(), "{}", text(&third.stderr));
    assert!(text(&third.stderr).contains("rendering reference"));
}

/// An animated scene (a sun brightening 16-fold over six frames) is measured frame by
/// frame, each against the reference of its own scene frame: the error then falls with
/// spp as noise does. Measured against another frame's reference, the frames' change
/// (30-50 % per frame) would dominate and barely fall.
#[test]
fn an_animated_study_measures_each_frame_against_its_own_reference() {
    let dir = scratch("animated");
    let scene = dir.join("tiny.toml");
    let animated = TINY_BOX.replace(
        "irradiance = [3.0, 2.0, 1.0]\n",
        "irradiance = [3.0, 2.0, 1.0]\n\
         [[light.keyframe]]\nframe = 0\nirradiance = [0.5, 0.3, 0.2]\n\
         [[light.keyframe]]\nframe = 6\nirradiance = [8.0, 4.8, 3.2]\n",
    );
    assert_ne!(animated, TINY_BOX);
    std::fs::write(&scene, animated).unwrap();
    let (cache, out) = (dir.join("cache"), dir.join("out"));
    let s = scene.to_str().unwrap();
    let refused = study(&[s, "--vary", "spp=1,4"]);
    assert!(!refused.status.success());
    assert!(
        text(&refused.stderr).contains("--per-frame"),
        "{}",
        text(&refused.stderr)
    );
    let run = study(&[
        s,
        "--per-frame",
        "--frames",
        "3",
        "--warmup",
        "2",
        "--vary",
        "spp=1,4",
        "--reference-frames",
        "16",
        "--cache-dir",
        cache.to_str().unwrap(),
        "--out-dir",
        out.to_str().unwrap(),
    ]);
    let stderr = text(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    let md = std::fs::read_to_string(out.join("study.md")).unwrap();
    assert!(md.contains("measures scene frames 2..4"), "{md}");
    let (header, rows) = read_csv(&out.join("study.csv"));
    let rmse = column(&header, &rows, "rmse");
    assert!(rmse.iter().all(|r| r.is_finite() && *r > 0.0), "{rmse:?}");
    assert!(
        rmse[1] < 0.7 * rmse[0],
        "RMSE {rmse:?} does not fall with spp as noise does"
    );
    // One stacked EXR of the three frames: 16 x 48.
    let exr = std::fs::read_dir(&cache)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "exr"))
        .expect("a cached reference");
    let image = nimbus::output::read_exr(&exr).unwrap();
    assert_eq!((image.width, image.height), (16, 48));
    // The frames differ as the sun brightens (frame 3 is (0.5 + 7.5·3/6)/(0.5 + 7.5·2/6)
    // = 1.42 times frame 2, the box lit by it alone).
    let mean = |rows: std::ops::Range<usize>| {
        let d = &image.data[rows.start * 16..rows.end * 16];
        d.iter().map(|p| f64::from(p[0])).sum::<f64>() / d.len() as f64
    };
    let ratio = mean(16..32) / mean(0..16);
    assert!((ratio - 1.42).abs() < 0.1, "frame 3 / frame 2 = {ratio}");
}

/// Bad flags fail before any rendering, naming the flag and what it accepts.
#[test]
fn study_errors_name_the_flag() {
    let dir = scratch("errors");
    let scene = dir.join("tiny.toml");
    std::fs::write(&scene, TINY_BOX).unwrap();
    let blocker = dir.join("a-file");
    std::fs::write(&blocker, "").unwrap();
    let s = scene.to_str().unwrap();
    let cache_dir = dir.join("cache");
    let cache = cache_dir.to_str().unwrap();
    let unwritable = blocker.join("out");
    let cases: Vec<(Vec<&str>, Vec<&str>)> = vec![
        (
            vec!["--vary", "colour=1,2"],
            vec!["--vary colour=1,2", "valid keys", "box_estimator"],
        ),
        (vec!["--vary", "spp="], vec!["--vary spp=", "empty"]),
        (
            vec!["--vary", "box_estimator=rm,fast"],
            vec![
                "--vary box_estimator=fast",
                "\"mcwvds\", \"reds\", \"rees\", \"rm\", \"mcds\", \"me\"",
            ],
        ),
        (vec!["--vary", "spp=0"], vec!["--vary spp=0", "[1, 65536]"]),
        (
            vec!["--vary", "spp=1", "--vary", "spp=2"],
            vec!["--vary spp=2", "already varied"],
        ),
        (
            vec!["--vary", "spp=1,2", "--baseline", "spp=1"],
            vec!["--baseline spp=1", "knob"],
        ),
        (
            vec!["--reference-estimator", "exact"],
            vec!["--reference-estimator exact", "rm"],
        ),
        (
            vec!["--vary", "spp=1", "--out-dir", unwritable.to_str().unwrap()],
            vec!["--out-dir", "a-file"],
        ),
        (
            vec![
                "--vary",
                "spp=1",
                "--cache-dir",
                unwritable.to_str().unwrap(),
            ],
            vec!["--cache-dir", "a-file"],
        ),
    ];
    for (extra, needles) in cases {
        // A scratch cache unless the case is about the cache; never the user's.
        let mut args = vec![s];
        if !extra.contains(&"--cache-dir") {
            args.extend(["--cache-dir", cache]);
        }
        args.extend(&extra);
        let out = study(&args);
        let stderr = text(&out.stderr);
        assert!(!out.status.success(), "{extra:?} should fail");
        assert!(!stderr.contains("panicked"), "{extra:?}: {stderr}");
        assert!(
            !stderr.contains("device:"),
            "{extra:?} reached the GPU: {stderr}"
        );
        for needle in needles {
            assert!(
                stderr.contains(needle),
                "{extra:?}: {needle:?} missing in: {stderr}"
            );
        }
    }

    let missing = dir.join("missing.toml");
    let out = study(&[
        missing.to_str().unwrap(),
        "--vary",
        "spp=1",
        "--cache-dir",
        cache,
    ]);
    assert!(!out.status.success());
    assert!(
        text(&out.stderr).contains("missing.toml"),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn help_lists_every_vary_key() {
    let help = study(&["--help"]);
    assert!(help.status.success(), "{}", text(&help.stderr));
    let help = text(&help.stdout);
    assert!(help.contains("Usage: nimbus study"), "{help}");
    for key in nimbus_study::vary_keys() {
        assert!(
            help.contains(key),
            "nimbus study --help does not list the --vary key {key}"
        );
    }
}
