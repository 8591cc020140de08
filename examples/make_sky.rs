//! Writes the benchmark scenes' HDR sky: an equirectangular environment map (the
//! mapping of `docs/scene-format.md`: −Z at the centre column, +Y the top row) with a
//! smooth daylight gradient and a small, very bright sun, the case where importance
//! sampling of the map decides the noise. `assets/scenes/bench/sky-sun.toml` reads it
//! from `target/bench/sky-sun.exr`:
//!
//! ```sh
//! cargo run --example make_sky -- target/bench/sky-sun.exr
//! ```
//!
//! Optional arguments: `W H SUN_ELEVATION_DEG SUN_AZIMUTH_DEG SUN_DIAMETER_DEG`
//! (defaults 1024 512 25 40 1.5). The sun's radiance is set so that it alone gives an
//! irradiance of 20 W/m² at normal incidence (`nimbus_scene::daylight_sky`).

use std::path::PathBuf;

use anyhow::{bail, Context, Result};

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.is_empty() || args.len() > 6 {
        bail!("usage: make_sky OUT.exr [W H SUN_ELEVATION_DEG SUN_AZIMUTH_DEG SUN_DIAMETER_DEG]");
    }
    let out = PathBuf::from(&args[0]);
    let number = |i: usize, default: f64| -> Result<f64> {
        match args.get(i) {
            None => Ok(default),
            Some(text) => text
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .with_context(|| format!("argument {i} ({text:?}) is not a number")),
        }
    };
    let (w, h) = (number(1, 1024.0)?, number(2, 512.0)?);
    if !(8.0..=8192.0).contains(&w) || !(4.0..=4096.0).contains(&h) {
        bail!("W must be in 8..=8192 and H in 4..=4096");
    }
    let (w, h) = (w as usize, h as usize);
    let elevation = number(3, 25.0)?.to_radians();
    let azimuth = number(4, 40.0)?.to_radians();
    let diameter = number(5, 1.5)?.to_radians();
    if !(1e-3..=0.5).contains(&diameter) {
        bail!("SUN_DIAMETER_DEG must be in (0.06, 28)");
    }
    let sun = nimbus_scene::sun_direction(elevation as f32, azimuth as f32);
    let texels = nimbus_scene::daylight_sky(w, h, sun, diameter, 20.0);
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    exr::prelude::write_rgb_file(&out, w, h, |x, y| {
        let [r, g, b] = texels[y * w + x];
        (r, g, b)
    })
    .with_context(|| format!("writing {}", out.display()))?;
    println!(
        "wrote {} ({w}x{h}, sun {:.2} deg across)",
        out.display(),
        diameter.to_degrees()
    );
    Ok(())
}
