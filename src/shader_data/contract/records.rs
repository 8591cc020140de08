// The one source of every record the passes share with their shaders: GPU records,
// parameter blocks and push constants, and the type tags of their tagged records.
//
// `build.rs` includes this file and writes `gpu_records.glsl` into OUT_DIR (the GLSL
// structs, std430 / std140, and `#define` tags, which `shaders/include/scene.glsl`,
// `grid_types.glsl` and `shaders/restir/resources.glsl` include), plus a compile-time
// check that each `#[repr(C)]` struct below has the offsets and size GLSL gives its
// struct. `src/shader_data/records.rs` includes it and expands it to those `Pod` structs
// (`crate::shader_data::contract` holds both expansions' rules).
//
// Rules: a field is `f32`, `u32`, `i32`, `[T; 2..=4]` of those (a GLSL vector), an array
// `[T; N]` (a GLSL array) or a record declared earlier (by its Rust name). A `vec3` is
// `[f32; 3]` followed by the scalar (or `_padN`) that shares its 16 bytes, so std430 and
// `repr(C)` agree with no implicit padding (which `Pod` forbids and the check refuses).
// A constant's literal with a `u32` suffix is a GLSL `uint` (`0u`), one without an `int`.
// Doc comments become the GLSL comments.

gpu_consts! {
    /// Shape.type
    pub const SHAPE_QUAD: u32 = 0u32;
    pub const SHAPE_BOX: u32 = 1u32;
    pub const SHAPE_SPHERE: u32 = 2u32;
    pub const SHAPE_MESH: u32 = 3u32;
    /// Emitter.type
    pub const EMITTER_TRIANGLE: u32 = 0u32;
    pub const EMITTER_SPHERE: u32 = 1u32;
    /// Light.type
    pub const LIGHT_DIRECTIONAL: u32 = 0u32;
    pub const LIGHT_POINT: u32 = 1u32;
    pub const LIGHT_SPHERE: u32 = 2u32;
    /// Every emitting shape at once (the emitter table, `EmitterGpu`); grid passes only.
    pub const LIGHT_AREA: u32 = 3u32;
    /// DenoisePush.flags (the denoiser, src/denoise): which guides are given, where the
    /// variance comes from, the temporal history.
    pub const DENOISE_HAS_DEPTH: u32 = 1u32;
    pub const DENOISE_HAS_NORMAL: u32 = 2u32;
    pub const DENOISE_HAS_ALBEDO: u32 = 4u32;
    pub const DENOISE_HAS_MOTION: u32 = 8u32;
    /// The film's per-pixel variance is known (two or more estimates).
    pub const DENOISE_FILM_VARIANCE: u32 = 16u32;
    /// The history holds a previous frame to reproject.
    pub const DENOISE_HISTORY: u32 = 32u32;
    /// Temporal accumulation is on (the history is read and written).
    pub const DENOISE_TEMPORAL: u32 = 64u32;
    /// This a-trous iteration also writes its output into the history colour.
    pub const DENOISE_WRITE_HISTORY: u32 = 128u32;
}

gpu_records! {
    /// A homogeneous box or convex medium. 112 bytes. A convex medium (plane_count > 0)
    /// is the intersection of its planes' half-spaces n . x <= d in the local frame (unit
    /// n), inside the box |x_a| <= half_size that bounds it.
    #[derive(Clone, Copy, Debug, Pod, Zeroable)]
    struct BoxMediumGpu as BoxMedium [std430] {
        /// Rows of R^T (w 0): local = R^T (x - center).
        world_to_local: [[f32; 4]; 3],
        /// World position of the local origin (convex: the centroid of its vertices).
        center: [f32; 3],
        /// Extinction (1/m).
        sigma_t: f32,
        /// Half extents along the local axes (m); convex: of its bounding box.
        half_size: [f32; 3],
        /// HG asymmetry.
        g: f32,
        /// rgb sigma_s = albedo * sigma_t (1/m).
        sigma_s: [f32; 3],
        /// 0 for a box; the number of planes of a convex medium.
        plane_count: u32,
        /// Index of a convex medium's first plane in medium_planes[].
        plane_first: u32,
        _pad0: u32,
        _pad1: u32,
        _pad2: u32,
    }

    /// An opaque Lambertian shape, perhaps an area light. 112 bytes. `p` is a tagged union
    /// on `type` (GLSL has no unions; one named member per shape's parameter would more
    /// than double the record):
    /// ```text
    ///   quad:   p[0] corner, p[1] edge_u, p[2] edge_v, p[3].xyz w = n / dot(n, n),
    ///           n = cross(edge_u, edge_v)
    ///   box:    p[0..2] rows of R^T (w 0), p[3].xyz centre, p[4].xyz half extents
    ///   sphere: p[0].xyz centre, p[0].w radius
    ///   mesh:   p[0] uints bit-cast to floats (floatBitsToUint): x its root's index in
    ///           bvh_nodes[], y its first triangle's in mesh_triangles[], z its triangle
    ///           count, w its node count
    /// ```
    #[derive(Clone, Copy, Debug, Pod, Zeroable)]
    struct ShapeGpu as Shape [std430] {
        p: [[f32; 4]; 5],
        /// rgb Lambertian albedo.
        albedo: [f32; 3],
        /// `SHAPE_QUAD`, `SHAPE_BOX`, `SHAPE_SPHERE` or `SHAPE_MESH`.
        r#type: u32,
        /// rgb radiance it emits (W/(m^2 sr)), zero if it is no area light: quads and mesh
        /// triangles towards their normal, boxes and spheres outwards.
        emission: [f32; 3],
        /// Index of its first primitive in emitters[], `NO_INDEX` if it does not emit.
        emitter_first: u32,
    }

    /// One primitive of an emitting shape: the emitter table that next-event estimation
    /// samples (emitters.glsl). 64 bytes. A quad is 2 triangles, a box 12, a mesh its
    /// triangles in BVH leaf order (so a mesh hit's emitter is emitter_first + the leaf
    /// index minus the mesh's first), a sphere 1. A triangle emits towards
    /// cross(p1 - p0, p2 - p0), a sphere outwards.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
    struct EmitterGpu as Emitter [std430] {
        /// Triangle: corner 0; sphere: centre.
        p0: [f32; 3],
        /// `EMITTER_TRIANGLE` or `EMITTER_SPHERE`.
        r#type: u32,
        /// Triangle: corner 1; sphere: (radius, 0, 0).
        p1: [f32; 3],
        /// Index of its shape in shapes[].
        shape: u32,
        /// Triangle: corner 2 (counter-clockwise seen from the side it emits to).
        p2: [f32; 3],
        /// Its area (m^2); a sphere's whole surface.
        area: f32,
        /// rgb radiance it emits, Le (W/(m^2 sr)).
        radiance: [f32; 3],
        /// Power CDF over the table, inclusive: P(index <= this) (power = pi area
        /// luminance(Le)).
        cdf: f32,
    }

    /// A node of a mesh's BVH (bvh.glsl). 32 bytes. The box [min, max] bounds its
    /// subtree. Interior (count 0): its children are nodes left_or_first and
    /// left_or_first + 1; leaf: triangles left_or_first .. left_or_first + count - 1 of
    /// mesh_triangles[]. Indices are into the scene's concatenated buffers (every mesh's
    /// rebased on upload). The Rust struct is `nimbus_scene::BvhNode`, built by the CPU
    /// BVH; only its layout is checked here.
    extern struct nimbus_scene::BvhNode as BvhNode [std430] {
        /// Lower corner of the box (world, m).
        min: [f32; 3],
        /// Interior: first child; leaf: first triangle.
        left_or_first: u32,
        /// Upper corner.
        max: [f32; 3],
        /// Leaf: triangles (1..BVH_MAX_LEAF_TRIANGLES); 0: interior.
        count: u32,
    }

    /// One triangle of a mesh in BVH leaf order. 48 bytes. Counter-clockwise seen from the
    /// side its normal cross(p1 - p0, p2 - p0) points to.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
    struct MeshTriangleGpu as MeshTriangle [std430] {
        /// Corners (world, m).
        p0: [f32; 3],
        /// Its index in its mesh as loaded (for per-triangle data).
        triangle: u32,
        p1: [f32; 3],
        _pad0: u32,
        p2: [f32; 3],
        _pad1: u32,
    }

    /// An analytic light. 96 bytes. The crepuscular pass reads directional lights with
    /// their gobos; the grid-medium passes read every type with its selection CDF.
    #[derive(Clone, Copy, Debug, Pod, Zeroable)]
    struct LightGpu as Light [std430] {
        /// Directional: unit travel direction; point: position; sphere: centre.
        direction_or_position: [f32; 3],
        /// `LIGHT_DIRECTIONAL`, `LIGHT_POINT`, `LIGHT_SPHERE` or `LIGHT_AREA`.
        r#type: u32,
        /// rgb: directional E (W/m^2), point I (W/sr), sphere L (W/(m^2 sr)); area: unused.
        irradiance: [f32; 3],
        /// Sphere radius (m); 0 for the other types.
        radius: f32,
        /// A point on the gobo plane.
        gobo_origin: [f32; 3],
        /// Gobo half-planes (0: no gobo).
        gobo_plane_count: u32,
        /// Gobo plane u axis.
        gobo_u: [f32; 3],
        /// Index of the light's first half-plane in gobo_planes[] (`GpuScene::gobo_planes`).
        gobo_first_plane: u32,
        /// Gobo plane v axis.
        gobo_v: [f32; 3],
        /// Grid passes: CDF of next-event light selection over the light set.
        select_cdf: f32,
        /// Its light group (`[[light]] group`; an area light's: `default`), an index into
        /// the render's groups (`crate::plan::AovPlan::groups`); 0 without light groups.
        group: u32,
        _pad0: u32,
        _pad1: u32,
        _pad2: u32,
    }

    /// Parameters fixed for a frame (std430 storage buffer, see film.glsl). 128 bytes.
    #[derive(Clone, Copy, Debug, Pod, Zeroable)]
    struct FrameUniforms as FrameUniforms [std430] {
        cam_position: [f32; 3],
        /// tan(hfov / 2).
        tan_half_fov_x: f32,
        cam_forward: [f32; 3],
        /// tan(vfov / 2).
        tan_half_fov_y: f32,
        cam_right: [f32; 3],
        _pad0: f32,
        cam_up: [f32; 3],
        _pad1: f32,
        /// rgb radiance of the constant environment.
        env_radiance: [f32; 3],
        /// Weight of the background (environment) that camera rays see directly: 1, or 0
        /// for a transparent film (`[render] transparent_background`).
        background: f32,
        /// Image width in pixels.
        width: u32,
        /// Image height in pixels.
        height: u32,
        /// Samples per pixel per frame (path tracers).
        spp: u32,
        /// The render's seed folded to 32 bits.
        seed: u32,
        /// Records in the box-media buffer, media[].
        box_media_count: u32,
        /// Records in the shapes buffer, shapes[].
        shape_count: u32,
        /// Analytic lights in one light set of lights[].
        light_count: u32,
        /// Box estimators: samples along one camera segment (N).
        ray_samples: u32,
        /// Environment map width and height (1 x 1 without a map); the crepuscular pass
        /// reads it (the grid passes read `BaselineUniformsGpu::env_size`).
        env_size: [u32; 2],
        /// (cos, sin) of the environment map's turn about +Y at this frame (envmap.glsl,
        /// `nimbus_scene::EnvRotation`); exactly (1, 0) for none, which the shaders skip.
        env_rotation: [f32; 2],
    }

    /// What the AOVs read beside the frame's uniforms (std430 storage buffer at
    /// BINDING_AOV_UNIFORMS, aov.glsl). 144 bytes.
    #[derive(Clone, Copy, Debug, Pod, Zeroable)]
    struct AovUniformsGpu as AovUniforms [std430] {
        /// The previous scene frame's uniforms (its camera), for motion vectors.
        prev: FrameUniforms,
        /// 1 when `prev` holds a previous frame (0 for scene frame 0: motion is 0).
        has_prev: u32,
        /// The light group of the environment (it has no light record).
        env_group: u32,
        /// The `default` group: media emission and emitting shapes.
        default_group: u32,
        _pad0: u32,
    }

    /// Where light l's moment shadow map lies (the ME estimator, moments.glsl): an
    /// orthographic map perpendicular to the light's travel direction over the box media's
    /// footprint.
    #[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
    struct MomentFrameGpu as MomentFrame [std430] {
        /// Unit world axis of the map's u.
        u_axis: [f32; 3],
        /// u of the map's left edge (m).
        u_min: f32,
        /// Unit world axis of the map's v.
        v_axis: [f32; 3],
        /// v of its bottom edge (m).
        v_min: f32,
        /// The light's unit travel direction: depth z = omega . x.
        omega: [f32; 3],
        /// Depth at which the map's rays start, upstream of every shape.
        trace_start: f32,
        /// Level-0 texels per metre along u.
        texels_u: f32,
        /// Level-0 texels per metre along v.
        texels_v: f32,
        /// Depth of the box media's upstream end (normalised depth 0.1).
        depth_near: f32,
        /// Depth of their downstream end (normalised depth 0.9).
        depth_far: f32,
        /// Level-0 texels per side (a power of two).
        size: u32,
        /// Mip levels: log2(size) + 1.
        levels: u32,
        /// Index of level 0's first texel in moment_map[].
        first: u32,
        _pad0: u32,
    }

    /// Push constants of the moment-map pass: one dispatch per light and mip level.
    #[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
    struct MomentPush as MomentPush [std430] {
        /// Which light's map.
        light: u32,
        /// 0: trace the shapes; > 0: average level - 1's 2x2 texels.
        level: u32,
        /// Texels per side of this level.
        size: u32,
        /// Index of this level's first texel in moment_map[].
        dst: u32,
        /// Index of level - 1's first texel (level > 0).
        src: u32,
        _pad0: u32,
        _pad1: u32,
        _pad2: u32,
    }

    /// Push constants of a dispatch of the per-pixel passes. 16 bytes.
    #[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
    struct PassPush as PassPush [std430] {
        /// Frame index within the render.
        frame: u32,
        /// The first camera sample of the pixel this dispatch takes.
        sample_base: u32,
        /// How many it takes (the frame's spp, or a share of it where the device limits
        /// the loop iterations of an invocation).
        sample_count: u32,
        _pad1: u32,
    }

    /// A sparse grid on the GPU: where its index space (p-space) sits in the world, and
    /// where its 8^3 bricks are (an indirection section of grid_bricks[] and an atlas of
    /// 9^3-texel slots, each a brick plus one apron layer on its high side). See
    /// grid.glsl for the index spaces. 160 bytes; std140 and std430 lay it out
    /// identically.
    #[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
    struct GridSpaceGpu as GridSpace [std140, std430] {
        /// Rows of the world -> p-space affine map (general path):
        /// p = (dot(row, vec4(x, 1)) per row).
        world_to_index_x: [f32; 4],
        world_to_index_y: [f32; 4],
        world_to_index_z: [f32; 4],
        /// Axis-aligned path: the world box the p-space box maps to.
        box_min: [f32; 3],
        /// 1 for the axis-aligned path: p = (x - box_min) * scale + index_min,
        /// scale = index / box size.
        axis_aligned: u32,
        box_max: [f32; 3],
        /// First indirection entry of the grid in grid_bricks[].
        bricks_offset: u32,
        /// The p-space box the grid fills (0 outside).
        index_min: [f32; 3],
        /// Atlas slots along x (z follows from the slot count).
        slots_x: u32,
        index_max: [f32; 3],
        /// Atlas slots along y.
        slots_y: u32,
        /// Lattice clamp range (inclusive).
        lattice_min: [i32; 3],
        /// Values per lattice point (1, or 3 for rgb emission).
        channels: u32,
        lattice_max: [i32; 3],
        _pad0: u32,
        /// Bricks per axis of the indirection section.
        brick_dims: [u32; 3],
        _pad1: u32,
    }

    /// The grid medium's extent and majorant with its density grid. 192 bytes. A member of
    /// BaselineUniforms, and the storage buffer of the grid_volume test shader (the
    /// includer of grid.glsl declares `u_grid` of this type).
    #[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
    struct GridParamsGpu as GridParams [std140, std430] {
        /// World bounding box of the medium's extent.
        bounds_min: [f32; 3],
        /// sigma_t = density_scale * density.
        density_scale: f32,
        bounds_max: [f32; 3],
        /// Global max of sigma_t: the majorant of ratio / delta tracking.
        sigma_t_max: f32,
        /// The density grid (unscaled) and its super-voxel records.
        space: GridSpaceGpu,
    }

    /// The grid medium and what lights it, read by the baseline path tracer and the
    /// ReSTIR passes (std430 storage buffer at BINDING_BASELINE_UNIFORMS, named `u_base`
    /// by includers). 736 bytes.
    #[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
    struct BaselineUniformsGpu as BaselineUniforms [std430] {
        grid: GridParamsGpu,
        /// rgb single-scattering albedo (times albedo_grid with one).
        albedo: [f32; 3],
        /// HG asymmetry.
        g: f32,
        /// Probability that next-event estimation picks the environment.
        env_select: f32,
        /// Primitives in emitters[] (0 without area lights).
        emitter_count: u32,
        /// Kelvin = temperature_offset + temperature_scale * trilinear temperature grid.
        temperature_offset: f32,
        temperature_scale: f32,
        /// rgb: Le = emission_scale * trilinear emission grid ...
        emission_scale: [f32; 3],
        /// ... + blackbody_scale * RGB(kelvin) (with a temperature grid, SC_HAS_BLACKBODY).
        blackbody_scale: f32,
        /// The emission grid (its own index space and bricks; an empty grid without one).
        emission: GridSpaceGpu,
        /// The temperature grid (SC_HAS_BLACKBODY; an empty grid without one).
        temperature: GridSpaceGpu,
        /// The albedo grid (SC_HAS_ALBEDO_GRID; an empty grid without one).
        albedo_grid: GridSpaceGpu,
        /// Environment map width and height (1 x 1 without a map).
        env_size: [u32; 2],
        _pad5: [u32; 2],
    }

    /// A derived level of the density (a piecewise-constant level or a ray-march mip) as
    /// a sparse grid (restir/resources.glsl): its lattice (level voxels, `factor` density
    /// voxels per edge, lattice point j at p = (j + 0.5) factor of the density's p-space),
    /// its indirection section and atlas slots. 64 bytes.
    #[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
    struct GridLevelGpu as GridLevel [std430] {
        /// Lattice clamp range (inclusive).
        lattice_min: [i32; 3],
        /// First indirection entry in grid_bricks[].
        bricks_offset: u32,
        lattice_max: [i32; 3],
        /// Density voxels per level voxel edge (2^level).
        factor: u32,
        /// Bricks per axis of the indirection section.
        brick_dims: [u32; 3],
        /// Atlas slots along x.
        slots_x: u32,
        /// Atlas slots along y.
        slots_y: u32,
        /// A ray-march mip's first slot in the buffer of quads the marches read where
        /// SC_MARCH_BUFFER (restir/transmittance.glsl); 0 elsewhere.
        quad_base: u32,
        _pad1: u32,
        _pad2: u32,
    }

    /// Settings of the ReSTIR passes (std430 storage buffer, see film.glsl for why not a
    /// uniform buffer). 336 bytes.
    #[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
    struct RestirUniformsGpu as RestirUniforms [std430] {
        /// The piecewise-constant levels of camera and scattered rays (u_pc).
        pc_primary: GridLevelGpu,
        pc_indirect: GridLevelGpu,
        /// The ray-march mips of reuse targets (u_march_reuse) and of NEE of initial
        /// candidates (u_march_nee).
        march_reuse: GridLevelGpu,
        march_nee: GridLevelGpu,
        /// Indirection sections of the previous frame's reuse mip and density.
        march_reuse_prev_offset: u32,
        density_prev_offset: u32,
        /// Candidates one dispatch of the initial pass draws (M unless the device limits
        /// the loop iterations of an invocation; its aux: the first).
        candidates_per_dispatch: u32,
        /// 1 when the previous frame's camera, lights and density are this frame's, so
        /// that the temporal neighbour at the same pixel has this frame's target function;
        /// 2 when only the lights differ (camera and density as before, no velocity
        /// field): the aligned neighbour is the pixel itself, unshifted, at the camera's
        /// full confidence; 0 otherwise (restir/temporal.comp).
        history_static: u32,
        /// M: random walks per pixel.
        candidates: u32,
        /// Q: cap of the temporal M, in multiples of M.
        temporal_limit: u32,
        /// Neighbours of a spatial round.
        spatial_neighbors: u32,
        /// u32s per reservoir.
        reservoir_stride: u32,
        /// Pixels.
        spatial_radius: f32,
        /// Reuse march step (m).
        march_reuse_step: f32,
        /// NEE march step (m).
        march_nee_step: f32,
        /// The lights' confidence in the previous frame as this one's, in [0, 1]: 1 when
        /// they did not change (temporal.comp scales the history's M by it).
        history_confidence: f32,
        /// Velocity grid dims (1 x 1 x 1 without one).
        velocity_dims: [u32; 3],
        /// Spatial reuse only where the temporal reservoir's M < this (0: everywhere).
        spatial_max_m: f32,
        /// Rows of the affine map from world points to the velocity texture's coordinates.
        velocity_uvw_x: [f32; 4],
        velocity_uvw_y: [f32; 4],
        velocity_uvw_z: [f32; 4],
        /// Spatial reuse rejects a neighbour whose centre camera ray ends elsewhere or
        /// whose T~ differs from the pixel's by this relative change or more (0: none).
        spatial_feature_tolerance: f32,
        /// 1: spatial reuse anchors each pixel's ray where its centre ray enters the
        /// medium (CameraRay.anchor), as temporal reuse does.
        spatial_anchor: u32,
        /// The previous frame's reuse mip's first slot in the buffer of march quads
        /// (SC_MARCH_BUFFER; the current frame's when the density does not change).
        march_reuse_prev_quad_base: u32,
        /// Where the shade cache starts in the reservoir buffer (in u32s; 0: no cache):
        /// per pixel the RGB F of the path its last shading evaluated and a flag that it
        /// is still the pixel's path (restir/shade.comp reuses it on a still frame whose
        /// temporal stage kept the history's sample; restir/temporal.comp clears the flag
        /// where it did not).
        shade_cache_base: u32,
        /// 1 when the previous frame's density is this frame's (the same density frame):
        /// temporal reuse's optical-depth shift (SC_TEMPORAL_TAU_SHIFT) walks both frames'
        /// rays through the one density it has at full resolution.
        history_same_density: u32,
        _pad0: u32,
        _pad1: u32,
        _pad2: u32,
    }

    /// Push constants of every dispatch of the denoiser (src/denoise, shaders/denoise).
    /// 64 bytes.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
    struct DenoisePush as DenoisePush [std430] {
        /// Image size in pixels.
        width: u32,
        height: u32,
        /// Pixel step of this a-trous iteration (1, 2, 4, ...).
        step: u32,
        /// DENOISE_* bits.
        flags: u32,
        /// Luminance edge-stopping: differences in units of the local standard deviation.
        sigma_luminance: f32,
        /// Depth edge-stopping: differences in units of the depth gradient's prediction.
        sigma_depth: f32,
        /// Normal edge-stopping exponent: max(0, dot(n_p, n_q))^sigma_normal.
        sigma_normal: f32,
        /// Temporal accumulation: weight of the new frame once the history is long.
        temporal_alpha: f32,
        /// The same for the luminance moments.
        moments_alpha: f32,
        /// Factor of the spatial variance estimate (one-frame images).
        variance_boost: f32,
        /// Albedo below this is not demodulated (the colour is filtered as it is).
        albedo_epsilon: f32,
        /// Longest history (frames) a pixel accumulates.
        max_history: f32,
        /// Depth edge-stopping: the relative depth difference per pixel of offset that
        /// is tolerated besides the gradient's prediction.
        depth_relative: f32,
        _pad0: u32,
        _pad1: u32,
        _pad2: u32,
    }

    /// Push constants of every ReSTIR dispatch. 16 bytes.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
    struct RestirPush as RestirPush [std430] {
        /// Frame index within the render (0 = first).
        frame: u32,
        /// Reservoir slot read.
        src: u32,
        /// Reservoir slot written.
        dst: u32,
        /// Initial: first candidate; temporal: previous slot; spatial: the round; shade: 1
        /// where the shade cache's F may stand in for a kept path's (else 0).
        aux: u32,
    }
}
