//! PLY meshes (ascii, binary little and big endian): `vertex` x/y/z and `face`
//! vertex index lists; every other element and property is read and skipped.
//!
//! Hand-written: `ply-rs` 0.1.3 has had no release since 2020, and its maintained
//! fork `ply-rs-bw` reads every element into a map of properties (hundreds of bytes
//! per vertex) unless a trait is implemented per element type, and brings a parser
//! generator. A mesh needs three properties and one list; reading them directly
//! keeps memory at the final mesh's size and every error located.

use std::io::{BufRead, ErrorKind, Read};

use anyhow::{anyhow, bail, Result};
use glam::Vec3;

use super::lines::{parse, show, tokens, LineReader};
use super::{Polygons, MAX_FACE_VERTICES, MAX_MESH_TRIANGLES, MAX_MESH_VERTICES};

/// Most instances of any other element (they are read and skipped).
const MAX_OTHER_ELEMENTS: u64 = 1 << 32;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Format {
    Ascii,
    BinaryLittle,
    BinaryBig,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(name: &[u8]) -> Option<Self> {
        Some(match name {
            b"char" | b"int8" => Self::I8,
            b"uchar" | b"uint8" => Self::U8,
            b"short" | b"int16" => Self::I16,
            b"ushort" | b"uint16" => Self::U16,
            b"int" | b"int32" => Self::I32,
            b"uint" | b"uint32" => Self::U32,
            b"float" | b"float32" => Self::F32,
            b"double" | b"float64" => Self::F64,
            _ => return None,
        })
    }

    fn name(self) -> &'static str {
        match self {
            Self::I8 => "int8",
            Self::U8 => "uint8",
            Self::I16 => "int16",
            Self::U16 => "uint16",
            Self::I32 => "int32",
            Self::U32 => "uint32",
            Self::F32 => "float32",
            Self::F64 => "float64",
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Self::F32 | Self::F64)
    }

    fn bytes(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

/// What a property is used for.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Role {
    Skip,
    Coordinate(usize),
    FaceIndices,
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
    role: Role,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: u64,
    properties: Vec<Property>,
}

/// Reads a PLY mesh.
pub(crate) fn read_ply(reader: &mut dyn BufRead, name: &str) -> Result<Polygons> {
    let (format, elements, header_lines) = read_header(reader, name)?;
    let mut out = Polygons::default();
    let mut body = match format {
        Format::Ascii => Body::Ascii {
            lines: LineReader::starting_after(reader, header_lines),
            pos: 0,
            have_line: false,
        },
        Format::BinaryLittle | Format::BinaryBig => Body::Binary {
            reader,
            big_endian: format == Format::BinaryBig,
        },
    };
    // Only the first `vertex` and `face` elements count; later ones are skipped.
    let (mut vertices_read, mut faces_read) = (false, false);
    for element in &elements {
        match element.name.as_str() {
            "vertex" if !vertices_read => {
                vertices_read = true;
                out.positions.reserve_exact(initial_capacity(element.count));
                for i in 0..element.count {
                    let p = read_vertex(&mut body, element)
                        .map_err(|e| anyhow!("{name}: vertex {i}: {e}"))?;
                    out.positions.push(p);
                }
            }
            "face" if !faces_read => {
                faces_read = true;
                out.arities.reserve_exact(initial_capacity(element.count));
                out.corners.reserve(3 * initial_capacity(element.count));
                for i in 0..element.count {
                    read_face(&mut body, element, &mut out)
                        .map_err(|e| anyhow!("{name}: face #{}: {e}", i + 1))?;
                }
            }
            // An element without properties has no data, whatever its count.
            _ if element.properties.is_empty() => {}
            _ => {
                for i in 0..element.count {
                    for property in &element.properties {
                        skip_property(&mut body, property.kind).map_err(|e| {
                            anyhow!(
                                "{name}: element `{}` #{} property `{}`: {e}",
                                element.name,
                                i + 1,
                                property.name
                            )
                        })?;
                    }
                }
            }
        }
    }
    Ok(out)
}

/// Room reserved up front for `count` elements: the header's count, but at most 2^20,
/// so a header that promises more data than follows costs no memory.
fn initial_capacity(count: u64) -> usize {
    count.min(1 << 20) as usize
}

fn read_vertex(body: &mut Body, element: &Element) -> Result<Vec3> {
    let mut xyz = [0.0f64; 3];
    for property in &element.properties {
        match (property.role, property.kind) {
            (Role::Coordinate(axis), Kind::Scalar(ty)) => {
                let v = body.scalar(ty)?;
                if let Some(slot) = xyz.get_mut(axis) {
                    *slot = v;
                }
            }
            (_, kind) => skip_property(body, kind)?,
        }
    }
    let p = Vec3::new(xyz[0] as f32, xyz[1] as f32, xyz[2] as f32);
    if !p.is_finite() {
        bail!("not finite as f32: ({}, {}, {})", xyz[0], xyz[1], xyz[2]);
    }
    Ok(p)
}

fn read_face(body: &mut Body, element: &Element, out: &mut Polygons) -> Result<()> {
    for property in &element.properties {
        match (property.role, property.kind) {
            (Role::FaceIndices, Kind::List { count, item }) => {
                let n = list_length(body, count)?;
                if n < 3 {
                    bail!("a face needs at least 3 vertices, got {n}");
                }
                if n > MAX_FACE_VERTICES {
                    bail!("{n} vertices, more than {MAX_FACE_VERTICES}");
                }
                out.triangle_count += n - 2;
                if out.triangle_count > MAX_MESH_TRIANGLES {
                    bail!("the faces so far make more than {MAX_MESH_TRIANGLES} triangles");
                }
                for _ in 0..n {
                    let v = body.scalar(item)?;
                    if v < 0.0 || v > f64::from(u32::MAX) {
                        bail!("vertex index {v} is out of range");
                    }
                    out.corners.push(v as u32);
                }
                out.arities.push(n as u32);
            }
            (_, kind) => skip_property(body, kind)?,
        }
    }
    Ok(())
}

/// A list's length: a non-negative integer.
fn list_length(body: &mut Body, count: Scalar) -> Result<u64> {
    let n = body.scalar(count)?;
    if n < 0.0 {
        bail!("negative list length {n}");
    }
    Ok(n as u64)
}

fn skip_property(body: &mut Body, kind: Kind) -> Result<()> {
    match kind {
        Kind::Scalar(ty) => {
            body.scalar(ty)?;
        }
        Kind::List { count, item } => {
            let n = list_length(body, count)?;
            for _ in 0..n {
                body.scalar(item)?;
            }
        }
    }
    Ok(())
}

/// The data after the header.
enum Body<'a> {
    Ascii {
        lines: LineReader<'a>,
        /// Byte offset of the next token in the current line.
        pos: usize,
        have_line: bool,
    },
    Binary {
        reader: &'a mut dyn BufRead,
        big_endian: bool,
    },
}

impl Body<'_> {
    /// The next value of type `ty` (integers are exact in f64).
    fn scalar(&mut self, ty: Scalar) -> Result<f64> {
        match self {
            Body::Binary { reader, big_endian } => {
                let mut b = [0u8; 8];
                let n = ty.bytes();
                let bytes = &mut b[..n];
                if let Err(e) = reader.read_exact(bytes) {
                    if e.kind() == ErrorKind::UnexpectedEof {
                        bail!("unexpected end of file");
                    }
                    bail!("read error: {e}");
                }
                if *big_endian {
                    bytes.reverse();
                }
                Ok(match ty {
                    Scalar::I8 => f64::from(b[0] as i8),
                    Scalar::U8 => f64::from(b[0]),
                    Scalar::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
                    Scalar::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
                    Scalar::I32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                    Scalar::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                    Scalar::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                    Scalar::F64 => f64::from_le_bytes(b),
                })
            }
            Body::Ascii {
                lines,
                pos,
                have_line,
            } => {
                let token = loop {
                    if *have_line {
                        let line = lines.current();
                        let rest = line.get(*pos..).unwrap_or(&[]);
                        let skip = rest.iter().take_while(|b| b.is_ascii_whitespace()).count();
                        let len = rest
                            .iter()
                            .skip(skip)
                            .take_while(|b| !b.is_ascii_whitespace())
                            .count();
                        if len > 0 {
                            let start = *pos + skip;
                            *pos = start + len;
                            break (start, start + len);
                        }
                    }
                    if lines.next_line()?.is_none() {
                        bail!("unexpected end of file");
                    }
                    *pos = 0;
                    *have_line = true;
                };
                let word = lines.current().get(token.0..token.1).unwrap_or(&[]);
                let value = if ty.is_integer() {
                    parse::<i64>(word).map(|v| v as f64)
                } else {
                    parse::<f64>(word)
                };
                value.ok_or_else(|| {
                    anyhow!(
                        "line {}: `{}` is not a valid {} value",
                        lines.line,
                        show(word),
                        ty.name()
                    )
                })
            }
        }
    }
}

/// Reads the header up to and including `end_header`; returns its line count too.
fn read_header(reader: &mut dyn BufRead, name: &str) -> Result<(Format, Vec<Element>, u64)> {
    let mut lines = LineReader::new(reader);
    match lines.next_line().map_err(|e| anyhow!("{name}: {e}"))? {
        Some((_, b"ply")) => {}
        _ => bail!("{name}: not a PLY file (the first line must be `ply`)"),
    }
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let Some((at, line)) = lines
            .next_line()
            .map_err(|e| anyhow!("{name}: header: {e}"))?
        else {
            bail!("{name}: the header has no `end_header`");
        };
        let words: Vec<&[u8]> = tokens(line).collect();
        let bad = |what: &str| anyhow!("{name}: header line {at}: {what}");
        match words.as_slice() {
            [] => {}
            [b"end_header"] => break,
            [b"comment", ..] | [b"obj_info", ..] => {}
            [b"format", f, version] => {
                if *version != b"1.0" {
                    return Err(bad(&format!("unsupported version `{}`", show(version))));
                }
                format = Some(match *f {
                    b"ascii" => Format::Ascii,
                    b"binary_little_endian" => Format::BinaryLittle,
                    b"binary_big_endian" => Format::BinaryBig,
                    other => return Err(bad(&format!("unknown format `{}`", show(other)))),
                });
            }
            [b"element", element, count] => {
                let element = String::from_utf8_lossy(element).into_owned();
                let Some(count) = parse::<u64>(count) else {
                    return Err(bad(&format!("bad count `{}`", show(count))));
                };
                let limit = match element.as_str() {
                    "vertex" => MAX_MESH_VERTICES,
                    "face" => MAX_MESH_TRIANGLES,
                    _ => MAX_OTHER_ELEMENTS,
                };
                if count > limit {
                    return Err(bad(&format!(
                        "{count} `{element}` elements, more than the limit of {limit}"
                    )));
                }
                elements.push(Element {
                    name: element,
                    count,
                    properties: Vec::new(),
                });
            }
            [b"property", rest @ ..] => {
                let Some(element) = elements.last_mut() else {
                    return Err(bad("`property` before any `element`"));
                };
                let (kind, property) = match rest {
                    [b"list", count, item, property] => {
                        let (Some(count), Some(item)) =
                            (Scalar::from_name(count), Scalar::from_name(item))
                        else {
                            return Err(bad("unknown list types"));
                        };
                        if !count.is_integer() {
                            return Err(bad("a list length type must be an integer type"));
                        }
                        (Kind::List { count, item }, property)
                    }
                    [ty, property] => {
                        let Some(ty) = Scalar::from_name(ty) else {
                            return Err(bad(&format!("unknown type `{}`", show(ty))));
                        };
                        (Kind::Scalar(ty), property)
                    }
                    _ => return Err(bad("malformed `property` line")),
                };
                let property = String::from_utf8_lossy(property).into_owned();
                let role = match (element.name.as_str(), property.as_str(), kind) {
                    ("vertex", "x", Kind::Scalar(_)) => Role::Coordinate(0),
                    ("vertex", "y", Kind::Scalar(_)) => Role::Coordinate(1),
                    ("vertex", "z", Kind::Scalar(_)) => Role::Coordinate(2),
                    ("face", "vertex_indices" | "vertex_index", Kind::List { item, .. }) => {
                        if !item.is_integer() {
                            return Err(bad("face vertex indices must have an integer type"));
                        }
                        Role::FaceIndices
                    }
                    _ => Role::Skip,
                };
                element.properties.push(Property {
                    name: property,
                    kind,
                    role,
                });
            }
            _ => return Err(bad(&format!("unexpected `{}`", show(line)))),
        }
    }
    let Some(format) = format else {
        bail!("{name}: the header has no `format` line");
    };
    check_elements(&elements, name)?;
    Ok((format, elements, lines.line))
}

/// The vertex element has x, y, z; the face element has its index list.
fn check_elements(elements: &[Element], name: &str) -> Result<()> {
    let find = |n: &str| elements.iter().find(|e| e.name == n);
    let Some(vertex) = find("vertex") else {
        bail!("{name}: no `vertex` element in the header");
    };
    for (axis, label) in ["x", "y", "z"].iter().enumerate() {
        let found = vertex
            .properties
            .iter()
            .filter(|p| p.role == Role::Coordinate(axis))
            .count();
        if found != 1 {
            bail!("{name}: the `vertex` element needs exactly one scalar property `{label}`");
        }
    }
    match find("face") {
        None => bail!("{name}: the mesh has no faces (no `face` element)"),
        Some(face) => {
            let lists = face
                .properties
                .iter()
                .filter(|p| p.role == Role::FaceIndices)
                .count();
            if lists != 1 {
                bail!("{name}: the `face` element needs exactly one list property `vertex_indices` (or `vertex_index`)");
            }
        }
    }
    Ok(())
}
