//! The records the passes share with their shaders are declared once
//! (`src/shader_data/contract/records.rs`); `build.rs` writes their GLSL structs and the std430
//! layout it gives them ([`RECORD_LAYOUTS`]), which the crate asserts against its
//! `#[repr(C)]` structs at compile time. This test closes the loop with the compiler:
//! every struct of every compiled module (`nimbus::shaders::ALL`) that is a record has,
//! in the SPIR-V itself, the member names and offsets of that layout (and a buffer of
//! them its size as array stride), and every record is found in some module.

use std::collections::{BTreeSet, HashMap};

use nimbus::shader_data::contract::{RecordLayout, RECORD_LAYOUTS};

const OP_NAME: u32 = 5;
const OP_MEMBER_NAME: u32 = 6;
const OP_TYPE_ARRAY: u32 = 28;
const OP_TYPE_RUNTIME_ARRAY: u32 = 29;
const OP_TYPE_STRUCT: u32 = 30;
const OP_DECORATE: u32 = 71;
const OP_MEMBER_DECORATE: u32 = 72;
const DECORATION_ARRAY_STRIDE: u32 = 6;
const DECORATION_OFFSET: u32 = 35;

/// A struct type of a module with explicit layout: its name, members by index (name,
/// offset) and the strides of the arrays of it.
#[derive(Debug, Default)]
struct SpirvStruct {
    name: String,
    members: Vec<(String, Option<u32>)>,
    strides: BTreeSet<u32>,
}

/// A literal string operand (UTF-8, nul-terminated, packed little-endian).
fn string(words: &[u32]) -> String {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    String::from_utf8_lossy(&bytes[..end]).into_owned()
}

/// The struct types of a module (debug names included: build.rs compiles with them).
fn spirv_structs(bytes: &[u8]) -> Vec<SpirvStruct> {
    let words: Vec<u32> = bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    assert_eq!(words.first(), Some(&0x0723_0203), "not SPIR-V");
    let mut names: HashMap<u32, String> = HashMap::new();
    let mut member_names: HashMap<(u32, u32), String> = HashMap::new();
    let mut offsets: HashMap<(u32, u32), u32> = HashMap::new();
    let mut strides: HashMap<u32, u32> = HashMap::new();
    let mut structs: Vec<(u32, usize)> = Vec::new();
    let mut arrays: Vec<(u32, u32)> = Vec::new(); // (array type, element type)
    let mut at = 5;
    while at < words.len() {
        let (count, op) = ((words[at] >> 16) as usize, words[at] & 0xffff);
        assert!(count > 0 && at + count <= words.len(), "truncated SPIR-V");
        let o = &words[at + 1..at + count];
        match op {
            OP_NAME => {
                names.insert(o[0], string(&o[1..]));
            }
            OP_MEMBER_NAME => {
                member_names.insert((o[0], o[1]), string(&o[2..]));
            }
            OP_MEMBER_DECORATE if o[2] == DECORATION_OFFSET => {
                offsets.insert((o[0], o[1]), o[3]);
            }
            OP_DECORATE if o[1] == DECORATION_ARRAY_STRIDE => {
                strides.insert(o[0], o[2]);
            }
            OP_TYPE_STRUCT => structs.push((o[0], o.len() - 1)),
            OP_TYPE_ARRAY | OP_TYPE_RUNTIME_ARRAY => arrays.push((o[0], o[1])),
            _ => {}
        }
        at += count;
    }
    structs
        .into_iter()
        .map(|(id, count)| SpirvStruct {
            name: names.get(&id).cloned().unwrap_or_default(),
            members: (0..count as u32)
                .map(|m| {
                    let name = member_names.get(&(id, m)).cloned().unwrap_or_default();
                    (name, offsets.get(&(id, m)).copied())
                })
                .collect(),
            strides: arrays
                .iter()
                .filter(|&&(_, element)| element == id)
                .filter_map(|(array, _)| strides.get(array).copied())
                .collect(),
        })
        .collect()
}

/// The differences between the records' layouts and the module `module`'s structs of the
/// same names (those with explicit offsets: a private copy has none), one line each; and
/// the names of the records found.
fn check_module(
    module: &str,
    structs: &[SpirvStruct],
    layouts: &[RecordLayout],
) -> (Vec<String>, BTreeSet<&'static str>) {
    let mut errors = Vec::new();
    let mut found = BTreeSet::new();
    for s in structs {
        let Some(layout) = layouts.iter().find(|l| l.glsl == s.name) else {
            continue;
        };
        if s.members.iter().any(|(_, offset)| offset.is_none()) {
            continue;
        }
        found.insert(layout.glsl);
        let at = format!("{module}: {}", layout.glsl);
        let spirv: Vec<(&str, u32)> = s
            .members
            .iter()
            .map(|(name, offset)| (name.as_str(), offset.unwrap_or_default()))
            .collect();
        let rust: Vec<(&str, u32)> = layout.members.iter().map(|&(n, o, _)| (n, o)).collect();
        if spirv.len() != rust.len() {
            errors.push(format!(
                "{at}: {} members in the SPIR-V, {} in the contract",
                spirv.len(),
                rust.len()
            ));
        }
        for (i, (s, r)) in spirv.iter().zip(&rust).enumerate() {
            if s != r {
                errors.push(format!(
                    "{at}: member {i} is `{}` at {} in the SPIR-V, `{}` at {} in the contract",
                    s.0, s.1, r.0, r.1
                ));
            }
        }
        for stride in &s.strides {
            if *stride != layout.size {
                errors.push(format!(
                    "{at}: arrays of it have stride {stride} in the SPIR-V, the contract's \
                     size is {}",
                    layout.size
                ));
            }
        }
    }
    (errors, found)
}

/// Every module against `layouts`: the errors, and the records no module declares.
fn check_all(layouts: &[RecordLayout]) -> (Vec<String>, Vec<&'static str>) {
    let mut errors = Vec::new();
    let mut found = BTreeSet::new();
    for (module, bytes) in nimbus::shaders::ALL {
        let (e, f) = check_module(module, &spirv_structs(bytes), layouts);
        errors.extend(e);
        found.extend(f);
    }
    let missing = layouts
        .iter()
        .map(|l| l.glsl)
        .filter(|name| !found.contains(name))
        .collect();
    (errors, missing)
}

#[test]
fn every_record_in_the_spirv_has_the_contracts_layout() {
    assert!(nimbus::shaders::ALL.len() >= 12, "modules missing");
    let (errors, missing) = check_all(RECORD_LAYOUTS);
    assert!(errors.is_empty(), "\n{}", errors.join("\n"));
    assert!(
        missing.is_empty(),
        "no compiled shader uses these records, so nothing checks them: {missing:?}"
    );
    // Lavapipe (and the Vulkan minimum) allow 128 bytes of push constants.
    for push in ["PassPush", "RestirPush", "MomentPush"] {
        let layout = RECORD_LAYOUTS.iter().find(|l| l.glsl == push).unwrap();
        assert!(layout.size <= 128, "{push}: {} bytes", layout.size);
    }
}

/// A member of a [`RecordLayout`]: name, offset, size.
type Member = (&'static str, u32, u32);

/// The check fails when the contract and the compiled shaders differ: a record whose
/// expected layout is changed on purpose (a member moved, one renamed, one dropped, the
/// size changed) is reported, exactly.
#[test]
fn a_record_out_of_step_with_the_spirv_is_reported() {
    let mutated = |glsl: &str, edit: &dyn Fn(&mut Vec<Member>, &mut u32)| {
        let mut layouts = RECORD_LAYOUTS.to_vec();
        let layout = layouts.iter_mut().find(|l| l.glsl == glsl).unwrap();
        let mut members = layout.members.to_vec();
        edit(&mut members, &mut layout.size);
        layout.members = Box::leak(members.into_boxed_slice());
        layouts
    };
    let errors_of = |layouts: &[RecordLayout]| {
        let mut errors = check_all(layouts).0;
        // One line per record and mutation: modules repeat it.
        for e in &mut errors {
            *e = e.split_once(": ").unwrap().1.to_owned();
        }
        errors.sort();
        errors.dedup();
        errors
    };

    // Light.radius moved by 4 bytes.
    let layouts = mutated("Light", &|m, _| m[3].1 += 4);
    assert_eq!(
        errors_of(&layouts),
        ["Light: member 3 is `radius` at 28 in the SPIR-V, `radius` at 32 in the contract"]
    );
    // RestirUniforms.history_static under another name.
    let layouts = mutated("RestirUniforms", &|m, _| m[7].0 = "history_stable");
    assert_eq!(
        errors_of(&layouts),
        [
            "RestirUniforms: member 7 is `history_static` at 268 in the SPIR-V, \
             `history_stable` at 268 in the contract"
        ]
    );
    // PassPush without its padding member.
    let layouts = mutated("PassPush", &|m, _| {
        m.pop();
    });
    assert_eq!(
        errors_of(&layouts),
        ["PassPush: 4 members in the SPIR-V, 3 in the contract"]
    );
    // Emitter 16 bytes larger: the emitter table's stride says otherwise.
    let layouts = mutated("Emitter", &|_, size| *size += 16);
    assert_eq!(
        errors_of(&layouts),
        ["Emitter: arrays of it have stride 64 in the SPIR-V, the contract's size is 80"]
    );
}
