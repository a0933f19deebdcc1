// roughplastic's rough-interface tables (core/scene/plastic_table.h, looked up by
// kernels/shared/plastic_table.h) against an independent quadrature, their smooth-interface limit,
// and the properties the BSDF and its gradient rely on.
//
// The reference: the same integrals as Mitsuba's eval_transmittance / eval_reflectance, but over
// the microfacet normals in the parametrisation of D(m) cos(theta_m) (u = its CDF in theta_m,
// substituted u = 1 - v^2 to remove the 1 / cos(theta_m) singularity at the horizon; phi over
// [0, pi], doubled by symmetry), with the visibility weight G1(wi) (wi.m) / cos_i written out, by a
// midpoint rule in double on n x n points. It shares no code with the table's quadrature (which
// maps visible normals by Heitz's 2018 sampling routine). Its own error, measured against
// n = 2048 at the points below: transmittance <= 4e-5 at n = 512 (largest at grazing cosines and
// small alpha); reflectance from inside <= 1.2e-4 per cosine at n = 256 (total internal
// reflection puts a kink in that integrand, which both rules resolve slowly).
//
// Tolerances:
// - Transmittance at the table's nodes (cos_theta = k / 63) and off-node alphas: 1.5e-4. The table
//   uses Mitsuba's 32 x 32 Gauss-Legendre rule, measured <= 1e-4 from the n = 2048 reference; its
//   cubic in alpha adds <= 6e-6 (measured against the same rule evaluated at the alpha itself).
// - Internal reflectance: 4e-4. Its 64 x 64 rule has errors up to ~3e-4 per alpha node (Mitsuba's
//   128 x 128 float rule ~1e-4); the spline through the nodes smooths them (measured <= 1.5e-4).
// - Smooth limit (alpha = GGX_ALPHA_MIN): t_k within 2e-3 of 1 - F(mu_k) for k >= 1 (the rough
//   interface still differs at grazing angles below ~alpha), r within 1e-3 of Mitsuba's 64-node
//   mean of the smooth internal Fresnel reflectance.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "core/scene/plastic_table.h"
#include "shared/fresnel.h"
#include "shared/plastic_table.h"

using namespace tandem;
using gpu::PlasticCell;

namespace {

constexpr double kPi = 3.14159265358979323846;

/// Unpolarised Fresnel reflectance for incidence cosine c > 0 into relative IOR eta (double).
double fresnel(double c, double eta) {
    const double ct2 = 1.0 - (1.0 - c * c) / (eta * eta);
    if (ct2 <= 0.0) return 1.0;
    const double ct = std::sqrt(ct2);
    const double rs = (c - eta * ct) / (c + eta * ct), rp = (ct - eta * c) / (ct + eta * c);
    return 0.5 * (rs * rs + rp * rp);
}

/// Smith's G1(v, m) for GGX, 0 when v sees the back of m.
double g1(double a, double vx, double vy, double vz, double mx, double my, double mz) {
    if ((vx * mx + vy * my + vz * mz) * vz <= 0.0) return 0.0;
    return 2.0 / (1.0 + std::sqrt(1.0 + a * a * (vx * vx + vy * vy) / (vz * vz)));
}

/// The reference integral (header comment): transmittance from outside (transmit) or reflectance,
/// incidence cosine mu, relative IOR eta of the other side.
double reference(double a, double mu, double eta, bool transmit, int n) {
    const double st = std::sqrt(1.0 - mu * mu);
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
        const double v = (i + 0.5) / n, q = std::sqrt(v * v + a * a * (1.0 - v * v));
        const double cm = v / q, sm = a * std::sqrt(1.0 - v * v) / q; // cos, sin theta_m
        double row = 0.0;
        for (int j = 0; j < n; ++j) {
            const double phi = kPi * (j + 0.5) / n;
            const double mx = sm * std::cos(phi), my = sm * std::sin(phi), mz = cm;
            const double c = st * mx + mu * mz; // wi.m
            if (c <= 0.0) continue;
            const double f = fresnel(c, eta);
            double ox, oy, oz, value;
            if (transmit) {
                const double ct2 = 1.0 - (1.0 - c * c) / (eta * eta);
                if (ct2 <= 0.0) continue;
                const double k = c / eta - std::sqrt(ct2);
                ox = mx * k - st / eta, oy = my * k, oz = mz * k - mu / eta;
                if (oz >= 0.0) continue;
                value = 1.0 - f;
            } else {
                ox = 2.0 * c * mx - st, oy = 2.0 * c * my, oz = 2.0 * c * mz - mu;
                if (oz <= 0.0) continue;
                value = f;
            }
            row += g1(a, st, 0.0, mu, mx, my, mz) * c * value * g1(a, ox, oy, oz, mx, my, mz);
        }
        // D cos dw = du dphi / (2 pi), du = 2 v dv, phi doubled; visibility / (cos_i cos_m)
        sum += row * (1.0 / n) * 2.0 * v * (1.0 / n) / (mu * cm);
    }
    return sum;
}

/// Mitsuba's internal reflectance by the reference rule.
double reference_internal(double a, double eta, int n) {
    double sum = 0.0;
    for (unsigned k = 0; k < PLASTIC_MU_NODES; ++k) {
        const double mu = std::max(1e-6, k / 63.0);
        sum += reference(a, mu, 1.0 / eta, false, n) * mu;
    }
    return 2.0 * sum / PLASTIC_MU_NODES;
}

float lookup_t(const std::vector<float>& table, float alpha, float mu) {
    const PlasticCell c = gpu::plastic_cell(alpha);
    return gpu::plastic_transmittance(table.data(), &c, mu);
}
float lookup_r(const std::vector<float>& table, float alpha) {
    const PlasticCell c = gpu::plastic_cell(alpha);
    return gpu::plastic_internal_reflectance(table.data(), &c);
}

} // namespace

TEST_SUITE("plastic_table") {

    TEST_CASE("plastic table: transmittance and internal reflectance against a reference") {
        double worst_t = 0.0, worst_r = 0.0;
        for (float eta : {1.5f, 1.33f}) {
            const std::vector<float>& table = plastic_table(eta);
            REQUIRE(table.size() == PLASTIC_TABLE_FLOATS);
            // off the alpha nodes (and two on them: 1e-4 and 1)
            for (float a : {1e-4f, 0.004f, 0.03f, 0.15f, 0.42f, 0.77f, 1.0f}) {
                for (int k : {1, 4, 16, 40, 63}) {
                    const double want = reference(a, k / 63.0, eta, true, 512);
                    const double got = lookup_t(table, a, k / 63.0f);
                    worst_t = std::max(worst_t, std::fabs(got - want));
                    INFO("eta " << eta << " alpha " << a << " cos " << k << "/63: table " << got
                                << " reference " << want);
                    CHECK(std::fabs(got - want) <= 1.5e-4);
                }
            }
            for (float a : {0.01f, 0.15f, 0.42f, 1.0f}) {
                const double want = reference_internal(a, eta, 256);
                const double got = lookup_r(table, a);
                worst_r = std::max(worst_r, std::fabs(got - want));
                INFO("eta " << eta << " alpha " << a << ": r " << got << " reference " << want);
                CHECK(std::fabs(got - want) <= 4e-4);
            }
        }
        std::printf("plastic table vs reference: worst |t| error %.2e, |r| error %.2e\n", worst_t,
                    worst_r);
    }

    TEST_CASE("plastic table: the rough interface tends to the smooth one as alpha -> 0") {
        for (float eta : {1.33f, 1.5f, 1.9f}) {
            const std::vector<float>& table = plastic_table(eta);
            for (int k = 1; k < 64; ++k) {
                const double mu = k / 63.0;
                INFO("eta " << eta << " cos " << k << "/63");
                CHECK(std::fabs(lookup_t(table, GGX_ALPHA_MIN, (float)mu) -
                                (1.0 - fresnel(mu, eta))) <= 2e-3);
            }
            // Mitsuba's r is a 64-node mean of 2 F(mu) mu: in the smooth limit that is below the
            // hemispherical integral 2 int F mu dmu (the diffuse Fresnel reflectance) by about
            // (mean - integral) / 64, ~0.009 at eta 1.5.
            double mean = 0.0, integral = 0.0;
            for (unsigned k = 0; k < PLASTIC_MU_NODES; ++k) {
                const double mu = std::max(1e-6, k / 63.0);
                mean += 2.0 * fresnel(mu, 1.0 / eta) * mu / PLASTIC_MU_NODES;
            }
            const int n = 200000;
            for (int i = 0; i < n; ++i) {
                const double mu = (i + 0.5) / n;
                integral += 2.0 * fresnel(mu, 1.0 / eta) * mu / n;
            }
            const double r = lookup_r(table, GGX_ALPHA_MIN);
            std::printf("plastic table eta %.2f, alpha 1e-4: r %.5f, smooth 64-node mean %.5f, "
                        "2 int F mu dmu %.5f, fit %.5f\n",
                        eta, r, mean, integral, gpu::fresnel_diffuse_reflectance(1.0f / eta));
            CHECK(std::fabs(r - mean) <= 1e-3);
            CHECK(r < integral);
            CHECK(integral - r <= 0.015);
        }
    }

    TEST_CASE("plastic table: bounded relative alpha sensitivity, no undershoot") {
        // The gradient test's bound on the plastic's base (tests/kernels/shared/
        // test_bsdf_grad.cpp, kPlasticT = 1.5, kPlasticR = 1) holds over the whole grid: at every
        // cosine node and 8 points per alpha cell, |d ln t / d ln alpha| <= 1.5 and
        // |d r / d ln alpha| <= 1, and t > 0 (the cubic never dips to the clamp). For eta >= 1
        // only: below 1, total internal reflection from outside makes t vanish wherever the
        // interface reflects totally (cos_theta < sqrt(1 - eta^2) when smooth), and no relative
        // bound holds next to those zeros; there t >= 0 and r's bound are checked.
        double worst_t = 0.0, worst_r = 0.0;
        for (float eta : {1.0f / 3.0f, 0.5f, 1.0f / 1.5f, 1.0f, 1.33f, 1.5f, 2.0f, 3.0f, 10.0f}) {
            const std::vector<float>& table = plastic_table(eta);
            for (unsigned j = 0; j + 1 < PLASTIC_ALPHAS; ++j)
                for (int q = 0; q < 8; ++q) {
                    const double s = PLASTIC_S_MIN + (j + (q + 0.5) / 8.0) * PLASTIC_DS;
                    const float a = (float)(s * s * s * s);
                    const PlasticCell c = gpu::plastic_cell(a);
                    for (unsigned k = 0; k < PLASTIC_MU_NODES; ++k) {
                        const float mu = k / 63.0f;
                        const float t = gpu::plastic_transmittance(table.data(), &c, mu);
                        const float dt = gpu::plastic_transmittance_dalpha(table.data(), &c, mu);
                        INFO("eta " << eta << " alpha " << a << " cos " << k << "/63: t " << t);
                        CHECK(std::isfinite(dt));
                        if (eta < 1.0f) {
                            CHECK(t >= 0.0f);
                            continue;
                        }
                        CHECK(t > 0.0f);
                        worst_t = std::max(worst_t, std::fabs((double)a * dt / t));
                    }
                    worst_r = std::max(
                        worst_r, std::fabs((double)a * gpu::plastic_internal_reflectance_dalpha(
                                                           table.data(), &c)));
                }
        }
        std::printf("plastic table: max |d ln t / d ln alpha| %.3f, max |d r / d ln alpha| %.3f\n",
                    worst_t, worst_r);
        CHECK(worst_t <= 1.5);
        CHECK(worst_r <= 1.0);
    }

    TEST_CASE("plastic table: alpha derivatives of the lookups against finite differences") {
        // Central differences of the float lookups in double, step 1e-3 alpha: truncation
        // ~(1e-3)^2 of the O(1 / alpha) second derivative; rounding ~1e-7 / 1e-3 alpha.
        const std::vector<float>& table = plastic_table(1.5f);
        for (float a : {2e-4f, 0.003f, 0.05f, 0.2f, 0.6f, 0.9f}) {
            const double h = 1e-3 * a;
            const PlasticCell c = gpu::plastic_cell(a);
            for (float mu : {0.01f, 0.3f, 0.77f, 1.0f}) {
                const double fd = ((double)lookup_t(table, (float)(a + h), mu) -
                                   lookup_t(table, (float)(a - h), mu)) /
                                  (2.0 * h);
                const double an = gpu::plastic_transmittance_dalpha(table.data(), &c, mu);
                INFO("alpha " << a << " cos " << mu << ": analytic " << an << " fd " << fd);
                CHECK(std::fabs(fd - an) <= 2e-3 * std::fabs(an) + 2e-4 / a);
            }
            const double fd =
                ((double)lookup_r(table, (float)(a + h)) - lookup_r(table, (float)(a - h))) /
                (2.0 * h);
            const double an = gpu::plastic_internal_reflectance_dalpha(table.data(), &c);
            INFO("alpha " << a << ": dr analytic " << an << " fd " << fd);
            CHECK(std::fabs(fd - an) <= 2e-3 * std::fabs(an) + 2e-4 / a);
        }
        // outside [GGX_ALPHA_MIN, 1] the lookups are clamped: zero derivatives
        const PlasticCell lo = gpu::plastic_cell(5e-5f), hi = gpu::plastic_cell(1.5f);
        CHECK(gpu::plastic_transmittance_dalpha(table.data(), &lo, 0.5f) == 0.0f);
        CHECK(gpu::plastic_transmittance_dalpha(table.data(), &hi, 0.5f) == 0.0f);
        CHECK(gpu::plastic_internal_reflectance_dalpha(table.data(), &lo) == 0.0f);
        CHECK(lookup_t(table, 5e-5f, 0.5f) == lookup_t(table, GGX_ALPHA_MIN, 0.5f));
        CHECK(lookup_r(table, 1.5f) == lookup_r(table, 1.0f));
    }

    TEST_CASE("plastic table: built once per IOR") {
        const std::vector<float>& a = plastic_table(1.49f);
        CHECK(&plastic_table(1.49f) == &a);
        CHECK(plastic_table(1.5f) != a);
    }
}
