//! What a compute shader's SPIR-V asks of its pipeline, read from the module itself: the
//! specialization constants it declares (`SpecId`), the descriptors of set 0 it uses
//! (`Binding`, with the kind of resource) and the size of its push-constant block. The
//! pipeline checks them against its description ([`check`]): a specialization constant
//! a pass forgets to set would silently take the shader's default, the way kajiya
//! reflects its layouts instead of trusting hand-kept lists.
//!
//! Only what GLSL compute shaders compiled by shaderc contain is understood; anything
//! else is ignored (a module this reader does not follow is checked less, never refused).

use std::collections::{BTreeMap, BTreeSet, HashMap};

use anyhow::{bail, Result};
use ash::vk;

const OP_TYPE_INT: u32 = 21;
const OP_TYPE_FLOAT: u32 = 22;
const OP_TYPE_VECTOR: u32 = 23;
const OP_TYPE_MATRIX: u32 = 24;
const OP_TYPE_IMAGE: u32 = 25;
const OP_TYPE_SAMPLED_IMAGE: u32 = 27;
const OP_TYPE_ARRAY: u32 = 28;
const OP_TYPE_RUNTIME_ARRAY: u32 = 29;
const OP_TYPE_STRUCT: u32 = 30;
const OP_TYPE_POINTER: u32 = 32;
const OP_CONSTANT: u32 = 43;
const OP_SPEC_CONSTANT_TRUE: u32 = 48;
const OP_SPEC_CONSTANT_FALSE: u32 = 49;
const OP_SPEC_CONSTANT: u32 = 50;
const OP_VARIABLE: u32 = 59;
const OP_DECORATE: u32 = 71;
const OP_MEMBER_DECORATE: u32 = 72;

const DECORATION_SPEC_ID: u32 = 1;
const DECORATION_ARRAY_STRIDE: u32 = 6;
const DECORATION_BINDING: u32 = 33;
const DECORATION_DESCRIPTOR_SET: u32 = 34;
const DECORATION_OFFSET: u32 = 35;

const STORAGE_UNIFORM_CONSTANT: u32 = 0;
const STORAGE_UNIFORM: u32 = 2;
const STORAGE_PUSH_CONSTANT: u32 = 9;
const STORAGE_STORAGE_BUFFER: u32 = 12;

/// The kind of resource a descriptor binding holds, as the shader declares it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResourceKind {
    /// A buffer block (`buffer` or `uniform`).
    Buffer,
    /// A `sampler2D` / `sampler3D` (combined image sampler).
    SampledImage,
    /// An `image2D` / `image3D` (storage image).
    StorageImage,
    /// Anything else.
    Other,
}

impl ResourceKind {
    /// Whether a layout binding of descriptor type `ty` can back it.
    fn accepts(self, ty: vk::DescriptorType) -> bool {
        match self {
            ResourceKind::Buffer => {
                ty == vk::DescriptorType::STORAGE_BUFFER || ty == vk::DescriptorType::UNIFORM_BUFFER
            }
            ResourceKind::SampledImage => ty == vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
            ResourceKind::StorageImage => ty == vk::DescriptorType::STORAGE_IMAGE,
            ResourceKind::Other => true,
        }
    }
}

/// What a module declares (see the module docs).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Reflection {
    /// `SpecId` of every specialization constant.
    pub spec_ids: BTreeSet<u32>,
    /// Binding → kind of every descriptor variable of set 0.
    pub bindings: BTreeMap<u32, ResourceKind>,
    /// Bytes of the push-constant block (its last member's offset plus size), if any.
    pub push_constant_size: Option<u32>,
}

/// One instruction: opcode and operands.
fn instructions(words: &[u32]) -> impl Iterator<Item = (u32, &[u32])> {
    let mut at = 5.min(words.len());
    std::iter::from_fn(move || {
        let head = *words.get(at)?;
        let count = (head >> 16) as usize;
        if count == 0 || at + count > words.len() {
            return None;
        }
        let operands = &words[at + 1..at + count];
        at += count;
        Some((head & 0xffff, operands))
    })
}

/// Reads `words` (a SPIR-V module).
pub fn reflect(words: &[u32]) -> Reflection {
    let mut spec_ids = BTreeSet::new();
    let mut binding_of: HashMap<u32, u32> = HashMap::new();
    let mut set_of: HashMap<u32, u32> = HashMap::new();
    let mut stride_of: HashMap<u32, u32> = HashMap::new();
    let mut member_offsets: HashMap<u32, Vec<(u32, u32)>> = HashMap::new();
    // Types: id → the instruction that declares it.
    let mut types: HashMap<u32, (u32, Vec<u32>)> = HashMap::new();
    let mut constants: HashMap<u32, u32> = HashMap::new();
    let mut variables: Vec<(u32, u32, u32)> = Vec::new(); // (id, pointer type, storage)
    for (op, o) in instructions(words) {
        match op {
            OP_DECORATE if o.len() >= 3 => match o[1] {
                DECORATION_SPEC_ID => {
                    spec_ids.insert(o[2]);
                }
                DECORATION_BINDING => {
                    binding_of.insert(o[0], o[2]);
                }
                DECORATION_DESCRIPTOR_SET => {
                    set_of.insert(o[0], o[2]);
                }
                DECORATION_ARRAY_STRIDE => {
                    stride_of.insert(o[0], o[2]);
                }
                _ => {}
            },
            OP_MEMBER_DECORATE if o.len() >= 4 && o[2] == DECORATION_OFFSET => {
                member_offsets.entry(o[0]).or_default().push((o[1], o[3]));
            }
            OP_TYPE_INT
            | OP_TYPE_FLOAT
            | OP_TYPE_VECTOR
            | OP_TYPE_MATRIX
            | OP_TYPE_IMAGE
            | OP_TYPE_SAMPLED_IMAGE
            | OP_TYPE_ARRAY
            | OP_TYPE_RUNTIME_ARRAY
            | OP_TYPE_STRUCT
            | OP_TYPE_POINTER
                if !o.is_empty() =>
            {
                types.insert(o[0], (op, o[1..].to_vec()));
            }
            OP_CONSTANT if o.len() >= 3 => {
                constants.insert(o[1], o[2]);
            }
            OP_VARIABLE if o.len() >= 3 => variables.push((o[1], o[0], o[2])),
            _ => {}
        }
    }
    let pointee = |pointer: u32| match types.get(&pointer) {
        Some((OP_TYPE_POINTER, args)) if args.len() >= 2 => Some(args[1]),
        _ => None,
    };
    // Bytes of a type as a block member (scalars, vectors, matrices, arrays, structs).
    fn size_of(
        id: u32,
        types: &HashMap<u32, (u32, Vec<u32>)>,
        constants: &HashMap<u32, u32>,
        stride_of: &HashMap<u32, u32>,
        member_offsets: &HashMap<u32, Vec<(u32, u32)>>,
        depth: u32,
    ) -> Option<u32> {
        if depth > 16 {
            return None;
        }
        let (op, args) = types.get(&id)?;
        let size = |t| size_of(t, types, constants, stride_of, member_offsets, depth + 1);
        match *op {
            OP_TYPE_INT | OP_TYPE_FLOAT => Some(args.first()? / 8),
            OP_TYPE_VECTOR | OP_TYPE_MATRIX => Some(size(*args.first()?)? * args.get(1)?),
            OP_TYPE_ARRAY => {
                let length = constants.get(args.get(1)?)?;
                let stride = match stride_of.get(&id) {
                    Some(s) => *s,
                    None => size(*args.first()?)?,
                };
                Some(stride * length)
            }
            OP_TYPE_STRUCT => {
                let offsets = member_offsets.get(&id)?;
                offsets
                    .iter()
                    .map(|(member, offset)| Some(offset + size(*args.get(*member as usize)?)?))
                    .try_fold(0u32, |end, m| Some(end.max(m?)))
            }
            _ => None,
        }
    }
    let mut bindings = BTreeMap::new();
    let mut push_constant_size = None;
    for (id, pointer, storage) in variables {
        let Some(mut ty) = pointee(pointer) else {
            continue;
        };
        if storage == STORAGE_PUSH_CONSTANT {
            push_constant_size = size_of(ty, &types, &constants, &stride_of, &member_offsets, 0);
            continue;
        }
        let Some(&binding) = binding_of.get(&id) else {
            continue;
        };
        if set_of.get(&id).copied().unwrap_or(0) != 0 {
            continue;
        }
        // An array of descriptors: its element decides.
        while let Some((OP_TYPE_ARRAY | OP_TYPE_RUNTIME_ARRAY, args)) = types.get(&ty) {
            match args.first() {
                Some(element) => ty = *element,
                None => break,
            }
        }
        let kind = match (storage, types.get(&ty)) {
            (STORAGE_STORAGE_BUFFER | STORAGE_UNIFORM, _) => ResourceKind::Buffer,
            (STORAGE_UNIFORM_CONSTANT, Some((OP_TYPE_SAMPLED_IMAGE, _))) => {
                ResourceKind::SampledImage
            }
            // OpTypeImage: Sampled (operand 6 after the result id) is 2 for storage images.
            (STORAGE_UNIFORM_CONSTANT, Some((OP_TYPE_IMAGE, args))) if args.get(5) == Some(&2) => {
                ResourceKind::StorageImage
            }
            _ => ResourceKind::Other,
        };
        bindings.insert(binding, kind);
    }
    Reflection {
        spec_ids,
        bindings,
        push_constant_size,
    }
}

/// `words` with its specialization constants' defaults replaced by `values` (`(SpecId,
/// the 4 bytes the driver would read from VkSpecializationInfo)`): `OpSpecConstant`'s
/// literal becomes the value, and a boolean's `OpSpecConstantTrue` / `False` follows
/// whether the value is nonzero (a `VkBool32`). Specialization constants not named in
/// `values` keep their defaults, and a value naming no constant is ignored, as
/// `VkSpecializationInfo` does.
///
/// A pipeline made from the result with no specialization info is the pipeline the
/// original module and `values` specify: drivers apply specialization by these same
/// defaults (Mesa's `spirv_to_nir` reads a constant's literal unless a specialization
/// entry replaces it). Nimbus does this so that [`crate::spirv_strip`] can then remove
/// the code the values switch off before the driver sees the module.
///
/// Refuses (naming `name`) a constant of more than 32 bits that `values` sets, and a
/// module whose instruction stream ends early.
pub fn specialize(name: &str, words: &[u32], values: &[(u32, u32)]) -> Result<Vec<u32>> {
    let value_of: HashMap<u32, u32> = values.iter().copied().collect();
    // Result id -> the value its SpecId asks for.
    let mut wanted: HashMap<u32, u32> = HashMap::new();
    let mut walked = 5.min(words.len());
    for (op, o) in instructions(words) {
        walked += o.len() + 1;
        if op == OP_DECORATE && o.len() >= 3 && o[1] == DECORATION_SPEC_ID {
            if let Some(v) = value_of.get(&o[2]) {
                wanted.insert(o[0], *v);
            }
        }
    }
    if walked != words.len() {
        bail!(
            "pipeline '{name}': the shader's instruction stream ends at word {walked} of {} \
             (a truncated or malformed module)",
            words.len()
        );
    }
    let mut out = words.to_vec();
    let mut at = 5.min(out.len());
    while at < out.len() {
        let head = out[at];
        let count = (head >> 16) as usize;
        let op = head & 0xffff;
        // Operands: result type, result id, then the literal.
        let result = out.get(at + 2).copied();
        match (op, result.and_then(|id| wanted.get(&id))) {
            (OP_SPEC_CONSTANT_TRUE | OP_SPEC_CONSTANT_FALSE, Some(v)) => {
                let op = if *v != 0 {
                    OP_SPEC_CONSTANT_TRUE
                } else {
                    OP_SPEC_CONSTANT_FALSE
                };
                out[at] = (head & 0xffff_0000) | op;
            }
            (OP_SPEC_CONSTANT, Some(v)) => {
                if count != 4 {
                    bail!(
                        "pipeline '{name}': specialization constant %{} is {} bits wide; \
                         only 32-bit constants can be set",
                        result.unwrap_or(0),
                        32 * (count.saturating_sub(3))
                    );
                }
                out[at + 3] = *v;
            }
            _ => {}
        }
        at += count;
    }
    Ok(out)
}

/// Checks a pipeline description against its module: every specialization constant the
/// module declares is set, every descriptor of set 0 it uses is in the layout with a
/// type that can back it, and its push-constant block fits the range. Errors name the
/// pipeline and what is out of step.
pub fn check(
    name: &str,
    words: &[u32],
    bindings: &[(u32, vk::DescriptorType)],
    specialization: &[u32],
    push_constant_size: u32,
) -> Result<()> {
    let r = reflect(words);
    let given: BTreeSet<u32> = specialization.iter().copied().collect();
    let unset: Vec<u32> = r.spec_ids.difference(&given).copied().collect();
    if !unset.is_empty() {
        bail!(
            "pipeline '{name}': the shader declares specialization constant(s) {unset:?} that \
             the pass does not set: they would silently take the shader's defaults"
        );
    }
    let layout: HashMap<u32, vk::DescriptorType> = bindings.iter().copied().collect();
    for (binding, kind) in &r.bindings {
        match layout.get(binding) {
            None => bail!(
                "pipeline '{name}': the shader uses binding {binding} ({kind:?}), which the \
                 pass's layout does not declare"
            ),
            Some(ty) if !kind.accepts(*ty) => bail!(
                "pipeline '{name}': the shader's binding {binding} is a {kind:?}, the layout \
                 declares it {ty:?}"
            ),
            Some(_) => {}
        }
    }
    if let Some(size) = r.push_constant_size {
        if size > push_constant_size {
            bail!(
                "pipeline '{name}': the shader's push constants take {size} bytes, the \
                 pipeline's range {push_constant_size}"
            );
        }
    }
    Ok(())
}
