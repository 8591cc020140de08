//! The numbers the shaders and the Rust side must agree on: specialization-constant IDs,
//! the box estimator IDs and the limits the shaders hard-code. They are declared once, in
//! `src/shader_data/contract/features.rs`, from which `build.rs` also writes the defines that
//! `shaders/include/features.glsl` includes (and refuses two features with one ID). The
//! unit test below checks that no shader names a specialization constant by a bare
//! number.

include!("contract/features.rs");

// The limits that depend on each other.
const _: () = assert!(MAX_CANDIDATES == MAX_SPATIAL_NEIGHBORS + 1);
// The scene loader validates `spatial_neighbors` against its own copy of the limit.
const _: () = assert!(MAX_SPATIAL_NEIGHBORS == nimbus_scene::MAX_SPATIAL_NEIGHBORS);
// The scene loader validates convex media against its own copy of the limit.
const _: () = assert!(MAX_CONVEX_PLANES as usize == nimbus_scene::convex::MAX_CONVEX_PLANES);
// The CPU BVH build bounds the depth, and the leaves, by what the shaders assume.
const _: () = assert!(BVH_STACK_SIZE as usize == nimbus_scene::BVH_STACK_SIZE);
const _: () = assert!(BVH_MAX_LEAF_TRIANGLES == nimbus_scene::BVH_MAX_LEAF_TRIANGLES);
// k' has 5 bits in a reservoir's info word.
const _: () = assert!(MAX_RESTIR_BOUNCES <= 31);

#[cfg(test)]
mod tests {
    use std::path::{Path, PathBuf};

    const ROOT: &str = env!("CARGO_MANIFEST_DIR");

    fn shader_files(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
            let path = entry.expect("directory entry").path();
            if path.is_dir() {
                shader_files(&path, out);
            } else if path.extension().is_some_and(|e| e == "comp" || e == "glsl") {
                out.push(path);
            }
        }
    }

    #[test]
    fn no_shader_names_a_constant_id_by_number() {
        let mut files = Vec::new();
        shader_files(Path::new(&format!("{ROOT}/shaders")), &mut files);
        assert!(!files.is_empty(), "no shaders found under {ROOT}/shaders");
        for file in files {
            let text = std::fs::read_to_string(&file)
                .unwrap_or_else(|e| panic!("{}: {e}", file.display()));
            for (number, line) in text.lines().enumerate() {
                let compact: String = line.chars().filter(|c| !c.is_whitespace()).collect();
                let bare = compact.match_indices("constant_id=").any(|(at, key)| {
                    compact[at + key.len()..]
                        .chars()
                        .next()
                        .is_some_and(|c| c.is_ascii_digit())
                });
                assert!(
                    !bare,
                    "{}:{}: `{}` names a specialization constant by number; use an \
                     SC_ID_* name from features.glsl",
                    file.display(),
                    number + 1,
                    line.trim()
                );
            }
        }
    }
}
