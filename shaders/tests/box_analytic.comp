#version 460
// Test harness for box_analytic.glsl (tests/suite/kernels/box_analytic/). One invocation per query;
// a query names a configuration (camera ray, light direction, box or convex polyhedron,
// sigma_t, interval), a random number for sample_wvds and a distance at which to
// evaluate wvds_pdf. A configuration with planes (plane_count > 0) is the convex
// polyhedron of planes[plane_first ..] (n . x <= d, local frame); SC_MAX_PIECES sizes
// the piece tables as the renderer does.

#extension GL_GOOGLE_include_directive : require

#include "box_analytic.glsl"
#include "features.glsl"
// Included twice on purpose: the include guard must make the second one a no-op.
#include "box_analytic.glsl"

layout(local_size_x = 64) in;

// A configuration, in the box's local frame. 80 bytes, mirrored in tests/suite/kernels/box_analytic/.
struct Config {
    vec4 origin_sigma_t;  // xyz camera origin, w sigma_t
    vec4 dir_t_enter;     // xyz unit camera direction, w t_enter
    vec4 omega_t_a;       // xyz unit light travel direction, w t_a
    vec4 half_size_t_b;   // xyz box half extents, w t_b
    uvec4 planes;         // x plane_first, y plane_count (0: the box)
};

// What to do with a configuration. 16 bytes.
struct Query {
    uint config;   // index into configs[]
    uint flags;    // bit 0: write the configuration's pieces to pieces[config]
    float u;       // random number for sample_wvds
    float t_eval;  // where to evaluate wvds_pdf
};

// The answers. 32 bytes.
struct Result {
    float total;       // T_box
    uint count;        // non-empty pieces
    float t_sample;    // sample_wvds(u)
    float pdf_sample;  // its pdf
    float pdf_eval;    // wvds_pdf(t_eval)
    uint non_finite;   // how many of the values computed here are NaN or infinite
    uint pad0;
    uint pad1;
};

// The pieces of a configuration (entries past BOX_MAX_PIECES stay 0). 1280 bytes.
struct PiecesOut {
    float t_start[MAX_CONVEX_PLANES];
    float len[MAX_CONVEX_PLANES];
    float tau0[MAX_CONVEX_PLANES];
    float slope[MAX_CONVEX_PLANES];
    float integral[MAX_CONVEX_PLANES];
};

layout(push_constant) uniform PushBlock {
    uint query_count;
    uint pad0;
    uint pad1;
    uint pad2;
} u_push;

layout(std430, set = 0, binding = 0) readonly buffer ConfigBlock {
    Config configs[];
};
layout(std430, set = 0, binding = 1) readonly buffer QueryBlock {
    Query queries[];
};
layout(std430, set = 0, binding = 2) writeonly buffer ResultBlock {
    Result results[];
};
layout(std430, set = 0, binding = 3) writeonly buffer PiecesBlock {
    PiecesOut pieces[];
};
layout(std430, set = 0, binding = 4) readonly buffer PlaneBlock {
    vec4 planes[];
};

// 1 if x is NaN or infinite, judged by its exponent bits (immune to fast-math folding).
uint non_finite(float x) {
    return ((floatBitsToUint(x) & 0x7f800000u) == 0x7f800000u) ? 1u : 0u;
}

void main() {
    uint index = gl_GlobalInvocationID.x;
    if (index >= u_push.query_count) {
        return;
    }
    Query q = queries[index];
    Config c = configs[q.config];

    BoxPieces p;
    if (c.planes.y == 0u) {
        p = box_pieces(c.origin_sigma_t.xyz, c.dir_t_enter.xyz, c.omega_t_a.xyz,
            c.half_size_t_b.xyz, c.origin_sigma_t.w, c.dir_t_enter.w, c.omega_t_a.w, c.half_size_t_b.w);
    } else {
        // The exit lines of the polyhedron's planes, re-based at t_a (as box_media.glsl).
        vec3 x_a = fma(vec3(c.omega_t_a.w), c.dir_t_enter.xyz, c.origin_sigma_t.xyz);
        exit_lines_clear();
        for (uint i = 0u; i < c.planes.y; ++i) {
            exit_lines_add_plane(planes[c.planes.x + i], x_a, c.dir_t_enter.xyz, c.omega_t_a.xyz);
        }
        p = pieces_from_lines(c.origin_sigma_t.w, c.dir_t_enter.w, c.omega_t_a.w, c.half_size_t_b.w);
    }
    float pdf_sample;
    float t_sample = sample_wvds(p, q.u, pdf_sample);
    float pdf_eval = wvds_pdf(p, q.t_eval);

    // Count non-finite values among everything computed.
    uint bad = non_finite(p.total) + non_finite(t_sample) + non_finite(pdf_sample) + non_finite(pdf_eval);
    for (uint i = 0u; i < BOX_MAX_PIECES; ++i) {
        bad += non_finite(piece_t_start[i]) + non_finite(piece_len[i]) + non_finite(piece_tau0[i])
            + non_finite(piece_slope[i]) + non_finite(piece_integral[i]);
    }

    Result r;
    r.total = p.total;
    r.count = p.count;
    r.t_sample = t_sample;
    r.pdf_sample = pdf_sample;
    r.pdf_eval = pdf_eval;
    r.non_finite = bad;
    r.pad0 = 0u;
    r.pad1 = 0u;
    results[index] = r;

    if ((q.flags & 1u) != 0u) {
        for (uint i = 0u; i < min(BOX_MAX_PIECES, MAX_CONVEX_PLANES); ++i) {
            pieces[q.config].t_start[i] = piece_t_start[i];
            pieces[q.config].len[i] = piece_len[i];
            pieces[q.config].tau0[i] = piece_tau0[i];
            pieces[q.config].slope[i] = piece_slope[i];
            pieces[q.config].integral[i] = piece_integral[i];
        }
    }
}
