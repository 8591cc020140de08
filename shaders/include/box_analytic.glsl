// Analytic single scattering in a homogeneous box or convex polyhedron under collimated
// light (Velinov & Mitchell, Sec. 4-5): the unoccluded transmittance integral T_box over
// a camera segment (the paper's trapezoid segments, Eq. 6-8) and whole-volume distance
// sampling (Eq. 9-11). Pure math: no buffers, no bindings.
//
// Convex media (the paper's Sec. 7, "other medium shapes"). A convex polyhedron
// n_i . x <= d_i (unit n_i, local frame) is left along -omega through plane i at
//     s_i(x) = (d_i - n_i . x) / w_i,   w_i = -n_i . omega > 0,
// and d_m(x) = min_i s_i(x) over the planes the light enters by (w_i > BOX_PARALLEL_EPS;
// the others never stop the ray x - s omega). On the camera ray s_i is again linear in
// t (slope -(n_i . d) / w_i), so everything below holds with more lines: a box is the
// case of its three entry faces (s_a is s_i of the face with n = -sign(omega_a) e_a).
// The pieces of a polyhedron are at most its light-facing planes; the piece table has
// BOX_MAX_PIECES entries, a specialization constant the render plan sets to the most
// light-facing planes of any medium and light (3 without convex media), so boxes keep
// their three-entry tables.
//
// Frame. Everything is in the box's rotated, unscaled local frame (metres): local =
// R^T (x - center), the box is |x_a| <= h_a. The camera ray is o + t d (d unit) and the
// light travels along omega (unit), so light reaches x from the boundary along -omega.
//
// Light distance. The ray x - s omega (s >= 0) leaves slab a (|omega_a| > 0) through the
// face it entered by, x_a - s omega_a = -sign(omega_a) h_a, so
//     s_a(x) = (h_a + sign(omega_a) x_a) / |omega_a|,     d_m(x) = min_a s_a(x).
// A slab the light is parallel to (|omega_a| <= BOX_PARALLEL_EPS) limits nothing for x
// inside it (the slab is closed, as in intersect_slabs). On the camera ray each s_a is
// linear in t with slope B_a = d_a / omega_a, so d_m(t) is concave and piecewise linear,
// the lower envelope of at most 3 lines: at most 2 breakpoints, at most 3 pieces. The
// pieces are exactly the paper's trapezoid segments (the light-ray exit face is constant
// on each) and the breakpoints are the box-section corners projected onto the camera ray.
//
// Optical depth. Camera transmittance starts at t_enter (max(box entry, 0)); on a piece
// the optical depth of camera entry -> x(t) -> boundary towards the light is
//     tau(t) = sigma_t ((t - t_enter) + d_m(t)) = tau0 + sigma_t c (t - t_start),
// with the paper's slope c = 1 + B_k for the piece's exit face k. c is NOT confined to
// [0, 2]: |d_k| <= 1 but |omega_k| may be small (grazing light), so c lies in
// [1 - 1/|omega_k|, 1 + 1/|omega_k|]; c < 0 (optical depth falling along the ray: walking
// towards the lit face faster than away from the camera) and c = 0 (d = -omega, Eq. 7)
// both happen. tau(t) >= 0 always.
//
// Piece integral (Eq. 6 with the factor 1 / (sigma_t c) the printed equation drops):
//     I = int_0^L exp(-tau0 - sigma_t c s) ds = exp(-tau0) L f(x),   x = sigma_t c L,
//     f(x) = (1 - exp(-x)) / x  (f(0) = 1: the paper's linear limit I = L exp(-tau0)).
// For x < 0, exp(-tau0) underflows where f(x) ~ exp(|x|)/|x| overflows, so the integral
// is taken from the piece's low end instead: I = exp(-min(tau0, tau1)) L f(|x|), tau1 the
// depth at the piece end, computed directly (a sum of non-negative terms, no
// cancellation). The parallel cases need no special code: d = -omega makes every slab
// slope -1 (c = 0, Eq. 7) and d = omega makes it +1 (c = 2, Eq. 8), one piece each.
//
// Sampling (Eq. 9-11). A piece is chosen with probability I_k / T_box (CDF over the
// pieces, Eq. 9), the random number is rescaled into it (Eq. 10), and the offset inside
// the piece is a truncated exponential with rate |sigma_t c| sampled from the piece's
// low-depth end: s = -log(1 - (1 - exp(-x)) r) / (sigma_t c) for c >= 0 and the mirror
// image L - s(1 - r) for c < 0, which is the same distribution without exp(|x|)
// overflowing. pdf(t) = exp(-tau(t)) / T_box (Eq. 11), evaluated as
// (I_k / T_box) * (density of t within piece k), which uses only I_k, L and sigma_t c and
// matches the sampler exactly. When T_box == 0 (empty interval, or every piece underflowed)
// nothing can be sampled: sample_wvds returns t_a with pdf 0, and callers must treat the
// contribution as zero (check pdf > 0 before dividing by it).
//
// Precision (float32). Optical depths reach 1e7 and more; exp(-tau) then underflows to 0,
// which is the right answer. Every intermediate stays finite for scene limits (sizes
// <= 1e7 m, sigma_t <= 1e9 /m): lines only exist for |omega_a| > 1e-20, so |B_a| <= 1e20
// and sigma_t c <= 1e29. Accuracy is limited by the inputs, not the formulas: rounding a
// position of magnitude S to f32 moves tau by about 2^-24 sigma_t S / |omega_k|, which
// matters only for optically thick boxes seen from far away (tests/suite/kernels/box_analytic/
// measures everything else to within 1e-5 of an f64 quadrature).
#ifndef NIMBUS_BOX_ANALYTIC_GLSL
#define NIMBUS_BOX_ANALYTIC_GLSL

#include "constants.glsl"
#include "features.glsl"
#include "sampling.glsl"

// Entries of the piece and line tables: the most pieces a segment can have.
layout(constant_id = SC_ID_MAX_PIECES) const uint SC_MAX_PIECES = 3u;
#define BOX_MAX_PIECES SC_MAX_PIECES
// A light component at or below this magnitude makes the light parallel to that slab.
#define BOX_PARALLEL_EPS 1e-20
// The largest float below 1: random numbers are clamped to it so that 1 - r > 0.
#define BOX_ONE_MINUS_EPSILON 0.99999994

// The piece table of the segment last built by pieces_from_lines, and the exit lines it
// was built from. GLSL cannot copy arrays sized by a specialization constant, so the
// tables are invocation-private globals (one of each per invocation) and a BoxPieces
// value is the summary of the table as it was built: building another segment's pieces
// replaces the table (callers that alternate between segments rebuild).
float piece_t_start[BOX_MAX_PIECES];   // along the camera ray (same t as the caller's ray)
float piece_len[BOX_MAX_PIECES];       // piece length along the camera ray
float piece_tau0[BOX_MAX_PIECES];      // optical depth at the start: sigma_t * ((t_start - t_enter) + d_m(t_start))
float piece_slope[BOX_MAX_PIECES];     // sigma_t * c
float piece_integral[BOX_MAX_PIECES];  // Eq. 6 for the piece
// The light-exit lines s_j(u) = A_j + B_j u (u = t - t_a) of a segment: one per face the
// light enters by.
uint line_count;
float line_A[BOX_MAX_PIECES];
float line_B[BOX_MAX_PIECES];

struct BoxPieces {
    uint count;   // non-empty pieces in the table, 0..BOX_MAX_PIECES
    float t_a;    // start of the segment (where an empty table's samples land)
    float total;  // sum of the pieces' integrals: T_box over [t_a, t_b]
};

// Distance to the box boundary towards the light (along -omega) from local point x inside
// the box; 0 if no component of omega exceeds BOX_PARALLEL_EPS (omega not unit).
float box_light_distance(vec3 x_local, vec3 omega_local, vec3 half_size) {
    float d_m = FAR;
    bool limited = false;
    for (int a = 0; a < 3; ++a) {
        float w = omega_local[a];
        if (abs(w) > BOX_PARALLEL_EPS) {
            // Domain: |w| > 1e-20.
            d_m = min(d_m, (half_size[a] + sign(w) * x_local[a]) / abs(w));
            limited = true;
        }
    }
    return limited ? max(d_m, 0.0) : 0.0;
}

// Start an empty set of exit lines.
void exit_lines_clear() {
    line_count = 0u;
}

// Add the line of the face n . x <= d (plane = (n, d), unit n) for the segment starting
// at x_a along d_local, if the light (omega_local) enters by it.
void exit_lines_add_plane(vec4 plane, vec3 x_a, vec3 d_local, vec3 omega_local) {
    float w = -dot(plane.xyz, omega_local);
    if (w > BOX_PARALLEL_EPS && line_count < BOX_MAX_PIECES) {
        // Domain: w > 1e-20; d - n . x >= 0 inside (up to rounding, clamped later).
        line_A[line_count] = (plane.w - dot(plane.xyz, x_a)) / w;
        line_B[line_count] = -dot(plane.xyz, d_local) / w;
        line_count += 1u;
    }
}

// Set the exit lines of the box |x_a| <= half_size for the segment starting at x_a.
void box_exit_lines(vec3 x_a, vec3 d_local, vec3 omega_local, vec3 half_size) {
    exit_lines_clear();
    for (int a = 0; a < 3; ++a) {
        float w = omega_local[a];
        if (abs(w) > BOX_PARALLEL_EPS) {
            // Domain: |w| > 1e-20, so |A| <= 1e28 and |B| <= 1e20 for scene-sized inputs.
            line_A[line_count] = (half_size[a] + sign(w) * x_a[a]) / abs(w);
            line_B[line_count] = d_local[a] / w;
            line_count += 1u;
        }
    }
}

// Build the piece table of T_box over [t_a, t_b] from the segment's exit lines (see the
// header): walk the lines' lower envelope d_m(t) and integrate each piece (Eq. 6).
BoxPieces pieces_from_lines(float sigma_t, float t_enter, float t_a, float t_b) {
    BoxPieces p;
    p.count = 0u;
    p.t_a = t_a;
    p.total = 0.0;
    for (uint i = 0u; i < BOX_MAX_PIECES; ++i) {
        piece_t_start[i] = t_a;
        piece_len[i] = 0.0;
        piece_tau0[i] = 0.0;
        piece_slope[i] = 0.0;
        piece_integral[i] = 0.0;
    }
    // Return no pieces for an empty (or NaN) interval.
    float span = t_b - t_a;
    if (!(span > 0.0)) {
        return p;
    }
    // Handle an omega with no usable component: the light is not attenuated.
    if (line_count == 0u) {
        line_A[0] = 0.0;
        line_B[0] = 0.0;
        line_count = 1u;
    }
    uint n = line_count;

    // Start on the line lowest at u = 0 (on a tie, the one that stays lowest).
    uint k = 0u;
    for (uint j = 1u; j < n; ++j) {
        if (line_A[j] < line_A[k] || (line_A[j] == line_A[k] && line_B[j] < line_B[k])) {
            k = j;
        }
    }

    // Walk the lower envelope; each switch goes to a line with a smaller slope, so there
    // are at most n pieces.
    float delta = max(t_a - t_enter, 0.0);
    float u_s = 0.0;
    for (uint iter = 0u; iter < BOX_MAX_PIECES; ++iter) {
        // Find the earliest u in [u_s, span] where another line drops below line k.
        float A_k = line_A[k];
        float B_k = line_B[k];
        float s_k0 = A_k + B_k * u_s;
        float s_k1 = A_k + B_k * span;
        float u_e = span;
        int next = -1;
        float B_next = 0.0;
        for (uint j = 0u; j < n; ++j) {
            float A_j = line_A[j];
            float B_j = line_B[j];
            if (j == k || !(B_j < B_k)) {
                continue;
            }
            float g1 = s_k1 - (A_j + B_j * span);
            if (g1 > 0.0) {
                float g0 = max((A_j + B_j * u_s) - s_k0, 0.0);
                // Domain: g0 + g1 >= g1 > 0; the fraction lies in [0, 1].
                float u = u_s + (span - u_s) * (g0 / (g0 + g1));
                if (u < u_e || (u == u_e && (next < 0 || B_j < B_next))) {
                    u_e = u;
                    next = int(j);
                    B_next = B_j;
                }
            }
        }

        // Add the piece [u_s, u_e] on line k unless it is empty.
        float len = u_e - u_s;
        if (len > 0.0) {
            uint i = p.count;
            float d_s = max(s_k0, 0.0);
            float d_e = max(A_k + B_k * u_e, 0.0);
            float tau_s = sigma_t * ((delta + u_s) + d_s);
            float tau_e = sigma_t * ((delta + u_e) + d_e);
            float slope = sigma_t * (1.0 + B_k);
            float x = slope * len;
            // Integrate from the end with the smaller depth (Eq. 6, stable for c < 0).
            // Domain: tau_low >= 0 and finite, so exp(-tau_low) lies in [0, 1] (0 for
            // tau_low > 104, the right answer); f(|x|) in (0, 1].
            float tau_low = (x >= 0.0) ? tau_s : tau_e;
            float integral = exp(-tau_low) * len * one_minus_exp_over_x(abs(x));
            piece_t_start[i] = t_a + u_s;
            piece_len[i] = len;
            piece_tau0[i] = tau_s;
            piece_slope[i] = slope;
            piece_integral[i] = integral;
            p.total += integral;
            p.count = i + 1u;
        }
        if (next < 0) {
            break;
        }
        k = uint(next);
        u_s = u_e;
    }
    return p;
}

// The pieces of T_box over the camera segment [t_a, t_b] of a box (see the header).
// o_local, d_local: camera ray in the box's local frame (d unit); omega_local: light travel
// direction (unit); half_size: box half extents; sigma_t: extinction; t_enter <= t_a <= t_b.
BoxPieces box_pieces(vec3 o_local, vec3 d_local, vec3 omega_local, vec3 half_size, float sigma_t, float t_enter, float t_a, float t_b) {
    // Re-base the lines at t_a: it keeps u small and A exact for a camera inside the box.
    vec3 x_a = fma(vec3(t_a), d_local, o_local);
    box_exit_lines(x_a, d_local, omega_local, half_size);
    return pieces_from_lines(sigma_t, t_enter, t_a, t_b);
}

// Distance to the face n . x <= d (plane = (n, d)) towards the light from x, or FAR when
// the light does not enter by it.
float plane_light_distance(vec4 plane, vec3 x_local, vec3 omega_local) {
    float w = -dot(plane.xyz, omega_local);
    // Domain: w > 1e-20.
    return (w > BOX_PARALLEL_EPS) ? (plane.w - dot(plane.xyz, x_local)) / w : FAR;
}

// pdf of t at fraction v in [0, 1] of piece k of the table p summarizes: (I_k / T_box)
// times the truncated exponential density of the piece (Eq. 11). Requires total > 0
// and a non-empty piece.
float box_piece_pdf(BoxPieces p, uint k, float v) {
    float len = piece_len[k];
    float slope = piece_slope[k];
    float x = abs(slope) * len;
    // The density falls away from the piece's low-depth end.
    float w = (slope >= 0.0) ? v : 1.0 - v;
    // Domain: x * w >= 0, so exp gives (0, 1]; len > 0 and f(x) >= min(1, 0.39 / x) > 0
    // for finite x >= 0; total > 0.
    float density = exp(-x * w) / (len * one_minus_exp_over_x(x));
    return (piece_integral[k] / p.total) * density;
}

// Choose piece k (Eq. 9) and the fraction v in [0, 1] along it (Eq. 10 and the
// inverted truncated exponential) for u in [0, 1). Requires total > 0.
void box_sample_piece(BoxPieces p, float u, out uint k, out float v) {
    // Select piece k with probability integral[k] / total (Eq. 9). The loop has a fixed
    // trip count and the piece's values are picked with selects, so the piece table can
    // stay in registers (dynamic indexing sends local arrays to memory on some devices).
    float target = clamp(u, 0.0, BOX_ONE_MINUS_EPSILON) * p.total;
    k = 0u;
    float below = 0.0;
    float cum = 0.0;
    bool found = false;
    float integral_k = piece_integral[0];
    float slope_k = piece_slope[0];
    float len_k = piece_len[0];
    for (uint i = 0u; i < BOX_MAX_PIECES; ++i) {
        float integral_i = piece_integral[i];
        bool positive = i < p.count && integral_i > 0.0 && !found;
        if (positive) {
            k = i;
            below = cum;
            integral_k = integral_i;
            slope_k = piece_slope[i];
            len_k = piece_len[i];
        }
        cum += i < p.count ? integral_i : 0.0;
        found = found || (positive && target < cum);
    }
    // Rescale the random number into the piece (Eq. 10). Domain: integral_k > 0, since
    // total > 0 makes some piece positive and k is the last positive one reached.
    float r = clamp((target - below) / integral_k, 0.0, BOX_ONE_MINUS_EPSILON);
    // Invert the piece's truncated exponential from its low-depth end.
    float x = abs(slope_k) * len_k;
    v = (slope_k >= 0.0)
        ? sample_truncated_exponential(x, r)
        : 1.0 - sample_truncated_exponential(x, min(1.0 - r, BOX_ONE_MINUS_EPSILON));
}

// The start and length of piece k, picked with selects (see box_sample_piece).
vec2 box_piece_span(uint k) {
    float start = piece_t_start[0];
    float len = piece_len[0];
    for (uint i = 1u; i < BOX_MAX_PIECES; ++i) {
        start = (k == i) ? piece_t_start[i] : start;
        len = (k == i) ? piece_len[i] : len;
    }
    return vec2(start, len);
}

// Whole-volume distance sampling: t in [t_a, t_b] with pdf = integrand / total; u in [0,1).
// Returns t_a with pdf 0 when total == 0 (callers must then count no contribution).
float sample_wvds(BoxPieces p, float u, out float pdf) {
    pdf = 0.0;
    if (!(p.total > 0.0)) {
        return p.t_a;
    }
    uint k;
    float v;
    box_sample_piece(p, u, k, v);
    pdf = box_piece_pdf(p, k, v);
    vec2 piece = box_piece_span(k);
    return piece.x + v * piece.y;
}

// Whole-volume distance sampling without the pdf, for estimators that know f / pdf in
// closed form (MCWVDS: f / pdf = total times the constant factors). Requires total > 0.
float sample_wvds_distance(BoxPieces p, float u) {
    uint k;
    float v;
    box_sample_piece(p, u, k, v);
    vec2 piece = box_piece_span(k);
    return piece.x + v * piece.y;
}

// pdf of sample_wvds at t (0 outside [t_a, t_b] or when total == 0).
float wvds_pdf(BoxPieces p, float t) {
    if (!(p.total > 0.0) || !(t >= p.t_a)) {
        return 0.0;
    }
    // Find the last piece starting at or before t.
    uint k = 0u;
    for (uint i = 1u; i < p.count; ++i) {
        if (t >= piece_t_start[i]) {
            k = i;
        }
    }
    float s = t - piece_t_start[k];
    float len = piece_len[k];
    // Accept t up to a rounding slack past the end (t_start + length is itself rounded).
    if (s > len + 1e-6 * max(abs(t), len)) {
        return 0.0;
    }
    // Domain: len > 0 for every counted piece.
    float v = clamp(s / len, 0.0, 1.0);
    return box_piece_pdf(p, k, v);
}

#endif
