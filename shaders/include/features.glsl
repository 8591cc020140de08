// The numbers the shaders and the Rust side must agree on: specialization-constant IDs,
// the box estimator IDs and the limits the shaders hard-code. Mirrored by
// src/gpu/features.rs, whose unit test parses every `#define NAME <integer>` line here and
// checks both sides name the same constants with the same values; keep every value a
// plain integer literal (a `u` suffix is allowed).
#ifndef NIMBUS_FEATURES_GLSL
#define NIMBUS_FEATURES_GLSL

// ---------------------------------------------------------------------------------------
// Specialization-constant IDs: `layout(constant_id = SC_ID_X) const ... SC_X`. One ID
// means one feature in every pass that declares it.

#define SC_ID_HAS_SHAPES 0
#define SC_ID_HAS_GOBOS 1
#define SC_ID_HAS_ENV 2
#define SC_ID_ESTIMATOR 3
#define SC_ID_HAS_MEDIA 4
#define SC_ID_MAX_BOUNCES 5
#define SC_ID_PIXEL_JITTER 6
#define SC_ID_HAS_EMISSION 7
#define SC_ID_HAS_ENV_MAP 8
// ReSTIR: vertex reuse (x_2 kept in world space) instead of direction reuse.
#define SC_ID_REUSE_VERTEX 9
// ReSTIR: final shading estimates transmittance by ratio tracking.
#define SC_ID_FINAL_RATIO_TRACKING 10
// ReSTIR: the medium has a velocity grid (temporal reprojection follows it).
#define SC_ID_HAS_VELOCITY 11
// ReSTIR: pairwise MIS in spatial reuse instead of Talbot's.
#define SC_ID_MIS_PAIRWISE 12
// Box estimators: entries of the piece and exit-line tables (box_analytic.glsl), the
// most light-facing planes of any medium and light (3 for boxes).
#define SC_ID_MAX_PIECES 13
// Box media: some media are convex polyhedra (planes in medium_planes[]).
#define SC_ID_HAS_CONVEX 14
// Shapes: some are triangle meshes (BVH traversal in bvh.glsl; declared by shapes.glsl).
#define SC_ID_HAS_MESHES 15
// Grid passes: some shapes emit (the emitter table is sampled; emitters.glsl).
#define SC_ID_HAS_AREA_LIGHTS 16
// ReSTIR: split next-event estimation (every delta light plus one environment sample).
#define SC_ID_NEE_SPLIT 17
// ReSTIR: every walk adds the camera ray's end as a candidate, not only escaping ones.
#define SC_ID_DIRECT_EACH_WALK 18
// Every pass: count work (counters.glsl) into the stats buffer's counter block...
#define SC_ID_COUNTERS 19
// ... of this pass slot (0 .. COUNTER_SLOTS - 1).
#define SC_ID_COUNTER_SLOT 20
// Super-voxel tracking (grid_blocks.glsl): some super-voxel span can be too hot for null
// collisions (residual majorant x longest chord > GRID_EXACT_SPAN_STEPS), so the exact
// tracking of hot spans is compiled in. The pass decides it from the super-voxels.
#define SC_ID_EXACT_SPANS 21
// Per-pixel passes: the film's alpha is wanted (the camera ray's transmittance is
// computed); off where nothing reads it (profiles, studies, benchmarks).
#define SC_ID_ALPHA 22
// Grid passes: some indirection section is two-level (a bounding box of more than 2^24
// bricks; crates/nimbus-scene/src/bricks/indirection.rs): grid_slot reads the offset's
// tag. Off, ordinary grids pay nothing for the second level.
#define SC_ID_TWO_LEVEL_BRICKS 23
// Grid passes: the medium has a temperature grid; grid_emission adds its blackbody
// radiance (the temperature atlas and the blackbody table are read).
#define SC_ID_HAS_BLACKBODY 24
// Grid passes: the medium's albedo is a grid (grid_albedo reads its atlas).
#define SC_ID_HAS_ALBEDO_GRID 25
// ReSTIR's spatial reuse moves x_1 between pixels by its optical depth through the
// conservative grid instead of its distance (restir/combine.glsl).
#define SC_ID_SPATIAL_TAU_SHIFT 26
// ReSTIR: a medium vertex's emission joins its split-NEE light candidate instead of being
// a candidate of its own (restir/path.glsl, "Folded emission").
#define SC_ID_FOLD_EMISSION 27

// ---------------------------------------------------------------------------------------
// Values of SC_ESTIMATOR: the box-medium estimators of Velinov & Mitchell.

#define ESTIMATOR_MCWVDS 0u
#define ESTIMATOR_REDS 1u
#define ESTIMATOR_REES 2u
#define ESTIMATOR_RM 3u
#define ESTIMATOR_MCDS 4u
// Moment-based estimation (Peters et al. 2017) of the visibility ratio.
#define ESTIMATOR_ME 5u

// ---------------------------------------------------------------------------------------
// Limits.

// Workgroup size of every per-pixel pass (the dispatch is ceil(image / group) groups).
#define GROUP_SIZE_X 8
#define GROUP_SIZE_Y 8

// Most directional lights the crepuscular pass takes (its light-selection arrays).
#define MAX_LIGHTS 16u
// Most box media the crepuscular pass takes.
#define MAX_MEDIA 16u
// Most planes of a convex medium (the scene loader's limit).
#define MAX_CONVEX_PLANES 64u

// A mesh BVH's traversal stack: one entry per level below the root (the CPU build
// bounds the depth by it, nimbus_scene::BVH_STACK_SIZE), and the most triangles in a leaf.
#define BVH_STACK_SIZE 32u
#define BVH_MAX_LEAF_TRIANGLES 4u

// Rays per side of a moment-map texel: MOMENT_MAP_RAYS² stratified rays (moments.glsl).
#define MOMENT_MAP_RAYS 2u

// Most scattering events a ReSTIR path stores (k' has 5 bits in a reservoir's info word,
// see reservoir.glsl, so at most 31 would fit).
#define MAX_RESTIR_BOUNCES 16u
// Most analytic lights a ReSTIR path can name: a reservoir keeps the light index in 8
// bits, and 0xff names the environment.
#define MAX_RESTIR_LIGHTS 255u
// Most spatial neighbours of a ReSTIR spatial round.
#define MAX_SPATIAL_NEIGHBORS 16u
// Reservoirs combined at once: the spatial neighbours plus the pixel's own.
#define MAX_CANDIDATES 17
// A reservoir is RESERVOIR_HEADER_UINTS + RESERVOIR_VERTEX_UINTS K uints (K = max bounces).
#define RESERVOIR_HEADER_UINTS 8u
#define RESERVOIR_VERTEX_UINTS 2u

// Most midpoint steps of one ReSTIR ray march (a cap against absurd lengths; the step
// grows instead).
#define MARCH_MAX_STEPS 4096
// Work counters (counters.glsl): counters per pass slot, and pass slots. Each counter is
// 64 bits (two uints, low word first) after the STAT_COUNT words of the stats buffer.
#define COUNTER_COUNT 8
#define COUNTER_SLOTS 4

// A super-voxel span on which null-collision tracking would take more than this many
// tentative collisions on average (residual majorant x length) is tracked exactly.
#define GRID_EXACT_SPAN_STEPS 64

// Guard on loop trip counts of the grid estimators: far beyond any expected count
// (sigma_max * length), it only stops a runaway loop from hanging the device.
#define GRID_MAX_STEPS 1048576

#endif
