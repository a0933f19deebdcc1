// The resampling pass of ReSTIR across gradient iterations ("Amortizing Samples in Physics-Based
// Inverse Rendering using ReSTIR", Wang, Wyman, Wu, Zhao, SIGGRAPH Asia 2023, Sec. 4, Alg. 4
// lines 7-10; docs/restir.md), one sample slot at a time: fresh candidates by streaming RIS (the
// paper's Alg. 1), then one combine with reservoirs of the previous iteration (the slot's own and
// nearby slots') under defensive pairwise MIS with confidences (shared/reservoir.h). Run by its
// own kernel (kernels/restir.cl), or fused into the kernel whose paths read the reservoirs, at
// each path's first hit (restir_resample_at: its camera ray traced once). RESTIR builds only.
#ifndef TANDEM_KERNELS_PATH_RESAMPLE_H
#define TANDEM_KERNELS_PATH_RESAMPLE_H

#include "path/interaction.h"
#include "path/restir.h"

/// The weight of the channel-mixing term of the target (restir_target).
#define RESTIR_CHANNEL_MIX 0.1f

/// Dimensions of the pass's random stream per fresh candidate m: RESTIR_CANDIDATE_DIMS m + 0..3
/// its light choice, alias coin and point on the light (unused for m = 0, the path's own NEE
/// sample), + 4 its reservoir coin; the rest of the eight unused. One vertex_random each.
#define RESTIR_CANDIDATE_DIMS RNG_DIMS_PER_BOUNCE

/// Whether parameter element `param` is differentiated (bit param % 32 of active[param / 32]).
TANDEM_INLINE int restir_differentiated(__global const uint* active, uint param) {
    return param != NO_PARAM && ((active[param >> 5] >> (param & 31u)) & 1u) != 0u;
}

/// The target of light sample (light, u1, u2) at the shaded point `it` under `params`, without
/// visibility: lum(f ⊙ Le') + RESTIR_CHANNEL_MIX lum(f) lum(Le'), times G w_L, with w_L the
/// weight of the reservoir's share of direct light at `it` (restir_light_weight) and Le' = Le,
/// plus the pass's radiance floor where the light's radiance is differentiated (`active`). The
/// first term is the integrand's luminance (path/restir.h). The channel-mixing term keeps the
/// target positive where a light and an albedo share no colour channel (d h_c / d albedo_c is
/// Le_c, whatever albedo_c is), and the floor where a differentiated radiance is 0 (d h / d Le is
/// f G). A light whose radiance is not differentiated gets no floor: where its Le is 0 (a spot
/// seen outside its cone) every derivative of the term is 0 too, and a floor there would only
/// spend the reservoirs on samples that contribute nothing. The target is positive wherever
/// NEE's term or a derivative of it is not 0. Sets *ls to the decoded sample (for its shadow
/// ray); a non-finite target counts in *dropped and is 0.
TANDEM_INLINE float restir_target(const SceneRefs* s, __global const float* params,
                                  const Interaction* it, uint light, float u1, float u2,
                                  const RestirParams* rs, __global const uint* active,
                                  LightSample* ls, uint* dropped) {
    *ls = nee_decode_light(s, params, it->origin, light, u1, u2);
    const NeeEval ev = nee_eval(it, ls);
    if (!(ls->pdf > 0.0f && ls->G > 0.0f && max_component(ev.f) > 0.0f)) return 0.0f;
    const float lift = restir_differentiated(active, ls->Le_param) ? rs->radiance_floor : 0.0f;
    const float3 Le = ls->Le + make_float3(lift, lift, lift);
    const float p = (luminance(ev.f * Le) + RESTIR_CHANNEL_MIX * luminance(ev.f) * luminance(Le)) *
                    (restir_light_weight(rs->direct, it, ls, &ev) * ls->G);
    if (!isfinite(p)) {
        ++*dropped;
        return 0.0f;
    }
    return fmax(p, 0.0f);
}

/// The target as above times visibility when the pass traces it (a ray only where it is > 0).
TANDEM_INLINE float restir_target_visible(const SceneRefs* s, __global const float* params,
                                          const Interaction* it, uint light, float u1, float u2,
                                          const RestirParams* rs, __global const uint* active,
                                          uint* dropped) {
    LightSample ls;
    const float p = restir_target(s, params, it, light, u1, u2, rs, active, &ls, dropped);
    return p > 0.0f && rs->visibility && !nee_unoccluded(s, it->origin, &ls) ? 0.0f : p;
}

/// The shading point a reservoir stores, seen from the camera and shaded under `params`, in the
/// scene `s` of that state (its shading normals: restir_previous_scene). Returns 0 where no light
/// sample could be evaluated there.
TANDEM_INLINE int restir_stored_point(const SceneRefs* s, __global const float* params,
                                      const Reservoir* r, Interaction* it) {
    float3 x, n_front;
    primitive_point(s, r->prim, r->b1, r->b2, &x, &n_front);
#if SHAPE_GRAD
    // On a moving mesh the point is where it was under `params`, at its barycentrics: its
    // triangle's corners are parameters there (not a light: check_shape_gradients).
    const uint4 pp = s->prim_params[r->prim];
    if (pp.x != NO_PARAM) {
        const float3 p0 = make_float3(params[pp.x], params[pp.x + 1u], params[pp.x + 2u]);
        const float3 p1 = make_float3(params[pp.y], params[pp.y + 1u], params[pp.y + 2u]);
        const float3 p2 = make_float3(params[pp.z], params[pp.z + 1u], params[pp.z + 2u]);
        x = p0 * (1.0f - r->b1 - r->b2) + p1 * r->b1 + p2 * r->b2;
        const float3 n = vcross(p1 - p0, p2 - p0);
        const float len = vlength(n);
        if (!(len > 0.0f)) return 0;
        // the side the triangle's own normal faces (its winding and flip_normals) as it is now
        n_front = vdot(n, n_front) >= 0.0f ? n * (1.0f / len) : n * (-1.0f / len);
    }
#endif
    const float3 eye = xyz(s->cam->origin);
    Hit hit;
    hit.t = vlength(x - eye);
    hit.prim = r->prim;
    hit.u = r->b1;
    hit.v = r->b2;
    interaction_at(s, make_ray(eye, vnormalize(x - eye), 0.0f, hit.t), hit, it);
    it->x = x;
    it->n_front = n_front;
    return interaction_shade(s, params, it) && nee_applies(it);
}

/// Whether the slot whose primary vertex is `it` needs a reservoir: where its material has a
/// differentiated parameter, judged by the parameter's first element (optimize and grad
/// differentiate whole parameters; a slot judged wrongly by a partial range still takes NEE's
/// own, unbiased, sample).
/// With every light's radiance left alone, the primary vertex's NEE term has no derivative
/// anywhere else: the deeper vertices' derivatives read only the radiance after it (PRB's L_rem),
/// so its estimator does not matter there, and such a slot takes NEE's own sample.
TANDEM_INLINE int restir_serves(const SceneRefs* s, const Interaction* it,
                                __global const uint* active) {
    const Material* m = &it->mat;
    int served = restir_differentiated(active, m->reflectance_param) ||
                 restir_differentiated(active, m->specular_param) ||
                 restir_differentiated(active, m->alpha_param);
#if HAS_TEXTURES
    served = served || (m->texture != NO_TEXTURE &&
                        restir_differentiated(active, s->textures[m->texture].param));
#endif
#if SHAPE_GRAD
    // a moving mesh: its light samples' terms carry the interior term of shape gradients
    served = served || restir_differentiated(active, s->prim_params[it->hit.prim].x);
#else
    (void)s;
#endif
    return served;
}

/// What a resampling pass reads besides the scene: the parameters theta_n and theta_{n-1} (the
/// previous reservoirs' domain), RestirParams, the previous iteration's reservoirs (all empty on
/// the first), the bits of the differentiated elements (restir_serves) and whether every slot is
/// served (a light's radiance is differentiated).
typedef struct PathResample {
    __global const float* params;
    __global const float* params_old;
    /// the geometry under params_old, where shapes move (DeviceScene::geometry_at): its tree and
    /// its shading normals
    __global const float4* nodes_old;
    __global const BvhTriangle* tris_old;
    __global const TriangleNormals* normals_old;
    const RestirParams* rs;
    __global const Reservoir* prev;
    __global const uint* active;
    uint serve_all;
} PathResample;

/// The scene `s` as it was under the pass's params_old, into *prev: where shapes move, the tree
/// that the neighbours' shadow rays trace and the shading normals of their points are those of
/// the previous vertex positions (their points themselves: restir_stored_point). Returns the
/// scene to evaluate the previous reservoirs' domains in: *prev, or s itself where nothing moves.
TANDEM_INLINE const SceneRefs* restir_previous_scene(const SceneRefs* s, const PathResample* pass,
                                                     SceneRefs* prev) {
#if SHAPE_GRAD
    *prev = *s;
    prev->nodes = pass->nodes_old;
    prev->tris = pass->tris_old;
    prev->normals = pass->normals_old;
    return prev;
#else
    (void)pass;
    (void)prev;
    return s;
#endif
}

/// What the combine keeps of an accepted neighbour.
typedef struct Neighbour {
    uint light;
    float u1, u2, W;
    float M;    ///< its confidence, capped
    float P_ci; ///< the current target at this slot's point for its sample
    float P_ii; ///< its own target at its point for its sample (previous parameters)
    float P_ic; ///< its own target at its point for the canonical sample
} Neighbour;

/// One slot at its first hit: the reservoir of sample `sample` of pixel (px, py), whose path
/// (random numbers `rng`, path_rng of the paths' seed rp.seed) left the camera along `ray` and
/// found `hit` (trace_closest). Adds non-finite targets and weights (set to zero) to *dropped.
TANDEM_INLINE Reservoir restir_resample_at(const SceneRefs* s, const PathResample* pass, uint px,
                                           uint py, uint sample, PathRng rng, Ray ray, Hit hit,
                                           uint* dropped) {
    __global const float* params = pass->params;
    __global const float* params_old = pass->params_old;
    const RestirParams* rs = pass->rs;
    __global const Reservoir* prev = pass->prev;
    __global const uint* active = pass->active;
    const RenderParams* rp = s->rp;
    const DeviceCamera* cam = s->cam;
    const uint pixel = py * cam->width + px;
    Reservoir out = reservoir_empty();

    // 1. The primary hit, as the path finds it (same camera ray, same parameters).
    if (rp->max_depth < 2u) return out; // the path takes no NEE sample
    if (hit.prim == HIT_NONE) return out;
    Interaction it;
    interaction_at(s, ray, hit, &it);
    if (!interaction_shade(s, params, &it) || !nee_applies(&it)) return out;
    if (!pass->serve_all && !restir_serves(s, &it, active)) return out; // NEE's own sample
    out.prim = hit.prim;
    out.b1 = hit.u;
    out.b2 = hit.v;

    // 2. Canonical streaming RIS over fresh candidates, ranked by the unshadowed target.
    // Candidate 0 is the path's own NEE sample; the others and the coins use the pass's stream,
    // RESTIR_CANDIDATE_DIMS dimensions per candidate, hashed at once where the device has lanes
    // (vertex_random: a candidate's target costs about what its five scalar hashes would).
    const uint M_cand = rs->candidates;
    const uint dim = path_dim(0u);
    const PathRng pass_rng = path_rng(rs->seed, pixel, sample);
    float w_sum = 0.0f, p_pick = 0.0f;
    uint c_light = RESERVOIR_NO_LIGHT;
    float c_u1 = 0.0f, c_u2 = 0.0f;
    LightSample c_ls = nee_no_sample();
    for (uint m = 0; m < M_cand; ++m) {
        const VertexRandom vr = vertex_random(pass_rng, RESTIR_CANDIDATE_DIMS * m);
        float u[4];
        if (m == 0u) {
            u[0] = path_rand(rng, dim + DIM_LIGHT_CHOICE);
            u[1] = path_rand(rng, dim + DIM_ALIAS);
            u[2] = path_rand(rng, dim + DIM_LIGHT_POINT);
            u[3] = path_rand(rng, dim + DIM_LIGHT_POINT + 1u);
        } else {
            u[0] = vertex_rand(vr, 0u);
            u[1] = vertex_rand(vr, 1u);
            u[2] = vertex_rand(vr, 2u);
            u[3] = vertex_rand(vr, 3u);
        }
        const uint light = nee_choose_light(s, u[0], u[1]);
        LightSample ls;
        const float p = restir_target(s, params, &it, light, u[2], u[3], rs, active, &ls, dropped);
        const float w = p > 0.0f ? p / ls.pdf_light : 0.0f;
        if (wrs_update(&w_sum, w, vertex_rand(vr, 4u))) {
            c_light = light;
            c_u1 = u[2];
            c_u2 = u[3];
            c_ls = ls;
            p_pick = p;
        }
    }
    const float W_c = p_pick > 0.0f ? w_sum / ((float)M_cand * p_pick) : 0.0f;
    // its target with visibility: one shadow ray
    const float P_c =
        p_pick > 0.0f && rs->visibility && !nee_unoccluded(s, it.origin, &c_ls) ? 0.0f : p_pick;

    // 3. Neighbours from the previous iteration: the slot's own, then spatial picks in a disk.
    // They are accepted on their shading points only, never on their samples: a reservoir left
    // without a sample still counts as a domain (its confidence, and its target for the canonical
    // sample), with resampling weight 0. Dropping it would select neighbours by their own random
    // numbers and inflate the survivors' contribution weights (biased:
    // tests/kernels/shared/test_reservoir.cpp).
    uint slots[RESTIR_MAX_NEIGHBOURS];
    uint candidates = 0u;
    const uint slot = pixel * rs->spp + sample;
    if (rs->temporal) slots[candidates++] = slot;
    const uint coin_dim = RESTIR_CANDIDATE_DIMS * M_cand; // after the candidates' dimensions
    for (uint j = 0; j < rs->spatial && candidates < RESTIR_MAX_NEIGHBOURS; ++j) {
        const float3 d =
            sample_concentric_disk(rng_uniform(rs->seed, pixel, sample, coin_dim + 3u * j),
                                   rng_uniform(rs->seed, pixel, sample, coin_dim + 3u * j + 1u));
        const int qx = clamp((int)px + (int)round(d.x * (float)rs->radius), 0, (int)cam->width - 1);
        const int qy =
            clamp((int)py + (int)round(d.y * (float)rs->radius), 0, (int)cam->height - 1);
        const uint qs = min(
            (uint)(rng_uniform(rs->seed, pixel, sample, coin_dim + 3u * j + 2u) * (float)rs->spp),
            rs->spp - 1u);
        const uint q = ((uint)qy * cam->width + (uint)qx) * rs->spp + qs;
        int duplicate = 0;
        for (uint i = 0; i < candidates; ++i)
            duplicate |= slots[i] == q;
        if (!duplicate) slots[candidates++] = q;
    }
    SceneRefs prev_scene;
    const SceneRefs* s_old = restir_previous_scene(s, pass, &prev_scene);
    const float3 eye = xyz(cam->origin);
    const float depth = vlength(it.x - eye);
    Neighbour nb[RESTIR_MAX_NEIGHBOURS];
    uint k = 0u;
    float M_sum = 1.0f; // the canonical reservoir's confidence, M_c = 1
    for (uint i = 0; i < candidates; ++i) {
        const Reservoir r = prev[slots[i]];
        if (r.prim == HIT_NONE) continue; // no shading point: no light sample was ever drawn
        Interaction it_i;
        if (!restir_stored_point(s_old, params_old, &r, &it_i)) continue;
        if (vdot(it_i.n_out, it.n_out) < rs->normal_cos) continue;
        if (fabs(vlength(it_i.x - eye) - depth) > rs->depth_rel * depth) continue;
        Neighbour n;
        n.light = r.light;
        n.u1 = r.u1;
        n.u2 = r.u2;
        n.W = r.W;
        n.M = fmin(r.M, rs->m_cap);
        n.P_ci = 0.0f;
        n.P_ii = 0.0f;
        if (!reservoir_is_empty(&r)) {
            n.P_ci =
                restir_target_visible(s, params, &it, r.light, r.u1, r.u2, rs, active, dropped);
            // W_i > 0 implies its sample was visible from its point: no ray
            LightSample unused;
            n.P_ii = restir_target(s_old, params_old, &it_i, r.light, r.u1, r.u2, rs, active,
                                   &unused, dropped);
        }
        n.P_ic = P_c > 0.0f ? restir_target_visible(s_old, params_old, &it_i, c_light, c_u1, c_u2,
                                                    rs, active, dropped)
                            : 0.0f;
        M_sum += n.M;
        nb[k++] = n;
    }

    // 4.-5. Defensive pairwise MIS weights, then one pick over (canonical, neighbours) in order.
    float m_c = pairwise_mis_canonical_start(M_sum, 1.0f, k);
    float w_nb[RESTIR_MAX_NEIGHBOURS];
    for (uint i = 0; i < k; ++i) {
        const float m_i = pairwise_mis_neighbour(nb[i].M, M_sum, 1.0f, nb[i].P_ii, nb[i].P_ci);
        m_c += pairwise_mis_canonical_term(nb[i].M, M_sum, 1.0f, P_c, nb[i].P_ic);
        w_nb[i] = m_i * nb[i].P_ci * nb[i].W;
    }
    const uint pick_dim = coin_dim + 3u * rs->spatial;
    float total = 0.0f, P_Y = 0.0f;
    if (wrs_update(&total, m_c * P_c * W_c, rng_uniform(rs->seed, pixel, sample, pick_dim))) {
        out.light = c_light;
        out.u1 = c_u1;
        out.u2 = c_u2;
        P_Y = P_c;
    }
    for (uint i = 0; i < k; ++i)
        if (wrs_update(&total, w_nb[i], rng_uniform(rs->seed, pixel, sample, pick_dim + 1u + i))) {
            out.light = nb[i].light;
            out.u1 = nb[i].u1;
            out.u2 = nb[i].u2;
            P_Y = nb[i].P_ci;
        }
    float W = P_Y > 0.0f ? total / P_Y : 0.0f;
    if (!isfinite(W)) {
        W = 0.0f;
        ++*dropped;
    }
    out.W = W;
    out.M = M_sum;
    if (!(W > 0.0f)) { // no sample: the slot keeps its point but estimates 0
        out.light = RESERVOIR_NO_LIGHT;
        out.u1 = 0.0f;
        out.u2 = 0.0f;
    }
    return out;
}

/// The first hit of the path of sample `sample` of pixel (px, py), random numbers `rng`
/// (path_rng of rp.seed), which leaves the camera along *ray (set here); its slot's reservoir is
/// resampled there and stored in `reservoirs` (rs->spp slots per pixel). The resampling pass on
/// its own (kernels/restir.cl), or fused into the kernel whose paths read the reservoirs: they
/// go on from this hit (path_primal_from), and the camera ray is traced once for both.
TANDEM_INLINE Hit restir_first_hit(const SceneRefs* s, const PathResample* pass,
                                   __global Reservoir* reservoirs, uint px, uint py, uint sample,
                                   PathRng rng, Ray* ray, uint* dropped) {
    *ray = path_camera_ray(s, rng, px, py);
    const Hit hit = trace_closest(s, *ray);
    const uint slot = (py * s->cam->width + px) * pass->rs->spp + sample;
    reservoirs[slot] = restir_resample_at(s, pass, px, py, sample, rng, *ray, hit, dropped);
    return hit;
}

#endif // TANDEM_KERNELS_PATH_RESAMPLE_H
