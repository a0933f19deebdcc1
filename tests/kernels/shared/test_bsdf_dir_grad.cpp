// Derivatives of the BSDF values in their directions (kernels/shared/bsdf_dir_grad.h) on the
// host, against finite differences of bsdf_eval itself.
//
// The value differentiated is V(cos_i, cos_o, mu) = bsdf_eval(wi, wo) / wo.z * cos_o0: f cos_o
// with the explicit cos_o held at the stencil's centre, as bsdf_eval_dir_grad defines it (wo.z:
// the float the eval multiplies by). The directions are built in double from the three numbers,
// wi = (sin_i, 0, cos_i) and wo = (x, y, cos_o) with x = (mu - cos_i cos_o) / sin_i, then rounded
// to float, one coordinate stepped at a time.
//
// Tolerances (u = 2^-24):
// - Steps: h = 0.02 times the scale on which the value changes: the width of GGX's peak in m.z,
//   alpha^2 / 2, times L = |wi + wo| (m.z = (cos_i + cos_o) / L moves at 1 / L per unit of
//   either cosine); L^2 / 4 (L^2 = 2 + 2 mu itself, near wi = -wo); at most 0.1 (the Fresnel
//   factors, Smith's G1 and the plastic's tables vary on the scale of 1). Richardson's
//   (4 D(h) - D(2h)) / 3: truncation O((h / scale)^4) = 2e-7 relative, negligible.
// - Rounding: an eval is ~40 float roundings (the half vector and its normalisation ~8, D ~7,
//   each G1 / cos ~6, the Fresnel factor ~12, the products ~4), so <= 40 u f_max; D(h) carries
//   40 u f_max / h and the extrapolation 4/3 + 1/6 of that, 60 u f_max / h; and the directions'
//   rounding to float moves the three numbers by <= 4 u each, which moves V by <= 4 u |grad V|
//   (|grad V| the sum of the three derivatives' magnitudes) and D(h) by 4 u |grad V| / h, the
//   extrapolation by 6 u |grad V| / h. Accepted: (64 f_max + 8 |grad V|) u / h, plus 1e-4
//   |analytic| (the derivative's own rounding, ~20 operations).
// - The plastic's t(cos) is linear between the 64 nodes of its table: a stencil that straddles a
//   node in cos_i or cos_o sees the jump of its slope and is skipped (counted, at most a third).
// - Skipped too: stencils across which the value is zero somewhere (below the horizon, D flushed)
//   or below 1e-30.
// - Teeth: at least a quarter of the checks of each material are tight (tolerance < 5 % of the
//   derivative; measured 28 % for gold at alpha 0.05, where the directions' rounding dominates,
//   53-98 % for the others; the worst |fd - analytic| is 0.2 of the tolerance), and two negative
//   controls must fail on many checks: the conductor's Fresnel derivative dropped (its gradient
//   computed with material "none", F = 1, times gold's F; it changes d/dmu only; measured 17 %
//   of all checks, required 10 %) and the plastic's d/dcos_i and d/dcos_o swapped (measured 49 %,
//   required 30 %).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <string>

#include "bsdf_fixtures.h"
#include "shared/bsdf_dir_grad.h"

using namespace tandem::gpu;
using namespace bsdf_fixtures;

namespace {

constexpr double kU = 5.9604644775390625e-8; // 2^-24

double get(float3 v, int c) {
    return c == 0 ? v.x : (c == 1 ? v.y : v.z);
}
float3 grad_of(const BsdfDirGrad& g, int j) {
    return j == 0 ? g.d_cos_i : (j == 1 ? g.d_cos_o : g.d_mu);
}

/// wi, wo in float from (cos_i, cos_o, mu) in double; false where no such pair exists.
bool directions(double ci, double co, double mu, float3* wi, float3* wo) {
    const double si = std::sqrt(1.0 - ci * ci);
    const double x = (mu - ci * co) / si;
    const double y2 = 1.0 - co * co - x * x;
    if (!(si > 0.0) || !(y2 > 0.0)) return false;
    *wi = make_float3((float)si, 0.0f, (float)ci);
    *wo = make_float3((float)x, (float)std::sqrt(y2), (float)co);
    return true;
}

struct Tally {
    int checked = 0, skipped = 0, tight = 0, failed = 0, control_failed = 0;
    double worst = 0.0;
};

/// Checks the three derivatives of m at one configuration; `control` (when set) is a wrong
/// gradient that is counted as failed where it misses the same tolerance.
void check_config(const Material& m, float3 albedo, double ci, double co, double mu, Tally* t,
                  const std::function<BsdfDirGrad(float3, float3)>& control, std::string* why) {
    float3 wi, wo;
    if (!directions(ci, co, mu, &wi, &wo)) return;
    const BsdfDirGrad g = bsdf_eval_dir_grad(tables(), &m, albedo, wi, wo);
    const BsdfDirGrad bad = control ? control(wi, wo) : g;
    const double L = std::sqrt(2.0 + 2.0 * mu); // |wi + wo|
    const double scale = std::min({0.1, 0.5 * (double)m.alpha * m.alpha * L, 0.25 * L * L});
    const double h = 0.02 * scale;
    const double co0 = co;
    auto value = [&](int j, double x, float3* out) {
        double c3[3] = {ci, co, mu};
        c3[j] = x;
        float3 a, b;
        if (!directions(c3[0], c3[1], c3[2], &a, &b)) return false;
        const float3 v = bsdf_eval(tables(), &m, albedo, a, b);
        *out = v * (float)(co0 / (double)b.z); // explicit cos_o held at the centre
        return true;
    };
    for (int j = 0; j < 3; ++j) {
        const double x0 = j == 0 ? ci : (j == 1 ? co : mu);
        if (m.type == MATERIAL_ROUGHPLASTIC && j < 2) {
            const double n = PLASTIC_MU_NODES - 1.0;
            if (std::floor((x0 - 2 * h) * n) != std::floor((x0 + 2 * h) * n)) {
                ++t->skipped;
                continue;
            }
        }
        float3 v[4], v0;
        const double off[4] = {-2, -1, 1, 2};
        bool ok = value(j, x0, &v0);
        for (int i = 0; i < 4 && ok; ++i) ok = value(j, x0 + off[i] * h, &v[i]);
        for (int c = 0; c < 3 && ok; ++c) {
            if (get(v0, c) == 0.0 || std::fabs(get(v0, c)) < 1e-30) ok = false;
            for (int i = 0; i < 4; ++i)
                if (get(v[i], c) == 0.0 || !std::isfinite(get(v[i], c))) ok = false;
        }
        if (!ok) {
            ++t->skipped;
            continue;
        }
        for (int c = 0; c < 3; ++c) {
            double fmax = std::fabs(get(v0, c));
            for (int i = 0; i < 4; ++i) fmax = std::max(fmax, std::fabs(get(v[i], c)));
            const double d1 = (get(v[2], c) - get(v[1], c)) / (2 * h);
            const double d2 = (get(v[3], c) - get(v[0], c)) / (4 * h);
            const double fd = (4 * d1 - d2) / 3;
            const double an = get(grad_of(g, j), c);
            const double gnorm = std::fabs(get(g.d_cos_i, c)) + std::fabs(get(g.d_cos_o, c)) +
                                 std::fabs(get(g.d_mu, c));
            const double tol = (64 * fmax + 8 * gnorm) * kU / h + 1e-4 * std::fabs(an);
            ++t->checked;
            if (tol < 0.05 * std::fabs(an)) ++t->tight;
            const double err = std::fabs(fd - an) / tol;
            t->worst = std::max(t->worst, err);
            if (err > 1.0) {
                ++t->failed;
                if (why->empty())
                    *why = "d" + std::to_string(j) + " channel " + std::to_string(c) + " at (" +
                           std::to_string(ci) + ", " + std::to_string(co) + ", " +
                           std::to_string(mu) + "): fd " + std::to_string(fd) + " analytic " +
                           std::to_string(an) + " tol " + std::to_string(tol);
            }
            if (control && std::fabs(fd - get(grad_of(bad, j), c)) > tol) ++t->control_failed;
        }
    }
}

/// Random configurations: cos_i, cos_o in [0.05, 0.98], mu = cos_i cos_o + sin_i sin_o cos phi,
/// phi in [0.05, pi - 0.05]; a third of them near the specular peak (phi near pi, cos_o near
/// cos_i), where the GGX derivatives are largest.
Tally run(const Material& m, float3 albedo,
          const std::function<BsdfDirGrad(float3, float3)>& control = nullptr) {
    std::mt19937 rng(12345);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    Tally t;
    std::string why;
    for (int k = 0; k < 600; ++k) {
        const double ci = 0.05 + 0.93 * u(rng);
        double co = 0.05 + 0.93 * u(rng);
        double phi = 0.05 + (M_PI - 0.1) * u(rng);
        if (k % 3 == 0) {
            const double w = std::max((double)m.alpha, 0.02);
            co = std::clamp(ci + w * (u(rng) - 0.5), 0.05, 0.98);
            phi = M_PI - 0.05 - 2 * w * u(rng);
        }
        const double mu = ci * co + std::sqrt((1 - ci * ci) * (1 - co * co)) * std::cos(phi);
        check_config(m, albedo, ci, co, mu, &t, control, &why);
    }
    INFO(why);
    CHECK(t.failed == 0);
    return t;
}

} // namespace

TEST_CASE("bsdf dir grad: derivatives in (cos_i, cos_o, mu) match finite differences") {
    const float3 albedo = {0.7f, 0.4f, 0.2f};
    struct Case {
        const char* name;
        Material m;
    };
    const Case cases[] = {
        {"roughconductor gold 0.05", roughconductor(0.05f, kGoldEta, kGoldK)},
        {"roughconductor gold 0.2", roughconductor(0.2f, kGoldEta, kGoldK)},
        {"roughconductor gold 0.6", roughconductor(0.6f, kGoldEta, kGoldK)},
        {"roughplastic 1.5 0.1", roughplastic(0.1f, 1.5f, kWhite)},
        {"roughplastic 1.5 0.4 nonlinear", roughplastic(0.4f, 1.5f, kWhite, true)},
        {"roughplastic 1.33 0.25", roughplastic(0.25f, 1.33f, {0.5f, 0.6f, 0.7f})},
    };
    for (const Case& c : cases) {
        const Tally t = run(c.m, albedo);
        INFO(std::string(c.name) << ": " << t.checked << " checked, " << t.skipped << " skipped, " << t.tight
                    << " tight, worst " << t.worst);
        CHECK(t.checked >= 1000);
        CHECK(t.skipped * 2 <= t.checked);
        CHECK(t.tight >= 0.25 * t.checked);
        MESSAGE(std::string(c.name) << ": worst |fd - analytic| / tolerance " << t.worst);
    }
}

TEST_CASE("bsdf dir grad: zero for diffuse and delta BSDFs, and below the surface") {
    const float3 wi = {0.6f, 0.0f, 0.8f}, wo = {-0.3f, 0.5f, 0.812404f};
    const float3 albedo = {0.5f, 0.5f, 0.5f};
    const Material ms[] = {diffuse(), material(MATERIAL_CONDUCTOR, 0, kWhite, kGoldEta, kGoldK)};
    for (const Material& m : ms) {
        CHECK_FALSE(bsdf_has_dir_grad(&m));
        const BsdfDirGrad g = bsdf_eval_dir_grad(tables(), &m, albedo, wi, wo);
        for (int j = 0; j < 3; ++j)
            for (int c = 0; c < 3; ++c) CHECK(get(grad_of(g, j), c) == 0.0);
    }
    const Material glossy = roughconductor(0.2f, kGoldEta, kGoldK);
    CHECK(bsdf_has_dir_grad(&glossy));
    const BsdfDirGrad below =
        bsdf_eval_dir_grad(tables(), &glossy, albedo, wi, make_float3(0.3f, 0.0f, -0.95f));
    for (int j = 0; j < 3; ++j)
        for (int c = 0; c < 3; ++c) CHECK(get(grad_of(below, j), c) == 0.0);
}

TEST_CASE("bsdf dir grad: wrong derivatives are rejected (negative controls)") {
    const float3 albedo = {0.7f, 0.4f, 0.2f};
    const Material gold = roughconductor(0.4f, kGoldEta, kGoldK);
    const Material none = roughconductor(0.4f, kNoneEta, kNoneK);
    const Tally conductor = run(gold, albedo, [&](float3 wi, float3 wo) {
        BsdfDirGrad g = bsdf_eval_dir_grad(tables(), &none, albedo, wi, wo);
        float3 m;
        half_vector(wi, wo, &m);
        const float3 f = fresnel_conductor3(vdot(wi, m), kGoldEta, kGoldK);
        g.d_cos_i = g.d_cos_i * f;
        g.d_cos_o = g.d_cos_o * f;
        g.d_mu = g.d_mu * f;
        return g;
    });
    const Material plastic = roughplastic(0.25f, 1.5f, kWhite);
    const Tally swapped = run(plastic, albedo, [&](float3 wi, float3 wo) {
        BsdfDirGrad g = bsdf_eval_dir_grad(tables(), &plastic, albedo, wi, wo);
        const float3 a = g.d_cos_i;
        g.d_cos_i = g.d_cos_o;
        g.d_cos_o = a;
        return g;
    });
    INFO("Fresnel derivative dropped: " << conductor.control_failed << " of " << conductor.checked
                                        << "; cos_i and cos_o swapped: " << swapped.control_failed
                                        << " of " << swapped.checked);
    CHECK(conductor.control_failed >= 0.1 * conductor.checked);
    CHECK(swapped.control_failed >= 0.3 * swapped.checked);
}
