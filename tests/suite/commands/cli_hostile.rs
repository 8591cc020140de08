//! The hostile suite of the command line, by class (issue 24): every subcommand of
//! `nimbus` and every argument that takes a value, as its own `--help` lists them (so a
//! new flag is covered without a word of this file changing), gets hostile values (0,
//! -1, NaN, infinities, 1e300, 2⁶⁴, words, the empty string, a missing path, a directory,
//! a device) on a tiny, fast scene. Each run must either succeed and write only finite
//! images, or exit non-zero with a message that names the flag (the value, for a
//! positional argument); never a panic (exit 101), a signal or a hang.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::cli::{scratch, text};

/// The longest a single run may take: the values that render are tiny.
const TIMEOUT: Duration = Duration::from_secs(60);

/// Values every flag gets.
const VALUES: &[&str] = &[
    "0",
    "-1",
    "nan",
    "inf",
    "1e300",
    "18446744073709551616",
    "abc",
    "",
];

/// A static 8x8 box-medium scene: one sample renders in a fraction of a second.
const SCENE: &str = "[render]\nwidth = 8\nheight = 8\n[camera]\nposition = [0, 0, 3]\n\
    look_at = [0, 0, 0]\n[[light]]\ntype = \"directional\"\ndirection = [0.3, -1, 0]\n\
    irradiance = 2\n[[medium]]\ntype = \"box\"\ncenter = [0, 0, 0]\nsize = [1, 1, 1]\n\
    sigma_t = 1\nalbedo = 0.8\n";

/// The outcome of one run.
struct Run {
    code: Option<i32>,
    stderr: String,
    timed_out: bool,
    took: Duration,
}

/// Runs `nimbus ARGS` in `dir`, killed after [`TIMEOUT`].
fn run(dir: &Path, args: &[String]) -> Run {
    let start = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run nimbus");
    // Read stderr on a thread so a chatty child never blocks on a full pipe.
    let mut pipe = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut bytes = Vec::new();
        let _ = std::io::Read::read_to_end(&mut pipe, &mut bytes);
        bytes
    });
    let mut timed_out = false;
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > TIMEOUT {
            timed_out = true;
            let _ = child.kill();
            break child.wait().unwrap();
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let stderr = text(&reader.join().unwrap());
    Run {
        code: status.code(),
        stderr,
        timed_out,
        took: start.elapsed(),
    }
}

/// An argument of a subcommand as `--help` lists it: `--width` (taking a value) or a
/// positional `SCENE` / `OUT` / `IN`.
#[derive(Clone, Debug)]
enum Arg {
    Flag(String),
    Positional(String),
}

/// The subcommands `nimbus --help` lists.
fn subcommands() -> Vec<String> {
    let out = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .arg("--help")
        .output()
        .unwrap();
    let mut in_commands = false;
    let mut names = Vec::new();
    for line in text(&out.stdout).lines() {
        if line.starts_with("Commands:") {
            in_commands = true;
        } else if !line.starts_with(' ') {
            in_commands = false;
        } else if in_commands {
            let name = line.split_whitespace().next().unwrap_or("");
            if name != "help" && !name.is_empty() {
                names.push(name.to_string());
            }
        }
    }
    names
}

/// The arguments of `sub` that take a value, from `nimbus SUB --help`.
fn arguments(sub: &str) -> Vec<Arg> {
    let out = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args([sub, "--help"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{sub} --help");
    let mut section = "";
    let mut args = Vec::new();
    for line in text(&out.stdout).lines() {
        if !line.starts_with(' ') {
            section = if line.starts_with("Arguments:") {
                "arguments"
            } else if line.starts_with("Options:") {
                "options"
            } else {
                ""
            };
            continue;
        }
        let tokens: Vec<&str> = line.split_whitespace().collect();
        match section {
            "arguments" if line.starts_with("  ") && !line.starts_with("   ") => {
                let name = tokens[0].trim_matches(|c| "[]<>.".contains(c));
                args.push(Arg::Positional(name.to_string()));
            }
            "options" => {
                // "  -o, --out <FILE>", "      --width <PIXELS>" (help text lines are
                // deeper and do not start with '-').
                if !tokens.first().is_some_and(|t| t.starts_with('-')) {
                    continue;
                }
                let Some(i) = tokens.iter().position(|t| t.starts_with("--")) else {
                    continue;
                };
                let takes_value = tokens.get(i + 1).is_some_and(|t| t.starts_with('<'));
                let flag = tokens[i].trim_end_matches(',');
                if takes_value && flag != "--help" {
                    args.push(Arg::Flag(flag.to_string()));
                }
            }
            _ => {}
        }
    }
    args
}

/// Files every run may name: the scene, two parts to merge.
struct Fixture {
    scene: String,
    parts: [String; 2],
}

/// A link to /dev/zero in each run's directory: a device behind a name with an image's
/// extension (never the device itself: an atomic write renames over what it names, and
/// the tests may run as root).
const ZERO: &str = "zero.exr";

fn fixture(group: &str) -> Fixture {
    let dir = scratch(group, "fixture");
    let scene = dir.join("tiny.toml");
    std::fs::write(&scene, SCENE).unwrap();
    let scene = scene.display().to_string();
    let part = |seed: &str| {
        let out = dir.join(format!("part{seed}.exr")).display().to_string();
        let r = run(
            &dir,
            &["render", &scene, "--seed", seed, "--out", &out].map(String::from),
        );
        assert_eq!(r.code, Some(0), "{}", r.stderr);
        out
    };
    let parts = [part("1"), part("2")];
    Fixture { scene, parts }
}

/// A valid, fast invocation of `sub`: (arguments before the positionals' values, the
/// positionals in order). `None` for a subcommand this test does not know yet.
fn base(sub: &str, fx: &Fixture) -> Option<Vec<(String, Option<String>)>> {
    let s = |x: &str| x.to_string();
    let flag = |f: &str, v: &str| (s(f), Some(s(v)));
    let positional = |name: &str, v: &str| (format!("<{name}>"), Some(s(v)));
    Some(match sub {
        "render" => vec![positional("SCENE", &fx.scene), flag("--out", "out.exr")],
        "profile" => vec![
            positional("SCENE", &fx.scene),
            flag("--frames", "1"),
            flag("--warmup", "0"),
        ],
        "merge" => vec![
            flag("--out", "merged.exr"),
            positional("IN", &fx.parts[0]),
            (s("<IN2>"), Some(fx.parts[1].clone())),
        ],
        "study" => vec![
            positional("SCENE", &fx.scene),
            flag("--vary", "spp=1,2"),
            flag("--frames", "1"),
            flag("--reference-frames", "2"),
            flag("--reference-spp", "1"),
            flag("--reference-box-samples", "1"),
            flag("--seeds", "1"),
            flag("--warmup", "0"),
            flag("--width", "8"),
            flag("--height", "8"),
            flag("--out-dir", "study"),
            flag("--cache-dir", "cache"),
        ],
        "bench" => vec![
            flag("--case", "crepuscular-box-sphere"),
            flag("--baseline", "no-baseline.json"),
            flag("--json", "bench.json"),
        ],
        "make-sky" => vec![
            positional("OUT", "sky.exr"),
            flag("--width", "16"),
            flag("--height", "8"),
        ],
        "devices" => vec![],
        _ => return None,
    })
}

/// The command line of `base` with `arg` set to `value`.
fn command_line(base: &[(String, Option<String>)], arg: &Arg, value: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut set = false;
    for (name, v) in base {
        let v = v.clone().unwrap_or_default();
        match arg {
            Arg::Flag(f) if f == name => {
                out.push(format!("{f}={value}"));
                set = true;
            }
            Arg::Positional(p) if name == &format!("<{p}>") => {
                out.push(value.to_string());
                set = true;
            }
            _ if name.starts_with('<') => out.push(v),
            _ => out.push(format!("{name}={v}")),
        }
    }
    if !set {
        match arg {
            Arg::Flag(f) => out.push(format!("{f}={value}")),
            Arg::Positional(_) => out.push(value.to_string()),
        }
    }
    out
}

/// Every `.exr` under `dir` (recursively).
fn exr_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let path = entry.path();
        if entry.file_type().is_ok_and(|t| t.is_symlink()) {
            continue; // The link to /dev/zero, unless a run replaced it with its image.
        }
        if path.is_dir() {
            exr_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "exr") {
            out.push(path);
        }
    }
}

/// What is wrong with one run, if anything.
fn judge(run: &Run, dir: &Path, arg: &Arg, value: &str) -> Option<String> {
    if run.timed_out {
        return Some(format!("no end after {TIMEOUT:?}"));
    }
    let Some(code) = run.code else {
        return Some(format!("ended by a signal: {}", run.stderr));
    };
    if code == 101 || run.stderr.contains("panicked") {
        return Some(format!("panicked: {}", run.stderr));
    }
    if code == 0 {
        let mut images = Vec::new();
        exr_files(dir, &mut images);
        for image in images {
            match nimbus::output::read_exr(&image) {
                Ok(img) => {
                    if let Some(p) = img.first_non_finite() {
                        return Some(format!(
                            "{} holds a non-finite pixel {p:?}",
                            image.display()
                        ));
                    }
                }
                Err(e) => return Some(format!("{} does not read back: {e:#}", image.display())),
            }
        }
        return None;
    }
    let named = match arg {
        Arg::Flag(f) => run.stderr.contains(f.as_str()),
        // The value itself (unless too short to tell), or the argument by its name.
        Arg::Positional(p) => {
            let word = if p == "IN" { "input" } else { p.as_str() };
            (value.len() > 1 && run.stderr.contains(value))
                || run.stderr.contains(&format!("<{p}>"))
                || run.stderr.contains(&format!("{p} "))
                || run.stderr.to_lowercase().contains(&word.to_lowercase())
        }
    };
    (!named).then(|| format!("exit {code} without naming it: {}", run.stderr.trim()))
}

#[test]
fn every_flag_of_every_subcommand_takes_hostile_values_or_names_the_flag_slow() {
    let start = Instant::now();
    // Per process: two test runs in one checkout must not remove each other's files.
    let group = format!("cli_hostile-{}", std::process::id());
    let fx = fixture(&group);
    // Relative to each run's own directory, removed after it: a run that creates what
    // it names (--sequence, --out-dir) leaves nothing behind for the next.
    let missing = "no/such/dir/file.toml".to_string();
    let a_dir = ".".to_string();
    let mut failures = Vec::new();
    let mut tally: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    let mut slowest = (Duration::ZERO, String::new());
    for sub in subcommands() {
        let base = base(&sub, &fx).unwrap_or_else(|| {
            panic!("`nimbus {sub}` has no fast base invocation in cli_hostile.rs: add one")
        });
        let mut cases: Vec<(Arg, String)> = Vec::new();
        for arg in arguments(&sub) {
            let mut values: Vec<String> = VALUES.iter().map(|v| v.to_string()).collect();
            values.extend([missing.clone(), a_dir.clone(), ZERO.to_string()]);
            if let Arg::Flag(f) = &arg {
                // The flags whose values are keys of the scene or of a study.
                if f == "--set" {
                    values.extend(
                        [
                            "render.width=0",
                            "render.spp=nan",
                            "light.9.irradiance=1",
                            "medium.1.sigma_t=1e39",
                            "camera=1",
                            "=1",
                        ]
                        .map(String::from),
                    );
                }
                if f == "--vary" {
                    values.extend(
                        ["spp=0", "spp=", "nope=1", "seed=-1", "box_estimator=abc"]
                            .map(String::from),
                    );
                }
            }
            for value in values {
                cases.push((arg.clone(), value));
            }
        }
        if cases.is_empty() {
            cases.push((Arg::Positional(String::new()), String::new()));
        }
        for (i, (arg, value)) in cases.iter().enumerate() {
            let dir = scratch(&group, &format!("{sub}-{i}"));
            #[cfg(unix)]
            std::os::unix::fs::symlink("/dev/zero", dir.join(ZERO)).unwrap();
            let args: Vec<String> = if matches!(arg, Arg::Positional(p) if p.is_empty()) {
                vec![sub.clone()]
            } else {
                std::iter::once(sub.clone())
                    .chain(command_line(&base, arg, value))
                    .collect()
            };
            let r = run(&dir, &args);
            let key = format!("{sub} {arg:?}");
            let entry = tally.entry(key).or_default();
            if r.code == Some(0) {
                entry.0 += 1;
            } else {
                entry.1 += 1;
            }
            if r.took > slowest.0 {
                slowest = (r.took, args.join(" "));
            }
            if std::env::var_os("NIMBUS_HOSTILE_LOG").is_some() {
                let last = r.stderr.trim().lines().last().unwrap_or("").to_string();
                eprintln!("[{:?}] nimbus {}: {last}", r.code, args.join(" "));
            }
            if let Some(problem) = judge(&r, &dir, arg, value) {
                failures.push(format!("nimbus {}: {problem}", args.join(" ")));
            }
            let _ = std::fs::remove_dir_all(&dir);
        }
    }
    let _ = std::fs::remove_dir_all(Path::new(env!("CARGO_TARGET_TMPDIR")).join(&group));
    for (key, (ok, refused)) in &tally {
        eprintln!("{key}: {ok} accepted, {refused} refused");
    }
    eprintln!(
        "{} runs in {:.1} s; slowest {:.1} s: nimbus {}",
        tally.values().map(|(a, b)| a + b).sum::<usize>(),
        start.elapsed().as_secs_f64(),
        slowest.0.as_secs_f64(),
        slowest.1
    );
    assert!(
        failures.is_empty(),
        "{} hostile command lines failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
