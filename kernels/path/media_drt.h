// Differential ratio tracking in the path replay (HAS_MEDIA builds; "Unbiased Inverse Volume
// Rendering with Differential Trackers", Nimier-David, Müller, Keller, Jakob, SIGGRAPH 2022, §4;
// docs/method.md, "Gradients of media").
//
// The scattering term of a grid medium's d sigma_t along a segment [t0, t1) of a path,
//   int T(t0, t) albedo(t) d sigma_t(t) L_i(t) dt   (times the path's throughput and delta),
// is estimated by the replay at the path's own scattering collisions, with density ~ sigma_t T:
// its weight k / sigma_t is large where the medium is thin, the variance DRT removes. DRT draws
// instead a point with density mu exp(-int mu) from the majorant (medium_majorant_point),
// estimates T to it by ratio tracking and the in-scattered radiance L_i there by a path of its own
// (path/volume.h: volume_in_scattered), and weighs the term by 1 / density. The two are combined
// by MIS (media_adjoint.h: scatter_mis_weight and drt_mis_weight, a partition of unity at every
// point). One DRT point per path keeps the cost linear in the path's length: a reservoir over the
// path's segments in grid media, each weighted by the mean of |delta beta| at its start, keeps one
// of them, and its term is multiplied by the total weight over the kept one's (the reference
// implementation's "DRT subsampling"; unbiased, as each segment's term is counted with
// probability w_i / W and weight W / w_i). Nothing is stored per segment: constant memory.
#ifndef TANDEM_KERNELS_PATH_MEDIA_DRT_H
#define TANDEM_KERNELS_PATH_MEDIA_DRT_H

#include "path/media_adjoint.h"

/// The segment of a path that differential ratio tracking visits, chosen among the path's
/// segments in grid media.
typedef struct DrtReservoir {
    float3 o, d;       ///< the segment: o + t d over [t0, t1)
    float t0, t1;
    uint medium, depth; ///< its medium, and the depth of a vertex scattered on it
    float3 k;          ///< delta times the throughput at its start
    float w, W;        ///< its weight, and the sum of the weights offered
} DrtReservoir;

TANDEM_INLINE void drt_reset(DrtReservoir* r) {
    r->w = 0.0f;
    r->W = 0.0f;
}

/// Offers the segment o + t d over [t0, t1) in grid medium `medium`, at `depth`, with delta times
/// the throughput at its start k; keeps it with probability (its weight) / (the weights so far).
TANDEM_INLINE void drt_offer(DrtReservoir* r, MediaRng* pick, float3 o, float3 d, float t0,
                             float t1, uint medium, uint depth, float3 k) {
    const float w = media_mean(k);
    if (!(w > 0.0f) || !(w < INFINITY)) return;
    r->W += w;
    if (media_rand(pick) * r->W < w) {
        r->o = o;
        r->d = d;
        r->t0 = t0;
        r->t1 = t1;
        r->medium = medium;
        r->depth = depth;
        r->k = k;
        r->w = w;
    }
}

/// The kept segment's DRT point: *x, in medium *m (medium_load), and *k, what multiplies the
/// in-scattered radiance there in the adjoint of the extinction at x (for
/// medium_grid_sigma_t_adjoint): delta beta, times W / w (the reservoir), times T / density,
/// times the albedo at x, times drt_mis_weight. Draws from r. Returns whether there is a point.
TANDEM_INLINE int drt_point(const SceneRefs* s, __global const float* params,
                            const DrtReservoir* res, MediaRng* r, Medium* m, float3* x,
                            float3* k) {
    if (!(res->w > 0.0f)) return 0;
    *m = medium_load(s, params, res->medium);
    float t, pdf;
    if (!medium_majorant_point(s, m, res->o, res->d, res->t0, res->t1, r, &t, &pdf)) return 0;
    const float3 T = medium_transmittance(s, params, m, res->o, res->d, res->t0, t, r);
    if (!all_finite(T) || !(max_component(T) > 0.0f)) return 0;
    *x = res->o + res->d * t;
    float3 st, ss, albedo = xyz(m->albedo);
    medium_coefficients(s, params, m, *x, &st, &ss);
    if (m->albedo_grid != NO_GRID) {
        const DeviceGrid ga = s->grids[m->albedo_grid];
        albedo = grid_eval3(params, &ga, grid_local(&ga, *x));
    }
    const float w = drt_mis_weight(media_mean(st), medium_majorant_at(s, m, *x));
    *k = res->k * T * albedo * (res->W / res->w * w / pdf);
    return w > 0.0f;
}

#endif // TANDEM_KERNELS_PATH_MEDIA_DRT_H
