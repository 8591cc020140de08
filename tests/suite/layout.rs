//! The Rust mirrors of GPU data agree with the GLSL declarations: binding numbers with
//! `shaders/include/bindings.glsl`, record sizes with the std430/std140 layouts of the
//! structs in `shaders/include/scene.glsl`.

use std::collections::HashMap;
use std::mem::size_of;

use nimbus::gpu::bindings;
use nimbus::gpu::{
    BaselineUniformsGpu, BoxMediumGpu, FrameUniforms, GridParamsGpu, LightGpu, PassPush,
    RestirPush, RestirUniformsGpu, ShapeGpu,
};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn read(rel: &str) -> String {
    std::fs::read_to_string(format!("{ROOT}/{rel}")).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// `#define NAME <integer>` lines of a GLSL header.
fn defines(text: &str) -> HashMap<String, i64> {
    text.lines()
        .filter_map(|line| {
            let mut words = line.split_whitespace();
            (words.next()? == "#define").then_some(())?;
            let name = words.next()?;
            let value = words.next()?.parse().ok()?;
            Some((name.to_owned(), value))
        })
        .collect()
}

/// Byte size of each `struct` in a GLSL file whose members are 16-byte vectors (or
/// arrays of them) or 32-bit scalars, laid out without padding (true for std430 and,
/// for all-vec4 members, std140).
fn struct_sizes(text: &str) -> HashMap<String, usize> {
    let mut sizes = HashMap::new();
    let mut current: Option<(String, usize)> = None;
    for line in text.lines() {
        let code = line.split("//").next().unwrap_or("").trim();
        if let Some(rest) = code.strip_prefix("struct ") {
            let name = rest.trim_end_matches('{').trim().to_owned();
            current = Some((name, 0));
            continue;
        }
        if code.starts_with("};") {
            if let Some((name, size)) = current.take() {
                sizes.insert(name, size);
            }
            continue;
        }
        if let Some((_, size)) = current.as_mut() {
            let Some(decl) = code.strip_suffix(';') else {
                continue;
            };
            let mut parts = decl.split_whitespace();
            let ty = parts.next().unwrap_or("");
            let member = parts.next().unwrap_or("");
            let elem = match ty {
                "vec4" | "uvec4" | "ivec4" => 16,
                "uint" | "int" | "float" => 4,
                // A struct declared earlier in the same file.
                other => match sizes.get(other) {
                    Some(&size) => size,
                    // Not a GPU-interface struct (e.g. vec3 members of shader-local
                    // structs): left out, so checking it fails loudly.
                    None => {
                        current = None;
                        continue;
                    }
                },
            };
            let count = member.split_once('[').map_or(1, |(_, n)| {
                n.trim_end_matches(']')
                    .parse::<usize>()
                    .expect("array size")
            });
            *size += elem * count;
        }
    }
    sizes
}

#[test]
fn binding_numbers_match_the_glsl_header() {
    let defs = defines(&read("shaders/include/bindings.glsl"));
    for (name, value) in bindings::ALL {
        assert_eq!(defs.get(name).copied(), Some(i64::from(value)), "{name}");
    }
    assert_eq!(defs["STAT_NON_FINITE"], bindings::STAT_NON_FINITE as i64);
    assert_eq!(defs["STAT_COUNT"], bindings::STAT_COUNT as i64);
    let glsl_bindings = defs.keys().filter(|k| k.starts_with("BINDING_")).count();
    assert_eq!(
        glsl_bindings,
        bindings::ALL.len(),
        "a binding is missing on one side"
    );
}

#[test]
fn record_sizes_match_the_glsl_structs() {
    let sizes = struct_sizes(&read("shaders/include/scene.glsl"));
    assert_eq!(sizes["BoxMedium"], size_of::<BoxMediumGpu>());
    assert_eq!(sizes["Shape"], size_of::<ShapeGpu>());
    assert_eq!(sizes["Light"], size_of::<LightGpu>());
    assert_eq!(sizes["FrameUniforms"], size_of::<FrameUniforms>());
    assert_eq!(sizes["PassPush"], size_of::<PassPush>());
    // Lavapipe (and the Vulkan minimum) allow 128 bytes of push constants.
    assert!(size_of::<PassPush>() <= 128);
    assert_eq!(size_of::<FrameUniforms>() % 16, 0);

    let grid = struct_sizes(&read("shaders/include/grid_types.glsl"));
    assert_eq!(grid["GridParams"], size_of::<GridParamsGpu>());
    assert_eq!(grid["BaselineUniforms"], size_of::<BaselineUniformsGpu>());
    assert_eq!(size_of::<BaselineUniformsGpu>(), grid["GridParams"] + 80);

    let restir = struct_sizes(&read("shaders/restir/resources.glsl"));
    assert_eq!(restir["RestirUniforms"], size_of::<RestirUniformsGpu>());
    assert_eq!(restir["RestirPush"], size_of::<RestirPush>());
    assert!(size_of::<RestirPush>() <= 128);
}
