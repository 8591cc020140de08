//! Descriptor binding numbers (set 0) and the indices into the stats buffer, declared once
//! in `src/shader_data/contract/bindings.rs`, from which `build.rs` also writes the
//! `BINDING_*` / `STAT_*` defines that `shaders/include/bindings.glsl` includes.

include!("contract/bindings.rs");
