//! Wavefront OBJ geometry: `v` and `f` statements (see the module documentation of
//! `mesh` for what is accepted).
//!
//! Hand-written rather than read with `tobj` 4: tobj's errors name no line or face
//! (`FaceVertexOutOfBounds` alone), it renumbers vertices per object (so a bad vertex
//! cannot be named as the file numbers it), it gives no way to refuse a huge file
//! before allocating (~100 bytes per face in its own lists), and it reads an `l`
//! polyline with 3 or 4 points as a triangle or quad face. Only `v` and `f` matter
//! here, which take less code than working around those.

use std::io::BufRead;

use anyhow::{anyhow, bail, Result};
use glam::Vec3;

use super::lines::{parse, show, tokens, LineReader, MAX_LINE_BYTES};
use super::{Polygons, MAX_FACE_VERTICES, MAX_MESH_TRIANGLES, MAX_MESH_VERTICES};

/// Reads the faces and vertices of an OBJ file.
pub(crate) fn read_obj(reader: &mut dyn BufRead, name: &str) -> Result<Polygons> {
    let mut lines = LineReader::new(reader);
    let mut out = Polygons {
        index_base: 1,
        ..Polygons::default()
    };
    // A statement continued over lines ending in `\`.
    let mut joined: Vec<u8> = Vec::new();
    let mut start_line = 0;
    while let Some((number, line)) = lines.next_line().map_err(|e| anyhow!("{name}: {e}"))? {
        if joined.is_empty() {
            start_line = number;
        }
        if joined.len() + line.len() > MAX_LINE_BYTES {
            bail!("{name}: line {start_line}: statement continues past {MAX_LINE_BYTES} bytes");
        }
        joined.extend_from_slice(line);
        if joined.last() == Some(&b'\\') {
            joined.pop();
            joined.push(b' ');
            continue;
        }
        statement(&joined, start_line, name, &mut out)?;
        joined.clear();
    }
    if !joined.is_empty() {
        statement(&joined, start_line, name, &mut out)?;
    }
    Ok(out)
}

/// Handles one (joined) statement starting on `line`.
fn statement(text: &[u8], line: u64, name: &str, out: &mut Polygons) -> Result<()> {
    let mut words = tokens(text);
    match words.next() {
        Some(b"v") => vertex(words, line, name, out),
        Some(b"f") => face(words, line, name, out),
        _ => Ok(()),
    }
}

fn vertex<'a>(
    mut words: impl Iterator<Item = &'a [u8]>,
    line: u64,
    name: &str,
    out: &mut Polygons,
) -> Result<()> {
    let number = out.positions.len() as u64 + 1;
    if number > MAX_MESH_VERTICES {
        bail!("{name}: line {line}: more than {MAX_MESH_VERTICES} vertices");
    }
    let mut xyz = [0.0f32; 3];
    for (axis, value) in xyz.iter_mut().enumerate() {
        let Some(word) = words.next() else {
            bail!("{name}: line {line}: vertex {number} needs 3 coordinates, got {axis}");
        };
        let Some(v) = parse::<f32>(word) else {
            bail!(
                "{name}: line {line}: vertex {number}: `{}` is not a number",
                show(word)
            );
        };
        *value = v;
    }
    let p = Vec3::from(xyz);
    if !p.is_finite() {
        bail!("{name}: line {line}: vertex {number} is not finite: {p}");
    }
    out.positions.push(p);
    Ok(())
}

fn face<'a>(
    words: impl Iterator<Item = &'a [u8]>,
    line: u64,
    name: &str,
    out: &mut Polygons,
) -> Result<()> {
    let face = out.arities.len();
    let what = || format!("{name}: face #{} (line {line})", face + 1);
    let before = out.corners.len();
    let mut arity = 0u64;
    for word in words {
        arity += 1;
        if arity > MAX_FACE_VERTICES {
            bail!("{}: more than {MAX_FACE_VERTICES} vertices", what());
        }
        // `v`, `v/t`, `v//n` or `v/t/n`: only the position index matters.
        let position = word.split(|&b| b == b'/').next().unwrap_or(word);
        let Some(index) = parse::<i64>(position) else {
            bail!("{}: `{}` is not a vertex index", what(), show(word));
        };
        let count = out.positions.len() as i64;
        let zero_based = match index {
            0 => bail!("{}: vertex index 0 (OBJ indices start at 1)", what()),
            i if i < 0 => {
                if count + i < 0 {
                    bail!(
                        "{}: relative vertex index {i} reaches before the first vertex ({count} defined so far)",
                        what()
                    );
                }
                count + i
            }
            i => i - 1,
        };
        // Forward references are allowed; the range is checked once all are read.
        let Ok(zero_based) = u32::try_from(zero_based) else {
            bail!(
                "{}: vertex index {index} is out of range (at most {MAX_MESH_VERTICES} vertices)",
                what()
            );
        };
        out.corners.push(zero_based);
    }
    if arity < 3 {
        out.corners.truncate(before);
        bail!("{}: a face needs at least 3 vertices, got {arity}", what());
    }
    out.triangle_count += arity - 2;
    if out.triangle_count > MAX_MESH_TRIANGLES {
        bail!(
            "{}: the faces so far make more than {MAX_MESH_TRIANGLES} triangles",
            what()
        );
    }
    out.arities.push(arity as u32);
    out.lines.push(line);
    Ok(())
}
