// Fresnel equations shared by host and device, as Mitsuba 3's render/fresnel.h: unpolarised
// reflectance of dielectric and conductor interfaces, and the diffuse Fresnel reflectance fits.
#ifndef TANDEM_SHARED_FRESNEL_H
#define TANDEM_SHARED_FRESNEL_H

#include "shared/sampling.h"

TANDEM_NAMESPACE_BEGIN

/// Unpolarised Fresnel reflectance of a smooth dielectric interface (Mitsuba 3 `fresnel`).
/// cos_theta_i: cosine between the incident direction and the normal, negative when it arrives from
/// inside; eta: relative IOR int/ext. Writes *cos_theta_t, the cosine of the refracted direction
/// (sign opposite to cos_theta_i; 0 under total internal reflection), and *eta_ti = ext/int IOR
/// seen from the incident side (1/eta outside, eta inside). Returns 1 under total internal
/// reflection and at cos_theta_i = 0, and 0 for eta = 1.
///   cos_t^2 = 1 - eta_ti^2 (1 - cos_i^2)                                     (Snell)
///   a_s = (cos_i - eta_it cos_t) / (cos_i + eta_it cos_t)                     (s-polarised)
///   a_p = (cos_t - eta_it cos_i) / (cos_t + eta_it cos_i)                     (p-polarised)
///   F   = (a_s^2 + a_p^2) / 2
TANDEM_INLINE float fresnel_dielectric(float cos_theta_i, float eta, float* cos_theta_t,
                                       float* eta_ti) {
    const int outside = cos_theta_i >= 0.0f;
    const float eta_it = outside ? eta : 1.0f / eta;
    const float ti = outside ? 1.0f / eta : eta;
    const float cos_t_sqr = 1.0f - (1.0f - cos_theta_i * cos_theta_i) * (ti * ti);
    const float cos_i = fabs(cos_theta_i);
    const float cos_t = safe_sqrt(cos_t_sqr);
    *eta_ti = ti;
    *cos_theta_t = outside ? -cos_t : cos_t;
    if (eta == 1.0f) return 0.0f; // index-matched: no interface
    if (cos_t_sqr <= 0.0f) {      // total internal reflection
        *cos_theta_t = 0.0f;
        return 1.0f;
    }
    if (cos_i == 0.0f) return 1.0f; // grazing
    const float a_s = (cos_i - eta_it * cos_t) / (cos_i + eta_it * cos_t);
    const float a_p = (cos_t - eta_it * cos_i) / (cos_t + eta_it * cos_i);
    return 0.5f * (a_s * a_s + a_p * a_p);
}

/// The reflectance only, for callers that need neither cos_theta_t nor eta_ti.
TANDEM_INLINE float fresnel_dielectric_r(float cos_theta_i, float eta) {
    float cos_t, eta_ti;
    return fresnel_dielectric(cos_theta_i, eta, &cos_t, &eta_ti);
}

/// Unpolarised Fresnel reflectance of a conductor with complex relative IOR eta + i k, for
/// 0 <= cos_theta_i <= 1 (Mitsuba 3 `fresnel_conductor`, after K. D. Moeller, "Optics", 1988):
///   t1 = eta^2 - k^2 - sin^2,  a^2 + b^2 = sqrt(t1^2 + 4 eta^2 k^2),  a = sqrt((a^2 + b^2 + t1)/2)
///   r_s = (a^2 + b^2 + cos^2 - 2 a cos) / (a^2 + b^2 + cos^2 + 2 a cos)
///   r_p = r_s ((a^2 + b^2) cos^2 + sin^4 - 2 a cos sin^2) / ((a^2 + b^2) cos^2 + sin^4 + 2 a cos
///   sin^2) F = (r_s + r_p) / 2
/// eta = 0, k = 1 (Mitsuba's material "none") gives F = 1 at every angle.
TANDEM_INLINE float fresnel_conductor(float cos_theta_i, float eta, float k) {
    const float cos2 = cos_theta_i * cos_theta_i;
    const float sin2 = 1.0f - cos2, sin4 = sin2 * sin2;
    const float t1 = eta * eta - k * k - sin2;
    const float a2pb2 = safe_sqrt(t1 * t1 + 4.0f * k * k * eta * eta);
    const float a = safe_sqrt(0.5f * (a2pb2 + t1));
    const float term1 = a2pb2 + cos2, term2 = 2.0f * cos_theta_i * a;
    const float den_s = term1 + term2;
    if (!(den_s > 0.0f)) return 1.0f; // eta = 1, k = 0 at grazing: no interface, the limit is 1
    // Both numerators are >= 0 in exact arithmetic ((a - cos)^2 + b^2 for r_s); the clamps keep
    // rounding (e.g. at eta = 1, k = 0) from giving a slightly negative reflectance.
    const float r_s = fmax(0.0f, (term1 - term2) / den_s);
    const float term3 = a2pb2 * cos2 + sin4, term4 = term2 * sin2;
    const float den_p = term3 + term4;
    const float r_p = den_p > 0.0f ? r_s * fmax(0.0f, (term3 - term4) / den_p) : r_s;
    return 0.5f * (r_s + r_p);
}

/// fresnel_conductor per RGB channel.
TANDEM_INLINE float3 fresnel_conductor3(float cos_theta_i, float3 eta, float3 k) {
    return make_float3(fresnel_conductor(cos_theta_i, eta.x, k.x),
                       fresnel_conductor(cos_theta_i, eta.y, k.y),
                       fresnel_conductor(cos_theta_i, eta.z, k.z));
}

/// Diffuse Fresnel reflectance: the cosine-weighted hemispherical average of
/// fresnel_dielectric(., eta), by the fits Mitsuba 3 `fresnel_diffuse_reflectance` picks:
/// eta < 1: Egan and Hilgeman (1973), -1.4399 eta^2 + 0.7099 eta + 0.6681 + 0.0636 / eta;
/// eta >= 1: d'Eon and Irving (2011), a quintic in 1/eta (0.1-0.2% relative error up to eta 10).
TANDEM_INLINE float fresnel_diffuse_reflectance(float eta) {
    const float inv_eta = 1.0f / eta;
    if (eta < 1.0f) return 0.0636f * inv_eta + (eta * (-1.4399f * eta + 0.7099f) + 0.6681f);
    return 0.919317f +
           inv_eta *
               (-3.4793f +
                inv_eta * (6.75335f +
                           inv_eta * (-7.80989f + inv_eta * (4.98554f + inv_eta * -1.36881f))));
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_FRESNEL_H
