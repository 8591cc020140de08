//! The build side of `src/shader_data/contract/`: the record, binding and feature tables expanded
//! to GLSL (`$OUT_DIR/glsl/gpu_{records,bindings,features}.glsl`) and to the layout every
//! record has under the GLSL rules (`$OUT_DIR/record_layouts.rs`, which the crate asserts
//! against its `#[repr(C)]` structs at compile time). See `src/shader_data/contract/mod.rs`.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

/// `pub const NAME: T = value (=> GLSL)?;` of a table.
pub struct Const {
    pub name: &'static str,
    pub glsl: &'static str,
    pub value: &'static str,
    pub docs: &'static [&'static str],
}

/// A member of a record: its Rust name and type (as written) and its docs.
pub struct Field {
    pub name: &'static str,
    pub ty: &'static str,
    pub docs: &'static [&'static str],
}

/// `struct Rust as Glsl [rules] { fields }` of the record table.
pub struct Record {
    pub rust: &'static str,
    pub glsl: &'static str,
    pub external: bool,
    pub rules: &'static [&'static str],
    pub docs: &'static [&'static str],
    pub fields: Vec<Field>,
}

fn or_name(glsl: &'static str, name: &'static str) -> &'static str {
    if glsl.is_empty() {
        name
    } else {
        glsl
    }
}

macro_rules! gpu_consts {
    ($($(#[doc = $doc:literal])* pub const $name:ident : $ty:ty = $value:literal $(=> $glsl:ident)?;)*) => {
        pub fn consts() -> Vec<Const> {
            vec![$(Const {
                name: stringify!($name),
                glsl: or_name(stringify!($($glsl)?), stringify!($name)),
                value: stringify!($value),
                docs: &[$($doc),*],
            }),*]
        }
    };
}

macro_rules! gpu_records {
    (@list [$($out:expr),*]) => {
        pub fn records() -> Vec<Record> {
            vec![$($out),*]
        }
    };
    (@list [$($out:expr),*]
        $(#[doc = $doc:literal])*
        extern struct $rust:path as $glsl:ident [$($rule:ident),*] {
            $($(#[doc = $fdoc:literal])* $field:ident : $ty:ty),* $(,)?
        }
        $($rest:tt)*
    ) => {
        gpu_records!(@list [$($out,)* Record {
            rust: stringify!($rust),
            glsl: stringify!($glsl),
            external: true,
            rules: &[$(stringify!($rule)),*],
            docs: &[$($doc),*],
            fields: vec![$(Field { name: stringify!($field), ty: stringify!($ty), docs: &[$($fdoc),*] }),*],
        }] $($rest)*);
    };
    (@list [$($out:expr),*]
        $(#[doc = $doc:literal])*
        #[derive($($derive:path),*)]
        struct $rust:ident as $glsl:ident [$($rule:ident),*] {
            $($(#[doc = $fdoc:literal])* $field:ident : $ty:ty),* $(,)?
        }
        $($rest:tt)*
    ) => {
        gpu_records!(@list [$($out,)* Record {
            rust: stringify!($rust),
            glsl: stringify!($glsl),
            external: false,
            rules: &[$(stringify!($rule)),*],
            docs: &[$($doc),*],
            fields: vec![$(Field { name: stringify!($field), ty: stringify!($ty), docs: &[$($fdoc),*] }),*],
        }] $($rest)*);
    };
    ($($all:tt)*) => {
        gpu_records!(@list [] $($all)*);
    };
}

mod records_table {
    use super::*;
    include!("../src/shader_data/contract/records.rs");
}

mod bindings_table {
    use super::*;
    include!("../src/shader_data/contract/bindings.rs");
}

mod features_table {
    use super::*;
    include!("../src/shader_data/contract/features.rs");
}

/// The table files, for `cargo:rerun-if-changed`.
pub const SOURCES: [&str; 4] = [
    "src/shader_data/contract/records.rs",
    "src/shader_data/contract/bindings.rs",
    "src/shader_data/contract/features.rs",
    "build/contract.rs",
];

/// Writes the GLSL headers into `glsl_dir` and `record_layouts.rs` into `out_dir`.
pub fn generate(glsl_dir: &Path, out_dir: &Path) -> Result<(), String> {
    std::fs::create_dir_all(glsl_dir).map_err(|e| format!("{}: {e}", glsl_dir.display()))?;
    let write = |path: &Path, text: &str| {
        std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))
    };
    let records = records_table::records();
    let tags = records_table::consts();
    let mut text = header(
        "records",
        "GPU records (std430 / std140) and their type tags",
    );
    text += &consts_glsl("records", &tags)?;
    let (glsl, layouts) = records_glsl(&records)?;
    text += &glsl;
    text += "#endif\n";
    write(&glsl_dir.join("gpu_records.glsl"), &text)?;
    write(&out_dir.join("record_layouts.rs"), &layouts)?;

    let mut text = header(
        "bindings",
        "descriptor binding numbers (set 0), stats indices",
    );
    text += &consts_glsl("bindings", &bindings_table::consts())?;
    text += "#endif\n";
    write(&glsl_dir.join("gpu_bindings.glsl"), &text)?;

    let mut text = header(
        "features",
        "specialization-constant IDs, estimator IDs, limits",
    );
    text += &consts_glsl("features", &features_table::consts())?;
    text += "#endif\n";
    write(&glsl_dir.join("gpu_features.glsl"), &text)?;
    Ok(())
}

fn header(table: &str, what: &str) -> String {
    let guard = format!("NIMBUS_GPU_{}_GLSL", table.to_uppercase());
    format!(
        "// Generated by build.rs from src/shader_data/contract/{table}.rs ({what}): edit that file.\n\
         #ifndef {guard}\n#define {guard}\n\n"
    )
}

fn comment(out: &mut String, indent: &str, docs: &[&str]) {
    for line in docs {
        let line = line.strip_prefix(' ').unwrap_or(line);
        let _ = writeln!(out, "{indent}// {line}");
    }
}

/// `#define GLSL value` per constant: the literal without `_`, a `u32` suffix as `u`.
/// Two constants of one family (SC_ID_*, BINDING_*, ...) with one value are an error.
fn consts_glsl(table: &str, consts: &[Const]) -> Result<String, String> {
    const FAMILIES: [&str; 6] = [
        "SC_ID_",
        "BINDING_",
        "ESTIMATOR_",
        "SHAPE_",
        "LIGHT_",
        "EMITTER_",
    ];
    let mut out = String::new();
    let mut seen: HashMap<(&str, String), &str> = HashMap::new();
    for c in consts {
        let digits = c.value.replace('_', "");
        let (number, suffix) = match digits.strip_suffix("u32") {
            Some(n) => (n.to_owned(), "u"),
            None => (digits.clone(), ""),
        };
        if number.is_empty() || !number.chars().all(|ch| ch.is_ascii_digit()) {
            return Err(format!(
                "src/shader_data/contract/{table}.rs: {} = {}: a constant is a decimal literal, \
                 optionally with a u32 suffix",
                c.name, c.value
            ));
        }
        if let Some(family) = FAMILIES.iter().find(|f| c.glsl.starts_with(**f)) {
            if let Some(other) = seen.insert((family, number.clone()), c.glsl) {
                return Err(format!(
                    "src/shader_data/contract/{table}.rs: {other} and {} are both {number}",
                    c.glsl
                ));
            }
        }
        comment(&mut out, "", c.docs);
        let _ = writeln!(out, "#define {} {number}{suffix}", c.glsl);
    }
    out.push('\n');
    Ok(out)
}

/// A GLSL member type: scalar or vector name and array length.
struct GlslType {
    name: String,
    array: Option<u32>,
}

/// The GLSL type of a Rust field type (whitespace removed): `f32` float, `[u32;3]` uvec3,
/// `[[f32;4];5]` vec4[5], a record by its Rust name.
fn glsl_type(rust: &str, records: &HashMap<String, String>) -> Result<GlslType, String> {
    let scalar = |s: &str| match s {
        "f32" => Some(("float", "vec")),
        "u32" => Some(("uint", "uvec")),
        "i32" => Some(("int", "ivec")),
        _ => None,
    };
    if let Some(inner) = rust.strip_prefix('[').and_then(|r| r.strip_suffix(']')) {
        let (elem, count) = inner
            .rsplit_once(';')
            .ok_or(format!("array type {rust} without a length"))?;
        let count: u32 = count
            .parse()
            .map_err(|_| format!("array type {rust}: the length is not a number"))?;
        if let (Some((_, vector)), 2..=4) = (scalar(elem), count) {
            return Ok(GlslType {
                name: format!("{vector}{count}"),
                array: None,
            });
        }
        let elem = glsl_type(elem, records)?;
        if elem.array.is_some() {
            return Err(format!("{rust}: arrays of arrays have no GLSL member type"));
        }
        return Ok(GlslType {
            name: elem.name,
            array: Some(count),
        });
    }
    if let Some((name, _)) = scalar(rust) {
        return Ok(GlslType {
            name: name.to_owned(),
            array: None,
        });
    }
    let last = rust.rsplit("::").next().unwrap_or(rust);
    match records.get(last) {
        Some(glsl) => Ok(GlslType {
            name: glsl.clone(),
            array: None,
        }),
        None => Err(format!(
            "field type {rust} is neither f32 / u32 / i32, an array of them, nor a record \
             declared earlier in the table"
        )),
    }
}

fn round_up(x: u32, align: u32) -> u32 {
    x.div_ceil(align) * align
}

/// Base alignment and size of a GLSL type under `std140` or `std430` (GLSL 4.60
/// section 7.6.2.2; std430 drops the rounding of arrays and structures up to 16).
fn type_layout(
    ty: &GlslType,
    std140: bool,
    structs: &HashMap<String, (u32, u32, u32, u32)>,
) -> Result<(u32, u32), String> {
    let (align, size) = match ty.name.as_str() {
        "float" | "uint" | "int" => (4, 4),
        "vec2" | "uvec2" | "ivec2" => (8, 8),
        "vec3" | "uvec3" | "ivec3" => (16, 12),
        "vec4" | "uvec4" | "ivec4" => (16, 16),
        name => {
            let &(a140, s140, a430, s430) = structs
                .get(name)
                .ok_or(format!("unknown GLSL type {name}"))?;
            if std140 {
                (a140, s140)
            } else {
                (a430, s430)
            }
        }
    };
    Ok(match ty.array {
        None => (align, size),
        Some(count) => {
            let (mut align, mut stride) = (align, round_up(size, align));
            if std140 {
                align = round_up(align, 16);
                stride = round_up(stride, 16);
            }
            (align, stride * count)
        }
    })
}

/// The GLSL structs and the Rust layout file.
fn records_glsl(records: &[Record]) -> Result<(String, String), String> {
    let mut glsl = String::new();
    let mut rust = String::from(
        "// Generated by build.rs from src/shader_data/contract/records.rs: the std430 layout of \
         every record.\n\npub const RECORD_LAYOUTS: &[RecordLayout] = &[\n",
    );
    let mut asserts = String::new();
    let mut glsl_of: HashMap<String, String> = HashMap::new();
    // GLSL name -> (std140 align, size, std430 align, size).
    let mut structs: HashMap<String, (u32, u32, u32, u32)> = HashMap::new();
    for r in records {
        let rust_last = r
            .rust
            .rsplit("::")
            .next()
            .unwrap_or(r.rust)
            .trim()
            .to_owned();
        let at = format!(
            "src/shader_data/contract/records.rs: {} ({})",
            r.rust, r.glsl
        );
        let mut members = Vec::new();
        for f in &r.fields {
            let ty: String = f.ty.chars().filter(|c| !c.is_whitespace()).collect();
            let ty = glsl_type(&ty, &glsl_of).map_err(|e| format!("{at}.{}: {e}", f.name))?;
            members.push((f.name.trim_start_matches("r#"), ty, f));
        }
        let mut per_rule = Vec::new();
        for std140 in [true, false] {
            let (mut offset, mut align) = (0, 1);
            let mut placed = Vec::new();
            for (name, ty, _) in &members {
                let (a, size) = type_layout(ty, std140, &structs)?;
                let at_offset = round_up(offset, a);
                if at_offset != offset {
                    return Err(format!(
                        "{at}: {} bytes of implicit padding before `{name}`: name them (_padN)",
                        at_offset - offset
                    ));
                }
                placed.push((*name, offset, size));
                offset += size;
                align = align.max(a);
            }
            if std140 {
                align = round_up(align, 16);
            }
            let size = round_up(offset, align);
            per_rule.push((align, size, placed, offset));
        }
        let (a140, s140, p140, end140) = &per_rule[0];
        let (a430, s430, p430, end430) = &per_rule[1];
        if end430 != s430 {
            return Err(format!(
                "{at}: {} bytes of implicit padding at the end: name them (_padN)",
                s430 - end430
            ));
        }
        if r.rules.contains(&"std140") && (p140 != p430 || s140 != s430 || end140 != end430) {
            return Err(format!(
                "{at}: declared for std140 too, but std140 lays it out differently"
            ));
        }
        structs.insert(r.glsl.to_owned(), (*a140, *s140, *a430, *s430));
        glsl_of.insert(rust_last, r.glsl.to_owned());

        comment(&mut glsl, "", r.docs);
        let _ = writeln!(glsl, "struct {} {{", r.glsl);
        for (name, ty, f) in &members {
            comment(&mut glsl, "    ", f.docs);
            match ty.array {
                Some(n) => writeln!(glsl, "    {} {name}[{n}];", ty.name),
                None => writeln!(glsl, "    {} {name};", ty.name),
            }
            .map_err(|e| e.to_string())?;
        }
        glsl.push_str("};\n\n");

        let path = if r.external {
            r.rust.replace(' ', "")
        } else {
            format!("crate::shader_data::records::{}", r.rust)
        };
        let _ = writeln!(
            rust,
            "    RecordLayout {{ glsl: {:?}, rust: {:?}, size: {s430}, members: &[",
            r.glsl,
            r.rust.replace(' ', "")
        );
        let _ = writeln!(
            asserts,
            "const _: () = assert!(::core::mem::size_of::<{path}>() == {s430});"
        );
        for ((name, offset, size), (_, _, f)) in p430.iter().zip(&members) {
            let _ = writeln!(rust, "        ({name:?}, {offset}, {size}),");
            let _ = writeln!(
                asserts,
                "const _: () = assert!(::core::mem::offset_of!({path}, {}) == {offset});",
                f.name
            );
        }
        rust.push_str("    ] },\n");
    }
    rust.push_str("];\n\n");
    rust.push_str(&asserts);
    Ok((glsl, rust))
}
