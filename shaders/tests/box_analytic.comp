#version 460
// Test harness for box_analytic.glsl (tests/box_analytic.rs). One invocation per query;
// a query names a configuration (camera ray, light direction, box, sigma_t, interval),
// a random number for sample_wvds and a distance at which to evaluate wvds_pdf.

#extension GL_GOOGLE_include_directive : require

#include "box_analytic.glsl"
// Included twice on purpose: the include guard must make the second one a no-op.
#include "box_analytic.glsl"

layout(local_size_x = 64) in;

// A configuration, in the box's local frame. 64 bytes, mirrored in tests/box_analytic.rs.
struct Config {
    vec4 origin_sigma_t;  // xyz camera origin, w sigma_t
    vec4 dir_t_enter;     // xyz unit camera direction, w t_enter
    vec4 omega_t_a;       // xyz unit light travel direction, w t_a
    vec4 half_size_t_b;   // xyz box half extents, w t_b
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

// The pieces of a configuration, one per vec4 component (w unused). 80 bytes.
struct PiecesOut {
    vec4 t_start;
    vec4 len;
    vec4 tau0;
    vec4 slope;
    vec4 integral;
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

    BoxPieces p = box_pieces(c.origin_sigma_t.xyz, c.dir_t_enter.xyz, c.omega_t_a.xyz,
        c.half_size_t_b.xyz, c.origin_sigma_t.w, c.dir_t_enter.w, c.omega_t_a.w, c.half_size_t_b.w);
    float pdf_sample;
    float t_sample = sample_wvds(p, q.u, pdf_sample);
    float pdf_eval = wvds_pdf(p, q.t_eval);

    // Count non-finite values among everything computed.
    uint bad = non_finite(p.total) + non_finite(t_sample) + non_finite(pdf_sample) + non_finite(pdf_eval);
    for (int i = 0; i < BOX_MAX_PIECES; ++i) {
        bad += non_finite(p.t_start[i]) + non_finite(p.len[i]) + non_finite(p.tau0[i])
            + non_finite(p.slope[i]) + non_finite(p.integral[i]);
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
        PiecesOut out_p;
        out_p.t_start = vec4(p.t_start[0], p.t_start[1], p.t_start[2], 0.0);
        out_p.len = vec4(p.len[0], p.len[1], p.len[2], 0.0);
        out_p.tau0 = vec4(p.tau0[0], p.tau0[1], p.tau0[2], 0.0);
        out_p.slope = vec4(p.slope[0], p.slope[1], p.slope[2], 0.0);
        out_p.integral = vec4(p.integral[0], p.integral[1], p.integral[2], 0.0);
        pieces[q.config] = out_p;
    }
}
