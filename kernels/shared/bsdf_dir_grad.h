// Derivatives of the BSDF values of bsdfs.h with respect to their directions, for the interior
// term of shape gradients (kernels/path/shape_adjoint.h): when a surface moves, the directions
// toward the points before and after a vertex turn, and so does its normal. Shared by host and
// device.
//
// Every non-delta BSDF here is isotropic, so f cos_o is a function of three numbers only:
//     cos_i = n . wi,   cos_o = n . wo,   mu = wi . wo        (n, wi, wo unit vectors)
// (GGX's D depends on the half vector's m.z = (cos_i + cos_o) / |wi + wo|, |wi + wo|^2 = 2 + 2 mu;
// the Fresnel factors on wi . m = |wi + wo| / 2; Smith's G1 and the plastic's tables on cos_i and
// cos_o). bsdf_eval_dir_grad returns the partial derivatives of f cos_o in these three with the
// explicit factor cos_o of the projected solid angle held fixed: the caller differentiates that
// factor itself, with the geometry (shape_vertex_add's d log(n . wo)), for every BSDF alike, so a
// diffuse BSDF has none of these derivatives. In world space, with weights k per channel,
//     d/dn  = A wi + B wo,   d/dwo = B n + C wi,   d/dwi = A n + C wo
// for A = k . d_cos_i, B = k . d_cos_o, C = k . d_mu (bsdf_dir_weights).
//
// Checked against finite differences of bsdf_eval by tests/kernels/shared/test_bsdf_grad.cpp.
#ifndef TANDEM_SHARED_BSDF_DIR_GRAD_H
#define TANDEM_SHARED_BSDF_DIR_GRAD_H

#include "shared/bsdfs.h"

TANDEM_NAMESPACE_BEGIN

/// Partial derivatives of an RGB f cos_o in (cos_i, cos_o, mu), the explicit cos_o held fixed.
/// Private arithmetic only (float3 members: never in a shared buffer).
typedef struct BsdfDirGrad {
    float3 d_cos_i;
    float3 d_cos_o;
    float3 d_mu;
} BsdfDirGrad;

TANDEM_INLINE BsdfDirGrad bsdf_dir_grad_zero(void) {
    BsdfDirGrad g;
    g.d_cos_i = g.d_cos_o = g.d_mu = make_float3(0.0f, 0.0f, 0.0f);
    return g;
}

// ---- the factors' derivatives in the cosine they depend on ----

/// d F / d cos of fresnel_conductor (0 <= cos <= 1), its expressions differentiated one by one
/// (d sin^2 / d cos = -2 cos): t1' = 2 cos, (a^2 + b^2)' = t1 t1' / (a^2 + b^2),
/// a' = ((a^2 + b^2)' + t1') / (4 a); each quotient (u - v) / (u + v) has the derivative
/// 2 (v u' - u v') / (u + v)^2 (r_s: u = term1, v = term2; the factor R_p of r_p = r_s R_p:
/// u = term3, v = term4); F = (r_s + r_s R_p) / 2. Zero where fresnel_conductor clamps.
TANDEM_INLINE float fresnel_conductor_dcos(float cos_theta_i, float eta, float k) {
    const float c = cos_theta_i, cos2 = c * c;
    const float sin2 = 1.0f - cos2, sin4 = sin2 * sin2;
    const float t1 = eta * eta - k * k - sin2;
    const float a2pb2 = safe_sqrt(t1 * t1 + 4.0f * k * k * eta * eta);
    const float a = safe_sqrt(0.5f * (a2pb2 + t1));
    const float term1 = a2pb2 + cos2, term2 = 2.0f * c * a;
    const float den_s = term1 + term2;
    if (!(den_s > 0.0f)) return 0.0f;
    const float dt1 = 2.0f * c;
    const float da2pb2 = a2pb2 > 0.0f ? t1 * dt1 / a2pb2 : 0.0f;
    const float da = a > 0.0f ? (da2pb2 + dt1) / (4.0f * a) : 0.0f;
    const float dterm1 = da2pb2 + 2.0f * c, dterm2 = 2.0f * a + 2.0f * c * da;
    const float q_s = (term1 - term2) / den_s;
    const float r_s = fmax(0.0f, q_s);
    const float dr_s = q_s > 0.0f ? 2.0f * (term2 * dterm1 - term1 * dterm2) / (den_s * den_s) : 0.0f;
    const float term3 = a2pb2 * cos2 + sin4, term4 = term2 * sin2;
    const float den_p = term3 + term4;
    if (!(den_p > 0.0f)) return dr_s; // r_p = r_s
    const float dterm3 = da2pb2 * cos2 + 2.0f * c * a2pb2 - 4.0f * c * sin2;
    const float dterm4 = dterm2 * sin2 - 2.0f * c * term2;
    const float q_p = (term3 - term4) / den_p;
    const float R_p = fmax(0.0f, q_p);
    const float dR_p =
        q_p > 0.0f ? 2.0f * (term4 * dterm3 - term3 * dterm4) / (den_p * den_p) : 0.0f;
    return 0.5f * (dr_s + dr_s * R_p + r_s * dR_p);
}

/// d F / d cos_i of fresnel_dielectric from outside (cos_i > 0): with cos_t = sqrt(1 - (1 -
/// cos_i^2) / eta^2), cos_t' = cos_i / (eta^2 cos_t), a_s' = 2 eta (cos_t - cos_i cos_t') /
/// (cos_i + eta cos_t)^2, a_p' = 2 eta (cos_i cos_t' - cos_t) / (cos_t + eta cos_i)^2 and
/// F' = a_s a_s' + a_p a_p'. Zero under total internal reflection, at eta = 1 and at grazing.
TANDEM_INLINE float fresnel_dielectric_dcos(float cos_i, float eta) {
    if (eta == 1.0f || !(cos_i > 0.0f)) return 0.0f;
    const float ti = 1.0f / eta;
    const float cos_t_sqr = 1.0f - (1.0f - cos_i * cos_i) * (ti * ti);
    if (!(cos_t_sqr > 0.0f)) return 0.0f;
    const float cos_t = sqrt(cos_t_sqr);
    const float dcos_t = cos_i * (ti * ti) / cos_t;
    const float den_s = cos_i + eta * cos_t, den_p = cos_t + eta * cos_i;
    const float a_s = (cos_i - eta * cos_t) / den_s;
    const float a_p = (cos_t - eta * cos_i) / den_p;
    const float da_s = 2.0f * eta * (cos_t - cos_i * dcos_t) / (den_s * den_s);
    const float da_p = 2.0f * eta * (cos_i * dcos_t - cos_t) / (den_p * den_p);
    return a_s * da_s + a_p * da_p;
}

/// d ln D / d m.z for ggx_d at a unit m (m.z > 0): D = 1 / (pi alpha^2 b^2) with b = (1 - m.z^2)
/// / alpha^2 + m.z^2, so d ln D / d m.z = -2 b' / b = -4 m.z (1 - 1 / alpha^2) / b, b as ggx_d
/// computes it.
TANDEM_INLINE float ggx_d_dlog_mz(float alpha, float3 m) {
    const float a2 = alpha * alpha;
    const float b = (m.x * m.x + m.y * m.y) / a2 + m.z * m.z;
    return b > 0.0f ? -4.0f * m.z * (1.0f - 1.0f / a2) / b : 0.0f;
}

/// d ln(G1(v) / v.z) / d v.z for ggx_g1_over_cos at a unit v (v.z > 0): G1 / cos = 2 / (z + r),
/// r = sqrt(z^2 + alpha^2 (1 - z^2)), r' = z (1 - alpha^2) / r, so the derivative is
/// -(1 + r') / (z + r).
TANDEM_INLINE float ggx_g1_over_cos_dlog_cos(float alpha, float3 v) {
    if (v.z <= 0.0f) return 0.0f;
    const float r = sqrt(v.z * v.z + alpha * alpha * (v.x * v.x + v.y * v.y));
    return r > 0.0f ? -(1.0f + v.z * (1.0f - alpha * alpha) / r) / (v.z + r) : 0.0f;
}

/// d t / d cos of plastic_transmittance: the slope of its linear interpolation in cos (0 where it
/// clamps at 0).
TANDEM_INLINE float plastic_transmittance_dcos(TANDEM_GLOBAL const float* table,
                                               const PlasticCell* c, float cos_theta) {
    if (!(plastic_transmittance(table, c, cos_theta) > 0.0f)) return 0.0f;
    float v0, v1;
    plastic_mu_pair(table, c, cos_theta, c->w0, c->w1, c->w2, c->w3, &v0, &v1);
    return (v1 - v0) * (float)(PLASTIC_MU_NODES - 1u);
}

/// The microfacet part of a GGX lobe's derivatives: for a lobe value s (f cos_o per channel, zero
/// where it is) = fresnel * q, q = D (G1(wi) / cos_i) (G1(wo) / cos_o) cos_o / 4, with m the half
/// vector and dF the Fresnel factor's derivative in wi . m: adds to g the lobe's d/d cos_i, d/d
/// cos_o (cos_o held in q's last factor) and d/d mu, where m.z = (cos_i + cos_o) / L,
/// wi . m = L / 2 and L = |wi + wo| = sqrt(2 + 2 mu): d m.z / d cos = 1 / L, d m.z / d mu =
/// -m.z / L^2, d (wi . m) / d mu = 1 / (2 L).
TANDEM_INLINE void ggx_lobe_dir_grad(BsdfDirGrad* g, float alpha, float3 wi, float3 wo, float3 m,
                                     float3 s, float3 scale_dF) {
    const float L = 2.0f * vdot(wi, m);
    if (!(L > 0.0f)) return;
    const float dlog_d = ggx_d_dlog_mz(alpha, m);
    g->d_cos_i += s * (dlog_d / L + ggx_g1_over_cos_dlog_cos(alpha, wi));
    g->d_cos_o += s * (dlog_d / L + ggx_g1_over_cos_dlog_cos(alpha, wo));
    g->d_mu += s * (-dlog_d * m.z / (L * L)) + scale_dF * (1.0f / (2.0f * L));
}

// ---- per family ----

/// Of bsdf_roughconductor_eval: specular F(wi . m) q (ggx_lobe_dir_grad).
TANDEM_INLINE BsdfDirGrad bsdf_roughconductor_dir_grad(float3 specular, float3 eta, float3 k,
                                                       float alpha, float3 wi, float3 wo) {
    BsdfDirGrad g = bsdf_dir_grad_zero();
    float3 m;
    if (wi.z <= 0.0f || wo.z <= 0.0f || !half_vector(wi, wo, &m)) return g;
    const float a = ggx_alpha(alpha);
    const float d = ggx_d(a, m);
    if (d <= 0.0f) return g;
    const float q = d * ggx_g1_over_cos(a, wi) * ggx_g1_over_cos(a, wo) * (0.25f * wo.z);
    const float c = vdot(wi, m);
    const float3 s = specular * fresnel_conductor3(c, eta, k) * q;
    const float3 dF = make_float3(fresnel_conductor_dcos(c, eta.x, k.x),
                                  fresnel_conductor_dcos(c, eta.y, k.y),
                                  fresnel_conductor_dcos(c, eta.z, k.z));
    ggx_lobe_dir_grad(&g, a, wi, wo, m, s, specular * dF * q);
    return g;
}

/// Of bsdf_roughplastic_eval: the coating, specular F_dielectric(wi . m) q, and the base, diff t_i
/// t_o cos_o / (pi eta^2), whose t_i = t(cos_i) and t_o = t(cos_o) are the table's.
TANDEM_INLINE BsdfDirGrad bsdf_roughplastic_dir_grad(TANDEM_GLOBAL const float* table,
                                                     float3 diffuse, float3 specular, float eta,
                                                     float alpha, int nonlinear, float3 wi,
                                                     float3 wo) {
    BsdfDirGrad g = bsdf_dir_grad_zero();
    if (wi.z <= 0.0f || wo.z <= 0.0f) return g;
    float3 m;
    if (half_vector(wi, wo, &m)) {
        const float a = ggx_alpha(alpha);
        const float d = ggx_d(a, m);
        if (d > 0.0f) {
            const float q = d * ggx_g1_over_cos(a, wi) * ggx_g1_over_cos(a, wo) * (0.25f * wo.z);
            const float c = vdot(wi, m);
            ggx_lobe_dir_grad(&g, a, wi, wo, m, specular * (fresnel_dielectric_r(c, eta) * q),
                              specular * (fresnel_dielectric_dcos(c, eta) * q));
        }
    }
    const PlasticCell c = plastic_cell(alpha);
    const float3 diff =
        roughplastic_diff(diffuse, plastic_internal_reflectance(table, &c), nonlinear) *
        (TANDEM_INV_PI / (eta * eta) * wo.z);
    const float t_i = plastic_transmittance(table, &c, wi.z);
    const float t_o = plastic_transmittance(table, &c, wo.z);
    g.d_cos_i += diff * (plastic_transmittance_dcos(table, &c, wi.z) * t_o);
    g.d_cos_o += diff * (t_i * plastic_transmittance_dcos(table, &c, wo.z));
    return g;
}

/// The derivatives of bsdf_eval(tables, m, albedo, wi, wo) in (cos_i, cos_o, mu), the explicit
/// cos_o held fixed; same dispatch and feature macros as bsdf_eval. Zero for a diffuse BSDF (its
/// f is constant) and for the delta types.
TANDEM_INLINE BsdfDirGrad bsdf_eval_dir_grad(TANDEM_GLOBAL const float* tables, const Material* m,
                                             float3 albedo, float3 wi, float3 wo) {
    switch (m->type) {
#if BSDF_CONDUCTOR
    case MATERIAL_ROUGHCONDUCTOR:
        return bsdf_roughconductor_dir_grad(xyz(m->specular), xyz(m->eta), xyz(m->k), m->alpha, wi,
                                            wo);
#endif
#if BSDF_PLASTIC
    case MATERIAL_ROUGHPLASTIC:
        return bsdf_roughplastic_dir_grad(tables + m->plastic_table, albedo, xyz(m->specular),
                                          m->eta.x, m->alpha,
                                          (m->flags & MATERIAL_FLAG_NONLINEAR) != 0u, wi, wo);
#endif
    default:
        (void)tables;
        (void)albedo;
        return bsdf_dir_grad_zero();
    }
}

/// Whether bsdf_eval_dir_grad can be nonzero for the material (a glossy lobe or a table in cos).
TANDEM_INLINE int bsdf_has_dir_grad(const Material* m) {
    return m->type == MATERIAL_ROUGHCONDUCTOR || m->type == MATERIAL_ROUGHPLASTIC;
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_BSDF_DIR_GRAD_H
