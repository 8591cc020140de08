// Single scattering in a homogeneous box medium under collimated light, by the
// estimators of Velinov & Mitchell (Sec. 4-6). Each is a distance sampler times a
// combiner, over N = u_frame.ray_samples samples along one camera segment [t_enter, t_b]:
//
//   estimator  distance sampler                              combiner
//   MCWVDS     whole volume: the unoccluded integrand (Eq. 9-11)  Monte Carlo
//   REDS       along the camera ray: its transmittance            ratio
//   REES       jittered equidistant                               ratio
//   RM         jittered equidistant (ray marching)                Monte Carlo
//   MCDS       along the camera ray: its transmittance            Monte Carlo
//
// Sample k picks light l with probability P(l) = U_l / U, U_l its analytic unoccluded
// radiance along the segment (Eq. 6; Sec. 4, multiple lights), then a distance t in the
// light's gobo interval with the stratified random number r = (k + xi) / N, and returns
// the unoccluded integrand over the joint pdf, F = f(t) / (p(t) P(l)) (RGB). The combiner
// multiplies in the visibility V(t) towards the light (shapes, other media):
//   Monte Carlo  L = (1/N) sum_k F_k V_k
//   ratio        L = U (sum_k F_k V_k) / (sum_k F_k), per channel
// Whole-volume sampling draws t in proportion to f, so F = U_l / P(l) exactly and only V
// is random. Every sample draws two random numbers (light, r), whatever the estimator.
//
// The includer declares `BoxMedium media[]`, `Light lights[]`, `u_frame`, the constants
// SC_ESTIMATOR and SC_HAS_GOBOS, and includes box_analytic.glsl, phase.glsl,
// sampling.glsl, directional.glsl and moments.glsl first.
#ifndef NIMBUS_BOX_ESTIMATORS_GLSL
#define NIMBUS_BOX_ESTIMATORS_GLSL

#include "features.glsl"
#include "counters.glsl"

#define SAMPLER_WHOLE_VOLUME 0u
#define SAMPLER_CAMERA_DISTANCE 1u
#define SAMPLER_EQUIDISTANT 2u

#define COMBINER_MONTE_CARLO 0u
#define COMBINER_RATIO 1u

// The distance sampler of estimator `e` (features.glsl's ESTIMATOR_*).
uint estimator_sampler(uint e) {
    if (e == ESTIMATOR_MCWVDS) {
        return SAMPLER_WHOLE_VOLUME;
    }
    return (e == ESTIMATOR_REES || e == ESTIMATOR_RM) ? SAMPLER_EQUIDISTANT : SAMPLER_CAMERA_DISTANCE;
}

// The combiner of estimator `e`.
uint estimator_combiner(uint e) {
    return (e == ESTIMATOR_REDS || e == ESTIMATOR_REES) ? COMBINER_RATIO : COMBINER_MONTE_CARLO;
}

// A direction in the frame of box medium bm.
vec3 to_local_dir(BoxMedium bm, vec3 v) {
    return vec3(dot(bm.world_to_local[0].xyz, v), dot(bm.world_to_local[1].xyz, v), dot(bm.world_to_local[2].xyz, v));
}

// A point in the frame of box medium bm.
vec3 to_local_point(BoxMedium bm, vec3 x) {
    return to_local_dir(bm, x - bm.center);
}

// The trapezoid pieces of light l along o + t d in medium bm over the interval iv
// (camera transmittance from t_enter).
BoxPieces light_pieces(BoxMedium bm, Light l, vec3 o_local, vec3 d_local, float t_enter, vec2 iv) {
    vec3 omega_local = to_local_dir(bm, l.direction_or_position);
    return medium_pieces(bm, o_local, d_local, omega_local, t_enter, iv.x, iv.y);
}

// Pick a light in proportion to the weights `w` (sum `w_sum` > 0) with u in [0, 1).
uint select_light(float u, float w[MAX_LIGHTS], uint count, float w_sum, out float prob) {
    float target = u * w_sum;
    float acc = 0.0;
    uint chosen = NO_INDEX;
    for (uint l = 0u; l < count; ++l) {
        if (w[l] <= 0.0) {
            continue;
        }
        chosen = l;
        acc += w[l];
        if (target < acc) {
            break;
        }
    }
    // Domain: w_sum > 0, and the chosen light has w > 0.
    prob = w[chosen] / w_sum;
    return chosen;
}

// ---------------------------------------------------------------------------------------
// Distance samplers.

// One distance sample for the chosen light.
struct DistanceSample {
    float t;          // along the camera ray
    vec3 F;           // f(t) / (p(t) P(l)): the unoccluded integrand over the joint pdf
    bool lit;         // inside the light's gobo: only then is the visibility tested
};

// Whole-volume distance sampling (Eq. 9-11): t in proportion to light l's unoccluded
// integrand over its interval, so F = U_l / P(l) in closed form.
DistanceSample sample_whole_volume(BoxPieces pieces, vec3 U_l, float prob, float r) {
    DistanceSample s;
    // Domain: U_l > 0 for a chosen light, so its pieces have total > 0.
    s.t = sample_wvds_distance(pieces, r);
    // Domain: prob > 0 for a chosen light.
    s.F = U_l / prob;
    s.lit = true;
    return s;
}

// Jittered equidistant sampling: t uniform in the interval iv, pdf 1 / span.
float sample_equidistant(vec2 iv, float r, out float pdf) {
    float span = iv.y - iv.x;
    // Domain: span > 0 for a chosen light (its interval is not empty).
    pdf = 1.0 / span;
    return iv.x + r * span;
}

// Distance sampling along the camera ray: t in the interval iv by the camera's
// transmittance alone, pdf sigma_t exp(-sigma_t (t - iv.x)) / (1 - exp(-sigma_t span)),
// through the truncated exponential over the interval's optical depth x = sigma_t span.
float sample_camera_distance(vec2 iv, float sigma_t, float r, out float pdf) {
    float span = iv.y - iv.x;
    float x = sigma_t * span;
    float v = sample_truncated_exponential(x, r);
    // Domain: span > 0 for a chosen light; the density of v over span is that of t.
    pdf = truncated_exponential_pdf(x, v) / span;
    return iv.x + v * span;
}

// The unoccluded single-scattering integrand of light l at t on the camera ray o + t d
// in box medium bm (camera transmittance from t_enter), over the joint pdf `pdf` * `prob`:
//   f(t) = sigma_s p(omega, -d) E T(t_enter -> t) T(t -> boundary towards the light) gobo.
DistanceSample integrand_sample(BoxMedium bm, Light l, vec3 o, vec3 d, vec3 o_local, vec3 d_local,
                                float t_enter, float t, float pdf, float prob) {
    DistanceSample s;
    s.t = t;
    s.F = vec3(0.0);
    s.lit = false;
    // Handle a sample no density could produce (it adds nothing to either sum).
    if (!(pdf > 0.0)) {
        return s;
    }
    vec3 omega = l.direction_or_position;
    float sigma_t = bm.sigma_t;
    // Mask by the gobo at the sampled point.
    float gobo = (SC_HAS_GOBOS && !inside_gobo(l, o + t * d)) ? 0.0 : 1.0;
    // Transmittance from the camera's entry to t, then to the boundary towards the light.
    float d_light = medium_light_distance(bm, o_local + t * d_local, to_local_dir(bm, omega));
    float T = exp(-sigma_t * ((t - t_enter) + d_light));
    vec3 f = bm.sigma_s * hg_phase(dot(omega, -d), bm.g) * l.irradiance * T * gobo;
    // Domain: pdf > 0 (checked) and prob > 0 (a chosen light).
    s.F = f / (pdf * prob);
    s.lit = gobo > 0.0;
    return s;
}

// ---------------------------------------------------------------------------------------
// ME: moment-based estimation (Velinov & Mitchell, Sec. 8, after Peters et al. 2017).
//
// Per light l, the analytic unoccluded radiance U_l times a visibility ratio read from the
// light's moment shadow map (moments.glsl), with no random numbers: the n = ray_samples
// points at the quantiles (k + 1/2) / n of the light's whole-volume pdf each carry 1/n of
// U_l, so the ratio is the plain mean of their visibilities. ME replaces that mean by one
// moment reconstruction: the mean of the points' filtered moments (each from the mip
// level whose texels are as wide as the points' spacing, so together they cover the
// segment's footprint) against the mean of their normalised depths. This is the
// heuristic of prefiltered single scattering: exact where every occluder lies upstream
// of the whole segment (detached shadows, the shadowed fraction is then the moments'
// share at small depth), and wrong where occluders interleave with the segment in depth
// (false shadows and leaks, the paper's Figs. 12-13). Other box media on the way to the
// light multiply in their mean transmittance at the same points.
// Moment-map taps per point of ME along its share of the segment: one per
// ME_TAP_SPACING level-0 texels of it, at most ME_MAX_TAPS.
#define ME_MAX_TAPS 8u
#define ME_TAP_SPACING 2.0

vec3 single_scatter_me(uint m, BoxMedium bm, vec3 o, vec3 d, vec3 o_local, vec3 d_local, float t_enter,
                       vec3 U[MAX_LIGHTS], vec2 interval[MAX_LIGHTS], uint light_count) {
    uint n = max(u_frame.ray_samples, 1u);
    bool other_media = SC_HAS_MEDIA && u_frame.box_media_count > 1u;
    vec3 L = vec3(0.0);
    for (uint l = 0u; l < light_count; ++l) {
        if (!(U[l].r + U[l].g + U[l].b > 0.0)) {
            continue;
        }
        if (!SC_HAS_SHAPES && !other_media) {
            L += U[l];
            aov_parts_add(light_group(l), U[l]);
            continue;
        }
        Light light = lights[l];
        BoxPieces pieces = light_pieces(bm, light, o_local, d_local, t_enter, interval[l]);
        MomentFrame f = moment_frames[l];
        vec4 b = vec4(0.0);
        float z = 0.0;
        float T_other = 0.0;
        // The quantile interval of point k is [t_lo, t_hi): its share of the segment.
        float t_lo = interval[l].x;
        for (uint k = 0u; k < n; ++k) {
            COUNT_STEP();
            float t = sample_wvds_distance(pieces, (float(k) + 0.5) / float(n));
            float t_hi = k + 1u < n ? sample_wvds_distance(pieces, float(k + 1u) / float(n)) : interval[l].y;
            vec3 x = o + t * d;
            if (SC_HAS_SHAPES) {
                // The moments over the point's share of the segment: its interval's
                // footprint on the map, in taps along it at the mip level as wide as
                // one tap's stretch. (One tap at the mip of the points'
                // mean spacing left gaps where the pdf crowds the points, e.g. towards
                // the lit face of a box around the camera: a window's shaft was missed
                // or misplaced, its pixels up to 85 % off.)
                vec2 uv_lo = moment_texel(f, o + t_lo * d);
                vec2 uv_hi = moment_texel(f, o + t_hi * d);
                float len = length(uv_hi - uv_lo);
                uint taps = clamp(uint(ceil(len / ME_TAP_SPACING)), 1u, ME_MAX_TAPS);
                // Domain: taps >= 1.
                uint level = min(uint(floor(log2(max(len / float(taps), 1.0)))), f.levels - 1u);
                vec4 bk = vec4(0.0);
                for (uint j = 0u; j < taps; ++j) {
                    bk += moment_fetch(f, level, mix(uv_lo, uv_hi, (float(j) + 0.5) / float(taps)));
                }
                b += bk / float(taps);
                z += moment_depth(f, dot(x, f.omega));
            }
            t_lo = t_hi;
            if (other_media) {
                T_other += exp(-box_optical_depth_except(x, -light.direction_or_position, 0.0, FAR, m));
            }
        }
        // Domain: n >= 1.
        float V = SC_HAS_SHAPES ? 1.0 - msm_shadow_intensity(b / float(n), z / float(n)) : 1.0;
        if (other_media) {
            V *= T_other / float(n);
        }
        L += U[l] * V;
        aov_parts_add(light_group(l), U[l] * V);
    }
    return L;
}

// ---------------------------------------------------------------------------------------
// The estimator.

// Single-scattered radiance towards o from box medium m along o + t d, t in
// [t_enter, t_b], by the estimator SC_ESTIMATOR with u_frame.ray_samples samples. Excludes
// the transmittance of other media between o and t_enter. With light groups, the parts of
// each group (their sum is the result, to rounding) are added to aov.glsl's g_aov_parts,
// which the caller clears.
vec3 single_scatter_box(uint m, vec3 o, vec3 d, float t_enter, float t_b, inout uint rng) {
    uint sampling = estimator_sampler(SC_ESTIMATOR);
    uint combiner = estimator_combiner(SC_ESTIMATOR);
    BoxMedium bm = media[m];
    vec3 o_local = to_local_point(bm, o);
    vec3 d_local = to_local_dir(bm, d);

    // Compute every light's analytic unoccluded radiance U_l (Eq. 6) over its gobo
    // interval: the light-selection weights w_l and, summed, the ratio estimator's U.
    uint light_count = min(u_frame.light_count, MAX_LIGHTS);
    vec3 U[MAX_LIGHTS];
    float w[MAX_LIGHTS];
    vec2 interval[MAX_LIGHTS];
    vec3 U_total = vec3(0.0);
    float w_sum = 0.0;
    // The piece table holds the pieces of one light at a time (box_analytic.glsl):
    // whole-volume sampling rebuilds it when the sampled light changes.
    uint cached = NO_INDEX;
    BoxPieces pieces;
    for (uint l = 0u; l < light_count; ++l) {
        Light light = lights[l];
        interval[l] = light_interval(light, o, d, t_enter, t_b);
        BoxPieces p = light_pieces(bm, light, o_local, d_local, t_enter, interval[l]);
        pieces = p;
        cached = l;
        float phase = hg_phase(dot(light.direction_or_position, -d), bm.g);
        U[l] = bm.sigma_s * phase * light.irradiance * p.total;
        w[l] = U[l].r + U[l].g + U[l].b;
        U_total += U[l];
        w_sum += w[l];
    }
    if (!(w_sum > 0.0)) {
        return vec3(0.0);
    }
    if (SC_ESTIMATOR == ESTIMATOR_ME) {
        return single_scatter_me(m, bm, o, d, o_local, d_local, t_enter, U, interval, light_count);
    }

    uint n = max(u_frame.ray_samples, 1u);
    // Monte Carlo: sum of F V; ratio: its numerator, and the sum of F below.
    vec3 sum_FV = vec3(0.0);
    vec3 sum_F = vec3(0.0);
    for (uint k = 0u; k < n; ++k) {
        // One estimator sample along the segment, with its shadow ray.
        COUNT_STEP();
        COUNT(CTR_SHADOW_RAYS, 1);
        // Choose light l with probability P(l) = w_l / w_sum.
        float prob;
        uint l = select_light(rng_next(rng), w, light_count, w_sum, prob);
        Light light = lights[l];
        // Stratified random number k of n.
        float r = (float(k) + rng_next(rng)) / float(n);

        // Sample a distance t in the light's interval (a chosen light has U_l > 0, so its
        // interval is not empty).
        DistanceSample s;
        if (sampling == SAMPLER_WHOLE_VOLUME) {
            if (l != cached) {
                pieces = light_pieces(bm, light, o_local, d_local, t_enter, interval[l]);
                cached = l;
            }
            s = sample_whole_volume(pieces, U[l], prob, r);
        } else {
            float pdf;
            float t = sampling == SAMPLER_EQUIDISTANT ? sample_equidistant(interval[l], r, pdf)
                                                     : sample_camera_distance(interval[l], bm.sigma_t, r, pdf);
            s = integrand_sample(bm, light, o, d, o_local, d_local, t_enter, t, pdf, prob);
        }

        // Weight by the visibility towards the light.
        float V = s.lit ? light_visibility(o + s.t * d, light.direction_or_position, m) : 0.0;
        sum_FV += s.F * V;
        aov_parts_add(light_group(l), s.F * V);
        if (combiner == COMBINER_RATIO) {
            sum_F += s.F;
        }
    }
    if (combiner == COMBINER_RATIO) {
        // Ratio estimator: U times occluded / unoccluded estimates; a channel whose
        // unoccluded estimate is zero contributes zero. Domain: sum_F > 0 where divided.
        vec3 ratio = vec3(sum_F.r > 0.0 ? sum_FV.r / sum_F.r : 0.0, sum_F.g > 0.0 ? sum_FV.g / sum_F.g : 0.0,
                          sum_F.b > 0.0 ? sum_FV.b / sum_F.b : 0.0);
        // Each light group's part of the numerator, over the same denominator.
        aov_parts_scale(U_total * vec3(sum_F.r > 0.0 ? 1.0 / sum_F.r : 0.0, sum_F.g > 0.0 ? 1.0 / sum_F.g : 0.0,
                                       sum_F.b > 0.0 ? 1.0 / sum_F.b : 0.0));
        return U_total * ratio;
    }
    // Monte Carlo: the mean. Domain: n >= 1.
    aov_parts_scale(vec3(1.0 / float(n)));
    return sum_FV / float(n);
}

#endif
