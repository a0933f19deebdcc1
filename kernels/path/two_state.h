// The two-state estimator (CV-PS): one path sampled from the new parameter state that estimates
// both the new and the previous state ("Recursive Control Variates for Inverse Rendering",
// Nicolet, Rousselle, Novák, Keller, Jakob, Müller, SIGGRAPH 2023, Appendix B; docs/method.md,
// "Two-state path").
#ifndef TANDEM_KERNELS_PATH_TWO_STATE_H
#define TANDEM_KERNELS_PATH_TWO_STATE_H

#include "path/continuation.h"
#include "path/emission.h"
#include "path/nee.h"
#include "path/primal.h" // (and path/volume.h, in HAS_MEDIA builds)

/// The radiance (linear RGB) of one path for the two parameter states.
typedef struct TwoStateRadiance {
    float3 L;     ///< the new state's: <F_n>_n
    float3 L_old; ///< the previous state's along the same path: <F_{n-1}>_n
} TwoStateRadiance;

/// Steps 3-6 of path_two_state at vertex `depth`, the surface `hit` that `ray` found: its emission
/// and NEE terms are added to r in both states. Returns whether the path goes on; then *ray, *beta,
/// *beta_old and *prev_bsdf_pdf are the next bounce's (kernels/wavefront.cl calls it too).
TANDEM_INLINE int path_two_state_vertex(const SceneRefs* s, __global const float* params,
                                        __global const float* params_old, PathRng rng, uint depth,
                                        Hit hit, Ray* ray, float3* beta, float3* beta_old,
                                        TwoStateRadiance* r, float* prev_bsdf_pdf) {
    const RenderParams* rp = s->rp;

    // 3. The surface, and the emission seen by this ray.
    Interaction it;
    interaction_at(s, *ray, hit, &it);
#if HAS_AREA_LIGHTS
    Emission em;
    if (emission_area(s, params, &it, depth, *prev_bsdf_pdf, &em)) {
        r->L = path_term_add3(r->L, *beta, em.Le, em.w);
        r->L_old = path_term_add3(r->L_old, *beta_old, emission_Le_in(params_old, &em), em.w);
    }
#endif
    if (!path_continues(rp, depth)) return 0;
    if (!interaction_shade(s, params, &it)) return 0;
    const VertexRandom vr = vertex_random(rng, path_dim(depth));
    // the previous state's material at the same point
    const Material mat_old = material_load(s, params_old, it.info.material);
    const float3 albedo_old = material_albedo(s, &mat_old, params_old, it.tu, it.tv);

    // 4. Next-event estimation: one light sample and one shadow ray for both states, with the
    // new state's MIS weight.
    if (nee_applies(&it)) {
        const LightSample ls = nee_sample(s, params, it.origin, vr);
        const NeeEval ev = nee_eval(&it, &ls);
        const float3 f_old =
            bsdf_eval(it.plastic_tables, &mat_old, albedo_old, it.wi_local, ev.wo_local);
        if (ls.pdf > 0.0f && (max_component(ev.f) > 0.0f || max_component(f_old) > 0.0f) &&
            nee_unoccluded(s, it.origin, &ls)) {
            const float w = nee_weight(&it, &ls, &ev);
            r->L += nee_term3(*beta, ev.f, ls.Le, w);
            r->L_old += nee_term3(*beta_old, f_old, nee_Le_in(params_old, &ls), w);
        }
    }

    // 5. Continue the path by sampling the new state's BSDF; the old state weighs the same
    // direction with its own BSDF.
    const BsdfSample bs = continuation_sample(&it, vr);
    if (continuation_failed(&bs)) return 0;
    const float3 weight_old = continuation_weight_old(&it, &mat_old, albedo_old, &bs);
    if (max_component(bs.weight) <= 0.0f && max_component(weight_old) <= 0.0f) return 0;
    *beta = continuation_beta3(*beta, bs.weight);
    *beta_old = continuation_beta3(*beta_old, weight_old);
    *prev_bsdf_pdf = continuation_pdf(&bs);
    *ray = continuation_ray(&it, &bs);

    // 6. Russian roulette on both throughputs; both states divide by the same q. Neither
    // estimate is cut short where the other state carries less (a clamped albedo, say).
    if (roulette_applies(rp, depth)) {
        const float q = roulette_q_two_state(*beta, *beta_old);
        if (roulette_ends(vr, q)) return 0;
        *beta = roulette_beta3(*beta, q);
        *beta_old = roulette_beta3(*beta_old, q);
    }
    return 1;
}

/// Both radiances of a two-state sample, L and L_old, into their pixel's sums (w counts the sample
/// in each). A sample non-finite in either state is left out of both, so that the two stay
/// paired; returns whether it was kept (the caller counts the others in its guards).
TANDEM_INLINE int add_sample_two_state(float4* sum, float4* sum_old, float3 L, float3 L_old) {
    const int kept = all_finite(L) && all_finite(L_old);
    if (kept) {
        *sum += make_float4(L.x, L.y, L.z, 0.0f);
        *sum_old += make_float4(L_old.x, L_old.y, L_old.z, 0.0f);
    }
    sum->w += 1.0f;
    sum_old->w += 1.0f;
    return kept;
}

/// One path through pixel (px, py), sampled with `rng` from `params` (the new state) as
/// path_primal samples it, also estimating `params_old`. Geometry, texture coordinates, light
/// sampling and MIS weights are the new state's; the old state has its own materials, radiances
/// and throughput beta_old. Russian roulette's q is decided on both throughputs
/// (roulette_q_two_state): the new state's radiance is path_primal's bit for bit where
/// |beta_old| <= |beta| along the whole path, else another unbiased estimate of it.
TANDEM_INLINE TwoStateRadiance path_two_state(const SceneRefs* s, __global const float* params,
                                              __global const float* params_old, PathRng rng,
                                              uint px, uint py) {
    const RenderParams* rp = s->rp;
    const float3 one = make_float3(1.0f, 1.0f, 1.0f);
    // 1. The camera ray.
    Ray ray = path_camera_ray(s, rng, px, py);
    TwoStateRadiance r;
    r.L = make_float3(0.0f, 0.0f, 0.0f);
    r.L_old = r.L;
#if HAS_MEDIA
    // Scenes with media or null surfaces: the volumetric path carries the old state
    // (path/volume.h, path_volume_from).
    OldState old;
    old.params = params_old;
    old.beta = one;
    old.L = r.L;
    r.L = path_volume_from(s, params, rng, ray, 0, 0, &old);
    r.L_old = old.L;
    return r;
#else
    float3 beta = one, beta_old = one;
    if (rp->max_depth == 0u) return r; // Mitsuba: max_depth 0 renders black
    float prev_bsdf_pdf = 0.0f;        // density of the direction that led here (0: the camera's)
    for (uint depth = 0;; ++depth) {
        const Hit hit = trace_closest(s, ray);

        // 2. Escaped: the environment, in both states with the new state's weight.
        if (hit.prim == HIT_NONE) {
#if HAS_ENV_LIGHT
            const Emission env = emission_env(s, params, ray, depth, prev_bsdf_pdf);
            r.L = path_term_add3(r.L, beta, env.Le, env.w);
            r.L_old = path_term_add3(r.L_old, beta_old, emission_Le_in(params_old, &env), env.w);
#endif
            break;
        }

        // 3-6. The surface in both states: emission, NEE, the next direction, Russian roulette.
        if (!path_two_state_vertex(s, params, params_old, rng, depth, hit, &ray, &beta, &beta_old,
                                   &r, &prev_bsdf_pdf))
            break;
    }
    return r;
#endif
}

#endif // TANDEM_KERNELS_PATH_TWO_STATE_H
