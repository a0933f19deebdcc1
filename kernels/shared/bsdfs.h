// BSDFs, shared by host and device: eval, pdf and sample in the local shading frame (+z = shading
// normal), after Mitsuba 3's plugins diffuse, conductor, roughconductor, dielectric, roughplastic.
// wi points to the previous path vertex, wo to the next; both unit and pointing away from the
// surface. All but the dielectric are one-sided (zero when wi.z <= 0 or wo.z <= 0); `twosided` is
// the caller's business (it flips the frame). Checked by tests/kernels/shared/test_bsdf.cpp.
#ifndef TANDEM_SHARED_BSDFS_H
#define TANDEM_SHARED_BSDFS_H

#include "shared/fresnel.h"
#include "shared/microfacet.h"
#include "shared/plastic_table.h"
#include "shared/sampling.h"
#include "shared/scene_layout.h"

TANDEM_NAMESPACE_BEGIN

// ---- diffuse: Lambertian, f = reflectance / pi ----

/// Whether the Lambertian BSDF transmits anything between wi and wo (local z of each): both above
/// the surface.
TANDEM_INLINE int diffuse_lit(float wi_z, float wo_z) { return !(wi_z <= 0.0f || wo_z <= 0.0f); }
/// d(f cos)/d(albedo) of the Lambertian BSDF, the same for every channel: cos(theta_o) / pi, zero
/// below the surface. f cos of a channel is its albedo times this.
TANDEM_INLINE float diffuse_cos(float wi_z, float wo_z) {
    return diffuse_lit(wi_z, wo_z) ? TANDEM_INV_PI * wo_z : 0.0f;
}
/// One channel of f(wi, wo) * cos(theta_o) of the Lambertian BSDF: albedo / pi * cos, zero below
/// the surface. (The channel forms are the one definition: the wavefront's shading stage calls
/// them in scalars, bsdf_diffuse_eval on the three channels.)
TANDEM_INLINE float diffuse_f(float albedo, float wi_z, float wo_z) {
    return diffuse_lit(wi_z, wo_z) ? albedo * (TANDEM_INV_PI * wo_z) : 0.0f;
}
/// Density of the Lambertian BSDF's sample toward local z wo_z, seen from wi_z.
TANDEM_INLINE float diffuse_pdf(float wi_z, float wo_z) {
    return wi_z <= 0.0f ? 0.0f : cosine_hemisphere_pdf(wo_z);
}
/// Whether the Lambertian BSDF's sample of density pdf, seen from wi_z, succeeds (its weight is
/// then the albedo; else 0 with density 0).
TANDEM_INLINE int diffuse_sampled(float wi_z, float pdf) { return !(wi_z <= 0.0f || pdf <= 0.0f); }

/// f(wi, wo) * cos(theta_o) of the Lambertian BSDF: albedo / pi * cos, zero below the surface.
TANDEM_INLINE float3 bsdf_diffuse_eval(float3 albedo, float3 wi, float3 wo) {
    return make_float3(diffuse_f(albedo.x, wi.z, wo.z), diffuse_f(albedo.y, wi.z, wo.z),
                       diffuse_f(albedo.z, wi.z, wo.z));
}
TANDEM_INLINE float bsdf_diffuse_pdf(float3 wi, float3 wo) { return diffuse_pdf(wi.z, wo.z); }
/// Samples wo by the cosine; returns the weight f * cos / pdf (= albedo) and writes wo and pdf.
TANDEM_INLINE float3 bsdf_diffuse_sample(float3 albedo, float3 wi, float u1, float u2, float3* wo,
                                         float* pdf) {
    *wo = sample_cosine_hemisphere(u1, u2);
    *pdf = cosine_hemisphere_pdf(wo->z);
    if (!diffuse_sampled(wi.z, *pdf)) {
        *pdf = 0.0f;
        return make_float3(0.0f, 0.0f, 0.0f);
    }
    return albedo;
}

// ---- conductor: smooth mirror (delta), value specular * F_conductor(cos_i; eta + i k) ----

/// Writes the mirror direction and returns its weight specular * F (the lobe is chosen with
/// probability 1); 0 from behind (wi.z <= 0).
TANDEM_INLINE float3 bsdf_conductor_sample(float3 specular, float3 eta, float3 k, float3 wi,
                                           float3* wo) {
    *wo = make_float3(-wi.x, -wi.y, wi.z);
    if (wi.z <= 0.0f) return make_float3(0.0f, 0.0f, 0.0f);
    return specular * fresnel_conductor3(wi.z, eta, k);
}

// ---- roughconductor: GGX, f = specular F(wi.m) D(m) G1(wi) G1(wo) / (4 cos_i cos_o) ----

/// f(wi, wo) * cos_o = specular * F(wi.m) * D(m) * (G1(wi)/cos_i) * (G1(wo)/cos_o) * cos_o / 4,
/// m = normalize(wi + wo). alpha is clamped to >= 1e-4.
TANDEM_INLINE float3 bsdf_roughconductor_eval(float3 specular, float3 eta, float3 k, float alpha,
                                              float3 wi, float3 wo) {
    const float3 zero = make_float3(0.0f, 0.0f, 0.0f);
    float3 m;
    if (wi.z <= 0.0f || wo.z <= 0.0f || !half_vector(wi, wo, &m)) return zero;
    const float a = ggx_alpha(alpha);
    const float d = ggx_d(a, m);
    if (d <= 0.0f) return zero;
    const float s = d * ggx_g1_over_cos(a, wi) * ggx_g1_over_cos(a, wo) * (0.25f * wo.z);
    return specular * fresnel_conductor3(vdot(wi, m), eta, k) * s;
}
/// Density of bsdf_roughconductor_sample: D(m) G1(wi) / (4 cos_i) (visible normals, reflected).
TANDEM_INLINE float bsdf_roughconductor_pdf(float alpha, float3 wi, float3 wo) {
    float3 m;
    if (wi.z <= 0.0f || wo.z <= 0.0f || !half_vector(wi, wo, &m)) return 0.0f;
    return ggx_reflection_pdf(ggx_alpha(alpha), wi, m);
}
/// Samples a visible normal m and reflects wi about it; weight = specular * F(wi.m) * G1(wo), as
/// Mitsuba. Fails (pdf 0) when wo falls below the surface. F, G and the pdf use the half vector
/// recomputed from (wi, wo), so *pdf equals bsdf_roughconductor_pdf(wi, *wo) bit for bit.
TANDEM_INLINE float3 bsdf_roughconductor_sample(float3 specular, float3 eta, float3 k, float alpha,
                                                float3 wi, float u1, float u2, float3* wo,
                                                float* pdf) {
    const float3 zero = make_float3(0.0f, 0.0f, 0.0f);
    *pdf = 0.0f;
    *wo = zero;
    if (wi.z <= 0.0f) return zero;
    const float a = ggx_alpha(alpha);
    const float3 w = vreflect(wi, ggx_sample_visible(a, wi, u1, u2));
    float3 m;
    if (w.z <= 0.0f || !half_vector(wi, w, &m)) return zero;
    const float p = ggx_reflection_pdf(a, wi, m);
    if (!(p > 0.0f)) return zero;
    *wo = w;
    *pdf = p;
    return specular * fresnel_conductor3(vdot(wi, m), eta, k) * ggx_g1(a, w);
}

// ---- dielectric: smooth interface, delta reflection (prob. F) and refraction (prob. 1 - F) ----

/// Chooses reflection with probability F(cos_i) (u_lobe < F), else refraction; both sides (wi.z < 0
/// means inside, relative IOR 1/eta). Writes wo and the lobe's probability *prob. Weight:
/// reflection specular (F / F); refraction eta_ti^2 (1 - F)/(1 - F), Mitsuba's radiance scaling for
/// the solid angle compression (eta_ti = ext/int from wi's side: 1/eta^2 entering, eta^2 leaving).
TANDEM_INLINE float3 bsdf_dielectric_sample(float3 specular, float eta, float3 wi, float u_lobe,
                                            float3* wo, float* prob) {
    float cos_t, eta_ti;
    const float f = fresnel_dielectric(wi.z, eta, &cos_t, &eta_ti);
    if (u_lobe < f) {
        *wo = make_float3(-wi.x, -wi.y, wi.z);
        *prob = f;
        return specular;
    }
    // Snell: tangential part scaled by -eta_ti, normal part cos_t on the other side.
    *wo = make_float3(-eta_ti * wi.x, -eta_ti * wi.y, cos_t);
    *prob = 1.0f - f;
    const float s = eta_ti * eta_ti;
    return make_float3(s, s, s);
}

// ---- roughplastic: GGX dielectric coating over a diffuse base (Mitsuba 3's roughplastic) ----
// f cos_o = specular F(wi.m, eta) D G1(wi) G1(wo) / (4 cos_i)
//         + diff t(cos_i) t(cos_o) cos_o / (eta^2 pi),
// diff = diffuse / (1 - r)          (linear, Mitsuba's default),
//      = diffuse / (1 - diffuse r)  (nonlinear),
// t the rough interface's external transmittance and r its internal diffuse reflectance, both
// from the material's table at alpha (shared/plastic_table.h), as Mitsuba 3 computes them.

/// Probability of sampling the specular lobe: Mitsuba's (1 - t_i) w / ((1 - t_i) w + t_i (1 - w))
/// with w = s / (s + d), i.e. (1 - t_i) s / ((1 - t_i) s + t_i d), s = mean(specular),
/// d = mean(diffuse). 1/2 when both vanish (the BSDF is then black for this wi).
TANDEM_INLINE float roughplastic_specular_prob(float3 diffuse, float3 specular, float t_i) {
    const float ps = (1.0f - t_i) * mean3(specular), pd = t_i * mean3(diffuse);
    return ps + pd > 0.0f ? ps / (ps + pd) : 0.5f;
}

/// The rescaled base: diffuse / (1 - r), or diffuse / fmax(1 - diffuse r, 1e-3) when nonlinear.
TANDEM_INLINE float3 roughplastic_diff(float3 diffuse, float r, int nonlinear) {
    if (nonlinear)
        return make_float3(diffuse.x / fmax(1.0f - diffuse.x * r, 1e-3f),
                           diffuse.y / fmax(1.0f - diffuse.y * r, 1e-3f),
                           diffuse.z / fmax(1.0f - diffuse.z * r, 1e-3f));
    return diffuse * (1.0f / (1.0f - r));
}

/// The coating's share of f cos_o: specular F(wi.m) D G1(wi) G1(wo) / (4 cos_i) (wi, wo above).
TANDEM_INLINE float3 roughplastic_coating(float3 specular, float eta, float alpha, float3 wi,
                                          float3 wo) {
    float3 m;
    if (!half_vector(wi, wo, &m)) return make_float3(0.0f, 0.0f, 0.0f);
    const float a = ggx_alpha(alpha);
    const float d = ggx_d(a, m);
    const float g = ggx_g1_over_cos(a, wi) * ggx_g1_over_cos(a, wo);
    return specular * (fresnel_dielectric_r(vdot(wi, m), eta) * d * g * (0.25f * wo.z));
}

/// f cos_o with the cell of alpha and t_i = t(wi.z) already looked up. `table`: the material's.
TANDEM_INLINE float3 roughplastic_eval_at(TANDEM_GLOBAL const float* table, const PlasticCell* c,
                                          float t_i, float3 diffuse, float3 specular, float eta,
                                          float alpha, int nonlinear, float3 wi, float3 wo) {
    const float3 diff =
        roughplastic_diff(diffuse, plastic_internal_reflectance(table, c), nonlinear);
    const float t = t_i * plastic_transmittance(table, c, wo.z);
    return roughplastic_coating(specular, eta, alpha, wi, wo) +
           diff * (t * TANDEM_INV_PI / (eta * eta) * wo.z);
}

/// Mixture density with p_spec already known: p_spec D(m) G1(wi) / (4 cos_i) + (1 - p_spec) cos_o
/// / pi (wi, wo above).
TANDEM_INLINE float roughplastic_pdf_at(float p_spec, float alpha, float3 wi, float3 wo) {
    float3 m;
    const float spec = half_vector(wi, wo, &m) ? ggx_reflection_pdf(ggx_alpha(alpha), wi, m) : 0.0f;
    return p_spec * spec + (1.0f - p_spec) * pdf_cosine_hemisphere(wo);
}

/// f(wi, wo) cos_o; `table`: the material's interface table (shared/plastic_table.h).
TANDEM_INLINE float3 bsdf_roughplastic_eval(TANDEM_GLOBAL const float* table, float3 diffuse,
                                            float3 specular, float eta, float alpha, int nonlinear,
                                            float3 wi, float3 wo) {
    if (wi.z <= 0.0f || wo.z <= 0.0f) return make_float3(0.0f, 0.0f, 0.0f);
    const PlasticCell c = plastic_cell(alpha);
    const float t_i = plastic_transmittance(table, &c, wi.z);
    return roughplastic_eval_at(table, &c, t_i, diffuse, specular, eta, alpha, nonlinear, wi, wo);
}

/// Mixture density: p_spec * D(m) G1(wi) / (4 cos_i) + (1 - p_spec) * cos_o / pi.
TANDEM_INLINE float bsdf_roughplastic_pdf(TANDEM_GLOBAL const float* table, float3 diffuse,
                                          float3 specular, float alpha, float3 wi, float3 wo) {
    if (wi.z <= 0.0f || wo.z <= 0.0f) return 0.0f;
    const PlasticCell c = plastic_cell(alpha);
    const float t_i = plastic_transmittance(table, &c, wi.z);
    return roughplastic_pdf_at(roughplastic_specular_prob(diffuse, specular, t_i), alpha, wi, wo);
}

/// u_lobe < p_spec: reflect about a visible GGX normal, else cosine-weighted. As Mitsuba, the
/// weight is the full eval over the full mixture pdf; *pdf equals bsdf_roughplastic_pdf bit for
/// bit.
TANDEM_INLINE float3 bsdf_roughplastic_sample(TANDEM_GLOBAL const float* table, float3 diffuse,
                                              float3 specular, float eta, float alpha,
                                              int nonlinear, float3 wi, float u_lobe, float u1,
                                              float u2, float3* wo, float* pdf) {
    const float3 zero = make_float3(0.0f, 0.0f, 0.0f);
    *pdf = 0.0f;
    *wo = zero;
    if (wi.z <= 0.0f) return zero;
    const PlasticCell c = plastic_cell(alpha);
    const float t_i = plastic_transmittance(table, &c, wi.z);
    const float p_spec = roughplastic_specular_prob(diffuse, specular, t_i);
    const float3 w = u_lobe < p_spec
                         ? vreflect(wi, ggx_sample_visible(ggx_alpha(alpha), wi, u1, u2))
                         : sample_cosine_hemisphere(u1, u2);
    if (w.z <= 0.0f) return zero;
    const float p = roughplastic_pdf_at(p_spec, alpha, wi, w);
    if (!(p > 0.0f)) return zero;
    *wo = w;
    *pdf = p;
    return roughplastic_eval_at(table, &c, t_i, diffuse, specular, eta, alpha, nonlinear, wi, w) *
           (1.0f / p);
}

// ---- generic entry points, dispatching on Material.type ----
// BSDF_CONDUCTOR, BSDF_DIELECTRIC and BSDF_PLASTIC select which families the dispatch compiles:
// the host passes each to every kernel build as a -D option (render_features in
// core/render/features.h); the host's own build of this code compiles all of them.
#if !TANDEM_DEVICE
#define BSDF_CONDUCTOR 1
#define BSDF_DIELECTRIC 1
#define BSDF_PLASTIC 1
#endif

/// f(wi, wo) * |cos(theta_o)| for the non-delta components; 0 for purely specular materials.
/// tables: the scene's plastic_tables (roughplastic reads its own at m->plastic_table); albedo:
/// the (texture-resolved) `reflectance` of diffuse / diffuse_reflectance of roughplastic.
TANDEM_INLINE float3 bsdf_eval(TANDEM_GLOBAL const float* tables, const Material* m, float3 albedo,
                               float3 wi, float3 wo) {
    switch (m->type) {
    case MATERIAL_DIFFUSE:
        return bsdf_diffuse_eval(albedo, wi, wo);
#if BSDF_CONDUCTOR
    case MATERIAL_ROUGHCONDUCTOR:
        return bsdf_roughconductor_eval(xyz(m->specular), xyz(m->eta), xyz(m->k), m->alpha, wi, wo);
#endif
#if BSDF_PLASTIC
    case MATERIAL_ROUGHPLASTIC:
        return bsdf_roughplastic_eval(tables + m->plastic_table, albedo, xyz(m->specular), m->eta.x,
                                      m->alpha, (m->flags & MATERIAL_FLAG_NONLINEAR) != 0u, wi, wo);
#endif
    default:
        (void)tables;
        return make_float3(0.0f, 0.0f, 0.0f); // conductor, dielectric: delta only
    }
}

/// Solid-angle density with which bsdf_sample produces wo (non-delta components only).
TANDEM_INLINE float bsdf_pdf(TANDEM_GLOBAL const float* tables, const Material* m, float3 albedo,
                             float3 wi, float3 wo) {
    switch (m->type) {
    case MATERIAL_DIFFUSE:
        return bsdf_diffuse_pdf(wi, wo);
#if BSDF_CONDUCTOR
    case MATERIAL_ROUGHCONDUCTOR:
        return bsdf_roughconductor_pdf(m->alpha, wi, wo);
#endif
#if BSDF_PLASTIC
    case MATERIAL_ROUGHPLASTIC:
        return bsdf_roughplastic_pdf(tables + m->plastic_table, albedo, xyz(m->specular), m->alpha,
                                     wi, wo);
#endif
    default:
        (void)tables;
        return 0.0f;
    }
}

/// Samples wo; returns the weight f*|cos|/pdf (for a delta lobe: the lobe's value / its selection
/// probability); writes *wo, *pdf (for a delta lobe: 0 — callers must not MIS-weight it) and
/// *delta (1 if a delta lobe was sampled). On failure returns 0 with *pdf = 0, *delta = 0.
TANDEM_INLINE float3 bsdf_sample(TANDEM_GLOBAL const float* tables, const Material* m,
                                 float3 albedo, float3 wi, float u_lobe, float u1, float u2,
                                 float3* wo, float* pdf, int* delta) {
    const float3 zero = make_float3(0.0f, 0.0f, 0.0f);
    float3 weight = zero;
    *pdf = 0.0f;
    *delta = 0;
    switch (m->type) {
    case MATERIAL_DIFFUSE:
        return bsdf_diffuse_sample(albedo, wi, u1, u2, wo, pdf);
#if BSDF_CONDUCTOR
    case MATERIAL_ROUGHCONDUCTOR:
        return bsdf_roughconductor_sample(xyz(m->specular), xyz(m->eta), xyz(m->k), m->alpha, wi,
                                          u1, u2, wo, pdf);
    case MATERIAL_CONDUCTOR:
        if (wi.z <= 0.0f) break;
        weight = bsdf_conductor_sample(xyz(m->specular), xyz(m->eta), xyz(m->k), wi, wo);
        *delta = 1;
        return weight;
#endif
#if BSDF_PLASTIC
    case MATERIAL_ROUGHPLASTIC:
        return bsdf_roughplastic_sample(
            tables + m->plastic_table, albedo, xyz(m->specular), m->eta.x, m->alpha,
            (m->flags & MATERIAL_FLAG_NONLINEAR) != 0u, wi, u_lobe, u1, u2, wo, pdf);
#endif
#if BSDF_DIELECTRIC
    case MATERIAL_DIELECTRIC: {
        float prob;
        weight = bsdf_dielectric_sample(xyz(m->specular), m->eta.x, wi, u_lobe, wo, &prob);
        if (!(prob > 0.0f)) break;
        *delta = 1;
        return weight;
    }
#endif
    default:
        (void)tables;
        break;
    }
    *wo = zero;
    return zero;
}

/// The weight bsdf_sample would give the delta lobe that maps wi to wo (sampled before, possibly
/// with another material state of the same type and IOR), with the lobe's selection probability
/// held fixed: conductor specular * F; dielectric reflection (wi, wo on the same side) specular,
/// refraction eta_ti^2. The two-state path (kernels/path/two_state.h) multiplies the old
/// throughput by this for the old state's material.
TANDEM_INLINE float3 bsdf_delta_weight(const Material* m, float3 wi, float3 wo) {
    const float3 zero = make_float3(0.0f, 0.0f, 0.0f);
    switch (m->type) {
#if BSDF_CONDUCTOR
    case MATERIAL_CONDUCTOR:
        if (wi.z <= 0.0f) return zero;
        return xyz(m->specular) * fresnel_conductor3(wi.z, xyz(m->eta), xyz(m->k));
#endif
#if BSDF_DIELECTRIC
    case MATERIAL_DIELECTRIC: {
        if ((wi.z >= 0.0f) == (wo.z >= 0.0f)) return xyz(m->specular);
        float cos_t, eta_ti;
        fresnel_dielectric(wi.z, m->eta.x, &cos_t, &eta_ti);
        const float s = eta_ti * eta_ti;
        return make_float3(s, s, s);
    }
#endif
    default:
        return zero;
    }
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_BSDFS_H
