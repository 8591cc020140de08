// GPU scene records (std430 storage buffers), the frame's parameters (std430) and the
// push constants of a dispatch. Mirrored member by member by the #[repr(C)] structs in
// src/gpu/records.rs (same names); tests/suite/layout.rs parses this file and checks every
// member's type and offset and every struct's size.
//
// A float or uint after a vec3 shares the vec3's 16 bytes (std140 and std430 alike), so
// each xyz quantity carries one named scalar or an explicit `_padN`.
#ifndef NIMBUS_SCENE_GLSL
#define NIMBUS_SCENE_GLSL

// A homogeneous box or convex medium. 112 bytes. A convex medium (plane_count > 0) is
// the intersection of its planes' half-spaces n . x <= d in the local frame (unit n),
// inside the box |x_a| <= half_size that bounds it.
struct BoxMedium {
    vec4 world_to_local[3]; // rows of R^T (w 0); local = R^T (x - center)
    vec3 center;            // world (convex: the centroid of its vertices)
    float sigma_t;          // extinction (1/m)
    vec3 half_size;         // half extents along the local axes (m); convex: of its bounding box
    float g;                // HG asymmetry
    vec3 sigma_s;           // rgb sigma_s = albedo * sigma_t (1/m)
    uint plane_count;       // 0: a box; else the planes of a convex medium
    uint plane_first;       // index of its first plane in medium_planes[]
    uint _pad0;
    uint _pad1;
    uint _pad2;
};

// Shape.type
#define SHAPE_QUAD 0u
#define SHAPE_BOX 1u
#define SHAPE_SPHERE 2u
#define SHAPE_MESH 3u

// An opaque Lambertian shape, perhaps an area light. 112 bytes. `p` is a tagged union on `type` (GLSL has no
// unions; one named member per shape's parameter would more than double the record):
//   quad:   p[0] corner, p[1] edge_u, p[2] edge_v, p[3].xyz w = n / dot(n, n), n = cross(edge_u, edge_v)
//   box:    p[0..2] rows of R^T (w 0), p[3].xyz centre, p[4].xyz half extents
//   sphere: p[0].xyz centre, p[0].w radius
//   mesh:   p[0] uints bit-cast to floats (floatBitsToUint): x its root's index in
//           bvh_nodes[], y its first triangle's in mesh_triangles[], z its triangle
//           count, w its node count
struct Shape {
    vec4 p[5];
    vec3 albedo;         // rgb Lambertian albedo
    uint type;           // SHAPE_QUAD, SHAPE_BOX, SHAPE_SPHERE or SHAPE_MESH
    vec3 emission;       // rgb radiance it emits (W/m^2/sr): quads and mesh triangles towards their normal, boxes and spheres outwards
    uint emitter_first;  // its first primitive in emitters[] (NO_INDEX if it does not emit)
};

// Emitter.type
#define EMITTER_TRIANGLE 0u
#define EMITTER_SPHERE 1u

// One primitive of an emitting shape: the emitter table that next-event estimation
// samples (emitters.glsl). 64 bytes. A quad is 2 triangles, a box 12, a mesh its
// triangles in BVH leaf order (so a mesh hit's emitter is emitter_first + the leaf index
// minus the mesh's first), a sphere 1. A triangle emits towards cross(p1 - p0, p2 - p0),
// a sphere outwards.
struct Emitter {
    vec3 p0;         // triangle: corner 0; sphere: centre
    uint type;       // EMITTER_TRIANGLE or EMITTER_SPHERE
    vec3 p1;         // triangle: corner 1; sphere: (radius, 0, 0)
    uint shape;      // index of its shape in shapes[]
    vec3 p2;         // triangle: corner 2
    float area;      // m^2 (a sphere's whole surface)
    vec3 radiance;   // rgb Le (W/m^2/sr)
    float cdf;       // power CDF over the table, inclusive (power = pi area luminance(Le))
};

// A node of a mesh's BVH (bvh.glsl). 32 bytes. The box [min, max] bounds its subtree.
// Interior (count 0): its children are nodes left_or_first and left_or_first + 1; leaf:
// triangles left_or_first .. left_or_first + count - 1 of mesh_triangles[]. Indices are
// into the scene's concatenated buffers (every mesh's rebased on upload).
struct BvhNode {
    vec3 min;            // lower corner of the box (world, m)
    uint left_or_first;  // interior: first child; leaf: first triangle
    vec3 max;            // upper corner
    uint count;          // leaf: triangles (1..BVH_MAX_LEAF_TRIANGLES); 0: interior
};

// A mesh triangle in BVH leaf order. 48 bytes. Counter-clockwise seen from the side its
// normal cross(p1 - p0, p2 - p0) points to.
struct MeshTriangle {
    vec3 p0;        // corners (world, m)
    uint triangle;  // its index in its mesh as loaded (for per-triangle data)
    vec3 p1;
    uint _pad0;
    vec3 p2;
    uint _pad1;
};

// Light.type
#define LIGHT_DIRECTIONAL 0u
#define LIGHT_POINT 1u
#define LIGHT_SPHERE 2u
// Every emitting shape at once (the emitter table); grid passes only.
#define LIGHT_AREA 3u

// An analytic light. 80 bytes. The crepuscular pass reads directional lights with their
// gobos; the grid-medium passes read every type with its selection CDF.
struct Light {
    vec3 direction_or_position; // directional: unit travel direction; point: position; sphere: centre
    uint type;                  // LIGHT_DIRECTIONAL, LIGHT_POINT, LIGHT_SPHERE or LIGHT_AREA
    vec3 irradiance;            // rgb: directional E (W/m^2), point I (W/sr), sphere L (W/m^2/sr); area: unused
    float radius;               // sphere: radius (m); 0 otherwise
    vec3 gobo_origin;           // a point on the gobo plane
    uint gobo_plane_count;      // gobo half-planes (0: no gobo)
    vec3 gobo_u;                // gobo plane u axis
    uint gobo_first_plane;      // index of the first half-plane in gobo_planes[]
    vec3 gobo_v;                // gobo plane v axis
    float select_cdf;           // grid passes: CDF of next-event light selection over the set
};

// Parameters fixed for a frame (std430 storage buffer, see film.glsl). 128 bytes.
struct FrameUniforms {
    vec3 cam_position;
    float tan_half_fov_x;   // tan(hfov / 2)
    vec3 cam_forward;
    float tan_half_fov_y;   // tan(vfov / 2)
    vec3 cam_right;
    float _pad0;
    vec3 cam_up;
    float _pad1;
    vec3 env_radiance;      // rgb radiance of the constant environment
    float background;       // weight of the environment camera rays see directly: 1, or 0 (transparent film)
    uint width;             // image width in pixels
    uint height;            // image height in pixels
    uint spp;               // samples per pixel per frame (path tracers)
    uint seed;              // the render's seed (folded to 32 bits)
    uint box_media_count;   // records in media[]
    uint shape_count;       // records in shapes[]
    uint light_count;       // analytic lights in one light set of lights[]
    uint ray_samples;       // box estimators: samples N along one camera segment
    uvec2 env_size;         // environment map width and height (1 x 1 without a map; the crepuscular pass)
    vec2 env_rotation;      // (cos, sin) of the map's turn about +Y this frame (envmap.glsl); (1, 0): none
};

// Push constants of a dispatch. 16 bytes.
// Where light l's moment shadow map lies (the ME estimator, moments.glsl): an orthographic
// map perpendicular to the light's travel direction over the box media's footprint.
struct MomentFrame {
    vec3 u_axis;       // unit world axis of the map's u
    float u_min;       // u of the map's left edge (m)
    vec3 v_axis;       // unit world axis of the map's v
    float v_min;       // v of its bottom edge (m)
    vec3 omega;        // the light's unit travel direction: depth z = omega . x
    float trace_start; // depth at which the map's rays start, upstream of every shape
    float texels_u;    // level-0 texels per metre along u
    float texels_v;    // level-0 texels per metre along v
    float depth_near;  // depth of the media's upstream end (normalised depth 0.1)
    float depth_far;   // depth of their downstream end (normalised depth 0.9)
    uint size;         // level-0 texels per side (a power of two)
    uint levels;       // mip levels: log2(size) + 1
    uint first;        // index of level 0's first texel in moment_map[]
    uint _pad0;
};

// Push constants of the moment-map pass: one dispatch per light and mip level.
struct MomentPush {
    uint light;  // which light's map
    uint level;  // 0: trace the shapes; > 0: average level - 1's 2x2 texels
    uint size;   // texels per side of this level
    uint dst;    // index of this level's first texel in moment_map[]
    uint src;    // index of level - 1's first texel (level > 0)
    uint _pad0;
    uint _pad1;
    uint _pad2;
};

struct PassPush {
    uint frame;        // frame index within the render
    uint sample_base;  // index of this dispatch's first sample per pixel
    uint sample_count; // samples per pixel this dispatch takes
    uint _pad1;
};

#endif
