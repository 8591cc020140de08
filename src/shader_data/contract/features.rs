// The one source of the numbers the shaders and the Rust side must agree on:
// specialization-constant IDs, the box estimator IDs and the limits the shaders
// hard-code. `build.rs` includes this file and writes `gpu_features.glsl` (`#define NAME
// value`, which `shaders/include/features.glsl` includes) and refuses two SC_ID_* with
// one value; `src/shader_data/features.rs` includes it as the Rust constants. See
// `src/shader_data/contract/records.rs` for the literal rules (a `u32` suffix is a GLSL `uint`).

gpu_consts! {
    // -----------------------------------------------------------------------------------
    // Specialization-constant IDs: `layout(constant_id = SC_ID_X) const ... SC_X`. One ID
    // means one feature in every pass that declares it.
    pub const SC_ID_HAS_SHAPES: u32 = 0;
    pub const SC_ID_HAS_GOBOS: u32 = 1;
    pub const SC_ID_HAS_ENV: u32 = 2;
    pub const SC_ID_ESTIMATOR: u32 = 3;
    pub const SC_ID_HAS_MEDIA: u32 = 4;
    pub const SC_ID_MAX_BOUNCES: u32 = 5;
    pub const SC_ID_PIXEL_JITTER: u32 = 6;
    pub const SC_ID_HAS_EMISSION: u32 = 7;
    pub const SC_ID_HAS_ENV_MAP: u32 = 8;
    /// ReSTIR: vertex reuse (x_2 kept in world space) instead of direction reuse.
    pub const SC_ID_REUSE_VERTEX: u32 = 9;
    /// ReSTIR: final shading estimates transmittance by ratio tracking.
    pub const SC_ID_FINAL_RATIO_TRACKING: u32 = 10;
    /// ReSTIR: the medium has a velocity grid (temporal reprojection follows it).
    pub const SC_ID_HAS_VELOCITY: u32 = 11;
    /// ReSTIR: pairwise MIS in spatial reuse instead of Talbot's.
    pub const SC_ID_MIS_PAIRWISE: u32 = 12;
    /// Box estimators: entries of the piece and exit-line tables (box_analytic.glsl), the
    /// most light-facing planes of any medium and light (3 for boxes).
    pub const SC_ID_MAX_PIECES: u32 = 13;
    /// Box media: some media are convex polyhedra (planes in medium_planes[]).
    pub const SC_ID_HAS_CONVEX: u32 = 14;
    /// Shapes: some are triangle meshes (BVH traversal in bvh.glsl compiled in; declared
    /// by shapes.glsl).
    pub const SC_ID_HAS_MESHES: u32 = 15;
    /// Grid passes: some shapes emit (the emitter table is sampled; emitters.glsl).
    pub const SC_ID_HAS_AREA_LIGHTS: u32 = 16;
    /// ReSTIR: split next-event estimation (every delta light plus one environment
    /// sample).
    pub const SC_ID_NEE_SPLIT: u32 = 17;
    /// ReSTIR: every walk adds the camera ray's end as a candidate, not only escaping
    /// ones.
    pub const SC_ID_DIRECT_EACH_WALK: u32 = 18;
    /// Every pass: count work (`shaders/include/counters.glsl`) into the stats buffer's
    /// counter block...
    pub const SC_ID_COUNTERS: u32 = 19;
    /// ... of this pass slot (0 .. COUNTER_SLOTS - 1): the slot whose counters a pipeline
    /// adds to.
    pub const SC_ID_COUNTER_SLOT: u32 = 20;
    /// Super-voxel tracking (grid_blocks.glsl): some super-voxel span can be too hot for
    /// null collisions (residual majorant x longest chord > GRID_EXACT_SPAN_STEPS), so the
    /// exact tracking of hot spans is compiled in. The pass decides it from the
    /// super-voxels (`crate::shader_data::GpuGrid::needs_exact_spans`).
    pub const SC_ID_EXACT_SPANS: u32 = 21;
    /// Per-pixel passes: the film's alpha is wanted (the camera ray's transmittance is
    /// computed); off where nothing reads it (profiles, studies, benchmarks).
    pub const SC_ID_ALPHA: u32 = 22;
    /// Grid passes: some indirection section is two-level (a bounding box of more than
    /// 2^24 bricks; crates/nimbus-scene/src/bricks/indirection.rs): grid_slot reads the
    /// offset's tag. Off, ordinary grids pay nothing for the second level.
    pub const SC_ID_TWO_LEVEL_BRICKS: u32 = 23;
    /// Grid passes: the medium has a temperature grid; grid_emission adds its blackbody
    /// radiance (the temperature atlas and the blackbody table are read).
    pub const SC_ID_HAS_BLACKBODY: u32 = 24;
    /// Grid passes: the medium's albedo is a grid (grid_albedo reads its atlas).
    pub const SC_ID_HAS_ALBEDO_GRID: u32 = 25;
    /// ReSTIR's spatial reuse moves x_1 between pixels by its optical depth through the
    /// conservative grid instead of its distance (restir/combine.glsl).
    pub const SC_ID_SPATIAL_TAU_SHIFT: u32 = 26;
    /// ReSTIR: a medium vertex's emission joins its split-NEE light candidate instead of
    /// being a candidate of its own (restir/path_lights.glsl, "Folded emission").
    pub const SC_ID_FOLD_EMISSION: u32 = 27;
    /// Every per-pixel pass: the geometric AOVs (depth, normal, albedo, motion) are asked
    /// for: the pixel-centre camera ray is traced once per frame (aov.glsl).
    pub const SC_ID_AOV_GEOMETRY: u32 = 28;
    /// Every per-pixel pass: the path AOVs emission, direct and indirect are asked for.
    pub const SC_ID_AOV_PATHS: u32 = 29;
    /// Every per-pixel pass: light groups written (0: none; else the scene's groups,
    /// at most AOV_MAX_GROUPS).
    pub const SC_ID_AOV_GROUPS: u32 = 30;
    /// ReSTIR: reservoirs keep an environment sample's direction in the map's frame, so
    /// that a reused sample turns with a turning map (`env_reuse = "map"`;
    /// restir/path_value.glsl).
    pub const SC_ID_ENV_REUSE_MAP: u32 = 31;
    /// The baseline and ReSTIR read the density from the storage buffer
    /// GRID_DENSITY_TEXELS instead of the atlas image (grid.glsl): the plan's choice on
    /// CPU devices.
    pub const SC_ID_DENSITY_BUFFER: u32 = 32;
    /// The baseline's split NEE estimates a constant sky's transmittance along the path's
    /// next segment, in that segment's walk (pathtrace.comp).
    pub const SC_ID_SKY_ALONG_PATH: u32 = 33;
    /// The path tracers' pixel loop (film.glsl): every invocation of a workgroup takes
    /// the camera samples of the workgroup's first pixel, so all its lanes trace the same
    /// paths (`nimbus profile --coherent-lanes`: the cost of a frame without SIMD
    /// divergence; the image is not the scene's).
    pub const SC_ID_COHERENT_LANES: u32 = 34;
    /// Grid passes: some light is a sphere light (lights.glsl's nearest_sphere_light looks
    /// for one on every segment and shadow ray; without any it is compiled out).
    pub const SC_ID_HAS_SPHERE_LIGHTS: u32 = 35;
    /// ReSTIR passes: regular tracking reads the piecewise-constant levels from a
    /// slot-major storage buffer instead of their atlas image (CPU devices, where a
    /// texelFetch is a call into the sampler's code; pc_tracking.glsl).
    pub const SC_ID_PC_BUFFER: u32 = 36;
    /// ReSTIR's spatial pass traces the camera rays through the pixels' centres to test
    /// its neighbours or anchor their depths (`spatial_feature_tolerance`,
    /// `spatial_anchor`; restir/spatial.comp). Off, the pass carries none of that code.
    pub const SC_ID_SPATIAL_FEATURES: u32 = 37;
    /// ReSTIR's initial pass finds its candidates' medium vertices by the baseline's
    /// decomposition tracking on the exact density, not by regular tracking through the
    /// piecewise-constant grid (`candidate_tracking`; restir/initial.comp).
    pub const SC_ID_CANDIDATE_DELTA: u32 = 38;
    /// ReSTIR's target function: how p̂ makes a scalar of a path's RGB contribution
    /// (`target`: one of the SC_TARGET_* values below; restir/vertex_media.glsl).
    pub const SC_ID_TARGET_SCALAR: u32 = 39;
    /// ReSTIR: the camera segment's medium emission is estimated in final shading by
    /// samples along the camera ray stratified in sigma_t T, and no candidate
    /// path ends in it (`camera_emission = "stratified"`; restir/shade.comp).
    pub const SC_ID_CAMERA_EMISSION: u32 = 40;
    /// Temporal reuse aligns the two frames' pixels at the motion point
    /// (`temporal_reprojection = "aligned"`; restir/temporal.comp); else the paper's
    /// reprojection of the selected path's x_1.
    pub const SC_ID_TEMPORAL_ALIGNED: u32 = 41;
    /// ReSTIR's ray marches read the march mips from the storage buffer MARCH_QUADS
    /// instead of their linearly filtered atlases (restir/transmittance.glsl): the plan's
    /// choice on CPU devices, with SC_DENSITY_BUFFER.
    pub const SC_ID_MARCH_BUFFER: u32 = 42;
    /// ReSTIR's temporal pass of a still frame (camera, lights and density as in the
    /// previous frame, under the aligned reprojection): the pipeline the pass dispatches
    /// on such frames, which combines each pixel with its own history and carries none of
    /// the motion code (restir/temporal.comp). On lavapipe every instruction outside a
    /// loop runs for all lanes whether its branch is taken or not, so code a frame does not
    /// reach still costs it.
    pub const SC_ID_TEMPORAL_STILL: u32 = 43;
    /// The still pipeline's combination keeps the initial pass's target where both
    /// reservoirs hold it (`still_target = "initial"`; restir/temporal.comp,
    /// combine_still), so that it evaluates no target.
    pub const SC_ID_STILL_INITIAL_TARGET: u32 = 44;
    /// Temporal reuse moves a reused path's medium x_1 between the two frames' camera rays
    /// by its optical depth through the grid's own density (`temporal_shift =
    /// "optical_depth"`; restir/combine.glsl), on the frames whose density is the previous
    /// frame's; else by its depth past the anchors.
    pub const SC_ID_TEMPORAL_TAU_SHIFT: u32 = 45;
    /// Spatial reuse's optical-depth shift (SC_SPATIAL_TAU_SHIFT) takes the exact optical
    /// depth through the grid's own density instead of tau* through the conservative grid
    /// (`spatial_shift = "optical_depth_exact"`; restir/combine.glsl).
    pub const SC_ID_SPATIAL_TAU_EXACT: u32 = 46;
    /// Values of SC_TARGET_SCALAR.
    pub const SC_TARGET_LUMINANCE: u32 = 0;
    pub const SC_TARGET_SUM: u32 = 1;
    pub const SC_TARGET_MAX: u32 = 2;

    // -----------------------------------------------------------------------------------
    // Values of SC_ESTIMATOR (`shaders/box/crepuscular.comp`): the box-medium estimators
    // of Velinov & Mitchell.
    pub const ESTIMATOR_MCWVDS: u32 = 0u32;
    pub const ESTIMATOR_REDS: u32 = 1u32;
    pub const ESTIMATOR_REES: u32 = 2u32;
    pub const ESTIMATOR_RM: u32 = 3u32;
    pub const ESTIMATOR_MCDS: u32 = 4u32;
    /// Moment-based estimation (Peters et al. 2017) of the visibility ratio.
    pub const ESTIMATOR_ME: u32 = 5u32;

    // -----------------------------------------------------------------------------------
    // Kinds of a path AOV contribution (`aov_add` in aov.glsl): emitted radiance seen with
    // no scattering in between, light scattered exactly once, everything else.
    pub const AOV_EMISSION: u32 = 0u32;
    pub const AOV_DIRECT: u32 = 1u32;
    pub const AOV_INDIRECT: u32 = 2u32;

    // -----------------------------------------------------------------------------------
    // Limits.

    /// Most light groups (named ones and `default`), nimbus_scene::MAX_LIGHT_GROUPS.
    pub const AOV_MAX_GROUPS: u32 = 8u32;
    /// Most path-AOV slots: emission, direct, indirect and the light groups.
    pub const AOV_MAX_SLOTS: u32 = 11u32;
    /// vec4s per pixel of the geometric AOV buffer: (N, Z), (albedo, 0), (motion, 0, 0).
    pub const AOV_GEOMETRY_VEC4S: u32 = 3u32;

    /// Workgroup width of every per-pixel pass (the dispatch is ceil(image / group)
    /// groups).
    pub const GROUP_SIZE_X: u32 = 8;
    /// Workgroup height of every per-pixel pass.
    pub const GROUP_SIZE_Y: u32 = 8;
    /// Most directional lights the crepuscular pass takes (its light-selection arrays).
    pub const MAX_LIGHTS: u32 = 16u32;
    /// Most box media the crepuscular pass takes.
    pub const MAX_MEDIA: u32 = 16u32;
    /// Most planes of a convex medium (the scene loader's limit).
    pub const MAX_CONVEX_PLANES: u32 = 64u32;
    /// Entries of a mesh BVH traversal's stack: one per level below the root (the CPU
    /// build bounds the depth by it, nimbus_scene::BVH_STACK_SIZE).
    pub const BVH_STACK_SIZE: u32 = 32u32;
    /// Most triangles in a BVH leaf.
    pub const BVH_MAX_LEAF_TRIANGLES: u32 = 4u32;
    /// Rays per side of a moment-map texel: MOMENT_MAP_RAYS^2 stratified rays per texel
    /// (moments.glsl).
    pub const MOMENT_MAP_RAYS: u32 = 2u32;
    /// Most scattering events a ReSTIR path stores (k' has 5 bits in a reservoir's info
    /// word, see reservoir.glsl, so at most 31 would fit).
    pub const MAX_RESTIR_BOUNCES: u32 = 16u32;
    /// Most analytic lights a ReSTIR path can name: a reservoir keeps the light index in
    /// 8 bits, and 0xff names the environment.
    pub const MAX_RESTIR_LIGHTS: u32 = 255u32;
    /// Most spatial neighbours of a ReSTIR spatial round.
    pub const MAX_SPATIAL_NEIGHBORS: u32 = 16u32;
    /// Reservoirs combined at once: the spatial neighbours plus the pixel's own.
    pub const MAX_CANDIDATES: u32 = 17;
    /// u32s of a reservoir's header; a reservoir is
    /// `RESERVOIR_HEADER_UINTS + RESERVOIR_VERTEX_UINTS * K` u32s (K = max bounces).
    pub const RESERVOIR_HEADER_UINTS: u32 = 8u32;
    /// u32s per stored path vertex (z_i, omega_i).
    pub const RESERVOIR_VERTEX_UINTS: u32 = 2u32;
    /// Most midpoint steps of one ReSTIR ray march (a cap against absurd lengths; the
    /// step grows instead).
    pub const MARCH_MAX_STEPS: u32 = 4096;
    /// Work counters (counters.glsl, `crate::shader_data::counters`) per pass slot. Each counter
    /// is 64 bits (two uints, low word first) after the STAT_COUNT words of the stats
    /// buffer.
    pub const COUNTER_COUNT: u32 = 8;
    /// Pass slots of work counters.
    pub const COUNTER_SLOTS: u32 = 4;
    /// A super-voxel span on which null-collision tracking would take more than this many
    /// tentative collisions on average (residual majorant x length) is tracked exactly.
    pub const GRID_EXACT_SPAN_STEPS: u32 = 64;
    /// Guard on loop trip counts of the grid estimators: far beyond any expected count
    /// (sigma_max * length), it only stops a runaway loop from hanging the device.
    pub const GRID_MAX_STEPS: u32 = 1_048_576;
}
