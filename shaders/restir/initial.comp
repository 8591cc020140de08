#version 460
// Volumetric ReSTIR pass 1, initial candidates (Algorithm 3): M random walks per pixel by
// regular tracking through the conservative piecewise-constant grid (mip_candidates for
// the camera segment, mip_indirect after), each vertex spawning a scattering candidate
// (NEE, transmittance ray marched on mip_indirect) and, where the medium emits, an
// emission candidate; a camera ray that leaves the media spawns the "direct" candidate
// (what it sees). A segment that meets a shape before a collision ends on it: a surface
// vertex (path_surfaces.glsl), with its own NEE candidate, continuing by cosine sampling. One
// reservoir per pixel by streaming RIS.
//
// Per candidate the target p_hat is F with T* on the walked segments and T~ on the NEE
// segment, so the T* in p_hat and in the walk's pdf p cancel in w = p_hat / p (eq. 24-25);
// both are carried as RGB products: Fhat (target so far) and beta = Fhat / p.
// With SC_CANDIDATE_DELTA (candidate_tracking = "delta", the default) the walks are the
// baseline's decomposition tracking on the exact density instead: a vertex's density is
// sigma_t T, and the target takes the exact T on the walked segments, so w needs no T at
// all and a candidate's weight carries no tracking ratio (sigma_s/sigma* T/T*, the
// heavy tail of regular tracking). The selected path's walked T is computed once per
// dispatch (walked_transmittance), the only T a reservoir needs.
// Writes slot u_push.dst.

#extension GL_GOOGLE_include_directive : require
#include "path_value.glsl"

// The walk's vertices so far (z_i, omega_i), copied into the reservoir when one of its
// candidates is selected.
float walk_z[SC_MAX_BOUNCES + 1u];
uint walk_omega[SC_MAX_BOUNCES + 1u];
// Whether this dispatch selected a candidate (under delta tracking its target still lacks
// the walked T).
bool selected_here = false;

// Stream candidate (w, p_hat) for the path of the first `kp` walk vertices into r (the
// reservoir at `at`), copying the walk's vertices there when it is selected.
void add_candidate(uint at, inout Reservoir r, inout uint rng, float w, float p_hat, uint kp, uint info_bits,
                   vec3 light_point, uint light_dir) {
    // A candidate whose target is not a positive finite number is a null sample (so is
    // one whose weight is not: res_update skips it).
    if (!(p_hat > 0.0) || isinf(p_hat)) {
        return;
    }
    Reservoir c = res_empty();
    c.p_hat = p_hat;
    // Vertex reuse measures x_2 by volume: p_hat and F both carry G = 1 / z_2^2 (p too,
    // so w is unchanged).
    if (SC_REUSE_VERTEX && kp >= 2u) {
        // Domain: z_2 > 0 (a collision strictly after x_1).
        c.p_hat /= walk_z[1] * walk_z[1];
    }
    c.info = kp | INFO_VALID | info_bits;
    c.light_point = light_point;
    c.light_dir = light_dir;
    if (res_update(r, c, w, rng)) {
        selected_here = true;
        for (uint i = 1u; i <= kp; ++i) {
            res_store_vertex(at, i, walk_z[i - 1u], walk_omega[i - 1u]);
        }
    }
}

// The scattering candidate of vertex x by next-event estimation (surface `surface`, else a
// medium vertex reached along w with asymmetry g): one light drawn by power (the paper's),
// or with split NEE (path_lights.glsl) one environment direction drawn from u2 plus every delta
// light, all in one loop over light terms as path_value evaluates them. Fhat and beta are
// the path's target and weight so far (times sigma_s in a medium).
// `emitted` is the vertex's sigma_a Le, which folded emission (SC_FOLD_EMISSION) adds as
// one more term weighted by q (0 elsewhere).
void add_nee_candidate(uint at, inout Reservoir r, inout uint rng, vec3 x, SurfacePoint surface, vec3 w,
                       VertexMedium vm, float u_light, vec2 u2, vec3 Fhat, vec3 beta, uint kp, uint jitter_bits,
                       vec3 emitted) {
    LightSample ls;
    uint dir_code;
    if (SC_NEE_SPLIT) {
        ls = light_sample_none();
        vec3 wi;
        if (SC_HAS_ENV_MAP) {
            float pdf_drawn;
            env_sample_rotated(u2, u_frame.env_rotation, wi, pdf_drawn);
        } else {
            wi = sample_uniform_sphere(u2);
        }
        // The direction as the reservoir stores it and its density, both what path_value
        // evaluates (quantization moves it by < 6e-5 rad).
        dir_code = oct_encode(env_stored_dir(wi, u_frame.env_rotation));
        ls.wi = env_reused_dir(oct_decode(dir_code), u_frame.env_rotation);
        ls.index = LIGHT_ENV;
        ls.pdf = env_sample_pdf(ls.wi, u_frame.env_rotation);
        ls.L = env_radiance_along(ls.wi, u_frame.env_rotation);
        // Domain: pdf > 0 (checked below before use).
        ls.L_over_pdf = ls.pdf > 0.0 ? ls.L / ls.pdf : vec3(0.0);
    } else {
        ls = light_sample(0u, u_frame.env_rotation, x, u_light, u2);
        dir_code = light_is_area(0u, ls.index) ? ls.prim
                   : oct_encode(ls.index == LIGHT_ENV ? env_stored_dir(ls.wi, u_frame.env_rotation) : ls.wi);
    }
    if (!(ls.pdf > 0.0)) {
        return;
    }
    // Split NEE weighs the delta lights by the environment sample's density q.
    float q = SC_NEE_SPLIT ? ls.pdf : 1.0;
    vec3 Fs = vec3(0.0);
    vec3 bs = vec3(0.0);
    uint terms = light_terms();
    for (uint k = 0u; k < terms; ++k) {
        vec3 wi = ls.wi;
        float dist = ls.dist;
        vec3 L = ls.L;
        vec3 L_over_pdf = ls.L_over_pdf;
        if (k > 0u) {
            L_over_pdf = light_term(0u, u_frame.env_rotation, k, x, wi, dist);
            L = q * L_over_pdf;
        }
        vec3 s = vertex_scatter(surface, w, vm, wi);
        if (!any(greaterThan(s * L, vec3(0.0))) || light_blocked(0u, x, wi, dist) || shapes_block(x, wi, dist)) {
            continue;
        }
        float T_nee = nee_transmittance(x, wi, dist) * boxes_transmittance(x, wi, dist);
        Fs += s * L * T_nee;
        bs += s * L_over_pdf * T_nee;
    }
    if (SC_FOLD_EMISSION) {
        // Folded emission: g = ... + q(omega) sigma_a Le, whose integral over omega is the
        // vertex's emission. q is the light sample's density: split NEE's environment
        // sample, or, where the environment is the only light, the one light's sample
        // (the plan folds nowhere else); q > 0 wherever the sampler draws.
        Fs += ls.pdf * emitted;
        bs += emitted;
    }
    add_candidate(at, r, rng, target_scalar(beta * bs), target_scalar(Fhat * Fs), kp, jitter_bits | (ls.index << 8u),
                  ls.point, dir_code);
}

// The optical depth of [0, t) along o + t d through the grid (closed form) and the boxes.
float walked_depth(vec3 o, vec3 d, float t) {
    float tau = grid_optical_depth(o, d, 0.0, t);
    if (SC_HAS_MEDIA) {
        tau += box_optical_depth(o, d, 0.0, t);
    }
    return tau;
}

// The transmittance T (closed form through the trilinear grid, and the boxes) along the
// walked segments of the path stored at `at` from camera ray `cam`: the part of its target
// that delta-tracked candidates leave out.
float walked_transmittance(uint at, Reservoir r, CameraRay cam) {
    uint kp = res_vertices(r);
    float tau = 0.0;
    if (kp == 0u) {
        float t_end;
        camera_end(SET_CURRENT, cam.o, cam.d, t_end);
        tau = walked_depth(cam.o, cam.d, t_end);
    }
    // The segments as path_value rebuilds them: x_i = x_{i-1} + z_i omega_{i-1}, a
    // negative z a surface vertex where the ray meets a shape.
    vec3 x = cam.o;
    vec3 w = cam.d;
    for (uint i = 1u; i <= kp; ++i) {
        float z = res_z(at, i);
        if (i >= 2u) {
            w = oct_decode(res_omega(at, i - 1u));
        }
        if (SC_HAS_SHAPES && z < 0.0) {
            SurfacePoint surface = surface_along(x, w, FAR);
            tau += walked_depth(x, w, surface.t);
            x = surface.x;
            continue;
        }
        tau += walked_depth(x, w, z);
        x += z * w;
    }
    return exp(-min(tau, MARCH_MAX_TAU));
}

void restir_main();

// The stage, then its counters into the stats buffer.
void main() {
    restir_load();
    restir_main();
    film_flush_counters();
}

void restir_main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (!film_contains(pixel)) {
        return;
    }
    // One sample: the pixel's frame (initial: its first dispatch of candidates).
    if (u_push.aux == 0u) {
        COUNT(CTR_SAMPLES, 1);
    }
    uint at = res_at(u_push.dst, pixel);
    // This dispatch draws candidates m0 .. m1 (all M in one where the device allows),
    // from its own random stream, streaming into the reservoir the earlier ones left.
    uint m0 = u_push.aux;
    uint m1 = min(m0 + u_restir.candidates_per_dispatch, u_restir.candidates);
    uint rng = rng_init(pixel, u_push.frame, m0, u_frame.seed);
    Reservoir r = m0 == 0u ? res_empty() : res_load(at);
    for (uint m = m0; m < m1; ++m) {
        // Each walk starts at its own sub-pixel position, which its paths keep.
        uint code = SC_PIXEL_JITTER ? jitter_code_sample(rng) : 0u;
        uint jitter_bits = code << 16u;
        CameraRay cam = camera_ray(pixel, code, SET_CURRENT);
        vec3 x = cam.o;
        vec3 w = cam.d;
        vec3 Fhat = vec3(1.0);
        vec3 beta = vec3(1.0);
        for (uint i = 1u; i <= SC_MAX_BOUNCES; ++i) {
            // Where the segment ends without a collision: an emitting sphere, a shape or far
            // away.
            uint sphere;
            SurfacePoint surface;
            float t_end = opaque_end(0u, x, w, sphere, surface);
            uint level = i == 1u ? LEVEL_PRIMARY : LEVEL_INDIRECT;
            float sigma_star_unused;
            bool direct_here = SC_DIRECT_EACH_WALK && i == 1u;
            float sigma_star = 0.0;
            float tau = 0.0;
            float tau_all = 0.0;
            float z;
            if (SC_CANDIDATE_DELTA) {
                // The baseline's decomposition tracking on the exact density: the collision's
                // density is sigma_t(z) T(0, z), whose T is the target's own, so neither
                // Fhat nor beta carries it (walked_transmittance adds it to the selected
                // path's target). The plan never sets SC_DIRECT_EACH_WALK with it.
                z = grid_sample_collision(x, w, 0.0, t_end, rng);
            } else {
                // Regular tracking: an exponential optical depth through sigma_t*. The
                // camera segment's walk goes on to the segment's end where the direct
                // candidate needs its whole tau* (one walk, not two).
                float tau_target = sample_exponential(rng_next(rng), 1.0);
                z = pc_track_through(level, x, w, t_end, tau_target, direct_here, sigma_star, tau, tau_all);
            }
            if (direct_here) {
                // The direct candidate of the camera segment with probability 1 (the path
                // is fixed by the walk's sub-pixel position): target L T*, T* of the whole
                // segment through the piecewise-constant grid and the boxes, so w = p_hat.
                // The paper adds it only when the walk escapes (p = T*), a rare event
                // with weight L T / T* behind dense media.
                if (SC_HAS_MEDIA) {
                    tau_all += box_optical_depth(x, w, 0.0, t_end);
                }
                float t_seen;
                vec3 L = camera_end(SET_CURRENT, x, w, t_seen);
                // T* floored as the marches' T~ is (e^-64, a normal float), so p_hat > 0
                // wherever L > 0: the target must cover every path F does not vanish on.
                // Domain: tau_all >= 0.
                float p_hat = target_scalar(L * exp(-min(tau_all, MARCH_MAX_TAU)));
                add_candidate(at, r, rng, p_hat, p_hat, 0u,
                              jitter_bits | (sphere == NO_INDEX ? (LIGHT_ENV << 8u) : (sphere << 8u)), vec3(0.0), 0u);
            }
            // The box media: independent first collisions at their sigma_t; the earliest of
            // all wins (the media are disjoint, so the walk tracks their summed majorant).
            uint box = NO_INDEX;
            if (SC_HAS_MEDIA) {
                float z_box = min(z, t_end);
                uint count = u_frame.box_media_count;
                for (uint m = 0u; m < count; ++m) {
                    vec2 span = box_medium_span(m, x, w);
                    float a = max(span.x, 0.0);
                    float b = min(span.y, z_box);
                    float sigma_m = media[m].sigma_t;
                    if (b <= a || !(sigma_m > 0.0)) {
                        continue;
                    }
                    // Domain: sigma_m > 0.
                    float t = a + sample_exponential(rng_next(rng), sigma_m);
                    if (t < b) {
                        z_box = t;
                        box = m;
                    }
                }
                if (box != NO_INDEX) {
                    // The grid's tau* up to the box's collision.
                    z = z_box;
                    sigma_star = media[box].sigma_t;
                    if (!SC_CANDIDATE_DELTA) {
                        pc_track(level, x, w, z, FAR, sigma_star_unused, tau);
                    }
                }
                // tau* of the whole walked span: the grid's and the boxes' (regular tracking;
                // delta tracking leaves the walked T to walked_transmittance).
                if (!SC_CANDIDATE_DELTA) {
                    tau += box_optical_depth(x, w, 0.0, min(z, t_end));
                }
            }
            if (z >= FAR) {
                // Reached the segment's end with probability T* = exp(-tau) (delta tracking:
                // T, left out of both). Domain: tau >= 0.
                float T_star = SC_CANDIDATE_DELTA ? 1.0 : exp(-tau);
                if (i == 1u && !SC_DIRECT_EACH_WALK) {
                    // The direct candidate of the camera segment (p = T*, p_hat = L T*, so
                    // w = L); later segments reach lights through NEE only.
                    float t_seen;
                    vec3 L = camera_end(SET_CURRENT, x, w, t_seen);
                    add_candidate(at, r, rng, target_scalar(L), target_scalar(L * T_star), 0u,
                                  jitter_bits | (sphere == NO_INDEX ? (LIGHT_ENV << 8u) : (sphere << 8u)), vec3(0.0), 0u);
                }
                if (surface.shape == NO_INDEX) {
                    break;
                }
                // A surface vertex: p *= T*, Fhat *= T* (beta is unchanged).
                walk_z[i - 1u] = -surface.t;
                Fhat *= T_star;
                if (!any(greaterThan(surface.albedo, vec3(0.0)))) {
                    break;
                }
                x = surface.x;
                // Scattering candidate by next-event estimation: albedo cos / pi.
                float u_light = rng_next(rng);
                vec2 u2 = vec2(rng_next(rng), rng_next(rng));
                add_nee_candidate(at, r, rng, x, surface, w, vertex_medium_none(), u_light, u2, Fhat, beta, i,
                                  jitter_bits, vec3(0.0));
                if (i == SC_MAX_BOUNCES) {
                    break;
                }
                // Next direction by cosine sampling, stored quantized (as for the medium).
                vec3 w_sampled = sample_cosine_hemisphere(surface.n, vec2(rng_next(rng), rng_next(rng)));
                uint omega = oct_encode(w_sampled);
                vec3 w_next = oct_decode(omega);
                float cos_sampled = dot(surface.n, w_sampled);
                float cos_next = dot(surface.n, w_next);
                // Domain: a cosine-sampled direction has cos > 0; quantization may tip a
                // grazing one under the surface, which ends the walk.
                if (!(cos_sampled > 0.0 && cos_next > 0.0)) {
                    break;
                }
                walk_omega[i - 1u] = omega;
                Fhat *= surface_reflect(surface, w_next);
                // p *= cos_sampled / pi.
                beta *= surface.albedo * (cos_next / cos_sampled);
                w = w_next;
                if (i >= 3u && !russian_roulette(beta, rng)) {
                    break;
                }
                continue;
            }
            x += z * w;
            walk_z[i - 1u] = z;
            // The media there, as path_value finds them: the grid's sigma_s and g, and the
            // box's holding x (overlapping media add).
            float sigma_t_grid = grid_sigma_t(x);
            vec3 albedo = grid_albedo(x);
            VertexMedium vm = vertex_medium(x, sigma_t_grid, albedo);
            if (!(sigma_t_grid + vm.sigma_t_box > 0.0)) {
                break;
            }
            // The density of a collision at z among all media is the summed majorant there:
            // the grid's sigma_t* (pc_track's where the grid won, looked up where a box did)
            // plus the box's sigma_t; under delta tracking the grid's sigma_t itself.
            float sigma_star_total = SC_CANDIDATE_DELTA ? sigma_t_grid + vm.sigma_t_box
                                     : box != NO_INDEX  ? vm.sigma_t_box + pc_sigma_star_at(level, x)
                                                        : sigma_star + vm.sigma_t_box;
            // p *= sigma_t* T*, Fhat *= T* (delta tracking: T in neither). Domain:
            // sigma_star_total > 0 at a collision.
            if (!SC_CANDIDATE_DELTA) {
                Fhat *= exp(-tau);
            }
            beta /= sigma_star_total;

            vec3 emitted = vec3(0.0);
            // (SC_CAMERA_EMISSION: the camera segment's emission is shade.comp's.)
            if (SC_HAS_EMISSION && sigma_t_grid > 0.0 && !(SC_CAMERA_EMISSION && i == 1u)) {
                // The grid's sigma_a Le at x_i (eq. 25, emission case): a candidate of its
                // own, or folded into the NEE candidate below.
                emitted = (vec3(1.0) - albedo) * sigma_t_grid * grid_emission(x);
                if (!SC_FOLD_EMISSION) {
                    add_candidate(at, r, rng, target_scalar(beta * emitted), target_scalar(Fhat * emitted), i,
                                  jitter_bits | INFO_EMISSION, vec3(0.0), 0u);
                }
            }

            // Scattering candidate by next-event estimation.
            float u_light = rng_next(rng);
            vec2 u2 = vec2(rng_next(rng), rng_next(rng));
            add_nee_candidate(at, r, rng, x, surface_none(x, w), w, vm, u_light, u2, Fhat, beta, i, jitter_bits,
                              emitted);
            if (i == SC_MAX_BOUNCES) {
                break;
            }
            // Next direction by the phase functions, stored quantized (the walk continues
            // along the stored direction, so the path is exactly what was evaluated). Where
            // media overlap, a box's phase function is drawn with probability q_box (which
            // box, in proportion to its sigma_s), and the direction's density is the
            // mixture (random numbers more only there).
            float q_box = medium_box_share(vm);
            float g_pick = vm.g_grid;
            if (q_box >= 1.0 || (q_box > 0.0 && rng_next(rng) < q_box)) {
                g_pick = medium_pick_box_g(vm, rng);
            }
            vec3 w_sampled = sample_hg(w, g_pick, vec2(rng_next(rng), rng_next(rng)));
            uint omega = oct_encode(w_sampled);
            vec3 w_next = oct_decode(omega);
            float c_sampled = dot(w, w_sampled);
            float pdf_sampled = medium_phase_pdf(vm, q_box, c_sampled);
            vec3 s_next = medium_scatter(vm, dot(w, w_next));
            walk_omega[i - 1u] = omega;
            Fhat *= s_next;
            // p *= pdf(w_sampled). Domain: pdf_sampled > 0 (HG is positive for |g| < 1).
            beta *= s_next / pdf_sampled;
            w = w_next;
            // Russian roulette after the third bounce, by beta = Fhat / p (p *= q).
            if (i >= 3u && !russian_roulette(beta, rng)) {
                break;
            }
        }
    }
    if (SC_CANDIDATE_DELTA && selected_here && res_valid(r)) {
        // The walked segments' transmittance of the selected path, left out of every
        // candidate's target (it cancels in w = p_hat / p).
        r.p_hat *= walked_transmittance(at, r, camera_ray(pixel, res_jitter(r), SET_CURRENT));
    }
    r.M = float(m1);
    if (!res_valid(r)) {
        r.w_sum = 0.0;
    }
    res_store_header(at, r);
}
