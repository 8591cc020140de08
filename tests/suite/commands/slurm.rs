//! The farm scripts on a real Slurm: `tools/slurm-local.sh` starts a single-node
//! cluster on localhost (munged, slurmctld, slurmd, configured in a temporary
//! directory), `tools/slurm-render.sh shards 4` submits a 4-task job array of one render
//! and a merge job after it, and the merged image must hold all four shards' samples.
//!
//! It needs root and Debian's slurmctld, slurmd, slurm-client and munge
//! (`tools/install-deps.sh`). Without them it says why on stderr and passes, except
//! under CI, where it must run and fails instead.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use nimbus::output::layers::read_layers;

use crate::common::cli::text;

/// The longest the jobs may take: four 32x24 renders of 2 frames and a merge take a
/// few seconds; the rest is room for a loaded 2-core machine.
const JOB_TIMEOUT: Duration = Duration::from_secs(240);

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| !v.is_empty() && v != "0" && !v.eq_ignore_ascii_case("false"))
}

/// Why the test cannot run here, if it cannot.
fn unavailable() -> Option<String> {
    let uid = Command::new("id")
        .arg("-u")
        .output()
        .ok()
        .map(|o| text(&o.stdout).trim().to_string());
    if uid.as_deref() != Some("0") {
        return Some("not root (slurmd and munged of the local cluster need it)".into());
    }
    for tool in ["munged", "slurmctld", "slurmd", "sbatch", "squeue"] {
        let found = Command::new("sh")
            .args(["-c", &format!("command -v {tool}")])
            .output()
            .is_ok_and(|o| o.status.success());
        if !found {
            return Some(format!(
                "{tool} is not installed (tools/install-deps.sh installs slurmctld, slurmd, \
                 slurm-client and munge)"
            ));
        }
    }
    None
}

/// The local cluster; stopped (its daemons, by their pid files) when dropped.
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
}

impl Cluster {
    fn start(dir: &Path) -> Cluster {
        let out = Command::new(repo().join("tools/slurm-local.sh"))
            .arg("start")
            .arg(dir)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "tools/slurm-local.sh start failed: {}{}",
            text(&out.stdout),
            text(&out.stderr)
        );
        Cluster {
            dir: dir.to_path_buf(),
            conf: dir.join("slurm.conf"),
        }
    }

    fn command(&self, program: impl AsRef<std::ffi::OsStr>) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", &self.conf);
        c
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = Command::new(repo().join("tools/slurm-local.sh"))
            .arg("stop")
            .arg(&self.dir)
            .output();
    }
}

#[test]
fn a_four_task_job_array_renders_seed_shards_that_merge() {
    if let Some(why) = unavailable() {
        assert!(!in_ci(), "CI must run the Slurm test, but {why}");
        // Straight to stderr, past the test harness's capture: a skip must be seen.
        let _ = writeln!(
            std::io::stderr(),
            "slurm test SKIPPED (not run, not failed): {why}"
        );
        return;
    }
    // Unix socket paths are short: keep the cluster under /tmp.
    let dir = std::env::temp_dir().join(format!("nimbus-slurm-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let cluster = Cluster::start(&dir.join("cluster"));

    let out_exr = dir.join("out.exr");
    let submitted = cluster
        .command(repo().join("tools/slurm-render.sh"))
        .current_dir(&dir)
        .env("NIMBUS", env!("CARGO_BIN_EXE_nimbus"))
        .env("NIMBUS_VALIDATION", "1")
        .env("SEED_BASE", "100")
        .args(["shards", "4", out_exr.to_str().unwrap()])
        .args([
            "--width", "32", "--height", "24", "--frames", "2", "--spp", "2",
        ])
        .output()
        .unwrap();
    assert!(
        submitted.status.success(),
        "submit: {}",
        text(&submitted.stderr)
    );
    let ids: Vec<String> = text(&submitted.stdout)
        .lines()
        .map(str::to_string)
        .collect();
    assert_eq!(
        ids.len(),
        2,
        "expected the array's and the merge's job ids: {ids:?}"
    );

    // Wait for both jobs to leave the queue.
    let start = Instant::now();
    loop {
        let queue = cluster
            .command("squeue")
            .args(["--noheader", "--jobs", &ids.join(",")])
            .output()
            .unwrap();
        if text(&queue.stdout).trim().is_empty() {
            break;
        }
        assert!(
            start.elapsed() < JOB_TIMEOUT,
            "jobs still queued after {JOB_TIMEOUT:?}: {}",
            text(&queue.stdout)
        );
        std::thread::sleep(Duration::from_millis(500));
    }
    let logs = || {
        let mut all = String::new();
        for entry in std::fs::read_dir(dir.join("out.parts"))
            .into_iter()
            .flatten()
            .flatten()
        {
            if entry.path().extension().is_some_and(|e| e == "log") {
                all += &format!(
                    "--- {}\n{}",
                    entry.path().display(),
                    std::fs::read_to_string(entry.path()).unwrap_or_default()
                );
            }
        }
        all
    };
    assert!(out_exr.exists(), "no merged image; job logs:\n{}", logs());
    let merged = read_layers(&out_exr).unwrap();
    assert_eq!(merged.attributes["seeds"], "100,101,102,103", "{}", logs());
    assert_eq!(merged.attributes["samples"], "16");
    assert_eq!(merged.attributes["stop"], "merged from 4 renders");
    for k in 0..4 {
        let part = read_layers(&dir.join(format!("out.parts/part_{k:04}.exr"))).unwrap();
        assert_eq!(part.attributes["seeds"], (100 + k).to_string());
    }
    drop(cluster);
    let _ = std::fs::remove_dir_all(&dir);
}
