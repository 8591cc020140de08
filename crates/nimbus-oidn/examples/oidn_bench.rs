//! Times OIDN on this machine: device creation, the first filter call and the steady
//! state, at 640x480 and 1920x1080, colour only and colour + albedo + normal.
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
            for _ in 0..repeats.max(2) {
                let t = Instant::now();
                let out = denoiser.denoise(w, h, &color, a, nn, true)?;
                times.push(t.elapsed().as_secs_f64() * 1e3);
                std::hint::black_box(out);
            }
            let first = times[0];
            let mut rest = times[1..].to_vec();
            rest.sort_by(f64::total_cmp);
            println!(
                "{w}x{h} {}: first {first:.0} ms, then median {:.0} ms (min {:.0}, {} runs)",
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
