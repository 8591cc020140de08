//! Writes a procedural cloud as a Mitsuba `.vol` file, the asset generator behind
//! `assets/volumes/` (see `tools/README.md`):
//!
//! ```sh
//! cargo run --example make_cloud -- assets/volumes/cloud-48x32x48.vol 48 32 48 7
//! ```

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use glam::Vec3;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() != 5 {
        bail!("usage: make_cloud OUT.vol NX NY NZ SEED");
    }
    let out = PathBuf::from(&args[0]);
    let parse = |i: usize| -> Result<u64> {
        args[i]
            .parse()
            .with_context(|| format!("argument {i} ({:?}) is not a non-negative integer", args[i]))
    };
    let dims = [parse(1)? as u32, parse(2)? as u32, parse(3)? as u32];
    nimbus_scene::check_grid_memory(dims, 1, "make_cloud")?;
    let grid = nimbus_scene::procedural_cloud(dims, parse(4)?);
    nimbus_scene::write_vol(&out, &grid, Vec3::ZERO, Vec3::ONE)?;
    println!(
        "wrote {} ({}x{}x{})",
        out.display(),
        dims[0],
        dims[1],
        dims[2]
    );
    Ok(())
}
