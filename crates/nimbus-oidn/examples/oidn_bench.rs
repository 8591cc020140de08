//! Times OIDN on this machine: device creation, the first filter call and the steady
//! state, at 640x480 and 1920x1080, colour only and colour + albedo + normal.
//! Also prints the process's CPU time per call (all threads, from /proc/self/stat): on a
//! shared, loaded machine, CPU seconds / cores is the wall time an idle machine would give.
//! `cargo run --release -p nimbus-oidn --example oidn_bench [-- cpu] [-- REPEATS]`

use std::time::Instant;

use nimbus_oidn::Denoiser;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let cpu = args.iter().any(|a| a == "cpu");
    let repeats: usize = args.iter().find_map(|a| a.parse().ok()).unwrap_or(5);
    let start = Instant::now();
    let denoiser = if cpu {
        Denoiser::cpu()?
    } else {
        Denoiser::new()?
    };
    println!(
        "device creation: {:.1} ms ({})",
        start.elapsed().as_secs_f64() * 1e3,
        if cpu { "cpu" } else { "default device" }
    );
    for (w, h) in [(640u32, 480u32), (1920, 1080)] {
        let n = (w * h) as usize;
        let color: Vec<f32> = (0..n * 3)
            .map(|i| ((i * 7919) % 1000) as f32 / 500.0)
            .collect();
        let albedo = vec![0.5_f32; n * 3];
        let normal: Vec<f32> = (0..n).flat_map(|_| [0.0, 0.0, 1.0]).collect();
        for aux in [false, true] {
            let (a, nn) = if aux {
                (Some(&albedo[..]), Some(&normal[..]))
            } else {
                (None, None)
            };
            let mut times = Vec::new();
            let mut cpu_ms = Vec::new();
            for _ in 0..repeats.max(2) {
                let t = Instant::now();
                let c = process_cpu_ms();
                let out = denoiser.denoise(w, h, &color, a, nn, true)?;
                times.push(t.elapsed().as_secs_f64() * 1e3);
                cpu_ms.push(process_cpu_ms() - c);
                std::hint::black_box(out);
            }
            let cpu_rest = cpu_ms[1..].iter().sum::<f64>() / (cpu_ms.len() - 1) as f64;
            let first = times[0];
            let mut rest = times[1..].to_vec();
            rest.sort_by(f64::total_cmp);
            println!(
                "{w}x{h} {}: first {first:.0} ms, then median {:.0} ms (min {:.0}, {} runs); \
                 CPU time {cpu_rest:.0} ms per call",
                if aux {
                    "color+albedo+normal"
                } else {
                    "color only"
                },
                rest[rest.len() / 2],
                rest[0],
                rest.len()
            );
        }
    }
    Ok(())
}

/// User + system CPU time of the whole process so far, in ms (0 where /proc is absent).
fn process_cpu_ms() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the ")" that closes the command name: state is field 3, so utime
    // (14) and stime (15) are the 12th and 13th after it. Clock ticks are 100 Hz on Linux.
    let Some((_, rest)) = stat.rsplit_once(')') else {
        return 0.0;
    };
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| {
        fields
            .get(i)
            .and_then(|f| f.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    (ticks(11) + ticks(12)) * 10.0
}
