//! Descriptor binding numbers (set 0), mirrored from `shaders/include/bindings.glsl`.
//! `tests/suite/layout.rs` parses the header and checks every value here.

pub const FRAME_UNIFORMS: u32 = 0;
pub const ACCUM: u32 = 1;
pub const ACCUM_SQ: u32 = 2;
pub const STATS: u32 = 3;
pub const BOX_MEDIA: u32 = 4;
pub const SHAPES: u32 = 5;
pub const LIGHTS: u32 = 6;
pub const GOBO_PLANES: u32 = 7;
pub const BASELINE_UNIFORMS: u32 = 8;
pub const GRID_DENSITY: u32 = 9;
pub const SUPER_VOXELS: u32 = 10;
pub const GRID_EMISSION: u32 = 11;
pub const ENV_TEXELS: u32 = 12;
pub const ENV_CDF: u32 = 13;
pub const RESTIR_UNIFORMS: u32 = 14;
pub const RESERVOIRS: u32 = 15;
pub const PC_GRID: u32 = 16;
pub const MARCH_REUSE: u32 = 17;
pub const MARCH_REUSE_PREV: u32 = 18;
pub const MARCH_NEE: u32 = 19;
pub const GRID_DENSITY_PREV: u32 = 20;
pub const VELOCITY: u32 = 21;
pub const PREV_FRAME_UNIFORMS: u32 = 22;
/// A frame's partial sums while its samples are shared among dispatches (film.glsl).
pub const FILM_PARTIAL: u32 = 23;
pub const MEDIUM_PLANES: u32 = 24;
/// The ME estimator's moment shadow maps (one mip chain per directional light).
pub const MOMENT_MAP: u32 = 25;
/// Where each light's moment map lies in the world (`MomentFrameGpu`).
pub const MOMENT_FRAMES: u32 = 26;
/// The indirection sections of the sparse grids (`uint grid_bricks[]`).
pub const GRID_BRICKS: u32 = 27;
/// The BVH nodes of every mesh of the scene (`BvhNode bvh_nodes[]`, bvh.glsl).
pub const BVH_NODES: u32 = 28;
/// Their leaf triangles (`MeshTriangle mesh_triangles[]`).
pub const MESH_TRIANGLES: u32 = 29;
/// The emitting shapes' primitives with their power CDF (`Emitter emitters[]`).
pub const EMITTERS: u32 = 30;
/// The grid medium's temperature atlas (R32F, like the emission's).
pub const GRID_TEMPERATURE: u32 = 31;
/// The blackbody table RGB(T)/T uniform in 1/T (`vec4 blackbody[]`,
/// nimbus_scene::blackbody::BlackbodyTable).
pub const BLACKBODY: u32 = 32;
/// The grid medium's albedo atlas (R32F or RGBA32F).
pub const GRID_ALBEDO: u32 = 33;

/// Index of the non-finite sample counter in the stats buffer.
pub const STAT_NON_FINITE: usize = 0;
/// Index of the counter of walks cut short at `GRID_MAX_STEPS`.
pub const STAT_STEP_CAP: usize = 1;
/// Index of the counter of invocations whose loops the device cut short (lavapipe ends
/// every loop of an invocation after 65535 iterations in all).
pub const STAT_LOOPS_CUT: usize = 2;
/// Number of u32 counters in the stats buffer.
pub const STAT_COUNT: usize = 4;

/// Every binding with its GLSL name, for the layout test.
pub const ALL: [(&str, u32); 34] = [
    ("BINDING_FRAME_UNIFORMS", FRAME_UNIFORMS),
    ("BINDING_ACCUM", ACCUM),
    ("BINDING_ACCUM_SQ", ACCUM_SQ),
    ("BINDING_STATS", STATS),
    ("BINDING_BOX_MEDIA", BOX_MEDIA),
    ("BINDING_SHAPES", SHAPES),
    ("BINDING_LIGHTS", LIGHTS),
    ("BINDING_GOBO_PLANES", GOBO_PLANES),
    ("BINDING_BASELINE_UNIFORMS", BASELINE_UNIFORMS),
    ("BINDING_GRID_DENSITY", GRID_DENSITY),
    ("BINDING_SUPER_VOXELS", SUPER_VOXELS),
    ("BINDING_GRID_EMISSION", GRID_EMISSION),
    ("BINDING_ENV_TEXELS", ENV_TEXELS),
    ("BINDING_ENV_CDF", ENV_CDF),
    ("BINDING_RESTIR_UNIFORMS", RESTIR_UNIFORMS),
    ("BINDING_RESERVOIRS", RESERVOIRS),
    ("BINDING_PC_GRID", PC_GRID),
    ("BINDING_MARCH_REUSE", MARCH_REUSE),
    ("BINDING_MARCH_REUSE_PREV", MARCH_REUSE_PREV),
    ("BINDING_MARCH_NEE", MARCH_NEE),
    ("BINDING_GRID_DENSITY_PREV", GRID_DENSITY_PREV),
    ("BINDING_VELOCITY", VELOCITY),
    ("BINDING_PREV_FRAME_UNIFORMS", PREV_FRAME_UNIFORMS),
    ("BINDING_FILM_PARTIAL", FILM_PARTIAL),
    ("BINDING_MEDIUM_PLANES", MEDIUM_PLANES),
    ("BINDING_MOMENT_MAP", MOMENT_MAP),
    ("BINDING_MOMENT_FRAMES", MOMENT_FRAMES),
    ("BINDING_GRID_BRICKS", GRID_BRICKS),
    ("BINDING_BVH_NODES", BVH_NODES),
    ("BINDING_MESH_TRIANGLES", MESH_TRIANGLES),
    ("BINDING_EMITTERS", EMITTERS),
    ("BINDING_GRID_TEMPERATURE", GRID_TEMPERATURE),
    ("BINDING_BLACKBODY", BLACKBODY),
    ("BINDING_GRID_ALBEDO", GRID_ALBEDO),
];
