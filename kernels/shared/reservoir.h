// Light-sample reservoirs for ReSTIR across gradient iterations ("Amortizing Samples in
// Physics-Based Inverse Rendering using ReSTIR", Wang, Wyman, Wu, Zhao, SIGGRAPH Asia 2023, Sec. 4;
// docs/restir.md): the 32-byte record one adjoint sample slot keeps from one iteration to the next,
// streaming weighted reservoir sampling, and the defensive pairwise MIS weights of the combine
// (Bitterli, "Correlations and Reuse for Fast and Accurate Physically Based Light Transport", PhD
// thesis 2022, Sec. 9.1; the ReSTIR course notes, SIGGRAPH 2023, Sec. 5.9). Pure functions of
// their arguments, shared by the kernels (kernels/restir.cl) and the host tests.
#ifndef TANDEM_SHARED_RESERVOIR_H
#define TANDEM_SHARED_RESERVOIR_H

#include "shared/compat.h"

TANDEM_NAMESPACE_BEGIN

/// Reservoir::light of an empty reservoir (no sample: it estimates 0).
#define RESERVOIR_NO_LIGHT 0xffffffffu
/// Reservoir::light of an environment sample (its direction decoded from u1, u2).
#define RESERVOIR_LIGHT_ENV 0xfffffffeu
/// The confidence cap of a reservoir read from the previous iteration.
#define RESERVOIR_DEFAULT_M_CAP 20.0f

/// One light sample y and what it is worth at one shading point x. y is stored as the light and
/// the random numbers that decode it, x as the triangle and barycentrics of the primary hit:
/// nothing that depends on the parameters, so a reservoir survives a parameter update.
typedef struct Reservoir {
    uint light; ///< emissive triangle i < E; point or spot light E + j; RESERVOIR_LIGHT_ENV;
                ///< RESERVOIR_NO_LIGHT: empty
    float u1, u2; ///< the light sample's coordinates, decoded by the NEE routines
    float W;      ///< unbiased contribution weight, in the light's measure (area, solid angle
                  ///< or count)
    uint prim;    ///< shading point: the primitive hit (HIT_NONE for an empty slot)
    float b1, b2; ///< shading point: the hit's barycentrics (u, v)
    float M;      ///< confidence: canonical samples merged into it (capped when read)
} Reservoir;
TANDEM_STATIC_ASSERT_SIZE(Reservoir, 32);

/// The most reservoirs of the previous iteration one slot combines with (temporal + spatial).
#define RESTIR_MAX_NEIGHBOURS 8u

/// Which share of the primary vertex's direct light a reservoir estimates (RestirParams::direct,
/// the host's RestirDirect; docs/restir.md, "The reservoir's share of direct light").
#define RESTIR_DIRECT_MIS 0u  ///< NEE's MIS share; BSDF sampling keeps the rest, as in plain PRB
#define RESTIR_DIRECT_ALL 1u  ///< all of it wherever NEE can sample the light
#define RESTIR_DIRECT_AUTO 2u ///< ALL at a diffuse vertex, MIS elsewhere

/// What one resampling pass does (kernels/restir.cl: restir_resample; the host's RestirConfig).
typedef struct RestirParams {
    uint seed;        ///< the pass's own random stream (candidates, neighbour picks, coins)
    uint spp;         ///< reservoir slots per pixel: the adjoint's samples per pixel
    uint candidates;  ///< fresh light samples per slot (streaming RIS), at least 1
    uint temporal;    ///< 1: combine with the slot's own reservoir of the previous iteration
    uint spatial;     ///< reservoirs of nearby slots of the previous iteration to combine with
    uint radius;      ///< their pixel distance, at most (a disk)
    uint visibility;  ///< 1: targets include visibility (shadow rays); 0: they do not
    float m_cap;      ///< a previous reservoir's confidence is capped at this when read
    float normal_cos; ///< a neighbour's surface normal must be within this cosine of the slot's
    float depth_rel;  ///< and its camera distance within this fraction of the slot's
    /// Added to the radiance of every light whose radiance is differentiated, in the targets
    /// (never in the estimate): keeps a target positive where NEE's term has a derivative at a
    /// radiance of 0, so that reuse samples what PRB samples (kernels/restir.cl: restir_target)
    float radiance_floor;
    uint direct; ///< RESTIR_DIRECT_*: the share of direct light the reservoirs estimate
} RestirParams;
TANDEM_STATIC_ASSERT_SIZE(RestirParams, 48);

TANDEM_INLINE Reservoir reservoir_empty(void) {
    Reservoir r;
    r.light = RESERVOIR_NO_LIGHT;
    r.u1 = 0.0f;
    r.u2 = 0.0f;
    r.W = 0.0f;
    r.prim = 0xffffffffu;
    r.b1 = 0.0f;
    r.b2 = 0.0f;
    r.M = 0.0f;
    return r;
}

TANDEM_INLINE int reservoir_is_empty(const Reservoir* r) {
    return r->light == RESERVOIR_NO_LIGHT;
}

/// One step of streaming weighted reservoir sampling: adds weight w to the running sum and
/// returns 1 if the new candidate replaces the current pick (probability w / sum), for a uniform
/// coin in [0, 1). Zero or negative weights never win, and never change the sum; a first
/// candidate of positive weight always wins.
TANDEM_INLINE int wrs_update(float* w_sum, float w, float coin) {
    if (!(w > 0.0f)) return 0;
    *w_sum += w;
    return coin * *w_sum < w;
}

/// a / b with 0 / 0 := 0 (and x / 0 := 0: a weight whose denominator vanishes is not on any
/// domain's support).
TANDEM_INLINE float reservoir_ratio(float a, float b) {
    return b > 0.0f ? a / b : 0.0f;
}

/// The defensive pairwise MIS weight of neighbour i's own sample y_i.
///   M_i, M_c: the confidences of the neighbour (capped) and of the canonical reservoir;
///   M_sum: M_c plus every accepted neighbour's M_i;
///   P_ii: the neighbour's target at its own point for y_i (its domain, previous parameters);
///   P_ci: the canonical target for y_i at the current point (current parameters).
/// m_i = (M_i / M_sum) M_n P_ii / (M_n P_ii + M_c P_ci), with M_n = M_sum - M_c.
TANDEM_INLINE float pairwise_mis_neighbour(float M_i, float M_sum, float M_c, float P_ii,
                                           float P_ci) {
    const float M_n = M_sum - M_c;
    return (M_i / M_sum) * reservoir_ratio(M_n * P_ii, M_n * P_ii + M_c * P_ci);
}

/// Neighbour i's share of the canonical sample's weight m_c (the sum over neighbours plus
/// M_c / M_sum, pairwise_mis_canonical_start).
///   P_c: the canonical target for y_c at the current point;
///   P_ic: neighbour i's target for y_c at its own point (previous parameters).
/// (M_i / M_sum) M_c P_c / (M_c P_c + M_n P_ic).
TANDEM_INLINE float pairwise_mis_canonical_term(float M_i, float M_sum, float M_c, float P_c,
                                                float P_ic) {
    const float M_n = M_sum - M_c;
    return (M_i / M_sum) * reservoir_ratio(M_c * P_c, M_c * P_c + M_n * P_ic);
}

/// The canonical weight before any neighbour's term: M_c / M_sum, or 1 with no neighbour.
TANDEM_INLINE float pairwise_mis_canonical_start(float M_sum, float M_c, uint neighbours) {
    return neighbours == 0u ? 1.0f : M_c / M_sum;
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_RESERVOIR_H
