// BSDFs, shared by host and device: eval, pdf and sample in the local shading frame (+z = normal,
// both directions pointing away from the surface). Mitsuba's conventions: `diffuse` is one-sided.
#ifndef TANDEM_SHARED_BSDFS_H
#define TANDEM_SHARED_BSDFS_H

#include "shared/sampling.h"
#include "shared/scene_layout.h"

TANDEM_NAMESPACE_BEGIN

/// f(wi, wo) * cos(theta_o) of the Lambertian BSDF: albedo / pi * cos, zero below the surface.
TANDEM_INLINE float3 bsdf_diffuse_eval(float3 albedo, float3 wi, float3 wo) {
    if (wi.z <= 0.0f || wo.z <= 0.0f) return make_float3(0.0f, 0.0f, 0.0f);
    return albedo * (TANDEM_INV_PI * wo.z);
}
TANDEM_INLINE float bsdf_diffuse_pdf(float3 wi, float3 wo) {
    return wi.z <= 0.0f ? 0.0f : pdf_cosine_hemisphere(wo);
}
/// Samples wo by the cosine; returns the weight f * cos / pdf (= albedo) and writes wo and pdf.
TANDEM_INLINE float3 bsdf_diffuse_sample(float3 albedo, float3 wi, float u1, float u2, float3* wo,
                                         float* pdf) {
    *wo = sample_cosine_hemisphere(u1, u2);
    *pdf = pdf_cosine_hemisphere(*wo);
    if (wi.z <= 0.0f || *pdf <= 0.0f) {
        *pdf = 0.0f;
        return make_float3(0.0f, 0.0f, 0.0f);
    }
    return albedo;
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_BSDFS_H
