// Fresnel terms against double-precision textbook formulas, and the delta lobes of the smooth
// conductor and dielectric (tolerances: see the top of test_bsdf.cpp).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <vector>

#include "bsdf_fixtures.h"
#include "shared/rng.h"

using namespace tandem::gpu;
using namespace bsdf_fixtures;


TEST_SUITE("bsdf") {
    TEST_CASE("mis_power: complementary weights, exact at the extremes") {
        const float pdfs[] = {0.0f, 1e-30f, 0.5f, 2.0f, 1e19f, 1e30f, INFINITY};
        for (float a : pdfs)
            for (float b : pdfs) {
                INFO(a << " vs " << b);
                const float wa = mis_power(a, b), wb = mis_power(b, a);
                CHECK(std::isfinite(wa));
                CHECK(wa >= 0.0f);
                CHECK(wa <= 1.0f);
                if (a > 0.0f || b > 0.0f) CHECK(wa + wb == doctest::Approx(1.0f).epsilon(1e-6));
            }
        CHECK(mis_power(INFINITY, 3.0f) == 1.0f);
        CHECK(mis_power(3.0f, INFINITY) == 0.0f);
        CHECK(mis_power(1.0f, 1.0f) == 0.5f);
        CHECK(mis_power(2.0f, 1.0f) == doctest::Approx(0.8f));
    }

    TEST_CASE("fresnel: against textbook formulas in double precision") {
        // Dielectric: Hecht's amplitudes with n1 = 1 (outside) or eta (inside).
        auto dielectric_ref = [](double cos_i, double eta) {
            const double n1 = cos_i >= 0 ? 1.0 : eta, n2 = cos_i >= 0 ? eta : 1.0,
                         ci = std::fabs(cos_i);
            const double st = n1 / n2 * std::sqrt(std::max(0.0, 1.0 - ci * ci));
            if (st >= 1.0) return 1.0;
            const double ct = std::sqrt(1.0 - st * st);
            const double rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct),
                         rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct);
            return 0.5 * (rs * rs + rp * rp);
        };
        for (float eta : {1.0001f, 1.33f, 1.5f, 2.4f, 1.0f / 1.5f})
            for (int i = 0; i <= 200; ++i) {
                const float c = -1.0f + i / 100.0f;
                if (c == 0.0f) continue;
                // Near the critical angle (cos_t -> 0) F is ill-conditioned: cos_t^2 = 1 - (1 -
                // c^2) eta_ti^2 cancels, its absolute rounding error (~2e-7) moves cos_t by ~1e-7 /
                // cos_t, and |dF/dcos_t| <= 2 / cos_t: hence 2e-7 / cos_t^2.
                float ct, eta_ti;
                fresnel_dielectric(c, eta, &ct, &eta_ti);
                const double tol = 2e-6 + 2e-7 / std::max((double)ct * ct, 1e-6);
                INFO("eta " << eta << " cos " << c << " cos_t " << ct);
                CHECK(std::fabs(fresnel_dielectric_r(c, eta) - dielectric_ref(c, eta)) <= tol);
            }
        CHECK(fresnel_dielectric_r(1.0f, 1.5f) ==
              doctest::Approx(0.04).epsilon(1e-5)); // ((n-1)/(n+1))^2
        CHECK(fresnel_dielectric_r(0.0f, 1.5f) == 1.0f);
        CHECK(fresnel_dielectric_r(0.3f, 1.0f) == 0.0f);
        // Snell's law and the sign of the refracted cosine; Fresnel is the same seen from both
        // sides.
        for (int i = 1; i < 100; ++i) {
            const float c = i / 100.0f;
            float ct, eta_ti;
            const float f = fresnel_dielectric(c, 1.5f, &ct, &eta_ti);
            CHECK(ct < 0.0f);
            CHECK(eta_ti == doctest::Approx(1.0f / 1.5f));
            CHECK((1.0 - (double)ct * ct) ==
                  doctest::Approx((1.0 - (double)c * c) / 2.25).epsilon(1e-5));
            CHECK(fresnel_dielectric_r(ct, 1.5f) == doctest::Approx(f).epsilon(1e-4));
        }
        // Conductor: the standard complex-IOR amplitudes.
        auto conductor_ref = [](double c, double eta, double k) {
            const std::complex<double> n(eta, k), n2 = n * n, s = std::sqrt(n2 - (1.0 - c * c));
            const double rs = std::norm((c - s) / (c + s)),
                         rp = std::norm((n2 * c - s) / (n2 * c + s));
            return 0.5 * (rs + rp);
        };
        const float3 al_eta = {1.6574599f, 0.8803689f, 0.5212287f},
                     al_k = {9.2238691f, 6.2695232f, 4.8370012f};
        for (const auto& [eta, k] :
             {std::pair{kGoldEta, kGoldK}, std::pair{al_eta, al_k},
              std::pair{float3{1.5f, 0.2f, 3.0f}, float3{0.0f, 0.5f, 30.0f}}})
            for (int i = 0; i <= 100; ++i) {
                const float c = i / 100.0f;
                const float3 f = fresnel_conductor3(c, eta, k);
                INFO("cos " << c);
                CHECK(std::fabs(f.x - conductor_ref(c, eta.x, k.x)) <= 1e-5);
                CHECK(std::fabs(f.y - conductor_ref(c, eta.y, k.y)) <= 1e-5);
                CHECK(std::fabs(f.z - conductor_ref(c, eta.z, k.z)) <= 1e-5);
                CHECK(fresnel_conductor(c, 0.0f, 1.0f) ==
                      doctest::Approx(1.0f).epsilon(1e-6)); // "none"
                if (c > 0.0f)
                    CHECK(fresnel_conductor(c, 1.5f, 0.0f) ==
                          doctest::Approx(fresnel_dielectric_r(c, 1.5f)).epsilon(1e-4));
            }
        // Large k: nearly a perfect mirror. 1 - F = 4 eta / ((eta + 1)^2 + k^2) = 8.9e-4 at normal
        // incidence; the p-polarised dip near cos = 1 / |eta + i k| reaches 6.6e-3 but is narrow,
        // so the hemispherical albedo 2 int F mu dmu stays within 2e-3 of 1 (measured 1 - 1.1e-3).
        CHECK(fresnel_conductor(1.0f, 0.2f, 30.0f) ==
              doctest::Approx(1.0 - 0.8 / 901.44).epsilon(1e-6));
        double albedo = 0.0;
        for (int i = 0; i < 10000; ++i)
            albedo += 2.0 * fresnel_conductor((i + 0.5f) / 1e4f, 0.2f, 30.0f) * (i + 0.5) / 1e8;
        std::printf("fresnel: conductor eta 0.2, k 30: hemispherical albedo %.6f\n", albedo);
        CHECK(albedo >= 0.998);
        CHECK(albedo <= 1.0);
        // Diffuse reflectance fits against 2 int F(mu) mu dmu: Mitsuba quotes <= 0.1-0.6 % for IOR
        // <= 2.
        for (float eta : {1.0f / 1.9f, 1.0f / 1.5f, 1.0f / 1.33f, 1.33f, 1.5f, 1.9f, 3.0f}) {
            const double exact = eta < 1.0f ? exact_fdr_internal(1.0f / eta)
                                            : 1.0 - (1.0 - exact_fdr_internal(eta)) * eta * eta;
            INFO("eta " << eta << ": fit " << fresnel_diffuse_reflectance(eta) << " exact "
                        << exact);
            CHECK(fresnel_diffuse_reflectance(eta) ==
                  doctest::Approx(exact).epsilon(eta < 1.0f ? 6e-3 : 3e-3));
        }
    }

    TEST_CASE("conductor and dielectric: delta lobes") {
        const float3 spec = {0.9f, 0.8f, 0.7f};
        for (float th : {0.0f, 45.0f, 89.0f}) {
            const float3 wi = dir(th);
            Material m = material(MATERIAL_CONDUCTOR, 0, spec, kGoldEta, kGoldK);
            float3 wo;
            float pdf = -1.0f;
            int delta = 0;
            const float3 w =
                bsdf_sample(tables(), &m, kWhite, wi, 0.5f, 0.5f, 0.5f, &wo, &pdf, &delta);
            CHECK(delta == 1);
            CHECK(pdf == 0.0f);
            CHECK((wo.x == -wi.x && wo.y == -wi.y && wo.z == wi.z));
            CHECK(w.x == doctest::Approx(spec.x * fresnel_conductor(wi.z, kGoldEta.x, kGoldK.x)));
            CHECK(w.z == doctest::Approx(spec.z * fresnel_conductor(wi.z, kGoldEta.z, kGoldK.z)));
            CHECK(max_component(bsdf_eval(tables(), &m, kWhite, wi, wo)) == 0.0f);
            CHECK(bsdf_pdf(tables(), &m, kWhite, wi, wo) == 0.0f);
        }
        // Dielectric: lobe frequencies match F (binomial, 5 sigma; F = 1 beyond the critical angle
        // from inside), weights, Snell, reversibility.
        const uint n = 1u << 16;
        uint stream = 5000;
        for (float eta : {1.5f, 1.33f, 1.0f})
            for (float th : {0.0f, 30.0f, 45.0f, 60.0f, 89.0f})
                for (float side : {1.0f, -1.0f}) {
                    float3 wi = dir(th);
                    wi.z *= side;
                    Material m = material(MATERIAL_DIELECTRIC, 0, spec, {eta, eta, eta}, kWhite);
                    float ct, eta_ti;
                    const double f = fresnel_dielectric(wi.z, eta, &ct, &eta_ti);
                    uint reflected = 0;
                    for (uint i = 0; i < n; ++i) {
                        auto [w, wo, pdf, delta] = draw(m, kWhite, wi, 13u, stream, i);
                        REQUIRE(delta == 1);
                        REQUIRE(pdf == 0.0f);
                        REQUIRE(std::fabs(vlength(wo) - 1.0f) <= 1e-5f);
                        if (wo.z * wi.z > 0.0f) { // reflection
                            ++reflected;
                            REQUIRE((wo.x == -wi.x && wo.y == -wi.y && wo.z == wi.z));
                            REQUIRE((w.x == spec.x && w.y == spec.y && w.z == spec.z));
                        } else { // refraction: radiance scaled by eta_ti^2, Snell's law, reversible
                            REQUIRE(w.x == doctest::Approx(eta_ti * eta_ti));
                            REQUIRE(std::hypot(wo.x, wo.y) ==
                                    doctest::Approx(eta_ti * std::hypot(wi.x, wi.y)).epsilon(1e-5));
                            float3 back;
                            bsdf_sample(tables(), &m, kWhite, wo, 0.999999f, 0.5f, 0.5f, &back,
                                        &pdf, &delta);
                            REQUIRE(vlength(back - wi) <= 2e-5f);
                        }
                    }
                    ++stream;
                    const double sigma = std::sqrt(f * (1.0 - f) / n);
                    INFO("eta " << eta << " wi " << th << (side < 0 ? " inside" : "")
                                << ": reflected " << reflected / (double)n << " F " << f);
                    CHECK(std::fabs(reflected / (double)n - f) <= 5.0 * sigma + 1e-9);
                    CHECK(max_component(bsdf_eval(tables(), &m, kWhite, wi,
                                                  make_float3(-wi.x, -wi.y, wi.z))) == 0.0f);
                }
    }

}
