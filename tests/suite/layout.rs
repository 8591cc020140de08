//! The Rust mirrors of GPU data agree with the GLSL declarations: binding numbers with
//! `shaders/include/bindings.glsl`, the shape and light type tags with scene.glsl, and
//! every record, uniform and push-constant struct of `shaders/include/scene.glsl`,
//! `shaders/include/grid_types.glsl` and `shaders/restir/resources.glsl` member by
//! member: the same member names, each with the same type and the offset and size that
//! the GLSL std140 / std430 rules give it, and the same struct size.

use std::collections::HashMap;
use std::mem::size_of;

use nimbus::gpu::bindings;
use nimbus::gpu::{
    BaselineUniformsGpu, BoxMediumGpu, EmitterGpu, FrameUniforms, GridLevelGpu, GridParamsGpu,
    GridSpaceGpu, LightGpu, MeshTriangleGpu, MomentFrameGpu, MomentPush, PassPush, RestirPush,
    RestirUniformsGpu, ShapeGpu, EMITTER_SPHERE, EMITTER_TRIANGLE, LIGHT_AREA, LIGHT_DIRECTIONAL,
    LIGHT_POINT, LIGHT_SPHERE, SHAPE_BOX, SHAPE_MESH, SHAPE_QUAD, SHAPE_SPHERE,
};
use nimbus_scene::BvhNode;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The GLSL files whose structs are mirrored in `src/gpu/records.rs`. Every struct
/// declared in them must be checked below.
const RECORD_FILES: [&str; 3] = [
    "shaders/include/scene.glsl",
    "shaders/include/grid_types.glsl",
    "shaders/restir/resources.glsl",
];

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

#[test]
fn binding_numbers_match_the_glsl_header() {
    let defs = defines(&read("shaders/include/bindings.glsl"));
    for (name, value) in bindings::ALL {
        assert_eq!(defs.get(name).copied(), Some(i64::from(value)), "{name}");
    }
    assert_eq!(defs["STAT_NON_FINITE"], bindings::STAT_NON_FINITE as i64);
    assert_eq!(defs["STAT_STEP_CAP"], bindings::STAT_STEP_CAP as i64);
    assert_eq!(defs["STAT_LOOPS_CUT"], bindings::STAT_LOOPS_CUT as i64);
    assert_eq!(defs["STAT_COUNT"], bindings::STAT_COUNT as i64);
    let glsl_bindings = defs.keys().filter(|k| k.starts_with("BINDING_")).count();
    assert_eq!(
        glsl_bindings,
        bindings::ALL.len(),
        "a binding is missing on one side"
    );
}

/// The values of `Shape.type`, `Light.type` and `Emitter.type` (`#define NAME <n>u` in
/// scene.glsl).
#[test]
fn record_type_tags_match_the_glsl_defines() {
    let text = read("shaders/include/scene.glsl");
    let defs: HashMap<&str, u32> = text
        .lines()
        .filter_map(|line| {
            let mut words = line.split_whitespace();
            (words.next()? == "#define").then_some(())?;
            let name = words.next()?;
            let value = words.next()?.strip_suffix('u')?.parse().ok()?;
            Some((name, value))
        })
        .collect();
    let rust = [
        ("SHAPE_QUAD", SHAPE_QUAD),
        ("SHAPE_BOX", SHAPE_BOX),
        ("SHAPE_SPHERE", SHAPE_SPHERE),
        ("SHAPE_MESH", SHAPE_MESH),
        ("LIGHT_DIRECTIONAL", LIGHT_DIRECTIONAL),
        ("LIGHT_POINT", LIGHT_POINT),
        ("LIGHT_SPHERE", LIGHT_SPHERE),
        ("LIGHT_AREA", LIGHT_AREA),
        ("EMITTER_TRIANGLE", EMITTER_TRIANGLE),
        ("EMITTER_SPHERE", EMITTER_SPHERE),
    ];
    for (name, value) in rust {
        assert_eq!(defs.get(name).copied(), Some(value), "{name}");
    }
    let tags = defs
        .keys()
        .filter(|k| k.starts_with("SHAPE_") || k.starts_with("LIGHT_") || k.starts_with("EMITTER_"))
        .count();
    assert_eq!(tags, rust.len(), "a type tag is missing on one side");
}

// ---------------------------------------------------------------------------------------
// The GLSL side: struct declarations and their std140 / std430 layouts.

/// One member declaration `TYPE NAME;` or `TYPE NAME[N];`.
#[derive(Clone, Debug)]
struct GlslMember {
    ty: String,
    name: String,
    array: Option<usize>,
}

/// The structs declared in `text`, in order. A struct is `struct NAME {` on one line,
/// one member declaration per line, and `};`; anything else inside one (several
/// declarators, a preprocessor line, a block comment) fails the test, so nothing in a
/// mirrored struct goes unchecked.
fn glsl_structs(file: &str, text: &str) -> Result<Vec<(String, Vec<GlslMember>)>, String> {
    let mut structs = Vec::new();
    let mut current: Option<(String, Vec<GlslMember>)> = None;
    for (number, line) in text.lines().enumerate() {
        let at = format!("{file}:{}", number + 1);
        let code = line.split("//").next().unwrap_or("").trim();
        if let Some(rest) = code.strip_prefix("struct ") {
            if current.is_some() {
                return Err(format!("{at}: nested struct declaration"));
            }
            let name = rest
                .strip_suffix('{')
                .ok_or(format!("{at}: expected `struct NAME {{` on one line"))?
                .trim();
            current = Some((name.to_owned(), Vec::new()));
            continue;
        }
        let Some((_, members)) = current.as_mut() else {
            continue;
        };
        if code.is_empty() {
            continue;
        }
        if code == "};" {
            structs.extend(current.take());
            continue;
        }
        let expected = || format!("{at}: expected `TYPE NAME;` or `TYPE NAME[N];`: {code:?}");
        let decl = code.strip_suffix(';').ok_or_else(expected)?;
        let words: Vec<&str> = decl.split_whitespace().collect();
        let [ty, declarator] = words[..] else {
            return Err(expected());
        };
        let (name, array) = match declarator.split_once('[') {
            Some((name, count)) => {
                let count = count
                    .strip_suffix(']')
                    .and_then(|n| n.parse::<usize>().ok())
                    .ok_or_else(expected)?;
                (name, Some(count))
            }
            None => (declarator, None),
        };
        let is_identifier = |s: &str| {
            s.chars()
                .next()
                .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
                && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        };
        if !(is_identifier(ty) && is_identifier(name)) {
            return Err(expected());
        }
        members.push(GlslMember {
            ty: ty.to_owned(),
            name: name.to_owned(),
            array,
        });
    }
    match current {
        Some((name, _)) => Err(format!("{file}: struct {name} is not terminated")),
        None => Ok(structs),
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Rule {
    Std140,
    Std430,
}

fn round_up(x: usize, align: usize) -> usize {
    x.div_ceil(align) * align
}

/// A member of a struct as laid out by a rule.
#[derive(Debug)]
struct Placed {
    name: String,
    /// The declared type, `TYPE` or `TYPE[N]`.
    ty: String,
    offset: usize,
    size: usize,
}

/// A struct as laid out by a rule: its base alignment, size and members.
#[derive(Debug)]
struct StructLayout {
    align: usize,
    size: usize,
    members: Vec<Placed>,
}

/// Base alignment and size of a non-array type (GLSL 4.60 sec. 7.6.2.2, rules 1-3 and
/// 9; std430 drops the rounding of structures up to 16). Unknown types fail the test.
fn type_layout(
    ty: &str,
    rule: Rule,
    structs: &HashMap<String, Vec<GlslMember>>,
) -> Result<(usize, usize), String> {
    let vector = |n: usize| match n {
        2 => (8, 8),
        3 => (16, 12),
        4 => (16, 16),
        _ => unreachable!(),
    };
    Ok(match ty {
        "float" | "uint" | "int" => (4, 4),
        "vec2" | "uvec2" | "ivec2" => vector(2),
        "vec3" | "uvec3" | "ivec3" => vector(3),
        "vec4" | "uvec4" | "ivec4" => vector(4),
        name => {
            let members = structs.get(name).ok_or(format!(
                "unknown GLSL type {name:?}: neither a 32-bit scalar or vector nor a struct \
                 declared earlier in {RECORD_FILES:?}"
            ))?;
            let layout = struct_layout(name, members, rule, structs)?;
            (layout.align, layout.size)
        }
    })
}

/// Offsets of every member of struct `name`, its base alignment and size: each member
/// at the next multiple of its base alignment; an array's stride is its element's size
/// rounded up to the element's alignment (and, in std140, to 16); a struct's alignment
/// is its largest member's (in std140 rounded up to 16) and its size a multiple of it.
fn struct_layout(
    name: &str,
    members: &[GlslMember],
    rule: Rule,
    structs: &HashMap<String, Vec<GlslMember>>,
) -> Result<StructLayout, String> {
    let mut offset = 0;
    let mut struct_align = 1;
    let mut placed = Vec::new();
    for m in members {
        let (elem_align, elem_size) =
            type_layout(&m.ty, rule, structs).map_err(|e| format!("{name}.{}: {e}", m.name))?;
        let (align, size, ty) = match m.array {
            None => (elem_align, elem_size, m.ty.clone()),
            Some(count) => {
                let mut stride = round_up(elem_size, elem_align);
                let mut align = elem_align;
                if rule == Rule::Std140 {
                    stride = round_up(stride, 16);
                    align = round_up(align, 16);
                }
                (align, stride * count, format!("{}[{count}]", m.ty))
            }
        };
        offset = round_up(offset, align);
        placed.push(Placed {
            name: m.name.clone(),
            ty,
            offset,
            size,
        });
        offset += size;
        struct_align = struct_align.max(align);
    }
    if rule == Rule::Std140 {
        struct_align = round_up(struct_align, 16);
    }
    if placed.is_empty() {
        return Err(format!("struct {name} has no members"));
    }
    Ok(StructLayout {
        align: struct_align,
        size: round_up(offset, struct_align),
        members: placed,
    })
}

// ---------------------------------------------------------------------------------------
// The Rust side: offset_of! by member name.

/// A field of a `#[repr(C)]` mirror.
#[derive(Debug)]
struct RustField {
    name: &'static str,
    offset: usize,
    size: usize,
    type_name: &'static str,
}

fn field_info<T, F>(_: fn(&T) -> &F) -> (usize, &'static str) {
    (size_of::<F>(), std::any::type_name::<F>())
}

/// The fields of a mirror, listed by name (`r#type` stands for `type`).
macro_rules! rust_fields {
    ($t:ty { $($f:ident),* $(,)? }) => {
        vec![$({
            let (size, type_name) = field_info::<$t, _>(|r| &r.$f);
            RustField {
                name: stringify!($f).trim_start_matches("r#"),
                offset: std::mem::offset_of!($t, $f),
                size,
                type_name,
            }
        }),*]
    };
}

/// The GLSL type a Rust field type mirrors: `f32` float, `[f32; 3]` vec3, `[u32; 2]`
/// uvec2, `[[f32; 4]; 5]` vec4[5], a mirror struct by its GLSL name (`rust_to_glsl`).
fn glsl_type_of(rust: &str, rust_to_glsl: &HashMap<&str, &str>) -> String {
    if let Some(inner) = rust.strip_prefix('[').and_then(|r| r.strip_suffix(']')) {
        let (elem, count) = inner
            .rsplit_once("; ")
            .unwrap_or_else(|| panic!("Rust array type {rust:?}"));
        let vector = match (elem, count) {
            (_, "2" | "3" | "4") => match elem {
                "f32" => Some("vec"),
                "u32" => Some("uvec"),
                "i32" => Some("ivec"),
                _ => None,
            },
            _ => None,
        };
        return match vector {
            Some(prefix) => format!("{prefix}{count}"),
            None => format!("{}[{count}]", glsl_type_of(elem, rust_to_glsl)),
        };
    }
    match rust {
        "f32" => "float".to_owned(),
        "u32" => "uint".to_owned(),
        "i32" => "int".to_owned(),
        path => {
            let name = path.rsplit("::").next().unwrap_or(path);
            match rust_to_glsl.get(name) {
                Some(glsl) => (*glsl).to_owned(),
                None => panic!("Rust field type {path:?} has no GLSL counterpart"),
            }
        }
    }
}

/// One mirror to check: the GLSL struct, the rules it is used under (std140 in uniform
/// blocks, std430 in storage buffers and push constants), the Rust type's size and
/// fields.
struct Mirror {
    glsl: &'static str,
    rust: &'static str,
    rules: &'static [Rule],
    size: usize,
    fields: Vec<RustField>,
}

/// Every GPU record, uniform and push-constant struct with its Rust mirror.
fn mirrors() -> Vec<Mirror> {
    use Rule::*;
    vec![
        Mirror {
            glsl: "BoxMedium",
            rust: "BoxMediumGpu",
            rules: &[Std430],
            size: size_of::<BoxMediumGpu>(),
            fields: rust_fields!(BoxMediumGpu {
                world_to_local,
                center,
                sigma_t,
                half_size,
                g,
                sigma_s,
                plane_count,
                plane_first,
                _pad0,
                _pad1,
                _pad2,
            }),
        },
        Mirror {
            glsl: "Shape",
            rust: "ShapeGpu",
            rules: &[Std430],
            size: size_of::<ShapeGpu>(),
            fields: rust_fields!(ShapeGpu {
                p,
                albedo,
                r#type,
                emission,
                emitter_first,
            }),
        },
        Mirror {
            glsl: "Emitter",
            rust: "EmitterGpu",
            rules: &[Std430],
            size: size_of::<EmitterGpu>(),
            fields: rust_fields!(EmitterGpu {
                p0,
                r#type,
                p1,
                shape,
                p2,
                area,
                radiance,
                cdf,
            }),
        },
        Mirror {
            glsl: "BvhNode",
            rust: "BvhNode",
            rules: &[Std430],
            size: size_of::<BvhNode>(),
            fields: rust_fields!(BvhNode {
                min,
                left_or_first,
                max,
                count,
            }),
        },
        Mirror {
            glsl: "MeshTriangle",
            rust: "MeshTriangleGpu",
            rules: &[Std430],
            size: size_of::<MeshTriangleGpu>(),
            fields: rust_fields!(MeshTriangleGpu {
                p0,
                triangle,
                p1,
                _pad0,
                p2,
                _pad1,
            }),
        },
        Mirror {
            glsl: "Light",
            rust: "LightGpu",
            rules: &[Std430],
            size: size_of::<LightGpu>(),
            fields: rust_fields!(LightGpu {
                direction_or_position,
                r#type,
                irradiance,
                radius,
                gobo_origin,
                gobo_plane_count,
                gobo_u,
                gobo_first_plane,
                gobo_v,
                select_cdf,
            }),
        },
        Mirror {
            glsl: "FrameUniforms",
            rust: "FrameUniforms",
            rules: &[Std430],
            size: size_of::<FrameUniforms>(),
            fields: rust_fields!(FrameUniforms {
                cam_position,
                tan_half_fov_x,
                cam_forward,
                tan_half_fov_y,
                cam_right,
                _pad0,
                cam_up,
                _pad1,
                env_radiance,
                background,
                width,
                height,
                spp,
                seed,
                box_media_count,
                shape_count,
                light_count,
                ray_samples,
                env_size,
                env_rotation,
            }),
        },
        Mirror {
            glsl: "MomentFrame",
            rust: "MomentFrameGpu",
            rules: &[Std430],
            size: size_of::<MomentFrameGpu>(),
            fields: rust_fields!(MomentFrameGpu {
                u_axis,
                u_min,
                v_axis,
                v_min,
                omega,
                trace_start,
                texels_u,
                texels_v,
                depth_near,
                depth_far,
                size,
                levels,
                first,
                _pad0,
            }),
        },
        Mirror {
            glsl: "MomentPush",
            rust: "MomentPush",
            rules: &[Std430],
            size: size_of::<MomentPush>(),
            fields: rust_fields!(MomentPush {
                light,
                level,
                size,
                dst,
                src,
                _pad0,
                _pad1,
                _pad2,
            }),
        },
        Mirror {
            glsl: "PassPush",
            rust: "PassPush",
            rules: &[Std430],
            size: size_of::<PassPush>(),
            fields: rust_fields!(PassPush {
                frame,
                sample_base,
                sample_count,
                _pad1,
            }),
        },
        // A member of GridParams and BaselineUniforms (std140 and std430).
        Mirror {
            glsl: "GridSpace",
            rust: "GridSpaceGpu",
            rules: &[Std140, Std430],
            size: size_of::<GridSpaceGpu>(),
            fields: rust_fields!(GridSpaceGpu {
                world_to_index_x,
                world_to_index_y,
                world_to_index_z,
                box_min,
                axis_aligned,
                box_max,
                bricks_offset,
                index_min,
                slots_x,
                index_max,
                slots_y,
                lattice_min,
                channels,
                lattice_max,
                _pad0,
                brick_dims,
                _pad1,
            }),
        },
        // A member of BaselineUniforms, and the storage buffer of the
        // grid_volume test shader.
        Mirror {
            glsl: "GridParams",
            rust: "GridParamsGpu",
            rules: &[Std140, Std430],
            size: size_of::<GridParamsGpu>(),
            fields: rust_fields!(GridParamsGpu {
                bounds_min,
                density_scale,
                bounds_max,
                sigma_t_max,
                space,
            }),
        },
        Mirror {
            glsl: "BaselineUniforms",
            rust: "BaselineUniformsGpu",
            rules: &[Std430],
            size: size_of::<BaselineUniformsGpu>(),
            fields: rust_fields!(BaselineUniformsGpu {
                grid,
                albedo,
                g,
                env_select,
                emitter_count,
                temperature_offset,
                temperature_scale,
                emission_scale,
                blackbody_scale,
                emission,
                temperature,
                albedo_grid,
                env_size,
                _pad5,
            }),
        },
        Mirror {
            glsl: "GridLevel",
            rust: "GridLevelGpu",
            rules: &[Std430],
            size: size_of::<GridLevelGpu>(),
            fields: rust_fields!(GridLevelGpu {
                lattice_min,
                bricks_offset,
                lattice_max,
                factor,
                brick_dims,
                slots_x,
                slots_y,
                _pad0,
                _pad1,
                _pad2,
            }),
        },
        Mirror {
            glsl: "RestirUniforms",
            rust: "RestirUniformsGpu",
            rules: &[Std430],
            size: size_of::<RestirUniformsGpu>(),
            fields: rust_fields!(RestirUniformsGpu {
                pc_primary,
                pc_indirect,
                march_reuse,
                march_nee,
                march_reuse_prev_offset,
                density_prev_offset,
                candidates_per_dispatch,
                history_static,
                candidates,
                temporal_limit,
                spatial_neighbors,
                reservoir_stride,
                spatial_radius,
                march_reuse_step,
                march_nee_step,
                history_confidence,
                velocity_dims,
                spatial_max_m,
                velocity_uvw_x,
                velocity_uvw_y,
                velocity_uvw_z,
            }),
        },
        Mirror {
            glsl: "RestirPush",
            rust: "RestirPush",
            rules: &[Std430],
            size: size_of::<RestirPush>(),
            fields: rust_fields!(RestirPush {
                frame,
                src,
                dst,
                aux,
            }),
        },
    ]
}

/// Every struct of the record files, by name, in declaration order.
fn record_structs() -> Vec<(String, Vec<GlslMember>)> {
    let mut structs = Vec::new();
    for file in RECORD_FILES {
        structs.extend(glsl_structs(file, &read(file)).unwrap_or_else(|e| panic!("{e}")));
    }
    structs
}

/// The differences between a GLSL struct laid out by `rule` and its Rust mirror. Only
/// the structs declared before it (in `parsed`) may be its members' types.
fn mirror_errors(
    mirror: &Mirror,
    rule: Rule,
    parsed: &[(String, Vec<GlslMember>)],
    rust_to_glsl: &HashMap<&str, &str>,
) -> Vec<String> {
    let Some(index) = parsed.iter().position(|(name, _)| name == mirror.glsl) else {
        return vec![format!(
            "struct {} is not declared in {RECORD_FILES:?}",
            mirror.glsl
        )];
    };
    let structs: HashMap<String, Vec<GlslMember>> = parsed[..index].iter().cloned().collect();
    let members = &parsed[index].1;
    let what = format!("{} ({rule:?}) / {}", mirror.glsl, mirror.rust);
    let layout = match struct_layout(mirror.glsl, members, rule, &structs) {
        Ok(layout) => layout,
        Err(e) => return vec![format!("{what}: {e}")],
    };
    let mut errors = Vec::new();
    let rust_fields: HashMap<&str, &RustField> =
        mirror.fields.iter().map(|f| (f.name, f)).collect();
    for r in &mirror.fields {
        if !layout.members.iter().any(|g| g.name == r.name) {
            errors.push(format!(
                "{what}: Rust field `{}` is not a GLSL member",
                r.name
            ));
        }
    }
    let mut end = 0;
    for g in &layout.members {
        let member = format!("{what}: `{}`", g.name);
        // Padding is a named member on both sides, never implicit.
        if g.offset != end {
            errors.push(format!(
                "{member}: {} bytes of implicit padding before it; name them (_padN)",
                g.offset - end
            ));
        }
        end = g.offset + g.size;
        let Some(r) = rust_fields.get(g.name.as_str()) else {
            errors.push(format!("{member}: no Rust field of that name"));
            continue;
        };
        let rust_ty = glsl_type_of(r.type_name, rust_to_glsl);
        if g.ty != rust_ty {
            errors.push(format!(
                "{member}: GLSL {} but Rust {} (= {rust_ty})",
                g.ty, r.type_name
            ));
        }
        if g.offset != r.offset {
            errors.push(format!(
                "{member}: GLSL offset {} but Rust offset {}",
                g.offset, r.offset
            ));
        }
        if g.size != r.size {
            errors.push(format!(
                "{member}: GLSL size {} but Rust size {}",
                g.size, r.size
            ));
        }
    }
    if end != layout.size {
        errors.push(format!(
            "{what}: {} bytes of implicit padding at the end; name them (_padN)",
            layout.size - end
        ));
    }
    if layout.size != mirror.size {
        errors.push(format!(
            "{what}: GLSL size {} but Rust size {}",
            layout.size, mirror.size
        ));
    }
    errors
}

#[test]
fn records_match_the_glsl_structs_member_by_member() {
    let parsed = record_structs();
    let mirrors = mirrors();
    let rust_to_glsl: HashMap<&str, &str> = mirrors.iter().map(|m| (m.rust, m.glsl)).collect();

    let declared: Vec<&str> = parsed.iter().map(|(name, _)| name.as_str()).collect();
    let checked: Vec<&str> = mirrors.iter().map(|m| m.glsl).collect();
    assert_eq!(
        declared, checked,
        "every struct of {RECORD_FILES:?} has a Rust mirror checked here, in order"
    );

    let errors: Vec<String> = mirrors
        .iter()
        .flat_map(|m| m.rules.iter().map(move |&rule| (m, rule)))
        .flat_map(|(m, rule)| mirror_errors(m, rule, &parsed, &rust_to_glsl))
        .collect();
    assert!(errors.is_empty(), "\n{}", errors.join("\n"));

    // Lavapipe (and the Vulkan minimum) allow 128 bytes of push constants.
    assert!(size_of::<PassPush>() <= 128);
    assert!(size_of::<RestirPush>() <= 128);
}

/// The layout rules themselves, on declarations whose offsets follow from the GLSL
/// specification, and unknown types or malformed declarations failing instead of being
/// skipped.
#[test]
fn std140_and_std430_offsets_follow_the_glsl_rules() {
    let text = "struct Inner {\n    vec3 a;\n};\n\
                struct S {\n    float f;\n    vec3 v;\n    float after_vec3;\n    vec2 v2;\n    \
                float arr[3];\n    Inner inner;\n    uint last;\n};\n";
    let structs: HashMap<String, Vec<GlslMember>> =
        glsl_structs("inline", text).unwrap().into_iter().collect();
    let offsets = |rule| {
        let layout = struct_layout("S", &structs["S"], rule, &structs).unwrap();
        let offsets: Vec<usize> = layout.members.iter().map(|m| m.offset).collect();
        (offsets, layout.size)
    };
    // std140: vec3 aligned to 16 with the float after it in its last 4 bytes, vec2 at 8,
    // float[3] with a 16-byte stride, the struct aligned and sized to 16, the whole
    // struct rounded up to 16.
    assert_eq!(
        offsets(Rule::Std140),
        (vec![0, 16, 28, 32, 48, 96, 112], 128)
    );
    // std430: float[3] with a 4-byte stride; Inner is still aligned to 16 (its vec3).
    assert_eq!(offsets(Rule::Std430), (vec![0, 16, 28, 32, 40, 64, 80], 96));

    for bad in [
        "struct T {\n    mat3 m;\n};\n",
        "struct T {\n    dvec3 d;\n};\n",
        "struct T {\n    bool b;\n};\n",
        "struct T {\n    Later l;\n};\nstruct Later {\n    float x;\n};\n",
    ] {
        let parsed = glsl_structs("inline", bad).unwrap();
        // Only what is declared before T is known when T is laid out.
        let known: HashMap<String, Vec<GlslMember>> = parsed[..1].iter().cloned().collect();
        for rule in [Rule::Std140, Rule::Std430] {
            let result = struct_layout("T", &known["T"], rule, &known);
            assert!(result.is_err(), "unknown type accepted: {bad:?}");
        }
    }
    for bad in [
        "struct T {\n    float a, b;\n};\n",
        "struct T {\n#ifdef X\n    float a;\n#endif\n};\n",
        "struct T {\n    float a[N];\n};\n",
        "struct T {\n    float a;\n",
        "struct T\n{\n    float a;\n};\n",
    ] {
        assert!(
            glsl_structs("inline", bad).is_err(),
            "malformed struct accepted: {bad:?}"
        );
    }
}
