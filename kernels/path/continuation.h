// Continuing a path: sampling the BSDF for the next direction, the throughput weight of that
// sample for the two-state path's old state, the next ray, and Russian roulette
// (docs/method.md, "Primal path", steps 4 and 5).
#ifndef TANDEM_KERNELS_PATH_CONTINUATION_H
#define TANDEM_KERNELS_PATH_CONTINUATION_H

#include "path/interaction.h"

/// A direction sampled from the BSDF at a surface point.
typedef struct BsdfSample {
    float3 weight;   ///< f cos / pdf (a delta lobe: its value over its selection probability)
    float3 wo_local; ///< the direction, in the interaction's shading frame
    float pdf;       ///< solid-angle density (0 for a delta lobe)
    int delta;       ///< a delta lobe was sampled
} BsdfSample;

/// Per channel num / den, 0 where den is 0 (a channel the BSDF does not transmit carries no
/// radiance through it and gets no gradient).
static inline float3 safe_ratio(float3 num, float3 den) {
    return make_float3(den.x != 0.0f ? num.x / den.x : 0.0f, den.y != 0.0f ? num.y / den.y : 0.0f,
                       den.z != 0.0f ? num.z / den.z : 0.0f);
}

/// Samples the BSDF of shaded `it` with the vertex's random numbers `vr`.
TANDEM_INLINE BsdfSample continuation_sample(const Interaction* it, VertexRandom vr) {
    BsdfSample bs;
    bs.weight = bsdf_sample(it->plastic_tables, &it->mat, it->albedo, it->wi_local,
                            vertex_rand(vr, DIM_LOBE), vertex_rand(vr, DIM_BSDF),
                            vertex_rand(vr, DIM_BSDF + 1u), &bs.wo_local, &bs.pdf, &bs.delta);
    return bs;
}

/// Whether the sample ends the path: no delta lobe and no density (sampling failed).
TANDEM_INLINE int continuation_failed(const BsdfSample* bs) {
    return !bs->delta && bs->pdf <= 0.0f;
}

/// The old state's throughput weight for the direction sampled from the new state at `it`:
/// f_old / p_new, or for a delta lobe the old state's weight of the same lobe ("Recursive Control
/// Variates for Inverse Rendering", Appendix B; docs/method.md, "Two-state path").
/// A delta lobe's p_new is the discrete probability of choosing it (the dielectric's Fresnel
/// reflectance, else 1), so the exact weight is f_old / p_new; bsdf_delta_weight gives
/// f_old / p_old, the same because p depends only on eta, k and cos_i. eta and k are not
/// parameters (core/scene/params.h; material_load never reads them from params), so they are
/// equal in both states by construction (tests/core/scene/test_params.cpp checks that the
/// registry exposes nothing else); only specular_reflectance, a factor of f, differs.
TANDEM_INLINE float3 continuation_weight_old(const Interaction* it, const Material* mat_old,
                                             float3 albedo_old, const BsdfSample* bs) {
    if (bs->delta) return bsdf_delta_weight(mat_old, it->wi_local, bs->wo_local);
    // f_old / p as weight * (f_old / f_new) where f_new > 0: the same value, and exactly `weight`
    // when the two states agree (so H == F bit for bit on an unchanging scene, the steady state
    // of the paper's Fig. 3)
    const float3 f_new =
        bsdf_eval(it->plastic_tables, &it->mat, it->albedo, it->wi_local, bs->wo_local);
    const float3 f_old =
        bsdf_eval(it->plastic_tables, mat_old, albedo_old, it->wi_local, bs->wo_local);
    const float3 direct = f_old * (1.0f / bs->pdf), ratio = bs->weight * safe_ratio(f_old, f_new);
    return make_float3(f_new.x > 0.0f && isfinite(ratio.x) ? ratio.x : direct.x,
                       f_new.y > 0.0f && isfinite(ratio.y) ? ratio.y : direct.y,
                       f_new.z > 0.0f && isfinite(ratio.z) ? ratio.z : direct.z);
}

/// The density the next vertex's emission is MIS-weighted with: after a delta lobe +inf, as NEE
/// cannot sample that direction and the emission found gets full weight.
TANDEM_INLINE float continuation_pdf(const BsdfSample* bs) {
    return bs->delta ? INFINITY : bs->pdf;
}

/// The ray leaving `it` along the sample, from the side its direction points to (refraction
/// crosses the surface).
TANDEM_INLINE Ray continuation_ray(const Interaction* it, const BsdfSample* bs) {
    const float3 dir = frame_to_world(it->frame, bs->wo_local);
    const float3 origin =
        vdot(dir, it->n_out) >= 0.0f ? it->origin : offset_ray_origin(it->x, -it->n_out);
    return make_ray(origin, dir, 0.0f, INFINITY);
}

/// Russian roulette's survival probability for throughput beta: Mitsuba's rule, without its eta^2
/// factor (which refraction tracking would add; unbiased either way).
TANDEM_INLINE float roulette_q(float3 beta) {
    return fmin(max_component(beta), 0.95f);
}

/// Russian roulette's survival probability for the two-state path: roulette_q of the
/// componentwise max(|beta|, |beta_old|). Both states divide by it, so both stay unbiased (q > 0
/// wherever either throughput is non-zero), and q is never smaller than either state's own
/// roulette_q, so H's variance stays bounded where the old state carries more energy than the new
/// (docs/method.md, "Two-state path"). For beta == beta_old it is roulette_q(beta) bit for bit, as
/// on an unchanging scene.
TANDEM_INLINE float roulette_q_two_state(float3 beta, float3 beta_old) {
    return roulette_q(make_float3(fmax(fabs(beta.x), fabs(beta_old.x)),
                                  fmax(fabs(beta.y), fabs(beta_old.y)),
                                  fmax(fabs(beta.z), fabs(beta_old.z))));
}

/// Whether roulette ends the path at the vertex with random numbers `vr` (it survives with
/// probability q).
TANDEM_INLINE int roulette_ends(VertexRandom vr, float q) {
    return vertex_rand(vr, DIM_RR) >= q;
}

#endif // TANDEM_KERNELS_PATH_CONTINUATION_H
