// Shared fixtures of the BSDF tests (test_bsdf.cpp, test_fresnel.cpp, test_bsdf_grad.cpp):
// materials with their roughplastic tables, and directions.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <vector>

#include "core/scene/plastic_table.h"
#include "shared/bsdfs.h"
#include "shared/rng.h"

namespace bsdf_fixtures {

using namespace tandem::gpu;

const float3 kWhite = {1.0f, 1.0f, 1.0f};
const float3 kGoldEta = {0.1431189f, 0.3749570f, 1.4424785f}; // Mitsuba's Au, RGB
const float3 kGoldK = {3.9831604f, 2.3857207f, 1.6032152f};
const float3 kNoneEta = {0.0f, 0.0f, 0.0f}, kNoneK = {1.0f, 1.0f, 1.0f}; // material "none": F = 1
const float kPi = 3.14159265358979323846f;

/// The roughplastic tables of every IOR a fixture material uses, one after the other as in a
/// scene's plastic_tables. It grows when a new IOR appears: take tables() afresh for each call.
inline std::vector<float>& table_store() {
    static std::vector<float> store;
    return store;
}
inline const float* tables() {
    return table_store().data();
}
/// Offset of the table of eta in table_store(), added on first use.
inline uint plastic_offset(float eta) {
    static std::map<std::uint32_t, uint> offsets;
    std::uint32_t key;
    std::memcpy(&key, &eta, sizeof key);
    const auto at = offsets.find(key);
    if (at != offsets.end()) return at->second;
    const std::vector<float>& t = tandem::plastic_table(eta);
    const uint offset = (uint)table_store().size();
    table_store().insert(table_store().end(), t.begin(), t.end());
    offsets[key] = offset;
    return offset;
}

inline Material material(uint type, float alpha, float3 spec, float3 eta, float3 k, uint flags = 0) {
    Material m{};
    if (type == MATERIAL_ROUGHPLASTIC) m.plastic_table = plastic_offset(eta.x);
    m.type = type;
    m.alpha = alpha;
    m.flags = flags;
    m.specular = make_float4(spec.x, spec.y, spec.z, 0.0f);
    m.eta = make_float4(eta.x, eta.y, eta.z, 0.0f);
    m.k = make_float4(k.x, k.y, k.z, 0.0f);
    m.texture = NO_TEXTURE;
    return m;
}
inline Material diffuse() {
    return material(MATERIAL_DIFFUSE, 0.0f, kWhite, kWhite, kWhite);
}
inline Material roughconductor(float alpha, float3 eta, float3 k) {
    return material(MATERIAL_ROUGHCONDUCTOR, alpha, kWhite, eta, k);
}
inline Material roughplastic(float alpha, float eta, float3 spec, bool nonlinear = false) {
    return material(MATERIAL_ROUGHPLASTIC, alpha, spec, {eta, eta, eta}, kWhite,
                    nonlinear ? MATERIAL_FLAG_NONLINEAR : 0u);
}

/// A roughplastic's interface terms at its alpha: t(cos_theta) and r, as its eval reads them.
inline float plastic_t(const Material& m, float cos_theta) {
    const PlasticCell c = plastic_cell(m.alpha);
    return plastic_transmittance(tables() + m.plastic_table, &c, cos_theta);
}
inline float plastic_r(const Material& m) {
    const PlasticCell c = plastic_cell(m.alpha);
    return plastic_internal_reflectance(tables() + m.plastic_table, &c);
}
/// Hemispherical average 2 int t(mu) mu dmu of the roughplastic's transmittance as it is looked up
/// (linear between Mitsuba's 64 nodes): 20000-point midpoint rule, error ~1e-9.
inline double plastic_t_average(const Material& m) {
    const int n = 20000;
    double s = 0.0;
    for (int i = 0; i < n; ++i) {
        const double mu = (i + 0.5) / n;
        s += plastic_t(m, (float)mu) * mu;
    }
    return 2.0 * s / n;
}

/// Unit direction at polar angle theta_deg from +z, azimuth phi (radians).
inline float3 dir(float theta_deg, float phi = 0.7f) {
    const float t = theta_deg * kPi / 180.0f;
    return make_float3(std::sin(t) * std::cos(phi), std::sin(t) * std::sin(phi), std::cos(t));
}
const float kThetas[] = {0.0f, 45.0f, 89.0f};

/// One bsdf_sample call with (u_lobe, u1, u2) = rng_uniform(seed, stream, i, 0..2).
struct Draw {
    float3 w, wo;
    float pdf;
    int delta;
};
inline Draw draw(const Material& m, float3 albedo, float3 wi, uint seed, uint stream, uint i) {
    Draw d;
    d.w = bsdf_sample(tables(), &m, albedo, wi, rng_uniform(seed, stream, i, 0u),
                      rng_uniform(seed, stream, i, 1u), rng_uniform(seed, stream, i, 2u), &d.wo,
                      &d.pdf, &d.delta);
    return d;
}


/// Plastic's exact internal diffuse reflectance 1 - (1 - Fdr_ext) / eta^2 (Fdr_ext = 2 int F mu
/// dmu).
inline double exact_fdr_internal(float eta) {
    const int n = 200000;
    double s = 0.0;
    for (int i = 0; i < n; ++i) {
        const double mu = (i + 0.5) / n;
        s += fresnel_dielectric_r((float)mu, eta) * mu;
    }
    return 1.0 - (1.0 - 2.0 * s / n) / ((double)eta * eta);
}

} // namespace bsdf_fixtures
