//! Every `#[repr(C)]` mirror of a GLSL struct the passes share with their shaders.
//!
//! Each mirror has the GLSL struct's members, in order and by the same names: a `vec3`
//! is `[f32; 3]` followed by the scalar (or `_padN`) that shares its 16 bytes, so
//! std140 / std430 and `repr(C)` agree with no implicit padding (which `Pod` forbids).
//! `tests/suite/layout.rs` parses the GLSL declarations (`shaders/include/scene.glsl`,
//! `shaders/include/grid_types.glsl`, `shaders/restir/resources.glsl`) and checks every
//! member's type and offset and every struct's size.

use bytemuck::{Pod, Zeroable};

/// `BoxMedium` in scene.glsl: a homogeneous box or convex medium.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct BoxMediumGpu {
    /// Rows of Rᵀ (w 0): local = Rᵀ (x − center).
    pub world_to_local: [[f32; 4]; 3],
    /// World position of the local origin (convex: the vertices' centroid).
    pub center: [f32; 3],
    /// Extinction (1/m).
    pub sigma_t: f32,
    /// Half extents along the local axes (convex: of its bounding box).
    pub half_size: [f32; 3],
    /// HG asymmetry.
    pub g: f32,
    /// albedo · sigma_t.
    pub sigma_s: [f32; 3],
    /// 0 for a box; the number of planes of a convex medium.
    pub plane_count: u32,
    /// Index of a convex medium's first plane in the planes buffer.
    pub plane_first: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

/// Values of `ShapeGpu::type`.
pub const SHAPE_QUAD: u32 = 0;
pub const SHAPE_BOX: u32 = 1;
pub const SHAPE_SPHERE: u32 = 2;
pub const SHAPE_MESH: u32 = 3;

/// `Shape` in scene.glsl: an opaque Lambertian shape. `p` is a tagged union on `type`
/// (see scene.glsl for what each shape keeps there).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct ShapeGpu {
    pub p: [[f32; 4]; 5],
    pub albedo: [f32; 3],
    /// `SHAPE_QUAD`, `SHAPE_BOX`, `SHAPE_SPHERE` or `SHAPE_MESH`.
    pub r#type: u32,
    /// Radiance it emits (W/(m²·sr)); zero if it is no area light.
    pub emission: [f32; 3],
    /// Index of its first primitive in the emitter table, `NO_INDEX` if it does not emit.
    pub emitter_first: u32,
}

/// Values of `EmitterGpu::type`.
pub const EMITTER_TRIANGLE: u32 = 0;
pub const EMITTER_SPHERE: u32 = 1;

/// `Emitter` in scene.glsl: one primitive of an emitting shape in the emitter table
/// (next-event estimation of area lights).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct EmitterGpu {
    /// Triangle: corner 0; sphere: centre.
    pub p0: [f32; 3],
    /// `EMITTER_TRIANGLE` or `EMITTER_SPHERE`.
    pub r#type: u32,
    /// Triangle: corner 1; sphere: (radius, 0, 0).
    pub p1: [f32; 3],
    /// Index of its shape in the shape buffer.
    pub shape: u32,
    /// Triangle: corner 2 (counter-clockwise seen from the side it emits to).
    pub p2: [f32; 3],
    /// Its area (m²); a sphere's whole surface.
    pub area: f32,
    /// Radiance it emits (W/(m²·sr)).
    pub radiance: [f32; 3],
    /// Power CDF over the table, inclusive: P(index <= this).
    pub cdf: f32,
}

/// `MeshTriangle` in scene.glsl: one triangle of a mesh in BVH leaf order (the node
/// buffer is `nimbus_scene::BvhNode`, already the GLSL `BvhNode`'s layout).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct MeshTriangleGpu {
    pub p0: [f32; 3],
    /// Its index in its mesh as loaded.
    pub triangle: u32,
    pub p1: [f32; 3],
    pub _pad0: u32,
    pub p2: [f32; 3],
    pub _pad1: u32,
}

/// Values of `LightGpu::type`.
pub const LIGHT_DIRECTIONAL: u32 = 0;
pub const LIGHT_POINT: u32 = 1;
pub const LIGHT_SPHERE: u32 = 2;
/// All emitting shapes as one light of the grid passes' selection (`EmitterGpu` table).
pub const LIGHT_AREA: u32 = 3;

/// `Light` in scene.glsl: an analytic light.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct LightGpu {
    /// Directional: unit travel direction; point: position; sphere: centre.
    pub direction_or_position: [f32; 3],
    /// `LIGHT_DIRECTIONAL`, `LIGHT_POINT` or `LIGHT_SPHERE`.
    pub r#type: u32,
    /// Directional E, point I, sphere L.
    pub irradiance: [f32; 3],
    /// Sphere radius; 0 for the other types.
    pub radius: f32,
    pub gobo_origin: [f32; 3],
    /// Gobo half-planes (0: no gobo).
    pub gobo_plane_count: u32,
    pub gobo_u: [f32; 3],
    /// Index of the light's first half-plane in `GpuScene::gobo_planes`.
    pub gobo_first_plane: u32,
    pub gobo_v: [f32; 3],
    /// Grid passes: CDF of next-event light selection over the light set.
    pub select_cdf: f32,
}

/// `MomentFrame` in scene.glsl: where a directional light's moment shadow map lies.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct MomentFrameGpu {
    pub u_axis: [f32; 3],
    pub u_min: f32,
    pub v_axis: [f32; 3],
    pub v_min: f32,
    /// The light's unit travel direction (depth = omega · x).
    pub omega: [f32; 3],
    /// Depth at which the map's rays start, upstream of every shape.
    pub trace_start: f32,
    /// Level-0 texels per metre along u.
    pub texels_u: f32,
    /// Level-0 texels per metre along v.
    pub texels_v: f32,
    /// Depth of the box media's upstream end.
    pub depth_near: f32,
    /// Depth of their downstream end.
    pub depth_far: f32,
    /// Level-0 texels per side (a power of two).
    pub size: u32,
    /// Mip levels: log2(size) + 1.
    pub levels: u32,
    /// Index of level 0's first texel in the moment-map buffer.
    pub first: u32,
    pub _pad0: u32,
}

/// `MomentPush` in scene.glsl: one dispatch of the moment-map pass.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct MomentPush {
    pub light: u32,
    /// 0: trace the shapes; > 0: average level − 1's 2×2 texels.
    pub level: u32,
    /// Texels per side of this level.
    pub size: u32,
    /// Index of this level's first texel.
    pub dst: u32,
    /// Index of level − 1's first texel.
    pub src: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

/// `FrameUniforms` in scene.glsl (std430).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FrameUniforms {
    pub cam_position: [f32; 3],
    /// tan(hfov / 2).
    pub tan_half_fov_x: f32,
    pub cam_forward: [f32; 3],
    /// tan(vfov / 2).
    pub tan_half_fov_y: f32,
    pub cam_right: [f32; 3],
    pub _pad0: f32,
    pub cam_up: [f32; 3],
    pub _pad1: f32,
    /// Radiance of the constant environment.
    pub env_radiance: [f32; 3],
    /// Weight of the background (environment) that camera rays see directly: 1, or 0
    /// for a transparent film (`[render] transparent_background`).
    pub background: f32,
    pub width: u32,
    pub height: u32,
    /// Samples per pixel per frame.
    pub spp: u32,
    /// The render's seed folded to 32 bits.
    pub seed: u32,
    /// Records in the box-media buffer.
    pub box_media_count: u32,
    /// Records in the shapes buffer.
    pub shape_count: u32,
    /// Analytic lights in one light set.
    pub light_count: u32,
    /// Box estimators: samples along one camera segment (N).
    pub ray_samples: u32,
    /// Environment map width and height (1 × 1 without a map); the crepuscular pass
    /// reads it (the grid passes read `BaselineUniformsGpu::env_size`).
    pub env_size: [u32; 2],
    /// (cos θ, sin θ) of the environment map's turn about +Y at this frame
    /// (`nimbus_scene::EnvRotation`); exactly (1, 0) for none, which the shaders skip.
    pub env_rotation: [f32; 2],
}

/// `PassPush` in scene.glsl: the push constants of every dispatch.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct PassPush {
    pub frame: u32,
    /// The first camera sample of the pixel this dispatch takes.
    pub sample_base: u32,
    /// How many it takes (the frame's spp, or a share of it where the device limits
    /// the loop iterations of an invocation).
    pub sample_count: u32,
    pub _pad1: u32,
}

/// `GridSpace` in grid_types.glsl: where a sparse grid's p-space sits in the world and
/// where its bricks are (see `shaders/include/grid.glsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GridSpaceGpu {
    /// Rows of the world → p-space affine map (general path).
    pub world_to_index_x: [f32; 4],
    pub world_to_index_y: [f32; 4],
    pub world_to_index_z: [f32; 4],
    /// Axis-aligned path: the world box the p-space box maps to.
    pub box_min: [f32; 3],
    /// 1 for the axis-aligned path.
    pub axis_aligned: u32,
    pub box_max: [f32; 3],
    /// First indirection entry of the grid in `grid_bricks[]`.
    pub bricks_offset: u32,
    /// The p-space box the grid fills.
    pub index_min: [f32; 3],
    /// Atlas slots along x.
    pub slots_x: u32,
    pub index_max: [f32; 3],
    /// Atlas slots along y.
    pub slots_y: u32,
    /// Lattice clamp range (inclusive).
    pub lattice_min: [i32; 3],
    /// Values per lattice point.
    pub channels: u32,
    pub lattice_max: [i32; 3],
    pub _pad0: u32,
    /// Bricks per axis of the indirection section.
    pub brick_dims: [u32; 3],
    pub _pad1: u32,
}

/// `GridParams` in grid_types.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GridParamsGpu {
    /// World bounding box of the medium's extent.
    pub bounds_min: [f32; 3],
    /// sigma_t = density_scale · density.
    pub density_scale: f32,
    pub bounds_max: [f32; 3],
    /// Global max of sigma_t: the majorant of ratio / delta tracking.
    pub sigma_t_max: f32,
    /// The density grid.
    pub space: GridSpaceGpu,
}

/// `BaselineUniforms` in grid_types.glsl (std430).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct BaselineUniformsGpu {
    pub grid: GridParamsGpu,
    /// Single-scattering albedo.
    pub albedo: [f32; 3],
    /// HG asymmetry.
    pub g: f32,
    /// Probability that next-event estimation picks the environment.
    pub env_select: f32,
    /// Primitives in the emitter table (0 without area lights).
    pub emitter_count: u32,
    /// Kelvin = temperature_offset + temperature_scale · trilinear temperature grid.
    pub temperature_offset: f32,
    pub temperature_scale: f32,
    /// Le = emission_scale · trilinear emission grid ...
    pub emission_scale: [f32; 3],
    /// ... + blackbody_scale · RGB(kelvin) (with a temperature grid).
    pub blackbody_scale: f32,
    /// The emission grid (its own index space and bricks; an empty grid without one).
    pub emission: GridSpaceGpu,
    /// The temperature grid (an empty grid without one).
    pub temperature: GridSpaceGpu,
    /// The albedo grid (an empty grid without one).
    pub albedo_grid: GridSpaceGpu,
    /// Environment map width and height (1 × 1 without a map).
    pub env_size: [u32; 2],
    pub _pad5: [u32; 2],
}

/// `GridLevel` in restir/resources.glsl: a derived level of the density as a sparse grid.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GridLevelGpu {
    /// Lattice clamp range (inclusive).
    pub lattice_min: [i32; 3],
    /// First indirection entry in `grid_bricks[]`.
    pub bricks_offset: u32,
    pub lattice_max: [i32; 3],
    /// Density voxels per level voxel edge (2^level).
    pub factor: u32,
    /// Bricks per axis of the indirection section.
    pub brick_dims: [u32; 3],
    /// Atlas slots along x.
    pub slots_x: u32,
    /// Atlas slots along y.
    pub slots_y: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

/// `RestirUniforms` in restir/resources.glsl (std430).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct RestirUniformsGpu {
    /// The piecewise-constant levels of camera and scattered rays.
    pub pc_primary: GridLevelGpu,
    pub pc_indirect: GridLevelGpu,
    /// The ray-march mips of reuse targets and of NEE.
    pub march_reuse: GridLevelGpu,
    pub march_nee: GridLevelGpu,
    /// Indirection sections of the previous frame's reuse mip and density.
    pub march_reuse_prev_offset: u32,
    pub density_prev_offset: u32,
    /// Candidates one dispatch of the initial pass draws (M unless the device limits the
    /// loop iterations of an invocation).
    pub candidates_per_dispatch: u32,
    /// 1 when the previous frame's camera, lights and density are this frame's, so that
    /// the temporal neighbour at the same pixel has this frame's target function.
    pub history_static: u32,
    /// M.
    pub candidates: u32,
    /// Q.
    pub temporal_limit: u32,
    pub spatial_neighbors: u32,
    /// u32s per reservoir.
    pub reservoir_stride: u32,
    /// Pixels.
    pub spatial_radius: f32,
    /// Metres.
    pub march_reuse_step: f32,
    pub march_nee_step: f32,
    /// The lights' confidence in the previous frame as this one's, in [0, 1]: 1 when they
    /// did not change (temporal.comp scales the history's M by it).
    pub history_confidence: f32,
    /// Velocity grid dims (1 × 1 × 1 without one).
    pub velocity_dims: [u32; 3],
    /// Spatial reuse only where the temporal reservoir's M < this (0: everywhere).
    pub spatial_max_m: f32,
    /// Rows of the affine map from world points to the velocity texture's coordinates.
    pub velocity_uvw_x: [f32; 4],
    pub velocity_uvw_y: [f32; 4],
    pub velocity_uvw_z: [f32; 4],
}

/// `RestirPush` in restir/resources.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct RestirPush {
    pub frame: u32,
    pub src: u32,
    pub dst: u32,
    pub aux: u32,
}

/// Bytes per pixel of one reservoir slot for K = `max_bounces` (`Reservoir` in
/// reservoir.glsl): a 32-byte header (w_sum, M, p_hat, packed info, light point,
/// octahedral light direction) and per vertex z (f32) plus an octahedral direction
/// (2 × 16 bits).
pub fn reservoir_bytes(max_bounces: u32) -> u64 {
    use super::features::{RESERVOIR_HEADER_UINTS, RESERVOIR_VERTEX_UINTS};
    4 * u64::from(RESERVOIR_HEADER_UINTS + RESERVOIR_VERTEX_UINTS * max_bounces)
}
