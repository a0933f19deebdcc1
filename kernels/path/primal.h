// The primal estimator: one path of the path tracer, unidirectional with next-event estimation and
// MIS (power heuristic), Russian roulette and a box pixel filter (docs/method.md, "Primal path").
#ifndef TANDEM_KERNELS_PATH_PRIMAL_H
#define TANDEM_KERNELS_PATH_PRIMAL_H

#include "path/continuation.h"
#include "path/emission.h"
#include "path/nee.h"
#include "path/restir.h"
// (path/volume.h's own includes, above it: the kernel library inlines each file once, where it is
// first included, whatever #if surrounds it, so a file first reached inside a disabled block
// would be missing after it)
#include "path/adjoint.h"
#if HAS_MEDIA
#include "path/volume.h"
#endif

/// Steps 3-6 of path_primal at vertex `depth`, the surface `hit` that `ray` found: its emission and
/// NEE terms are added to *L. Returns whether the path goes on; then *ray, *beta and *prev_bsdf_pdf
/// are the next bounce's. The shadow ray goes through `rec` (path/record.h; 0: traced, not
/// recorded). (The wavefront's stage for materials other than diffuse calls it too:
/// kernels/wavefront.cl, wf_shade_general.)
TANDEM_INLINE int path_primal_vertex(const SceneRefs* s, __global const float* params, PathRng rng,
                                     uint depth, Hit hit, PrimaryReservoir pr, Ray* ray,
                                     float3* beta, float3* L, float* prev_bsdf_pdf,
                                     PathRecord* rec) {
    const RenderParams* rp = s->rp;

    // 3. The surface, and the emission seen by this ray.
    Interaction it;
    interaction_at(s, *ray, hit, &it);
#if HAS_AREA_LIGHTS
    Emission em;
    if (emission_area(s, params, &it, depth, *prev_bsdf_pdf, &em)) *L = path_term_add3(*L, *beta, em.Le, em.w);
#endif
    if (!path_continues(rp, depth)) return 0;
    if (!interaction_shade(s, params, &it)) return 0;
    const VertexRandom vr = vertex_random(rng, path_dim(depth));

    // The BSDF sample of step 5, drawn before the shadow ray of step 4 so that less lives across
    // it (the sums are the same, in the same order).
    const BsdfSample bs = continuation_sample(&it, vr);

    // 4. Next-event estimation: one point on a light, MIS-weighted against the BSDF.
    if (nee_applies(&it)) {
        LightSample ls;
        NeeEval ev;
        float w;
        if (path_nee_term(s, params, &it, vr, depth, pr, &ls, &ev, &w, rec))
            *L += nee_term3(*beta, ev.f, ls.Le, w);
    }

    // 5. Continue the path along the BSDF sample.
    if (continuation_failed(&bs) || max_component(bs.weight) <= 0.0f) return 0;
    *beta = continuation_beta3(*beta, bs.weight);
    *prev_bsdf_pdf = restir_next_pdf(pr, depth, &it, continuation_pdf(&bs));
    *ray = continuation_ray(&it, &bs);

    // 6. Russian roulette on the throughput.
    if (roulette_applies(rp, depth)) {
        const float q = roulette_q(*beta);
        if (roulette_ends(vr, q)) return 0;
        *beta = roulette_beta3(*beta, q);
    }
    return 1;
}

/// `sum` with sample radiance L added (rgb; w counts the sample), L left out where it is not
/// finite (the caller counts those in its guards). The megakernels and the wavefront
/// (kernels/wavefront.cl: wf_accumulate) add every sample through it.
TANDEM_INLINE float4 add_sample(float4 sum, float3 L) {
    if (all_finite(L)) sum += make_float4(L.x, L.y, L.z, 0.0f);
    sum.w += 1.0f;
    return sum;
}

/// The radiance (linear RGB) of the path that leaves the camera along `ray` (path_camera_ray of
/// `rng`), sampled with `rng` in the parameter state `params`: path_primal from its step 2. With
/// `first`, the camera ray's hit is not traced again but taken from there (the same hit, from a
/// packet of camera rays: kernels/shared/bvh8_packet.h, or traced for a fused resampling pass:
/// path/resample.h). With a record `rec` (path/record.h; rec->replay 0), the path's shadow rays
/// and first hits, `first` included, are written to it (0: no record). (One trace_closest for
/// every bounce, so that the traversal is inlined once.)
TANDEM_INLINE float3 path_primal_from(const SceneRefs* s, __global const float* params, PathRng rng,
                                      Ray ray, const Hit* first, PrimaryReservoir pr,
                                      PathRecord* rec) {
#if HAS_MEDIA
    // Scenes with media or null surfaces: the volumetric path (path/volume.h). The passes that
    // would need a reservoir or a record refuse such scenes (core/render/features.h: HAS_MEDIA).
    (void)pr;
    (void)rec;
    return path_volume_from(s, params, rng, ray, first, 0, 0);
#else
    float3 L = make_float3(0.0f, 0.0f, 0.0f), beta = make_float3(1.0f, 1.0f, 1.0f);
    if (s->rp->max_depth == 0u) return L; // Mitsuba: max_depth 0 renders black
    float prev_bsdf_pdf = 0.0f; // density of the direction that led here (0: the camera's)
    for (uint depth = 0;; ++depth) {
        const Hit hit = depth == 0u && first ? record_traced(*first, 0u, rec)
                                             : record_closest(s, ray, depth, rec);

        // 2. Escaped: the environment.
        if (hit.prim == HIT_NONE) {
#if HAS_ENV_LIGHT
            const Emission env = emission_env(s, params, ray, depth, prev_bsdf_pdf);
            L = path_term_add3(L, beta, env.Le, env.w);
#endif
            break;
        }

        // 3-6. The surface: its emission, NEE, the next direction and Russian roulette.
        if (!path_primal_vertex(s, params, rng, depth, hit, pr, &ray, &beta, &L, &prev_bsdf_pdf,
                                rec))
            break;
    }
    return L;
#endif
}

/// The radiance (linear RGB) of one path through pixel (px, py), sampled with `rng` in the
/// parameter state `params`. Every differentiable value is read from `params`. With a reservoir
/// (`pr`, RESTIR builds), the primary vertex's NEE term is the reservoir's (path/restir.h). `rec`
/// as path_primal_from's.
TANDEM_INLINE float3 path_primal(const SceneRefs* s, __global const float* params, PathRng rng,
                                 uint px, uint py, PrimaryReservoir pr, PathRecord* rec) {
    // 1. The camera ray.
    return path_primal_from(s, params, rng, path_camera_ray(s, rng, px, py), 0, pr, rec);
}

#endif // TANDEM_KERNELS_PATH_PRIMAL_H
