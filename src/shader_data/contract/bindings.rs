// The one source of the descriptor binding numbers of set 0 (shared by every pass) and
// the indices into the stats buffer. `build.rs` includes this file and writes
// `gpu_bindings.glsl` (`#define BINDING_X n`, which `shaders/include/bindings.glsl`
// includes); `src/shader_data/bindings.rs` includes it as the Rust constants. `=> NAME` names the
// GLSL define where it is not the Rust name. See `src/shader_data/contract/records.rs` for the
// literal rules.

gpu_consts! {
    pub const FRAME_UNIFORMS: u32 = 0 => BINDING_FRAME_UNIFORMS;
    pub const ACCUM: u32 = 1 => BINDING_ACCUM;
    pub const ACCUM_SQ: u32 = 2 => BINDING_ACCUM_SQ;
    pub const STATS: u32 = 3 => BINDING_STATS;
    pub const BOX_MEDIA: u32 = 4 => BINDING_BOX_MEDIA;
    pub const SHAPES: u32 = 5 => BINDING_SHAPES;
    pub const LIGHTS: u32 = 6 => BINDING_LIGHTS;
    pub const GOBO_PLANES: u32 = 7 => BINDING_GOBO_PLANES;
    pub const BASELINE_UNIFORMS: u32 = 8 => BINDING_BASELINE_UNIFORMS;
    pub const GRID_DENSITY: u32 = 9 => BINDING_GRID_DENSITY;
    pub const SUPER_VOXELS: u32 = 10 => BINDING_SUPER_VOXELS;
    pub const GRID_EMISSION: u32 = 11 => BINDING_GRID_EMISSION;
    pub const ENV_TEXELS: u32 = 12 => BINDING_ENV_TEXELS;
    pub const ENV_CDF: u32 = 13 => BINDING_ENV_CDF;
    pub const RESTIR_UNIFORMS: u32 = 14 => BINDING_RESTIR_UNIFORMS;
    pub const RESERVOIRS: u32 = 15 => BINDING_RESERVOIRS;
    pub const PC_GRID: u32 = 16 => BINDING_PC_GRID;
    pub const MARCH_REUSE: u32 = 17 => BINDING_MARCH_REUSE;
    pub const MARCH_REUSE_PREV: u32 = 18 => BINDING_MARCH_REUSE_PREV;
    pub const MARCH_NEE: u32 = 19 => BINDING_MARCH_NEE;
    pub const GRID_DENSITY_PREV: u32 = 20 => BINDING_GRID_DENSITY_PREV;
    pub const VELOCITY: u32 = 21 => BINDING_VELOCITY;
    pub const PREV_FRAME_UNIFORMS: u32 = 22 => BINDING_PREV_FRAME_UNIFORMS;
    /// A frame's partial sums while its samples are shared among dispatches (film.glsl).
    pub const FILM_PARTIAL: u32 = 23 => BINDING_FILM_PARTIAL;
    pub const MEDIUM_PLANES: u32 = 24 => BINDING_MEDIUM_PLANES;
    /// The ME estimator's moment shadow maps (one mip chain per directional light).
    pub const MOMENT_MAP: u32 = 25 => BINDING_MOMENT_MAP;
    /// Where each light's moment map lies in the world (`MomentFrameGpu`).
    pub const MOMENT_FRAMES: u32 = 26 => BINDING_MOMENT_FRAMES;
    /// The indirection sections of the sparse grids (`uint grid_bricks[]`).
    pub const GRID_BRICKS: u32 = 27 => BINDING_GRID_BRICKS;
    /// The BVH nodes of every mesh of the scene (`BvhNode bvh_nodes[]`, bvh.glsl).
    pub const BVH_NODES: u32 = 28 => BINDING_BVH_NODES;
    /// Their leaf triangles (`MeshTriangle mesh_triangles[]`).
    pub const MESH_TRIANGLES: u32 = 29 => BINDING_MESH_TRIANGLES;
    /// The emitting shapes' primitives with their power CDF (`Emitter emitters[]`).
    pub const EMITTERS: u32 = 30 => BINDING_EMITTERS;
    /// The grid medium's temperature atlas (R32F, like the emission's).
    pub const GRID_TEMPERATURE: u32 = 31 => BINDING_GRID_TEMPERATURE;
    /// The blackbody table RGB(T)/T uniform in 1/T (`vec4 blackbody[]`,
    /// nimbus_scene::blackbody::BlackbodyTable).
    pub const BLACKBODY: u32 = 32 => BINDING_BLACKBODY;
    /// The grid medium's albedo atlas (R32F or RGBA32F).
    pub const GRID_ALBEDO: u32 = 33 => BINDING_GRID_ALBEDO;
    /// The geometric AOVs of the last frame (`AOV_GEOMETRY_VEC4S` vec4 per pixel; one
    /// vec4 without them), aov.glsl.
    pub const AOV_GEOMETRY: u32 = 34 => BINDING_AOV_GEOMETRY;
    /// The path AOVs' sums over frames, slot-major (`vec4 aov_accum[slot * pixels +
    /// pixel]`; one vec4 without them) ...
    pub const AOV_ACCUM: u32 = 35 => BINDING_AOV_ACCUM;
    /// ... and their sums of squares.
    pub const AOV_ACCUM_SQ: u32 = 36 => BINDING_AOV_ACCUM_SQ;
    /// A frame's path-AOV partial sums while its samples are shared among dispatches.
    pub const AOV_PARTIAL: u32 = 37 => BINDING_AOV_PARTIAL;
    /// `AovUniforms`: the previous frame's camera and the light groups of what has no
    /// light record.
    pub const AOV_UNIFORMS: u32 = 38 => BINDING_AOV_UNIFORMS;
    /// The density's slots as a storage buffer of quads (`vec4 density_quads[slot * 1000 +
    /// texel]`, each slot's 10^3 texels from lattice point 8b - 1, x fastest): where the
    /// device is a CPU (lavapipe), the baseline and ReSTIR read the density from it
    /// instead of the atlas image (grid.glsl).
    pub const GRID_DENSITY_TEXELS: u32 = 39 => BINDING_GRID_DENSITY_TEXELS;
    /// The ReSTIR passes' piecewise-constant levels as a storage buffer (`float
    /// pc_texels[slot * 729 + texel]`, each slot's 9^3 texels x fastest): where the device
    /// is a CPU, regular tracking reads them from it instead of the PC_GRID atlas.
    pub const PC_TEXELS: u32 = 40 => BINDING_PC_TEXELS;
    /// The ReSTIR passes' ray-march mips (reuse, the previous frame's reuse, NEE) as one
    /// storage buffer of quads (`vec4 march_quads[slot * 729 + texel]`, each slot's 9^3
    /// texels x fastest, a texel and its +x, +y and +x+y neighbours): where the device is a
    /// CPU, the marches read it instead of the MARCH_* atlases (restir/transmittance.glsl).
    pub const MARCH_QUADS: u32 = 41 => BINDING_MARCH_QUADS;

    // The denoiser's own pipelines (src/denoise, shaders/denoise): per-pixel buffers.
    /// The noisy image (premultiplied RGB, A).
    pub const DENOISE_NOISY: u32 = 48 => BINDING_DENOISE_NOISY;
    /// The film's variance of the mean (stderr^2 of R, G, B, A).
    pub const DENOISE_FILM_VARIANCE: u32 = 49 => BINDING_DENOISE_FILM_VARIANCE;
    /// Guides: normal (xyz) and camera depth (w; < 0 where there is none).
    pub const DENOISE_GUIDES: u32 = 50 => BINDING_DENOISE_GUIDES;
    /// Guide: albedo (rgb).
    pub const DENOISE_ALBEDO: u32 = 51 => BINDING_DENOISE_ALBEDO;
    /// Guide: screen-space motion (pixels per frame; vec2).
    pub const DENOISE_MOTION: u32 = 52 => BINDING_DENOISE_MOTION;
    /// The depth gradient per pixel (dZ/dx, dZ/dy), from the guides.
    pub const DENOISE_GRADIENT: u32 = 53 => BINDING_DENOISE_GRADIENT;
    /// The colour (demodulated RGB, A) and luminance variance an iteration reads ...
    pub const DENOISE_COLOR_SRC: u32 = 54 => BINDING_DENOISE_COLOR_SRC;
    pub const DENOISE_VARIANCE_SRC: u32 = 55 => BINDING_DENOISE_VARIANCE_SRC;
    /// ... and writes.
    pub const DENOISE_COLOR_DST: u32 = 56 => BINDING_DENOISE_COLOR_DST;
    pub const DENOISE_VARIANCE_DST: u32 = 57 => BINDING_DENOISE_VARIANCE_DST;
    /// Temporal history: the previous frame's filtered colour (demodulated RGB, A).
    pub const DENOISE_HISTORY: u32 = 58 => BINDING_DENOISE_HISTORY;
    /// Luminance moments (m1, m2, history length) of this frame ...
    pub const DENOISE_MOMENTS: u32 = 59 => BINDING_DENOISE_MOMENTS;
    /// ... and of the previous one.
    pub const DENOISE_MOMENTS_PREV: u32 = 60 => BINDING_DENOISE_MOMENTS_PREV;
    /// The previous frame's guides (normal, depth).
    pub const DENOISE_GUIDES_PREV: u32 = 61 => BINDING_DENOISE_GUIDES_PREV;
    /// The denoised image (premultiplied RGB, A).
    pub const DENOISE_OUTPUT: u32 = 62 => BINDING_DENOISE_OUTPUT;
    /// Each pixel's squared luminance residual, for the spatial variance estimate.
    pub const DENOISE_RESIDUAL: u32 = 63 => BINDING_DENOISE_RESIDUAL;

    /// Index of the non-finite sample counter in the stats buffer (uint counters).
    pub const STAT_NON_FINITE: usize = 0;
    /// Index of the counter of walks cut short at `GRID_MAX_STEPS`.
    pub const STAT_STEP_CAP: usize = 1;
    /// Index of the counter of invocations whose loops the device cut short (lavapipe
    /// ends every loop of an invocation after 65535 iterations in all).
    pub const STAT_LOOPS_CUT: usize = 2;
    /// Number of u32 counters in the stats buffer.
    pub const STAT_COUNT: usize = 4;
}
