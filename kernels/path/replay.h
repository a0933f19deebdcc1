// The PRB replay: one path traced again with the random numbers of its primal estimate, pushing the
// derivative of every term into the parameter gradients ("Path Replay Backpropagation", Vicini,
// Speierer, Jakob, SIGGRAPH 2021, Sec. 4; docs/method.md, "Path Replay Backpropagation").
#ifndef TANDEM_KERNELS_PATH_REPLAY_H
#define TANDEM_KERNELS_PATH_REPLAY_H

#include "path/adjoint.h"
#include "path/continuation.h"
#include "path/emission.h"
#include "path/nee.h"
#include "path/restir.h"
#include "path/shape_adjoint.h"
#if HAS_MEDIA
#include "path/volume.h"
#endif

/// Steps 3-6 of path_replay at vertex `depth`, the surface `hit` that `ray` found: the derivatives
/// of its terms go into adj->grad and the terms leave adj->L_rem. Returns whether the path goes on;
/// then *ray, *beta and *prev_bsdf_pdf are the next bounce's (kernels/wavefront.cl calls it too).
/// The shadow ray's outcome is read from `rec` where it holds it (path/record.h; 0: traced
/// again).
TANDEM_INLINE int path_replay_vertex(const SceneRefs* s, __global const float* params, PathRng rng,
                                     uint depth, Hit hit, PrimaryReservoir pr, Adjoint* adj,
                                     Ray* ray, float3* beta, float* prev_bsdf_pdf,
                                     PathRecord* rec) {
    const RenderParams* rp = s->rp;

    // 3. The surface, and the emission seen by this ray: d/d(Le).
    Interaction it;
    interaction_at(s, *ray, hit, &it);
#if SHAPE_GRAD
    // a moving previous vertex: everything in L_rem arrived from this point (path/shape_adjoint.h)
    shape_vertex_continue(&adj->shape, adj->delta, adj->L_rem, 0, xyz(ray->dir), it.x, it.n_front);
#endif
#if HAS_AREA_LIGHTS
    Emission em;
    if (emission_area(s, params, &it, depth, *prev_bsdf_pdf, &em)) {
        adjoint_emission(adj, &em, *beta);
        adj->L_rem = path_term_sub3(adj->L_rem, *beta, em.Le, em.w);
    }
#endif
    if (!path_continues(rp, depth)) return 0;
    if (!interaction_shade(s, params, &it)) return 0;
    const VertexRandom vr = vertex_random(rng, path_dim(depth));
    AlbedoSource src;
    interaction_albedo_source(s, &it, &src);
    BsdfGrad acc = bsdf_grad_zero(); // this vertex's d/d(material), pushed once (path/adjoint.h)
#if SHAPE_GRAD
    // this vertex's shape derivatives; the one before it (adj->shape) is pushed once this one's
    // BSDF has added what it owes to the turn of wi (g_wi)
    ShapeVertex here = shape_vertex_at(s, &it, xyz(ray->dir));
    const int dirs = shape_dirs_needed(&it, &here, &adj->shape);
    float3 g_wi = make_float3(0.0f, 0.0f, 0.0f);
#endif

    // 4. Next-event estimation: d/d(material) through f, d/d(Le) through the light.
    if (nee_applies(&it)) {
        LightSample ls;
        NeeEval ev;
        float w;
        if (path_nee_term(s, params, &it, vr, depth, pr, &ls, &ev, &w, rec)) {
            adjoint_nee(adj, &acc, &it, &ls, &ev, *beta, w);
            const float3 term = nee_term3(*beta, ev.f, ls.Le, w);
            adj->L_rem -= term;
#if SHAPE_GRAD
            const int has_normal = ls.light_normal.x != 0.0f || ls.light_normal.y != 0.0f ||
                                   ls.light_normal.z != 0.0f;
            ShapeDirs bd;
            if (dirs) {
                const float3 d = adj->delta;
                bd = shape_bsdf_dirs(&it,
                                     make_float3(adjoint_nee_k(d.x, beta->x, ls.Le.x, w),
                                                 adjoint_nee_k(d.y, beta->y, ls.Le.y, w),
                                                 adjoint_nee_k(d.z, beta->z, ls.Le.z, w)),
                                     ev.wo_local, ls.wo);
                g_wi += bd.wi;
            }
            shape_vertex_add(&here, vdot(adj->delta, term), dirs ? &bd : 0, ls.wo, ls.dist,
                             isfinite(ls.dist), has_normal, ls.light_normal, ls.falloff_dx);
#endif
        }
    }

    // 5. Continue the path by sampling the BSDF: what remains in L_rem arrived through the
    // sampled direction, d/d(material) through f / p.
    const BsdfSample bs = continuation_sample(&it, vr);
    const bool ends = continuation_failed(&bs) || max_component(bs.weight) <= 0.0f;
    if (!ends) adjoint_continuation(adj, &acc, &it, &bs);
    grad_material(adj, &it.mat, &src, &acc);
#if SHAPE_GRAD
    if (dirs && !ends && !bs.delta)
        shape_vertex_sampled(
            &here, &g_wi, &it,
            adjoint_continuation_k3(adj->delta, adj->L_rem,
                                    bsdf_eval(it.plastic_tables, &it.mat, it.albedo, it.wi_local,
                                              bs.wo_local)),
            bs.wo_local, frame_to_world(it.frame, bs.wo_local));
    shape_vertex_texture(s, params, &here, &it, acc.d_albedo); // as the texture slides
    shape_vertex_incoming(s, adj, &adj->shape, g_wi, it.x);
    adj->shape = here;
#endif
    if (ends) return 0;
    *beta = continuation_beta3(*beta, bs.weight);
    *prev_bsdf_pdf = restir_next_pdf(pr, depth, &it, continuation_pdf(&bs));
    *ray = continuation_ray(&it, &bs);

    // 6. Russian roulette, the primal's decision.
    if (roulette_applies(rp, depth)) {
        const float q = roulette_q(*beta);
        if (roulette_ends(vr, q)) return 0;
        *beta = roulette_beta3(*beta, q);
    }
    return 1;
}

/// Replays the path of path_primal(s, params, rng, px, py, pr, ...): adj->L_rem must hold its
/// radiance. Each term (emission, NEE, the BSDF sample's f / p) pushes its derivative into
/// adj->grad and leaves L_rem; the sampling is detached (densities and MIS weights are constants).
/// The replay computes every primal value as path_primal does, bit for bit: the gradient code only
/// reads them. `rec`: the primal's record (path/record.h) with rec->replay set, or 0 (every ray
/// traced again).
TANDEM_INLINE void path_replay(const SceneRefs* s, __global const float* params, PathRng rng,
                               uint px, uint py, PrimaryReservoir pr, Adjoint* adj,
                               PathRecord* rec) {
#if HAS_MEDIA
    // Scenes with media or null surfaces: the volumetric path's replay (path/volume.h), with no
    // record or reservoir (the passes that would need them refuse such scenes).
    (void)pr;
    (void)rec;
    path_volume_from(s, params, rng, path_camera_ray(s, rng, px, py), 0, adj, 0);
#else
    const RenderParams* rp = s->rp;
    // 1. The camera ray.
    Ray ray = path_camera_ray(s, rng, px, py);
    float3 beta = make_float3(1.0f, 1.0f, 1.0f);
    if (rp->max_depth == 0u) return; // Mitsuba: max_depth 0 renders black
    float prev_bsdf_pdf = 0.0f;      // density of the direction that led here (0: the camera's)
    for (uint depth = 0;; ++depth) {
        const Hit hit = record_closest(s, ray, depth, rec);

        // 2. Escaped: the environment, d/d(Le) of a constant one.
        if (hit.prim == HIT_NONE) {
#if SHAPE_GRAD
            shape_vertex_continue(&adj->shape, adj->delta, adj->L_rem, 1, xyz(ray.dir),
                                  make_float3(0.0f, 0.0f, 0.0f), make_float3(0.0f, 0.0f, 0.0f));
#endif
#if HAS_ENV_LIGHT
            const Emission env = emission_env(s, params, ray, depth, prev_bsdf_pdf);
            adjoint_emission(adj, &env, beta);
            adj->L_rem = path_term_sub3(adj->L_rem, beta, env.Le, env.w);
#endif
            break;
        }

        // 3-6. The surface: its terms' derivatives, the next direction and Russian roulette.
        if (!path_replay_vertex(s, params, rng, depth, hit, pr, adj, &ray, &beta, &prev_bsdf_pdf,
                                rec))
            break;
    }
#if SHAPE_GRAD
    shape_vertex_push(s, adj, &adj->shape); // a path that ended at a moving vertex
#endif
#endif
}

#endif // TANDEM_KERNELS_PATH_REPLAY_H
