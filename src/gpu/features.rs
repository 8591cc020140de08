//! The numbers the shaders and the Rust side must agree on, mirrored from
//! `shaders/include/features.glsl`: specialization-constant IDs, the box estimator IDs
//! and the limits the shaders hard-code. The unit test below parses the GLSL header and
//! checks that both sides hold the same names with the same values, and that no shader
//! still names a specialization constant by a bare number.

// ---------------------------------------------------------------------------------------
// Specialization-constant IDs (`layout(constant_id = SC_ID_*)`).

pub const SC_ID_HAS_SHAPES: u32 = 0;
pub const SC_ID_HAS_GOBOS: u32 = 1;
pub const SC_ID_HAS_ENV: u32 = 2;
pub const SC_ID_ESTIMATOR: u32 = 3;
pub const SC_ID_HAS_MEDIA: u32 = 4;
pub const SC_ID_MAX_BOUNCES: u32 = 5;
pub const SC_ID_PIXEL_JITTER: u32 = 6;
pub const SC_ID_HAS_EMISSION: u32 = 7;
pub const SC_ID_HAS_ENV_MAP: u32 = 8;
/// ReSTIR: vertex reuse instead of direction reuse.
pub const SC_ID_REUSE_VERTEX: u32 = 9;
/// ReSTIR: final shading by ratio tracking.
pub const SC_ID_FINAL_RATIO_TRACKING: u32 = 10;
/// ReSTIR: temporal reprojection follows the velocity grid.
pub const SC_ID_HAS_VELOCITY: u32 = 11;
/// ReSTIR: pairwise MIS in spatial reuse instead of Talbot's.
pub const SC_ID_MIS_PAIRWISE: u32 = 12;
/// Box estimators: entries of the piece and exit-line tables.
pub const SC_ID_MAX_PIECES: u32 = 13;
/// Box media: some are convex polyhedra.
pub const SC_ID_HAS_CONVEX: u32 = 14;
/// Shapes: some are triangle meshes (BVH traversal compiled in).
pub const SC_ID_HAS_MESHES: u32 = 15;
/// Grid passes: some shapes emit (the emitter table is sampled).
pub const SC_ID_HAS_AREA_LIGHTS: u32 = 16;
/// ReSTIR: split next-event estimation (every delta light plus one environment sample).
pub const SC_ID_NEE_SPLIT: u32 = 17;
/// ReSTIR: every walk adds the camera ray's end as a candidate, not only escaping ones.
pub const SC_ID_DIRECT_EACH_WALK: u32 = 18;
/// Every pass: count work (`shaders/include/counters.glsl`) into the stats buffer.
pub const SC_ID_COUNTERS: u32 = 19;
/// The pass slot whose counters a pipeline adds to.
pub const SC_ID_COUNTER_SLOT: u32 = 20;
/// Super-voxel tracking: some span can be too hot for null collisions, so the exact
/// tracking of hot spans is compiled in ([`crate::gpu::GpuGrid::needs_exact_spans`]).
pub const SC_ID_EXACT_SPANS: u32 = 21;
/// Per-pixel passes: compute the film's alpha (the camera ray's transmittance).
pub const SC_ID_ALPHA: u32 = 22;
/// Grid passes: some brick indirection section is two-level.
pub const SC_ID_TWO_LEVEL_BRICKS: u32 = 23;
/// Grid passes: the medium has a temperature grid (blackbody emission).
pub const SC_ID_HAS_BLACKBODY: u32 = 24;
/// Grid passes: the medium's albedo is a grid.
pub const SC_ID_HAS_ALBEDO_GRID: u32 = 25;
pub const SC_ID_SPATIAL_TAU_SHIFT: u32 = 26;
pub const SC_ID_FOLD_EMISSION: u32 = 27;

// ---------------------------------------------------------------------------------------
// Values of `SC_ESTIMATOR` in `shaders/box/crepuscular.comp`.

pub const ESTIMATOR_MCWVDS: u32 = 0;
pub const ESTIMATOR_REDS: u32 = 1;
pub const ESTIMATOR_REES: u32 = 2;
pub const ESTIMATOR_RM: u32 = 3;
pub const ESTIMATOR_MCDS: u32 = 4;
pub const ESTIMATOR_ME: u32 = 5;

// ---------------------------------------------------------------------------------------
// Limits.

/// Workgroup width of every per-pixel pass.
pub const GROUP_SIZE_X: u32 = 8;
/// Workgroup height of every per-pixel pass.
pub const GROUP_SIZE_Y: u32 = 8;
/// Most directional lights the crepuscular pass takes.
pub const MAX_LIGHTS: u32 = 16;
/// Most box media the crepuscular pass takes.
pub const MAX_MEDIA: u32 = 16;
/// Most planes of a convex medium.
pub const MAX_CONVEX_PLANES: u32 = 64;
/// Entries of a mesh BVH traversal's stack.
pub const BVH_STACK_SIZE: u32 = 32;
/// Most triangles in a BVH leaf.
pub const BVH_MAX_LEAF_TRIANGLES: u32 = 4;
/// Rays per side of a moment-map texel (MOMENT_MAP_RAYS² stratified rays per texel).
pub const MOMENT_MAP_RAYS: u32 = 2;
/// Most scattering events a ReSTIR path stores.
pub const MAX_RESTIR_BOUNCES: u32 = 16;
/// Most analytic lights a ReSTIR path can name (8-bit index, 0xff = environment).
pub const MAX_RESTIR_LIGHTS: u32 = 255;
/// Most spatial neighbours of a ReSTIR spatial round.
pub const MAX_SPATIAL_NEIGHBORS: u32 = 16;
/// Reservoirs combined at once: the spatial neighbours plus the pixel's own.
pub const MAX_CANDIDATES: u32 = 17;
/// u32s of a reservoir's header; a reservoir is
/// `RESERVOIR_HEADER_UINTS + RESERVOIR_VERTEX_UINTS * K` u32s.
pub const RESERVOIR_HEADER_UINTS: u32 = 8;
/// u32s per stored path vertex (z_i, omega_i).
pub const RESERVOIR_VERTEX_UINTS: u32 = 2;
/// Most midpoint steps of one ReSTIR ray march.
pub const MARCH_MAX_STEPS: u32 = 4096;
/// Work counters per pass slot ([`crate::gpu::counters`]).
pub const COUNTER_COUNT: u32 = 8;
/// Pass slots of work counters.
pub const COUNTER_SLOTS: u32 = 4;
/// Tentative collisions on a super-voxel span past which it is tracked exactly.
pub const GRID_EXACT_SPAN_STEPS: u32 = 64;
/// Guard on loop trip counts of the grid estimators.
pub const GRID_MAX_STEPS: u32 = 1_048_576;

/// Every constant above with its GLSL name.
pub const ALL: [(&str, u32); 53] = [
    ("SC_ID_HAS_SHAPES", SC_ID_HAS_SHAPES),
    ("SC_ID_HAS_GOBOS", SC_ID_HAS_GOBOS),
    ("SC_ID_HAS_ENV", SC_ID_HAS_ENV),
    ("SC_ID_ESTIMATOR", SC_ID_ESTIMATOR),
    ("SC_ID_HAS_MEDIA", SC_ID_HAS_MEDIA),
    ("SC_ID_MAX_BOUNCES", SC_ID_MAX_BOUNCES),
    ("SC_ID_PIXEL_JITTER", SC_ID_PIXEL_JITTER),
    ("SC_ID_HAS_EMISSION", SC_ID_HAS_EMISSION),
    ("SC_ID_HAS_ENV_MAP", SC_ID_HAS_ENV_MAP),
    ("SC_ID_REUSE_VERTEX", SC_ID_REUSE_VERTEX),
    ("SC_ID_FINAL_RATIO_TRACKING", SC_ID_FINAL_RATIO_TRACKING),
    ("SC_ID_HAS_VELOCITY", SC_ID_HAS_VELOCITY),
    ("SC_ID_MIS_PAIRWISE", SC_ID_MIS_PAIRWISE),
    ("SC_ID_MAX_PIECES", SC_ID_MAX_PIECES),
    ("SC_ID_HAS_CONVEX", SC_ID_HAS_CONVEX),
    ("SC_ID_HAS_MESHES", SC_ID_HAS_MESHES),
    ("SC_ID_HAS_AREA_LIGHTS", SC_ID_HAS_AREA_LIGHTS),
    ("SC_ID_NEE_SPLIT", SC_ID_NEE_SPLIT),
    ("SC_ID_DIRECT_EACH_WALK", SC_ID_DIRECT_EACH_WALK),
    ("SC_ID_COUNTERS", SC_ID_COUNTERS),
    ("SC_ID_COUNTER_SLOT", SC_ID_COUNTER_SLOT),
    ("SC_ID_EXACT_SPANS", SC_ID_EXACT_SPANS),
    ("SC_ID_ALPHA", SC_ID_ALPHA),
    ("SC_ID_TWO_LEVEL_BRICKS", SC_ID_TWO_LEVEL_BRICKS),
    ("SC_ID_HAS_BLACKBODY", SC_ID_HAS_BLACKBODY),
    ("SC_ID_HAS_ALBEDO_GRID", SC_ID_HAS_ALBEDO_GRID),
    ("SC_ID_SPATIAL_TAU_SHIFT", SC_ID_SPATIAL_TAU_SHIFT),
    ("SC_ID_FOLD_EMISSION", SC_ID_FOLD_EMISSION),
    ("GRID_EXACT_SPAN_STEPS", GRID_EXACT_SPAN_STEPS),
    ("COUNTER_COUNT", COUNTER_COUNT),
    ("COUNTER_SLOTS", COUNTER_SLOTS),
    ("ESTIMATOR_MCWVDS", ESTIMATOR_MCWVDS),
    ("ESTIMATOR_REDS", ESTIMATOR_REDS),
    ("ESTIMATOR_REES", ESTIMATOR_REES),
    ("ESTIMATOR_RM", ESTIMATOR_RM),
    ("ESTIMATOR_MCDS", ESTIMATOR_MCDS),
    ("ESTIMATOR_ME", ESTIMATOR_ME),
    ("MOMENT_MAP_RAYS", MOMENT_MAP_RAYS),
    ("BVH_STACK_SIZE", BVH_STACK_SIZE),
    ("BVH_MAX_LEAF_TRIANGLES", BVH_MAX_LEAF_TRIANGLES),
    ("GROUP_SIZE_X", GROUP_SIZE_X),
    ("GROUP_SIZE_Y", GROUP_SIZE_Y),
    ("MAX_LIGHTS", MAX_LIGHTS),
    ("MAX_MEDIA", MAX_MEDIA),
    ("MAX_CONVEX_PLANES", MAX_CONVEX_PLANES),
    ("MAX_RESTIR_BOUNCES", MAX_RESTIR_BOUNCES),
    ("MAX_RESTIR_LIGHTS", MAX_RESTIR_LIGHTS),
    ("MAX_SPATIAL_NEIGHBORS", MAX_SPATIAL_NEIGHBORS),
    ("MAX_CANDIDATES", MAX_CANDIDATES),
    ("RESERVOIR_HEADER_UINTS", RESERVOIR_HEADER_UINTS),
    ("RESERVOIR_VERTEX_UINTS", RESERVOIR_VERTEX_UINTS),
    ("MARCH_MAX_STEPS", MARCH_MAX_STEPS),
    ("GRID_MAX_STEPS", GRID_MAX_STEPS),
];

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
    use std::collections::BTreeMap;
    use std::path::{Path, PathBuf};

    use super::*;

    const ROOT: &str = env!("CARGO_MANIFEST_DIR");

    /// An integer literal of GLSL: decimal or 0x hex, with an optional `u` suffix.
    fn parse_int(text: &str) -> Option<u64> {
        let digits = text.strip_suffix(['u', 'U']).unwrap_or(text);
        match digits
            .strip_prefix("0x")
            .or_else(|| digits.strip_prefix("0X"))
        {
            Some(hex) => u64::from_str_radix(hex, 16).ok(),
            None => digits.parse().ok(),
        }
    }

    /// Every `#define NAME value` line of `text`; a define whose value is not one integer
    /// literal is an error, so the header stays machine-readable.
    fn defines(text: &str) -> BTreeMap<String, u64> {
        let mut out = BTreeMap::new();
        for (number, line) in text.lines().enumerate() {
            let mut words = line.split_whitespace();
            if words.next() != Some("#define") {
                continue;
            }
            let name = words.next().unwrap_or_default();
            let rest: Vec<&str> = words.collect();
            // The include guard has no value.
            if rest.is_empty() && name.starts_with("NIMBUS_") {
                continue;
            }
            let value = match rest.as_slice() {
                [value] => parse_int(value),
                _ => None,
            };
            let value = value.unwrap_or_else(|| {
                panic!(
                    "features.glsl:{}: `{line}` is not `#define NAME <integer>`",
                    number + 1
                )
            });
            assert!(
                out.insert(name.to_owned(), value).is_none(),
                "features.glsl defines {name} twice"
            );
        }
        out
    }

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

    /// `pub const NAME: u32 = value;` lines of this file (every constant, whether or
    /// not `ALL` lists it).
    fn rust_consts() -> BTreeMap<String, u64> {
        let path = format!("{ROOT}/src/gpu/features.rs");
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        text.lines()
            .filter_map(|line| {
                let rest = line.trim().strip_prefix("pub const ")?;
                let (name, rest) = rest.split_once(": u32 = ")?;
                let value = rest.strip_suffix(';')?.replace('_', "");
                Some((
                    name.to_owned(),
                    parse_int(&value).expect("integer constant"),
                ))
            })
            .collect()
    }

    #[test]
    fn rust_and_glsl_features_agree() {
        let path = format!("{ROOT}/shaders/include/features.glsl");
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        let glsl = defines(&text);
        let listed: BTreeMap<String, u64> = ALL
            .iter()
            .map(|&(name, value)| (name.to_owned(), u64::from(value)))
            .collect();
        assert_eq!(listed.len(), ALL.len(), "ALL names a constant twice");
        assert_eq!(
            rust_consts(),
            listed,
            "ALL must list every `pub const` of src/gpu/features.rs under its own name"
        );
        for (name, value) in &listed {
            assert_eq!(
                glsl.get(name),
                Some(value),
                "{name}: src/gpu/features.rs has {value}, features.glsl differs or lacks it"
            );
        }
        let extra: Vec<&String> = glsl.keys().filter(|k| !listed.contains_key(*k)).collect();
        assert!(
            extra.is_empty(),
            "features.glsl defines what src/gpu/features.rs lacks: {extra:?}"
        );
    }

    #[test]
    fn ids_are_distinct() {
        let mut ids: Vec<u32> = ALL
            .iter()
            .filter(|(name, _)| name.starts_with("SC_ID_"))
            .map(|&(_, id)| id)
            .collect();
        let count = ids.len();
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(
            ids.len(),
            count,
            "two features share a specialization-constant ID"
        );
        let mut estimators: Vec<u32> = ALL
            .iter()
            .filter(|(name, _)| name.starts_with("ESTIMATOR_"))
            .map(|&(_, id)| id)
            .collect();
        estimators.sort_unstable();
        assert_eq!(estimators, (0..6).collect::<Vec<u32>>());
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
