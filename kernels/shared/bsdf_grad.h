// Analytic derivatives of the BSDF values of bsdfs.h with respect to the differentiable material
// parameters (albedo, specular, alpha), for Path Replay Backpropagation; shared by host and device.
// bsdf_eval_grad differentiates f * cos (what bsdf_eval returns), bsdf_delta_weight_grad the weight
// bsdf_sample returns for a delta lobe. Every derivative is written as a product of the float
// sub-expressions bsdf_eval itself computes (never as a quotient by f), so it is finite wherever f
// is, and exactly zero wherever f is zero for structural reasons (below the surface, no half
// vector, D flushed to zero). Checked against finite differences by tests/kernels/shared/test_bsdf_grad.cpp.
//
// The color parameters act per channel, so their Jacobians are diagonal and are stored as float3;
// alpha is a scalar, and d_alpha holds d(f cos)_c / d alpha for each channel c.
#ifndef TANDEM_SHARED_BSDF_GRAD_H
#define TANDEM_SHARED_BSDF_GRAD_H

#include "shared/bsdfs.h"

TANDEM_NAMESPACE_BEGIN

/// Derivatives of an RGB BSDF value v (f cos, or a delta lobe's sample weight) with respect to the
/// material parameters. Private arithmetic only (float3 members: never in a shared buffer).
typedef struct BsdfGrad {
    float3 d_albedo;   ///< dv_c / d albedo_c: diffuse reflectance, plastic diffuse_reflectance
    float3 d_specular; ///< dv_c / d specular_c: Material.specular (conductors, dielectric, plastic)
    float3 d_alpha;    ///< dv_c / d alpha: Material.alpha (0 where ggx_alpha clamps it)
} BsdfGrad;

/// A BsdfGrad with every derivative zero.
TANDEM_INLINE BsdfGrad bsdf_grad_zero(void) {
    BsdfGrad g;
    g.d_albedo = make_float3(0.0f, 0.0f, 0.0f);
    g.d_specular = make_float3(0.0f, 0.0f, 0.0f);
    g.d_alpha = make_float3(0.0f, 0.0f, 0.0f);
    return g;
}

// ---- logarithmic alpha derivatives of the GGX factors (alpha already clamped by ggx_alpha) ----

/// d ln D(m) / d alpha for ggx_d (m.z > 0). With t = (m.x^2 + m.y^2) / alpha^2 and b = t + m.z^2,
/// D = 1 / (pi alpha^2 b^2) and db / dalpha = -2 t / alpha, so
///   d ln D / d alpha = -2 / alpha - 2 (db / dalpha) / b = (2 / alpha) (2 t / b - 1),
/// which lies in [-2 / alpha, 2 / alpha] (0 <= t / b <= 1): D grows with alpha away from the peak
/// (tan^2 theta_m > alpha^2) and falls at it. t and b are ggx_d's expressions, bit for bit.
TANDEM_INLINE float ggx_d_dlog_alpha(float alpha, float3 m) {
    const float a2 = alpha * alpha;
    const float t = (m.x * m.x + m.y * m.y) / a2;
    const float b = t + m.z * m.z;
    return b > 0.0f ? (2.0f / alpha) * (2.0f * (t / b) - 1.0f) : 0.0f;
}

/// d ln(G1(v) / v.z) / d alpha for ggx_g1_over_cos (0 for v.z <= 0, where G1 / cos is 0). With
/// c = v.z, s^2 = v.x^2 + v.y^2 and r = sqrt(c^2 + alpha^2 s^2): G1 / cos = 2 / (c + r) and
/// dr / dalpha = alpha s^2 / r, so
///   d ln(G1 / cos) / d alpha = -(dr / dalpha) / (c + r) = -(alpha s^2 / r) / (c + r),
/// which lies in [-1 / alpha, 0] (alpha s^2 / r <= s and c + r >= alpha s). r >= c > 0, and r is
/// the square root ggx_g1_over_cos takes, bit for bit.
TANDEM_INLINE float ggx_g1_over_cos_dlog_alpha(float alpha, float3 v) {
    if (v.z <= 0.0f) return 0.0f;
    const float s2 = v.x * v.x + v.y * v.y;
    const float r = sqrt(v.z * v.z + alpha * alpha * s2);
    return r > 0.0f ? -(alpha * s2 / r) / (v.z + r) : 0.0f;
}

/// d ln(D(m) (G1(wi) / cos_i) (G1(wo) / cos_o)) / d alpha: the relative alpha derivative of every
/// GGX microfacet value of bsdfs.h (the Fresnel factor and the cosines do not depend on alpha).
/// Bounded by 4 / alpha in magnitude.
TANDEM_INLINE float ggx_dlog_alpha(float alpha, float3 m, float3 wi, float3 wo) {
    return ggx_d_dlog_alpha(alpha, m) + ggx_g1_over_cos_dlog_alpha(alpha, wi) +
           ggx_g1_over_cos_dlog_alpha(alpha, wo);
}

/// Whether alpha reaches the GGX factors unchanged: ggx_alpha(alpha) = fmax(alpha, GGX_ALPHA_MIN)
/// has derivative 1 for alpha >= GGX_ALPHA_MIN and 0 below, where it is clamped (also for NaN,
/// which fmax replaces by the bound). At alpha = GGX_ALPHA_MIN the right derivative (1) is used.
TANDEM_INLINE int ggx_alpha_unclamped(float alpha) {
    return alpha >= GGX_ALPHA_MIN;
}

// ---- per-family derivatives of f * cos, mirroring the eval functions of bsdfs.h ----

/// Derivatives of bsdf_diffuse_eval = albedo * cos_o / pi: d_albedo = cos_o / pi per channel, zero
/// below the surface; no specular or alpha.
TANDEM_INLINE BsdfGrad bsdf_diffuse_eval_grad(float3 wi, float3 wo) {
    BsdfGrad g = bsdf_grad_zero();
    const float c = diffuse_cos(wi.z, wo.z);
    g.d_albedo = make_float3(c, c, c);
    return g;
}

/// Derivatives of bsdf_roughconductor_eval, f cos = specular * F(wi.m) * s with
/// s = D(m) (G1(wi) / cos_i) (G1(wo) / cos_o) cos_o / 4:
///   d_specular = F * s,   d_alpha = specular * F * s * d ln(D G1 G1 / (cos_i cos_o)) / d alpha
/// (F does not depend on alpha; d_alpha is 0 where ggx_alpha clamps alpha). Zero where the eval
/// is (below the surface, no half vector, D flushed to 0).
TANDEM_INLINE BsdfGrad bsdf_roughconductor_eval_grad(float3 specular, float3 eta, float3 k,
                                                     float alpha, float3 wi, float3 wo) {
    BsdfGrad g = bsdf_grad_zero();
    float3 m;
    if (wi.z <= 0.0f || wo.z <= 0.0f || !half_vector(wi, wo, &m)) return g;
    const float a = ggx_alpha(alpha);
    const float d = ggx_d(a, m);
    if (d <= 0.0f) return g;
    const float s = d * ggx_g1_over_cos(a, wi) * ggx_g1_over_cos(a, wo) * (0.25f * wo.z);
    const float3 fresnel = fresnel_conductor3(vdot(wi, m), eta, k);
    g.d_specular = fresnel * s;
    // specular * fresnel * s is the value bsdf_roughconductor_eval returns, bit for bit.
    if (ggx_alpha_unclamped(alpha))
        g.d_alpha = specular * fresnel * s * ggx_dlog_alpha(a, m, wi, wo);
    return g;
}

/// d diff_c / d diffuse_c of roughplastic's nonlinear rescaling diff = x / fmax(1 - x r, 1e-3):
/// (1 - x r + x r) / (1 - x r)^2 = 1 / (1 - x r)^2 where the fmax keeps 1 - x r, and 1 / 1e-3
/// where it clamps (there diff is linear in x).
TANDEM_INLINE float roughplastic_nonlinear_grad(float x, float r) {
    const float den = 1.0f - x * r;
    return den > 1e-3f ? 1.0f / (den * den) : 1.0f / 1e-3f;
}

/// d diff_c / d r of the same: x^2 / (1 - x r)^2 where the fmax keeps 1 - x r, 0 where it clamps.
TANDEM_INLINE float roughplastic_nonlinear_grad_r(float x, float r) {
    const float den = 1.0f - x * r;
    return den > 1e-3f ? (x * x) / (den * den) : 0.0f;
}

/// Derivatives of bsdf_roughplastic_eval, f cos = specular * S + diff(diffuse, r) * T with
///   S = F(wi.m, eta) D(m) (G1(wi) / cos_i) (G1(wo) / cos_o) cos_o / 4  (0 without a half vector),
///   T = t_i t_o cos_o / (pi eta^2), t_i = t(cos_i), t_o = t(cos_o), r: the table's at alpha:
/// d_specular = S; d_albedo = T / (1 - r) (linear) or T / (1 - diffuse r)^2 per channel
/// (nonlinear; T / 1e-3 where the eval clamps the denominator); d_alpha = the coating's
/// specular * S * d ln(D G1 G1 / (cos_i cos_o)) / d alpha (0 where ggx_alpha clamps) plus the
/// base's (d diff / d r) (d r / d alpha) T + diff (d t_i / d alpha t_o + t_i d t_o / d alpha)
/// cos_o / (pi eta^2), with the table's alpha derivatives (0 outside [GGX_ALPHA_MIN, 1]) and
/// d diff / d r = diffuse / (1 - r)^2 (linear) or diffuse^2 / (1 - diffuse r)^2 (nonlinear).
TANDEM_INLINE BsdfGrad bsdf_roughplastic_eval_grad(TANDEM_GLOBAL const float* table, float3 diffuse,
                                                   float3 specular, float eta, float alpha,
                                                   int nonlinear, float3 wi, float3 wo) {
    BsdfGrad g = bsdf_grad_zero();
    if (wi.z <= 0.0f || wo.z <= 0.0f) return g;
    float3 m;
    if (half_vector(wi, wo, &m)) {
        const float a = ggx_alpha(alpha);
        const float d = ggx_d(a, m);
        const float gg = ggx_g1_over_cos(a, wi) * ggx_g1_over_cos(a, wo);
        const float s = fresnel_dielectric_r(vdot(wi, m), eta) * d * gg * (0.25f * wo.z);
        g.d_specular = make_float3(s, s, s);
        // specular * s is the coating's value in bsdf_roughplastic_eval, bit for bit.
        if (ggx_alpha_unclamped(alpha) && d > 0.0f)
            g.d_alpha = specular * s * ggx_dlog_alpha(a, m, wi, wo);
    }
    // The eval's table values and diffuse factor T, computed by the same expressions.
    const PlasticCell c = plastic_cell(alpha);
    const float r = plastic_internal_reflectance(table, &c);
    const float t_i = plastic_transmittance(table, &c, wi.z);
    const float t_o = plastic_transmittance(table, &c, wo.z);
    const float base = t_i * t_o * TANDEM_INV_PI / (eta * eta) * wo.z;
    float3 diff_r; // d diff / d r
    if (nonlinear) {
        g.d_albedo = make_float3(roughplastic_nonlinear_grad(diffuse.x, r) * base,
                                 roughplastic_nonlinear_grad(diffuse.y, r) * base,
                                 roughplastic_nonlinear_grad(diffuse.z, r) * base);
        diff_r = make_float3(roughplastic_nonlinear_grad_r(diffuse.x, r),
                             roughplastic_nonlinear_grad_r(diffuse.y, r),
                             roughplastic_nonlinear_grad_r(diffuse.z, r));
    } else {
        const float inv = 1.0f / (1.0f - r);
        const float lin = inv * base;
        g.d_albedo = make_float3(lin, lin, lin);
        diff_r = diffuse * (inv * inv);
    }
    if (plastic_alpha_unclamped(alpha)) {
        const float dr = plastic_internal_reflectance_dalpha(table, &c);
        const float dt = (plastic_transmittance_dalpha(table, &c, wi.z) * t_o +
                          t_i * plastic_transmittance_dalpha(table, &c, wo.z)) *
                         TANDEM_INV_PI / (eta * eta) * wo.z;
        g.d_alpha =
            g.d_alpha + diff_r * (dr * base) + roughplastic_diff(diffuse, r, nonlinear) * dt;
    }
    return g;
}

// ---- generic entry points, dispatching on Material.type as bsdfs.h does ----

/// Derivatives of bsdf_eval(tables, m, albedo, wi, wo) (the non-delta components) with respect to
/// the albedo, Material.specular and Material.alpha; same dispatch and feature macros
/// (BSDF_CONDUCTOR, BSDF_PLASTIC) as bsdf_eval. Zero wherever bsdf_eval is zero for structural
/// reasons (below the surface, purely specular types, families compiled out).
TANDEM_INLINE BsdfGrad bsdf_eval_grad(TANDEM_GLOBAL const float* tables, const Material* m,
                                      float3 albedo, float3 wi, float3 wo) {
    switch (m->type) {
    case MATERIAL_DIFFUSE:
        return bsdf_diffuse_eval_grad(wi, wo);
#if BSDF_CONDUCTOR
    case MATERIAL_ROUGHCONDUCTOR:
        return bsdf_roughconductor_eval_grad(xyz(m->specular), xyz(m->eta), xyz(m->k), m->alpha, wi,
                                             wo);
#endif
#if BSDF_PLASTIC
    case MATERIAL_ROUGHPLASTIC:
        return bsdf_roughplastic_eval_grad(tables + m->plastic_table, albedo, xyz(m->specular),
                                           m->eta.x, m->alpha,
                                           (m->flags & MATERIAL_FLAG_NONLINEAR) != 0u, wi, wo);
#endif
    default:
        (void)tables;
        return bsdf_grad_zero(); // conductor, dielectric: delta only
    }
}

/// Derivatives of the weight bsdf_sample returns for a sampled delta lobe (wi, wo as it returned
/// them), treating the lobe selection probability as a constant (detached sampling):
/// conductor: weight = specular * F(cos_i) -> d_specular = F (0 from behind, where it fails);
/// dielectric reflection: weight = specular -> d_specular = 1; dielectric refraction: weight
/// eta_ti^2 -> zero. Refraction is recognised by wi and wo lying strictly on opposite sides; every
/// other pair (including grazing wi.z = 0, where the interface reflects) counts as reflection.
/// d_albedo and d_alpha are always zero, as is everything for non-delta types.
TANDEM_INLINE BsdfGrad bsdf_delta_weight_grad(const Material* m, float3 wi, float3 wo) {
    BsdfGrad g = bsdf_grad_zero();
    switch (m->type) {
#if BSDF_CONDUCTOR
    case MATERIAL_CONDUCTOR:
        if (wi.z > 0.0f) g.d_specular = fresnel_conductor3(wi.z, xyz(m->eta), xyz(m->k));
        break;
#endif
#if BSDF_DIELECTRIC
    case MATERIAL_DIELECTRIC: {
        const int refracted = (wi.z > 0.0f && wo.z < 0.0f) || (wi.z < 0.0f && wo.z > 0.0f);
        if (!refracted) g.d_specular = make_float3(1.0f, 1.0f, 1.0f);
        break;
    }
#endif
    default:
        break;
    }
    return g;
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_BSDF_GRAD_H
