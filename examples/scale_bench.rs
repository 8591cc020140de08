//! One measurement of the scale table in `docs/volumes.md`: renders SCENE with the grid
//! integrator INTEGRATOR (`baseline` or `restir`) and prints, as one line of JSON, the
//! time from the start to the first measured frame (scene loading, the memory guard,
//! reading the grid into bricks, deriving its levels and uploading them: "load"), GPU and
//! wall milliseconds per frame, the device bytes the render created, and the process's
//! peak host memory (VmHWM of /proc/self/status). One process per measurement, so VmHWM
//! is this render's alone:
//!
//! ```sh
//! cargo run --release --example scale_bench -- target/sparse-cloud/cloud-512.toml restir 4
//! ```

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context as _, Result};
use nimbus_gpu::{Context, ContextDesc};
use nimbus_scene::FieldOverride;

/// VmHWM of this process in bytes.
fn vm_hwm() -> Result<u64> {
    let status = std::fs::read_to_string("/proc/self/status").context("/proc/self/status")?;
    for line in status.lines() {
        if let Some(rest) = line.strip_prefix("VmHWM:") {
            let kb: u64 = rest.trim().trim_end_matches("kB").trim().parse()?;
            return Ok(kb * 1024);
        }
    }
    bail!("no VmHWM in /proc/self/status")
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() != 3 {
        bail!("usage: scale_bench SCENE.toml baseline|restir FRAMES");
    }
    let frames: i64 = args[2].parse().context("FRAMES")?;
    let start = Instant::now();
    let overrides = [
        FieldOverride::new("integrator.volume", args[1].as_str()),
        FieldOverride::new("render.frames", frames),
    ];
    let scene = nimbus_scene::load_with(&PathBuf::from(&args[0]), &overrides)?;
    let plan = nimbus::plan::build(&scene, None)?;
    let ctx = Context::new(&ContextDesc::from_env())?;
    let result = nimbus::renderer::render(&ctx, &scene, &plan, &Default::default())?;
    let total = start.elapsed().as_secs_f64();
    let n = result.frame_timings.len().max(1) as f64;
    println!(
        "{{\"scene\": \"{}\", \"integrator\": \"{}\", \"load_s\": {:.2}, \"gpu_ms_per_frame\": {:.1}, \
         \"wall_ms_per_frame\": {:.1}, \"device_mib\": {:.1}, \"vm_hwm_mib\": {:.1}, \"total_s\": {:.2}}}",
        args[0],
        args[1],
        total - result.image_time.as_secs_f64(),
        result.gpu_ms() / n,
        result.image_time.as_secs_f64() * 1e3 / n,
        result.device_bytes as f64 / (1u64 << 20) as f64,
        vm_hwm()? as f64 / (1u64 << 20) as f64,
        total
    );
    Ok(())
}
