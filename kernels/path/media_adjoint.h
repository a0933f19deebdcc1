// The adjoint of participating media for the path replay (HAS_MEDIA builds; docs/method.md,
// "Gradients of media"): the derivatives of the transmittance of a piece of ray and of a
// scattering collision's factor, into the media's parameters.
#ifndef TANDEM_KERNELS_PATH_MEDIA_ADJOINT_H
#define TANDEM_KERNELS_PATH_MEDIA_ADJOINT_H

#include "path/adjoint.h"
#include "path/media.h"

// The adjoint of media (path replay: docs/method.md, "Gradients of media"). The sampling is
// detached, as on surfaces: the majorants, the collision distances and spectral tracking's
// probabilities are constants. What depends on the parameters is
// - the transmittance of every piece of ray through a medium, T = exp(-int sigma_t): its
//   estimate (the product of the null-collision weights of free flights, or ratio tracking) has
//   the expectation T, so a term that arrived through it has the derivative
//   -(int d sigma_t / d theta) times itself. The line integral is exact in a homogeneous medium
//   (length times d sigma_t) and, in a grid, estimated with one point drawn uniformly on the piece
//   inside the grid (unbiased, independent of the tracking). This is the transmittance's own
//   derivative, not that of each null-collision weight (sigma_n / mu): those vanish where the
//   majorant is tight (a homogeneous medium has no null collisions in its densest channel), and
//   differentiating them would then miss d T / d sigma_t entirely.
// - sigma_s(x) = sigma_t(x) albedo(x), a factor of everything after a scattering collision at x;
// - the phase function's value, in its light sample's term and its sampled direction's weight.

/// Adds k_c times d sigma_t_c / d theta of homogeneous medium m (medium_load), per channel c: into
/// its sigma_t (times scale) and its scale (times sigma_t before the scale; a medium's sigma_t and
/// scale are parameters together: core/scene/params.cpp, add_medium).
TANDEM_INLINE void medium_sigma_t_adjoint(Adjoint* adj, __global const float* params,
                                          const Medium* m, float3 k) {
    const float scale = m->sigma_t.w;
    if (m->sigma_t_param != NO_PARAM) grad_add_rgb(adj, m->sigma_t_param, k * scale);
    if (m->scale_param != NO_PARAM) {
        const float3 raw = param_rgb(params, m->sigma_t_param);
        grad_add(adj, m->scale_param, k.x * raw.x + k.y * raw.y + k.z * raw.z);
    }
}

/// Adds k_c times d v_c(l) / d(voxel) to the voxels of grid g (a parameter: g->offset is in the
/// parameter buffer) that the lookup at local point l blends; a one-channel grid gets the sum over
/// the channels.
TANDEM_INLINE void grid_adjoint(Adjoint* adj, const DeviceGrid* g, float3 l, float3 k) {
    uint index[8];
    float weight[8];
    grid_corners(g, l, index, weight);
    for (uint i = 0; i < 8u; ++i) {
        const uint e = g->offset + index[i];
        if (g->channels == 1u)
            grad_add(adj, e, weight[i] * (k.x + k.y + k.z));
        else
            grad_add_rgb(adj, e, k * weight[i]);
    }
}

/// Adds kk_c times d sigma_t_c(x) / d theta of grid medium m (medium_load) at world point x, per
/// channel: into the voxels of its sigma_t grid (times the scale) and its scale (times the grid's
/// value).
TANDEM_INLINE void medium_grid_sigma_t_adjoint(const SceneRefs* s, __global const float* params,
                                               const Medium* m, float3 x, float3 kk,
                                               Adjoint* adj) {
    const DeviceGrid g = s->grids[m->sigma_t_grid];
    const float3 l = grid_local(&g, x);
    grid_adjoint(adj, &g, l, kk * m->sigma_t.w);
    if (m->scale_param != NO_PARAM) grad_add(adj, m->scale_param, channel_sum(kk * grid_eval3(params, &g, l)));
}

/// The share of a grid medium's scattering estimator in the MIS of its d sigma_t terms with
/// differential ratio tracking (path/media_drt.h), at a point of extinction sigma_t (the channels'
/// mean) under majorant mu: the power heuristic for densities in the ratio sigma_t : mu (a free
/// flight scatters with density ~ sigma_t T, DRT's point has mu exp(-int mu)). The other share,
/// drt_mis_weight, is DRT's. Both are functions of the point alone, so they sum to 1 wherever
/// either estimator reaches.
TANDEM_INLINE float scatter_mis_weight(float sigma_t, float mu) {
    const float s2 = sigma_t * sigma_t, m2 = mu * mu;
    return s2 + m2 > 0.0f ? s2 / (s2 + m2) : 1.0f;
}
TANDEM_INLINE float drt_mis_weight(float sigma_t, float mu) {
    const float s2 = sigma_t * sigma_t, m2 = mu * mu;
    return s2 + m2 > 0.0f ? m2 / (s2 + m2) : 0.0f;
}

/// The part [*a, *b) of [t0, t1) of o + t d inside grid g's unit cube (empty: *a >= *b).
TANDEM_INLINE void grid_clip(const DeviceGrid* g, float3 o, float3 d, float t0, float t1, float* a,
                             float* b) {
    const float3 ol = grid_local(g, o), dl = grid_local_dir(g, d);
    *a = t0;
    *b = t1;
    walk_clip(ol.x, dl.x, 1.0f, a, b);
    walk_clip(ol.y, dl.y, 1.0f, a, b);
    walk_clip(ol.z, dl.z, 1.0f, a, b);
}

/// The adjoint of the transmittance of medium m (medium_load) along o + t d over [t0, t1), which
/// multiplies radiance whose adjoint is k (delta times that radiance, per channel): -k times the
/// line integral of d sigma_t (see above), in a grid at one point drawn with r.
TANDEM_INLINE void medium_transmittance_adjoint(const SceneRefs* s, __global const float* params,
                                                const Medium* m, float3 o, float3 d, float t0,
                                                float t1, float3 k, MediaRng* r, Adjoint* adj) {
    if (max_component(fabs(k)) == 0.0f) return;
    if (m->kind == MEDIUM_HOMOGENEOUS) {
        // an unbounded piece transmits only channels of sigma_t 0, where d T / d sigma_t is
        // -infinity: left out
        const float len = t1 - t0;
        if (len < INFINITY) medium_sigma_t_adjoint(adj, params, m, k * -len);
        return;
    }
    const DeviceGrid g = s->grids[m->sigma_t_grid];
    float a, b;
    grid_clip(&g, o, d, t0, t1, &a, &b);
    if (!(a < b)) return;
    const float t = a + (b - a) * media_rand(r);
    const float3 l = grid_local(&g, o + d * t);
    const float len = b - a;
    grid_adjoint(adj, &g, l, k * (-len * m->sigma_t.w));
    if (m->scale_param != NO_PARAM) {
        const float3 v = grid_eval3(params, &g, l);
        grad_add(adj, m->scale_param, -len * (k.x * v.x + k.y * v.y + k.z * v.z));
    }
}

/// The adjoint of the factor sigma_s(x) = sigma_t(x) albedo(x) of a scattering collision at x in
/// medium m (medium_load), which multiplies radiance whose adjoint is k: k / sigma_s times its
/// derivative, into sigma_t (and scale) and albedo. In a grid, the sigma_t part is weighted by
/// scatter_mis_weight: differential ratio tracking estimates the rest (path/media_drt.h).
TANDEM_INLINE void medium_scatter_adjoint(const SceneRefs* s, __global const float* params,
                                          const Medium* m, float3 x, float3 k, Adjoint* adj) {
    if (max_component(fabs(k)) == 0.0f) return;
    float3 albedo = xyz(m->albedo);
    DeviceGrid ga;
    float3 la;
    if (m->albedo_grid != NO_GRID) {
        ga = s->grids[m->albedo_grid];
        la = grid_local(&ga, x);
        albedo = grid_eval3(params, &ga, la);
    }
    if (m->kind == MEDIUM_HOMOGENEOUS) {
        medium_sigma_t_adjoint(adj, params, m, safe_ratio(k, xyz(m->sigma_t)));
    } else {
        const DeviceGrid g = s->grids[m->sigma_t_grid];
        const float3 st = grid_eval3(params, &g, grid_local(&g, x)) * m->sigma_t.w;
        const float w = scatter_mis_weight(media_mean(st), medium_majorant_at(s, m, x));
        medium_grid_sigma_t_adjoint(s, params, m, x, safe_ratio(k, st) * w, adj);
    }
    if (m->albedo_grid != NO_GRID)
        grid_adjoint(adj, &ga, la, safe_ratio(k, albedo));
    else if (m->albedo_param != NO_PARAM)
        grad_add_rgb(adj, m->albedo_param, safe_ratio(k, albedo));
}

#endif // TANDEM_KERNELS_PATH_MEDIA_ADJOINT_H
