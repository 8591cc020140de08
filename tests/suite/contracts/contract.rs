//! Every pipeline a pass creates against its own compiled SPIR-V, without a device (the
//! way kajiya reflects its layouts): the module's `SpecId`s are all set by the pass, its
//! set-0 `Binding`s are all in the pass's layout with a descriptor type that can back
//! them, and its push-constant block is exactly the size of the pass's push record. What
//! the pass sets comes from the same functions it builds the pipeline with
//! (`nimbus::passes::pipeline_contracts`); the module is read by `nimbus_gpu::spirv`,
//! which also checks every pipeline when it is created. The second test breaks each of
//! these on purpose and checks that the check names exactly that mismatch.

use std::collections::BTreeSet;

use nimbus::passes::{pipeline_contracts, spirv_words, PipelineContract};
use nimbus::shader_data::{bindings, features};
use nimbus_gpu::{vk, BindingDesc, SpecValue};

fn asset(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets/scenes")
        .join(name)
}

/// The pipelines of every pass: the crepuscular pass with the ME estimator's moment-map
/// stage, the baseline path tracer and the four ReSTIR stages.
fn all_contracts() -> Vec<PipelineContract> {
    let me = std::fs::read_to_string(asset("me-detached.toml"))
        .unwrap()
        .replace("box_estimator = \"mcwvds\"", "box_estimator = \"me\"");
    let scenes = [
        nimbus_scene::parse_str(&me, &asset("me-detached.toml")).unwrap(),
        nimbus_scene::load(&asset("cloud.toml")).unwrap(),
        nimbus_scene::load(&asset("cloud-restir.toml")).unwrap(),
    ];
    scenes
        .iter()
        .flat_map(|scene| pipeline_contracts(&nimbus::plan::build(scene, None).unwrap()))
        .collect()
}

/// The contract against its module: the first mismatch, or `Ok`.
fn check(c: &PipelineContract) -> Result<(), String> {
    let words = spirv_words(c.spirv).map_err(|e| e.to_string())?;
    let layout: Vec<(u32, vk::DescriptorType)> =
        c.bindings.iter().map(|b| (b.binding, b.ty)).collect();
    let ids: Vec<u32> = c.specialization.iter().map(|(id, _)| *id).collect();
    nimbus_gpu::spirv::check(&c.name, &words, &layout, &ids, c.push_constant_size)
        .map_err(|e| format!("{e:#}"))?;
    // Stricter than the pipeline's own check: the block is exactly the pass's record (a
    // shorter block would mean the two disagree on the record).
    let reflected = nimbus_gpu::spirv::reflect(&words);
    if reflected.push_constant_size != Some(c.push_constant_size) {
        return Err(format!(
            "pipeline '{}': the shader's push constants take {:?} bytes, the pass's record {}",
            c.name, reflected.push_constant_size, c.push_constant_size
        ));
    }
    Ok(())
}

#[test]
fn every_pass_pipeline_matches_its_spirv() {
    let contracts = all_contracts();
    let names: BTreeSet<&str> = contracts.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(
        names,
        BTreeSet::from([
            "baseline path tracer",
            "crepuscular",
            "moment maps",
            "restir initial",
            "restir shade",
            "restir spatial",
            "restir temporal",
            "restir temporal (still)",
        ]),
        "every pass's pipelines are checked"
    );
    let errors: Vec<String> = contracts.iter().filter_map(|c| check(c).err()).collect();
    assert!(errors.is_empty(), "\n{}", errors.join("\n"));
}

/// Each mutation puts one side out of step on purpose; the check reports exactly it.
#[test]
fn a_pass_out_of_step_with_its_spirv_is_reported() {
    let contracts = all_contracts();
    let initial = contracts
        .iter()
        .find(|c| c.name == "restir initial")
        .unwrap();
    let mutated = |edit: &dyn Fn(&mut PipelineContract)| {
        let mut c = PipelineContract {
            name: initial.name.clone(),
            spirv: initial.spirv,
            bindings: initial.bindings.clone(),
            specialization: initial.specialization.clone(),
            push_constant_size: initial.push_constant_size,
        };
        edit(&mut c);
        check(&c).unwrap_err()
    };
    assert_eq!(check(initial), Ok(()));

    // A specialization constant the pass forgets: the shader's default would be used.
    let err = mutated(&|c| {
        c.specialization
            .retain(|(id, _)| *id != features::SC_ID_FOLD_EMISSION)
    });
    assert_eq!(
        err,
        format!(
            "pipeline 'restir initial': the shader declares specialization constant(s) [{}] \
             that the pass does not set: they would silently take the shader's defaults",
            features::SC_ID_FOLD_EMISSION
        )
    );
    // A specialization ID off by one on the pass's side (NEE_SPLIT set as 18).
    let err = mutated(&|c| {
        c.specialization.retain(|(id, _)| {
            *id != features::SC_ID_NEE_SPLIT && *id != features::SC_ID_DIRECT_EACH_WALK
        });
        c.specialization
            .push((features::SC_ID_NEE_SPLIT + 1, SpecValue::Bool(true)));
    });
    assert_eq!(
        err,
        format!(
            "pipeline 'restir initial': the shader declares specialization constant(s) [{}] \
             that the pass does not set: they would silently take the shader's defaults",
            features::SC_ID_NEE_SPLIT
        )
    );
    // A binding missing from the pass's layout.
    let err = mutated(&|c| c.bindings.retain(|b| b.binding != bindings::RESERVOIRS));
    assert_eq!(
        err,
        format!(
            "pipeline 'restir initial': the shader uses binding {} (Buffer), which the \
             pass's layout does not declare",
            bindings::RESERVOIRS
        )
    );
    // A binding of the wrong kind (the density atlas as a buffer).
    let err = mutated(&|c| {
        for b in &mut c.bindings {
            if b.binding == bindings::GRID_DENSITY {
                *b = BindingDesc::storage_buffer(bindings::GRID_DENSITY);
            }
        }
    });
    assert_eq!(
        err,
        format!(
            "pipeline 'restir initial': the shader's binding {} is a SampledImage, the \
             layout declares it STORAGE_BUFFER",
            bindings::GRID_DENSITY
        )
    );
    // A push record of another size, shorter and longer.
    let err = mutated(&|c| c.push_constant_size -= 4);
    assert_eq!(
        err,
        "pipeline 'restir initial': the shader's push constants take 16 bytes, the \
         pipeline's range 12"
    );
    let err = mutated(&|c| c.push_constant_size += 4);
    assert_eq!(
        err,
        "pipeline 'restir initial': the shader's push constants take Some(16) bytes, the \
         pass's record 20"
    );
}

/// Every pass's pipeline, specialized as its pass does for the shipped scenes, strips
/// (`nimbus_gpu::spirv_strip`: a refusal would silently hand the driver the whole module
/// again, docs/performance.md "Pipelines built from the code a scene reaches") to a
/// smaller module with every specialization constant frozen, whose bindings and push
/// constants still fit the pass.
#[test]
fn every_pass_pipeline_strips_to_a_smaller_module_that_still_fits_its_pass() {
    const SPEC_CONSTANT_OPS: std::ops::RangeInclusive<u32> = 48..=52;
    let mut errors = Vec::new();
    for c in all_contracts() {
        let words = spirv_words(c.spirv).unwrap();
        let values: Vec<(u32, u32)> = c
            .specialization
            .iter()
            .map(|(id, v)| (*id, u32::from_ne_bytes(v.to_bytes())))
            .collect();
        let specialized = nimbus_gpu::spirv::specialize(&c.name, &words, &values).unwrap();
        let stripped = match nimbus_gpu::spirv_strip::strip_uncached(&specialized) {
            Ok(s) => s,
            Err(e) => {
                errors.push(format!("{}: SPIRV-Tools refused it: {e}", c.name));
                continue;
            }
        };
        if stripped.len() >= words.len() {
            errors.push(format!(
                "{}: {} words stripped to {}",
                c.name,
                words.len(),
                stripped.len()
            ));
        }
        // Header: magic, then the instruction stream; no specialization constant left.
        let mut at = 5;
        let mut spec_ops = 0;
        while at < stripped.len() {
            let count = (stripped[at] >> 16) as usize;
            assert!(count > 0, "{}: malformed at word {at}", c.name);
            spec_ops += usize::from(SPEC_CONSTANT_OPS.contains(&(stripped[at] & 0xffff)));
            at += count;
        }
        if stripped.first() != Some(&0x0723_0203) || at != stripped.len() || spec_ops > 0 {
            errors.push(format!(
                "{}: not a whole frozen module ({spec_ops} spec-constant instructions)",
                c.name
            ));
        }
        let layout: Vec<(u32, vk::DescriptorType)> =
            c.bindings.iter().map(|b| (b.binding, b.ty)).collect();
        let ids: Vec<u32> = c.specialization.iter().map(|(id, _)| *id).collect();
        if let Err(e) =
            nimbus_gpu::spirv::check(&c.name, &stripped, &layout, &ids, c.push_constant_size)
        {
            errors.push(format!("{e:#}"));
        }
    }
    assert!(errors.is_empty(), "\n{}", errors.join("\n"));
}
