// Isotropic GGX (Trowbridge-Reitz) microfacet distribution, shared by host and device: D, Smith's
// separable masking G1 (Walter et al., "Microfacet Models for Refraction", EGSR 2007, eqs. 33-34),
// and sampling of the visible normals (Heitz, "Sampling the GGX Distribution of Visible Normals",
// JCGT 7(4), 2018). Local frame, +z = macro normal. Mitsuba 3's MicrofacetDistribution (GGX).
#ifndef TANDEM_SHARED_MICROFACET_H
#define TANDEM_SHARED_MICROFACET_H

#include "shared/sampling.h"

TANDEM_NAMESPACE_BEGIN

/// Smallest roughness used: Mitsuba 3 clamps alpha to 1e-4 too. Below it D overflows nothing but
/// its peak (1 / (pi alpha^2)) is no longer resolved by float directions.
#define GGX_ALPHA_MIN 1e-4f

TANDEM_INLINE float ggx_alpha(float alpha) {
    return fmax(alpha, GGX_ALPHA_MIN);
}

/// D(m) = 1 / (pi alpha^2 cos^4 (1 + tan^2 / alpha^2)^2)
///      = 1 / (pi alpha^2 ((m.x^2 + m.y^2) / alpha^2 + m.z^2)^2)   (unit m; 0 for m.z <= 0).
/// Bounded by 1 / (pi alpha^2) <= 3.2e7 for alpha >= 1e-4 (the bracket is >= 1 for alpha <= 1).
/// As Mitsuba, values with D cos < 1e-20 are flushed to 0.
TANDEM_INLINE float ggx_d(float alpha, float3 m) {
    if (m.z <= 0.0f) return 0.0f;
    const float a2 = alpha * alpha;
    const float b = (m.x * m.x + m.y * m.y) / a2 + m.z * m.z;
    const float d = 1.0f / (TANDEM_PI * a2 * (b * b));
    return d * m.z > 1e-20f ? d : 0.0f;
}

/// Smith masking divided by the cosine, G1(v) / v.z, for v above the surface:
///   G1 = 2 / (1 + sqrt(1 + alpha^2 tan^2 theta))  =>  G1 / cos = 2 / (cos + sqrt(cos^2 + alpha^2
///   sin^2)).
/// This form stays bounded (<= 2 / (alpha sin)) as v.z -> 0, where G1 and cos both vanish.
/// Returns 0 for v.z <= 0. The caller checks that v sees the front of the microfacet (v.m > 0).
TANDEM_INLINE float ggx_g1_over_cos(float alpha, float3 v) {
    if (v.z <= 0.0f) return 0.0f;
    const float den = v.z + sqrt(v.z * v.z + alpha * alpha * (v.x * v.x + v.y * v.y));
    return den > 0.0f ? 2.0f / den : 0.0f;
}

/// G1(v) in [0, 1] (1 at normal incidence, 0 at the horizon).
TANDEM_INLINE float ggx_g1(float alpha, float3 v) {
    return fmin(1.0f, v.z * ggx_g1_over_cos(alpha, v));
}

/// Samples a microfacet normal from the distribution of normals visible from wi (wi.z > 0),
/// D_wi(m) = G1(wi) max(0, wi.m) D(m) / wi.z  (Heitz 2018, listing 1 and eq. 1).
TANDEM_INLINE float3 ggx_sample_visible(float alpha, float3 wi, float u1, float u2) {
    // Section 3.2: stretch the view direction into the hemisphere configuration (alpha = 1).
    const float3 vh = vnormalize(make_float3(alpha * wi.x, alpha * wi.y, wi.z));
    // Section 4.1: orthonormal basis (T1 = +x when vh is the pole).
    const float lensq = vh.x * vh.x + vh.y * vh.y;
    const float3 t1 = lensq > 0.0f ? make_float3(-vh.y, vh.x, 0.0f) * (1.0f / sqrt(lensq))
                                   : make_float3(1.0f, 0.0f, 0.0f);
    const float3 t2 = vcross(vh, t1);
    // Section 4.2: a uniform point on the disk, squeezed onto the projected visible half-disk.
    const float r = sqrt(u1);
    float sin_phi, cos_phi;
    det_sincos(2.0f * TANDEM_PI * u2, &sin_phi, &cos_phi);
    const float p1 = r * cos_phi;
    const float s = 0.5f * (1.0f + vh.z);
    const float p2 = (1.0f - s) * safe_sqrt(1.0f - p1 * p1) + s * (r * sin_phi);
    // Section 4.3: reproject onto the hemisphere.
    const float3 nh = t1 * p1 + t2 * p2 + vh * safe_sqrt(1.0f - p1 * p1 - p2 * p2);
    // Section 3.4: unstretch back to the ellipsoid configuration. |(alpha nh.x, alpha nh.y, nh.z)|
    // >= alpha |nh| > 0, so the normalisation cannot divide by zero.
    return vnormalize(make_float3(alpha * nh.x, alpha * nh.y, fmax(0.0f, nh.z)));
}

/// Density of reflected directions wo = reflect(wi, m), m ~ D_wi, in solid angle:
///   pdf(wo) = D_wi(m) / (4 |wo.m|) = D(m) G1(wi) / (4 wi.z)   (m the half vector, wi.m = wo.m).
/// Written with G1 / cos so that it stays finite as wi.z -> 0.
TANDEM_INLINE float ggx_reflection_pdf(float alpha, float3 wi, float3 m) {
    return ggx_d(alpha, m) * ggx_g1_over_cos(alpha, wi) * 0.25f;
}

/// The unit half vector of two directions on the same side: normalize(wi + wo). Returns 0 (and a
/// zero vector) when the sum has no usable length or the half vector is below the surface.
TANDEM_INLINE int half_vector(float3 wi, float3 wo, float3* m) {
    const float3 h = wi + wo;
    const float len2 = vdot(h, h);
    *m = make_float3(0.0f, 0.0f, 0.0f);
    if (!(len2 > 1e-30f)) return 0;
    *m = h * (1.0f / sqrt(len2));
    return m->z > 0.0f;
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_MICROFACET_H
