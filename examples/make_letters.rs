//! Writes block letters as a closed triangle mesh (`.obj`): each lit cell of a 5 × 7
//! glyph is a unit cube, and only the faces that lie on the outside are written (a face
//! between two lit cells would emit into its neighbour: an emitting mesh would spend
//! next-event samples on light no one sees). Every face is counter-clockwise seen from
//! outside, so `emission` on the mesh shines outwards (docs/emitters.md). The scene
//! `assets/scenes/cloud-logo.toml` (the spirit of Fig. 1 of Volumetric ReSTIR: a cloud lit
//! by emissive letters) reads the committed output of
//!
//! ```sh
//! cargo run --example make_letters -- assets/scenes/cloud-logo/nimbus.obj NIMBUS
//! ```
//!
//! Arguments: `OUT.obj [TEXT [CELL_SIZE DEPTH]]` (defaults NIMBUS, 0.1 m cells, 0.1 m
//! deep). The letters stand on y = 0, read along +x, face +z, and are centred on x = 0.
//! Glyphs exist for B I M N S U and the space; other characters are refused.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};

/// 5 × 7 glyphs, top row first.
fn glyph(c: char) -> Option<[&'static str; 7]> {
    Some(match c {
        'B' => [
            "11110", "10001", "10001", "11110", "10001", "10001", "11110",
        ],
        'I' => [
            "11111", "00100", "00100", "00100", "00100", "00100", "11111",
        ],
        'M' => [
            "10001", "11011", "10101", "10101", "10001", "10001", "10001",
        ],
        'N' => [
            "10001", "11001", "10101", "10011", "10001", "10001", "10001",
        ],
        'S' => [
            "01111", "10000", "10000", "01110", "00001", "00001", "11110",
        ],
        'U' => [
            "10001", "10001", "10001", "10001", "10001", "10001", "01110",
        ],
        ' ' => [
            "00000", "00000", "00000", "00000", "00000", "00000", "00000",
        ],
        _ => return None,
    })
}

/// The lit cells (column, row from the bottom) of `text`, one blank column between
/// letters.
fn cells(text: &str) -> Result<Vec<(i32, i32)>> {
    let mut out = Vec::new();
    for (k, c) in text.chars().enumerate() {
        let Some(rows) = glyph(c.to_ascii_uppercase()) else {
            bail!("no glyph for {c:?}: the letters are B I M N S U and the space");
        };
        for (r, row) in rows.iter().enumerate() {
            for (col, bit) in row.chars().enumerate() {
                if bit == '1' {
                    out.push((6 * k as i32 + col as i32, 6 - r as i32));
                }
            }
        }
    }
    Ok(out)
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.is_empty() || args.len() > 4 {
        bail!("usage: make_letters OUT.obj [TEXT [CELL_SIZE DEPTH]]");
    }
    let out = PathBuf::from(&args[0]);
    let text = args.get(1).map_or("NIMBUS", String::as_str);
    let number = |i: usize, default: f64| -> Result<f64> {
        match args.get(i) {
            None => Ok(default),
            Some(t) => t
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && *v > 0.0 && *v < 100.0)
                .with_context(|| format!("argument {i} ({t:?}) is not a size in (0, 100) m")),
        }
    };
    let (cell, depth) = (number(2, 0.1)?, number(3, 0.1)?);
    let lit = cells(text)?;
    if lit.is_empty() {
        bail!("{text:?} has no lit cell");
    }
    let set: std::collections::HashSet<(i32, i32)> = lit.iter().copied().collect();
    let width = lit.iter().map(|c| c.0).max().unwrap_or(0) + 1;
    let x0 = -0.5 * f64::from(width) * cell;

    let mut obj = format!("# {text:?} in block letters, written by examples/make_letters.rs\n");
    let mut vertices = 0usize;
    let mut faces = 0usize;
    // A quad with corners a, b, c, d counter-clockwise from outside: two triangles.
    let mut quad = |obj: &mut String, corners: [[f64; 3]; 4]| {
        for p in corners {
            obj.push_str(&format!("v {:.6} {:.6} {:.6}\n", p[0], p[1], p[2]));
        }
        let i = vertices + 1;
        obj.push_str(&format!(
            "f {} {} {}\nf {} {} {}\n",
            i,
            i + 1,
            i + 2,
            i,
            i + 2,
            i + 3
        ));
        vertices += 4;
        faces += 2;
    };
    for &(cx, cy) in &lit {
        let (xa, xb) = (x0 + f64::from(cx) * cell, x0 + f64::from(cx + 1) * cell);
        let (ya, yb) = (f64::from(cy) * cell, f64::from(cy + 1) * cell);
        let (za, zb) = (-0.5 * depth, 0.5 * depth);
        // Front (+z) and back (-z) always face out.
        quad(
            &mut obj,
            [[xa, ya, zb], [xb, ya, zb], [xb, yb, zb], [xa, yb, zb]],
        );
        quad(
            &mut obj,
            [[xb, ya, za], [xa, ya, za], [xa, yb, za], [xb, yb, za]],
        );
        if !set.contains(&(cx + 1, cy)) {
            quad(
                &mut obj,
                [[xb, ya, zb], [xb, ya, za], [xb, yb, za], [xb, yb, zb]],
            );
        }
        if !set.contains(&(cx - 1, cy)) {
            quad(
                &mut obj,
                [[xa, ya, za], [xa, ya, zb], [xa, yb, zb], [xa, yb, za]],
            );
        }
        if !set.contains(&(cx, cy + 1)) {
            quad(
                &mut obj,
                [[xa, yb, zb], [xb, yb, zb], [xb, yb, za], [xa, yb, za]],
            );
        }
        if !set.contains(&(cx, cy - 1)) {
            quad(
                &mut obj,
                [[xa, ya, za], [xb, ya, za], [xb, ya, zb], [xa, ya, zb]],
            );
        }
    }
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    std::fs::write(&out, obj).with_context(|| format!("writing {}", out.display()))?;
    println!(
        "wrote {} ({text:?}: {} cells, {faces} triangles)",
        out.display(),
        lit.len()
    );
    Ok(())
}
