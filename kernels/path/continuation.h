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

/// num / den, 0 where den is 0 (a channel the BSDF does not transmit carries no radiance through
/// it and gets no gradient).
TANDEM_INLINE float safe_div(float num, float den) { return den != 0.0f ? num / den : 0.0f; }

/// Per channel safe_div.
static inline float3 safe_ratio(float3 num, float3 den) {
    return make_float3(safe_div(num.x, den.x), safe_div(num.y, den.y), safe_div(num.z, den.z));
}

/// x is neither infinite nor NaN (isfinite, as a comparison: the loop vectoriser refuses the
/// library call).
TANDEM_INLINE int finite_value(float x) { return fabs(x) < INFINITY; }

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

/// One channel of continuation_weight_old for a sample that is not a delta lobe: `weight` the new
/// state's (f_new / p), f_new and f_old the two states' f cos toward it, inv_pdf 1 / p. f_old / p
/// as weight * (f_old / f_new) where f_new > 0: the same value, and exactly `weight` when the two
/// states agree (so H == F bit for bit on an unchanging scene, the steady state of the paper's
/// Fig. 3); f_old / p where that ratio is not finite or f_new is 0.
TANDEM_INLINE float continuation_weight_old_channel(float weight, float f_new, float f_old,
                                                    float inv_pdf) {
    const float ratio = weight * safe_div(f_old, f_new);
    return f_new > 0.0f && finite_value(ratio) ? ratio : f_old * inv_pdf;
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
    const float3 f_new =
        bsdf_eval(it->plastic_tables, &it->mat, it->albedo, it->wi_local, bs->wo_local);
    const float3 f_old =
        bsdf_eval(it->plastic_tables, mat_old, albedo_old, it->wi_local, bs->wo_local);
    const float inv_pdf = 1.0f / bs->pdf;
    return make_float3(continuation_weight_old_channel(bs->weight.x, f_new.x, f_old.x, inv_pdf),
                       continuation_weight_old_channel(bs->weight.y, f_new.y, f_old.y, inv_pdf),
                       continuation_weight_old_channel(bs->weight.z, f_new.z, f_old.z, inv_pdf));
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

/// One channel of the throughput after a BSDF sample of weight `weight` (f cos / p).
TANDEM_INLINE float continuation_beta(float beta, float weight) { return beta * weight; }
TANDEM_INLINE float3 continuation_beta3(float3 beta, float3 weight) {
    return make_float3(continuation_beta(beta.x, weight.x), continuation_beta(beta.y, weight.y),
                       continuation_beta(beta.z, weight.z));
}

/// Russian roulette's survival probability for throughput (bx, by, bz): Mitsuba's rule, without
/// its eta^2 factor (which refraction tracking would add; unbiased either way).
TANDEM_INLINE float roulette_survival(float bx, float by, float bz) {
    return fmin(fmax(bx, fmax(by, bz)), 0.95f);
}

TANDEM_INLINE float roulette_q(float3 beta) { return roulette_survival(beta.x, beta.y, beta.z); }

/// Russian roulette's survival probability for the two-state path: roulette_survival of the
/// componentwise max(|beta|, |beta_old|). Both states divide by it, so both stay unbiased (q > 0
/// wherever either throughput is non-zero), and q is never smaller than either state's own
/// roulette_q, so H's variance stays bounded where the old state carries more energy than the new
/// (docs/method.md, "Two-state path"). For beta == beta_old it is roulette_q(beta) bit for bit, as
/// on an unchanging scene.
TANDEM_INLINE float roulette_survival_two_state(float bx, float by, float bz, float box, float boy,
                                                float boz) {
    return roulette_survival(fmax(fabs(bx), fabs(box)), fmax(fabs(by), fabs(boy)),
                             fmax(fabs(bz), fabs(boz)));
}

TANDEM_INLINE float roulette_q_two_state(float3 beta, float3 beta_old) {
    return roulette_survival_two_state(beta.x, beta.y, beta.z, beta_old.x, beta_old.y, beta_old.z);
}

/// Whether roulette applies at a vertex of `depth` (Russian roulette starts at rr_depth).
TANDEM_INLINE int roulette_applies(const RenderParams* rp, uint depth) {
    return depth + 1u >= rp->rr_depth;
}

/// One channel of the throughput of a path that survived roulette with probability q.
TANDEM_INLINE float roulette_beta(float beta, float q) { return beta * (1.0f / q); }
TANDEM_INLINE float3 roulette_beta3(float3 beta, float q) {
    return make_float3(roulette_beta(beta.x, q), roulette_beta(beta.y, q), roulette_beta(beta.z, q));
}

/// Whether roulette with survival probability q ends a path whose random number is u_rr.
TANDEM_INLINE int roulette_ends_at(float u_rr, float q) { return u_rr >= q; }

/// Whether roulette ends the path at the vertex with random numbers `vr` (it survives with
/// probability q).
TANDEM_INLINE int roulette_ends(VertexRandom vr, float q) {
    return roulette_ends_at(vertex_rand(vr, DIM_RR), q);
}

#endif // TANDEM_KERNELS_PATH_CONTINUATION_H
