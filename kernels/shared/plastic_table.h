// roughplastic's rough-interface terms, as Mitsuba 3 tabulates them (src/bsdfs/roughplastic.cpp):
// the external transmittance t(cos_theta) over 64 cosines, and the internal reflectance r, here
// over an alpha grid as well (alpha is a parameter); shared by host and device. The host fills
// the tables (core/scene/plastic_table.h); checked by tests/core/scene/test_plastic_table.cpp.
#ifndef TANDEM_SHARED_PLASTIC_TABLE_H
#define TANDEM_SHARED_PLASTIC_TABLE_H

#include "shared/microfacet.h"

TANDEM_NAMESPACE_BEGIN

// One table per relative IOR eta, in the float buffer `plastic_tables` at Material.plastic_table:
// PLASTIC_ALPHAS rows, one per alpha node, of PLASTIC_ROW floats:
//   (t_k, h dt_k / ds) for k = 0..63, then (r, h dr / ds),
// where t_k is the transmittance at cos_theta = max(1e-6, k / 63) (Mitsuba's nodes), r the
// internal reflectance, s = alpha^(1/4) the grid variable (nodes s_j = PLASTIC_S_MIN + j h,
// h = PLASTIC_DS, alpha from GGX_ALPHA_MIN to 1) and the slopes are per cell (times h).
// Lookups are linear in cos_theta, as Mitsuba's lerp_gather, and cubic Hermite in s: the value
// and its alpha derivative are continuous, and at a node they are the node's.
#define PLASTIC_MU_NODES 64u
#define PLASTIC_ALPHAS 32u
#define PLASTIC_ROW (2u * PLASTIC_MU_NODES + 2u)
#define PLASTIC_TABLE_FLOATS (PLASTIC_ALPHAS * PLASTIC_ROW)
#define PLASTIC_S_MIN 0.1f /* GGX_ALPHA_MIN^(1/4) */
#define PLASTIC_DS (0.9f / 31.0f)
#define PLASTIC_INV_DS (31.0f / 0.9f)

/// Where an alpha falls in the grid: the lower node's row and the Hermite weights of (value,
/// slope) at the lower and upper node, with their derivatives in alpha. Private arithmetic only.
typedef struct PlasticCell {
    uint row;             ///< first float of the lower node's row
    float w0, w1, w2, w3; ///< weights of value_j, slope_j, value_j+1, slope_j+1
    float d0, d1, d2, d3; ///< d w / d alpha; 0 outside [GGX_ALPHA_MIN, 1], where alpha is clamped
} PlasticCell;

/// Whether alpha reaches the table unclamped (GGX_ALPHA_MIN <= alpha <= 1): where the lookups'
/// alpha derivatives are not zero.
TANDEM_INLINE int plastic_alpha_unclamped(float alpha) {
    return alpha >= GGX_ALPHA_MIN && alpha <= 1.0f;
}

/// The cell of alpha, clamped to [GGX_ALPHA_MIN, 1] as the GGX terms clamp it below. At the ends
/// the derivative is the one-sided one from inside (alpha = GGX_ALPHA_MIN: the right one, as
/// ggx_alpha_unclamped; alpha = 1: the left one).
TANDEM_INLINE PlasticCell plastic_cell(float alpha) {
    const float a = fmin(fmax(alpha, GGX_ALPHA_MIN), 1.0f);
    const float s = sqrt(sqrt(a));
    const float x = fmax((s - PLASTIC_S_MIN) * PLASTIC_INV_DS, 0.0f);
    const uint j = min((uint)x, PLASTIC_ALPHAS - 2u);
    const float f = x - (float)j, g = 1.0f - f;
    PlasticCell c;
    c.row = j * PLASTIC_ROW;
    c.w0 = (1.0f + 2.0f * f) * g * g;
    c.w1 = f * g * g;
    c.w2 = f * f * (3.0f - 2.0f * f);
    c.w3 = -f * f * g;
    // dx / dalpha = (ds / dalpha) / h with ds / dalpha = s / (4 alpha)
    const float dx = plastic_alpha_unclamped(alpha) ? PLASTIC_INV_DS * s / (4.0f * a) : 0.0f;
    c.d0 = -6.0f * f * g * dx;
    c.d1 = g * (1.0f - 3.0f * f) * dx;
    c.d2 = 6.0f * f * g * dx;
    c.d3 = f * (3.0f * f - 2.0f) * dx;
    return c;
}

/// The Hermite combination at float `i` of the cell's two rows with weights (w0..w3).
TANDEM_INLINE float plastic_hermite(TANDEM_GLOBAL const float* table, uint i, float w0, float w1,
                                    float w2, float w3) {
    TANDEM_GLOBAL const float* lo = table + i;
    TANDEM_GLOBAL const float* hi = lo + PLASTIC_ROW;
    return w0 * lo[0] + w1 * lo[1] + w2 * hi[0] + w3 * hi[1];
}

/// Mitsuba's lerp_gather position of cos_theta in (0, 1]: node k and the weight f of node k + 1.
TANDEM_INLINE uint plastic_mu_node(float cos_theta, float* f) {
    const float x = fmax(cos_theta, 0.0f) * (float)(PLASTIC_MU_NODES - 1u);
    const uint k = min((uint)x, PLASTIC_MU_NODES - 2u);
    *f = x - (float)k;
    return k;
}

/// The transmittance rows of the cell combined with Hermite weights (a0..a3) at cos_theta's two
/// mu nodes (plastic_mu_node): their values into *v0 and *v1; returns the weight f of the second.
TANDEM_INLINE float plastic_mu_pair(TANDEM_GLOBAL const float* table, const PlasticCell* c,
                                    float cos_theta, float a0, float a1, float a2, float a3,
                                    float* v0, float* v1) {
    float f;
    const uint i = c->row + 2u * plastic_mu_node(cos_theta, &f);
    *v0 = plastic_hermite(table, i, a0, a1, a2, a3);
    *v1 = plastic_hermite(table, i + 2u, a0, a1, a2, a3);
    return f;
}

/// External transmittance t(cos_theta) of the rough interface at the cell's alpha (cos_theta in
/// (0, 1]), clamped at 0 against the cubic's undershoot. `table`: the material's table.
TANDEM_INLINE float plastic_transmittance(TANDEM_GLOBAL const float* table, const PlasticCell* c,
                                          float cos_theta) {
    float v0, v1;
    const float f = plastic_mu_pair(table, c, cos_theta, c->w0, c->w1, c->w2, c->w3, &v0, &v1);
    return fmax(v0 + (v1 - v0) * f, 0.0f);
}

/// d t(cos_theta) / d alpha of plastic_transmittance (0 where it clamps).
TANDEM_INLINE float plastic_transmittance_dalpha(TANDEM_GLOBAL const float* table,
                                                 const PlasticCell* c, float cos_theta) {
    if (!(plastic_transmittance(table, c, cos_theta) > 0.0f)) return 0.0f;
    float v0, v1;
    const float f = plastic_mu_pair(table, c, cos_theta, c->d0, c->d1, c->d2, c->d3, &v0, &v1);
    return v0 + (v1 - v0) * f;
}

/// Largest internal reflectance used: keeps 1 - r away from 0 (reached only for eta >~ 8).
#define PLASTIC_R_MAX 0.999f

/// Internal diffuse reflectance r of the interface at the cell's alpha, clamped to
/// [0, PLASTIC_R_MAX].
TANDEM_INLINE float plastic_internal_reflectance(TANDEM_GLOBAL const float* table,
                                                 const PlasticCell* c) {
    const float r =
        plastic_hermite(table, c->row + 2u * PLASTIC_MU_NODES, c->w0, c->w1, c->w2, c->w3);
    return fmin(fmax(r, 0.0f), PLASTIC_R_MAX);
}

/// d r / d alpha of plastic_internal_reflectance (0 where it clamps).
TANDEM_INLINE float plastic_internal_reflectance_dalpha(TANDEM_GLOBAL const float* table,
                                                        const PlasticCell* c) {
    const uint i = c->row + 2u * PLASTIC_MU_NODES;
    const float r = plastic_hermite(table, i, c->w0, c->w1, c->w2, c->w3);
    if (!(r > 0.0f && r < PLASTIC_R_MAX)) return 0.0f;
    return plastic_hermite(table, i, c->d0, c->d1, c->d2, c->d3);
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_PLASTIC_TABLE_H
