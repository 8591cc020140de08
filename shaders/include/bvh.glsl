// Triangle meshes: the scene's BVH nodes and leaf triangles (every mesh's, concatenated
// with absolute indices), the watertight ray–triangle test and the stack traversal.
// The CPU twin, and the reference the tests compare with, is nimbus_scene's
// mesh/traverse.rs (Bvh::closest_hit / any_hit).
//
// Watertightness: Woop, Benthin and Wald 2013 as pbrt-v4 does it (sec. 6.5.3): the
// corners are translated to the ray origin, permuted so that the ray's largest
// direction component is z, and sheared so the ray is +z; the edge functions of the
// sheared 2D triangle decide the hit. pbrt re-evaluates an edge function that is
// exactly 0 in double precision; the device has no shaderFloat64 enabled, so this stays
// in f32. The edge functions are `precise` (no fused multiply-add): the two triangles
// sharing an edge then compute exactly opposite values from bit-identical sheared
// corners, so a ray through the edge never slips between them (it may hit both).
#ifndef NIMBUS_BVH_GLSL
#define NIMBUS_BVH_GLSL

#include "bindings.glsl"
#include "constants.glsl"
#include "features.glsl"
#include "counters.glsl"
#include "scene.glsl"

layout(std430, set = 0, binding = BINDING_BVH_NODES) readonly buffer BvhNodeBlock {
    BvhNode bvh_nodes[];
};
layout(std430, set = 0, binding = BINDING_MESH_TRIANGLES) readonly buffer MeshTriangleBlock {
    MeshTriangle mesh_triangles[];
};

// pbrt's gamma(n) = n eps / (1 - n eps), eps = 2^-24 the f32 unit roundoff: the bound on
// the relative error of n rounded operations.
float bvh_gamma(float n) {
    const float eps = 5.96046448e-8;
    // Domain: n eps << 1 for the n used here (<= 5).
    return n * eps / (1.0 - n * eps);
}

// A ray prepared once for all its box and triangle tests.
struct BvhRay {
    vec3 o;
    vec3 inv_d;    // 1 / d per axis; 0 where the ray is parallel to the slabs
    bvec3 flat_d;  // |d| < 1e-30 on the axis: parallel to its slabs
    uvec3 k;       // axes that become x, y, z of the shear (z: the largest |d|)
    vec3 shear;    // x += shear.x z, y += shear.y z, z *= shear.z
};

// Prepare o + t d. False for a zero or non-finite direction or a non-finite origin:
// such a ray hits nothing.
bool bvh_ray(vec3 o, vec3 d, out BvhRay r) {
    r.o = o;
    r.inv_d = vec3(0.0);
    r.flat_d = bvec3(true);
    r.k = uvec3(0u, 1u, 2u);
    r.shear = vec3(0.0);
    if (any(isnan(d)) || any(isinf(d)) || any(isnan(o)) || any(isinf(o))) {
        return false;
    }
    vec3 ad = abs(d);
    // The largest |d| component (ties to the later axis, as the CPU's max_axis).
    uint kz = ad.x > ad.y ? (ad.x > ad.z ? 0u : 2u) : (ad.y > ad.z ? 1u : 2u);
    if (!(ad[kz] > 0.0)) {
        return false;
    }
    uint kx = (kz + 1u) % 3u;
    uint ky = (kx + 1u) % 3u;
    r.k = uvec3(kx, ky, kz);
    // Domain: d[kz] != 0 (checked above).
    float inv_dz = 1.0 / d[kz];
    r.shear = vec3(-d[kx] * inv_dz, -d[ky] * inv_dz, inv_dz);
    r.flat_d = lessThan(ad, vec3(1e-30));
    // Domain: |d| >= 1e-30 where divided; parallel axes keep 0.
    r.inv_d = mix(vec3(1.0) / mix(d, vec3(1.0), r.flat_d), vec3(0.0), r.flat_d);
    return true;
}

// Where the ray enters the box [lo, hi] within [0, t_max]: the entry distance (>= 0),
// or -1 if it misses. Conservative (pbrt-v4 sec. 6.8.2, Ize 2013): the far distances
// are widened by 1 + 2 gamma(3), so rounding never loses a box that a hit lies in. An
// axis the ray is parallel to constrains nothing when the origin lies in its slab (the
// slab is closed) and misses otherwise.
float bvh_enter(BvhRay r, vec3 lo, vec3 hi, float t_max) {
    float widen = 1.0 + 2.0 * bvh_gamma(3.0);
    vec3 outside = vec3(lessThan(r.o, lo)) + vec3(greaterThan(r.o, hi));
    if (any(greaterThan(outside * vec3(r.flat_d), vec3(0.0)))) {
        return -1.0;
    }
    vec3 a = (lo - r.o) * r.inv_d;
    vec3 b = (hi - r.o) * r.inv_d;
    vec3 near = mix(min(a, b), vec3(0.0), r.flat_d);
    vec3 far = mix(max(a, b), vec3(FAR), r.flat_d) * widen;
    float t0 = max(max(near.x, near.y), max(near.z, 0.0));
    float t1 = min(min(far.x, far.y), min(far.z, t_max));
    return t0 <= t1 * widen ? t0 : -1.0;
}

// The watertight test of the ray against mesh triangle `index`: the hit distance in
// (t_min, t_max), conservatively > 0 (pbrt's bound on the error of t), else FAR. Both
// sides count; degenerate triangles are never hit.
float bvh_triangle(BvhRay r, uint index, float t_min, float t_max) {
    MeshTriangle tri = mesh_triangles[index];
    // Translate to the ray origin, permute and shear x and y (as the CPU does, in f32).
    precise vec3 q0 = tri.p0 - r.o;
    precise vec3 q1 = tri.p1 - r.o;
    precise vec3 q2 = tri.p2 - r.o;
    uvec3 k = r.k;
    precise float z0 = q0[k.z];
    precise float z1 = q1[k.z];
    precise float z2 = q2[k.z];
    precise float x0 = q0[k.x] + r.shear.x * z0;
    precise float y0 = q0[k.y] + r.shear.y * z0;
    precise float x1 = q1[k.x] + r.shear.x * z1;
    precise float y1 = q1[k.y] + r.shear.y * z1;
    precise float x2 = q2[k.x] + r.shear.x * z2;
    precise float y2 = q2[k.y] + r.shear.y * z2;
    // Edge functions: the signed doubled areas of the sheared triangle's sub-triangles.
    precise float e0 = x1 * y2 - y1 * x2;
    precise float e1 = x2 * y0 - y2 * x0;
    precise float e2 = x0 * y1 - y0 * x1;
    if ((e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0)) {
        return FAR;
    }
    float det = e0 + e1 + e2;
    if (det == 0.0) {
        return FAR;
    }
    // The scaled distance, compared with the range before dividing.
    z0 *= r.shear.z;
    z1 *= r.shear.z;
    z2 *= r.shear.z;
    float t_scaled = e0 * z0 + e1 * z1 + e2 * z2;
    if (det < 0.0 && (t_scaled >= 0.0 || t_scaled < t_max * det)) {
        return FAR;
    }
    if (det > 0.0 && (t_scaled <= 0.0 || t_scaled > t_max * det)) {
        return FAR;
    }
    // Domain: det != 0 (checked above); t is finite since |t_scaled| <= t_max |det|.
    float inv_det = 1.0 / det;
    float t = t_scaled * inv_det;
    // Ensure t is conservatively > 0 (pbrt-v4 sec. 6.8.4, with the shear's f32 error).
    float max_zt = max(max(abs(z0), abs(z1)), abs(z2));
    float max_xt = max(max(abs(x0), abs(x1)), abs(x2));
    float max_yt = max(max(abs(y0), abs(y1)), abs(y2));
    float delta_z = bvh_gamma(3.0) * max_zt;
    float delta_x = bvh_gamma(5.0) * (max_xt + max_zt);
    float delta_y = bvh_gamma(5.0) * (max_yt + max_zt);
    float delta_e = 2.0 * (bvh_gamma(2.0) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    float max_e = max(max(abs(e0), abs(e1)), abs(e2));
    float delta_t = 3.0 * (bvh_gamma(3.0) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * abs(inv_det);
    if (!(t > delta_t && t > t_min && t < t_max)) {
        return FAR;
    }
    return t;
}

// Trace o + t d for t in (t_min, t_max) through the mesh whose root is bvh_nodes[root]
// (node_count nodes): the closest hit's distance (FAR if none) and its index in
// mesh_triangles[]; with any_hit, the first hit found ends the traversal instead.
// Nearer child first, the farther pushed on a fixed stack of BVH_STACK_SIZE entries
// (enough: the build bounds the depth); a popped subtree the ray now enters beyond the
// closest hit is skipped. Each node is visited at most once, so the loop is bounded by
// twice the node count (visits and skipped pops).
float bvh_trace(uint root, uint node_count, vec3 o, vec3 d, float t_min, float t_max,
                bool any_hit, out uint hit_triangle) {
    hit_triangle = NO_INDEX;
    BvhRay r;
    if (!bvh_ray(o, d, r)) {
        return FAR;
    }
    float widen = 1.0 + 2.0 * bvh_gamma(3.0);
    float t_best = t_max;
    BvhNode root_node = bvh_nodes[root];
    float t_node = bvh_enter(r, root_node.min, root_node.max, t_best);
    if (t_node < 0.0) {
        return FAR;
    }
    uint stack_node[BVH_STACK_SIZE];
    float stack_t[BVH_STACK_SIZE];
    uint sp = 0u;
    uint node = root;
    uint guard = 2u * node_count + 1u;
    for (uint step = 0u; step < guard; ++step) {
        if (t_node <= t_best * widen) {
            COUNT(CTR_BVH_NODES, 1);
            BvhNode n = bvh_nodes[node];
            if (n.count > 0u) {
                // A leaf: test its triangles, shrinking the range to the closest hit.
                for (uint i = 0u; i < BVH_MAX_LEAF_TRIANGLES; ++i) {
                    if (i >= n.count) {
                        break;
                    }
                    uint index = n.left_or_first + i;
                    float t = bvh_triangle(r, index, t_min, t_best);
                    if (t < t_best) {
                        t_best = t;
                        hit_triangle = index;
                        if (any_hit) {
                            return t;
                        }
                    }
                }
            } else {
                // An interior node: descend into the nearer child, push the farther.
                uint left = n.left_or_first;
                BvhNode a = bvh_nodes[left];
                BvhNode b = bvh_nodes[left + 1u];
                float ta = bvh_enter(r, a.min, a.max, t_best);
                float tb = bvh_enter(r, b.min, b.max, t_best);
                if (ta >= 0.0 && tb >= 0.0) {
                    bool a_first = ta <= tb;
                    if (sp < BVH_STACK_SIZE) {
                        stack_node[sp] = a_first ? left + 1u : left;
                        stack_t[sp] = a_first ? tb : ta;
                        ++sp;
                    }
                    node = a_first ? left : left + 1u;
                    t_node = a_first ? ta : tb;
                    continue;
                }
                if (ta >= 0.0 || tb >= 0.0) {
                    node = ta >= 0.0 ? left : left + 1u;
                    t_node = max(ta, tb);
                    continue;
                }
            }
        }
        // Pop the next subtree (skipped at the loop's top if now beyond the closest hit).
        if (sp == 0u) {
            break;
        }
        --sp;
        node = stack_node[sp];
        t_node = stack_t[sp];
    }
    return hit_triangle == NO_INDEX ? FAR : t_best;
}

// The geometric normal cross(p1 - p0, p2 - p0) of mesh triangle `index`, scaled so its
// largest component is 1 (no underflow for tiny triangles); 0 if it has no area in f32.
vec3 mesh_triangle_normal(uint index) {
    MeshTriangle tri = mesh_triangles[index];
    vec3 n = cross(tri.p1 - tri.p0, tri.p2 - tri.p0);
    float m = max(max(abs(n.x), abs(n.y)), abs(n.z));
    // Domain: m > 0 where divided.
    return m > 0.0 ? n / m : vec3(0.0);
}

#endif
