// BSDF library (kernels/shared/bsdfs.h) on the host: energy, reciprocity, pdf normalisation,
// chi-square tests of every non-delta sampler against its pdf, sample/eval/pdf consistency, closed
// forms of the Fresnel terms, and finiteness under extreme inputs.
//
// Tolerances and how they were derived:
// - Chi-square: directions are binned over the sphere in (cos theta, phi), 32 x 64 cells, plus one
//   cell for the samples that fail or are delta. Expected counts are N = 2^20 times the integral of
//   bsdf_pdf over each cell, by adaptive 3x3 Gauss-Legendre cubature to 1e-6 relative (so the
//   expected counts are off by < 1e-6 E, far below the sqrt(E) noise); the extra cell expects
//   N (1 - integral over the sphere). Cells expecting < 5 are pooled, as Mitsuba's chi2 test does.
//   A test fails when the p-value of Pearson's statistic is below 0.01 / (number of chi-square
//   tests) (Bonferroni), so the whole suite raises a false alarm with probability < 1%. Wrong pdfs
//   and samplers (the pdf scaled by 1.1, alpha off by 10%, the plastic's lobe weights off by 10%,
//   normals drawn from D cos instead of the visible normals) must be rejected at the same level.
//   alpha = 1e-4 is left out: its lobe is far narrower than a cell.
// - Pdf integrals (same cubature): <= 1 + 1e-5, and the closed forms at normal incidence within
//   1e-5: diffuse 1, roughconductor 1 / (1 + alpha^2) (visible normals reflected above the horizon:
//   tan^2 theta_m < 1, whose GGX probability is 1 / (1 + alpha^2)), roughplastic
//   p_spec / (1 + alpha^2) + 1 - p_spec. 1e-5 covers the cubature (1e-6) and float pdfs (~1e-6).
// - Energy: the mean sample weight (own sampling, N = 2^17) must stay below 1 + 4 standard errors
//   (measured from the weights; 4 rather than 3 so that ~150 one-sided checks together raise a
//   false alarm < 0.5% of the time) + 1e-5 for float rounding, for white parameters. Roughplastic's
//   bound is its model's: coating <= E[F(wi.m)] over the visible normals (G1 <= 1), plus the base
//   t_i T_o / (eta^2 (1 - r)) (T_o = 2 int t mu dmu), whose factor after t_i must be <= 1, so that
//   the bound is <= E[F] + t_i <= 1 (t_i <= E[1 - F]); both are computed here. Broad lobes (alpha
//   >= 0.3) must also agree with an independent uniform-hemisphere estimate within 4 combined
//   errors.
// - Reciprocity: f(wi,wo)/cos_o = f(wo,wi)/cos_i within 1e-4 relative (rounding of F, D and G1 in
//   float is ~1e-6; measured worst 1e-5).
// - Consistency: weight = eval / pdf within 1e-3 relative where pdf > 1e-3, and the pdf that
//   bsdf_sample writes equals bsdf_pdf within 1e-5 relative (both are float computations).
// - Fresnel: against double-precision textbook formulas (Hecht; complex IOR via std::complex),
//   2e-6 (1e-5 for the conductor), widened near the critical angle by its conditioning (below).
// - Dielectric: the frequency of reflection within 5 binomial standard deviations of F.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "bsdf_fixtures.h"
#include "shared/bsdfs.h"
#include "shared/rng.h"

using namespace tandem::gpu;
using namespace bsdf_fixtures;

namespace {


bool finite3(float3 v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}
double rel_diff(double a, double b) {
    return std::fabs(a - b) / std::max({std::fabs(a), std::fabs(b), 1e-30});
}

/// Running mean and standard error of the mean.
struct Mean {
    double sum = 0.0, sum2 = 0.0, n = 0.0;
    void add(double x) { sum += x, sum2 += x * x, n += 1.0; }
    double mean() const { return sum / n; }
    double se() const { return std::sqrt(std::max(0.0, sum2 / n - mean() * mean()) / n); }
};

/// Diffuse, then roughconductor and two roughplastics per alpha, with their albedos.
std::vector<std::pair<Material, float3>> nondelta_cases(std::initializer_list<float> alphas) {
    std::vector<std::pair<Material, float3>> cases = {{diffuse(), {0.3f, 0.6f, 0.9f}}};
    for (float a : alphas) {
        cases.push_back({roughconductor(a, kGoldEta, kGoldK), kWhite});
        cases.push_back({roughplastic(a, 1.5f, {0.8f, 0.9f, 1.0f}), {0.5f, 0.3f, 0.2f}});
        cases.push_back({roughplastic(a, 1.9f, kWhite, true), {0.9f, 0.5f, 0.1f}});
    }
    return cases;
}

// ---- chi-square machinery ----

/// Regularised upper incomplete gamma Q(a, x) (series / continued fraction, Numerical Recipes 6.2);
/// the chi-square p-value of statistic s with k degrees of freedom is Q(k/2, s/2).
double gamma_q(double a, double x) {
    if (x <= 0.0) return 1.0;
    const double lead = std::exp(-x + a * std::log(x) - std::lgamma(a));
    if (x < a + 1.0) {
        double ap = a, del = 1.0 / a, sum = del;
        for (int n = 0; n < 100000 && std::fabs(del) > std::fabs(sum) * 1e-16; ++n) {
            ap += 1.0;
            del *= x / ap;
            sum += del;
        }
        return std::max(0.0, 1.0 - sum * lead);
    }
    double b = x + 1.0 - a, c = 1e300, d = 1.0 / b, h = d;
    for (int i = 1; i < 100000; ++i) {
        const double an = -i * (i - a);
        b += 2.0;
        d = an * d + b;
        if (std::fabs(d) < 1e-300) d = 1e-300;
        c = b + an / c;
        if (std::fabs(c) < 1e-300) c = 1e-300;
        d = 1.0 / d;
        h *= d * c;
        if (std::fabs(d * c - 1.0) < 1e-16) break;
    }
    return lead * h;
}

constexpr int kThetaBins = 32, kPhiBins = 64;
constexpr uint kChiSamples = 1u << 20;

using PdfFn = std::function<float(float3)>;
/// Draws sample `i`; returns 1 and writes wo for a non-delta direction, 0 for a failure or delta.
using SampleFn = std::function<int(uint i, float3* wo)>;

/// Integrand of the cubature over a cell: the pdf in coordinates (u, phi) with z = 1 - u^2 (upper
/// hemisphere) or z = u^2 - 1 (lower), dw = 2 u du dphi. The substitution removes the square-root
/// singularity of (x, y) = sqrt(1 - z^2) (cos phi, sin phi) at the poles, which otherwise stalls
/// the adaptive refinement there.
struct CellIntegrand {
    const PdfFn* pdf;
    bool upper;
    double operator()(double u, double phi) const {
        const double z = upper ? 1.0 - u * u : u * u - 1.0,
                     r = u * std::sqrt(std::max(0.0, 2.0 - u * u));
        const float3 wo =
            make_float3((float)(r * std::cos(phi)), (float)(r * std::sin(phi)), (float)z);
        return (*pdf)(wo)*2.0 * u;
    }
};

/// 3 x 3-point Gauss-Legendre rule on [x0,x1]x[y0,y1]. An open rule: it never evaluates the edges,
/// where the one-sided pdfs jump (at the horizon).
double gauss3(const CellIntegrand& f, double x0, double x1, double y0, double y1) {
    static const double t[3] = {-0.7745966692414834, 0.0, 0.7745966692414834};
    static const double w[3] = {5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0};
    const double cx = 0.5 * (x0 + x1), hx = 0.5 * (x1 - x0), cy = 0.5 * (y0 + y1),
                 hy = 0.5 * (y1 - y0);
    double s = 0.0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            s += w[i] * w[j] * f(cx + hx * t[i], cy + hy * t[j]);
    return s * hx * hy;
}

/// Adaptive cubature: splits into four until the quarters agree with the whole to 1e-6 relative or
/// `tol` absolute (divided among the quarters), but at least `forced` times so that narrow peaks
/// between the first nodes are not missed. The error of the 3-point rule falls as h^6.
double integrate(const CellIntegrand& f, double x0, double x1, double y0, double y1, double whole,
                 double tol, int depth, int forced) {
    const double xm = 0.5 * (x0 + x1), ym = 0.5 * (y0 + y1);
    const double q[4] = {gauss3(f, x0, xm, y0, ym), gauss3(f, xm, x1, y0, ym),
                         gauss3(f, x0, xm, ym, y1), gauss3(f, xm, x1, ym, y1)};
    const double sum = q[0] + q[1] + q[2] + q[3];
    if (depth >= 10 ||
        (forced <= 0 && std::fabs(sum - whole) <= std::max(tol, 1e-6 * std::fabs(sum))))
        return sum;
    return integrate(f, x0, xm, y0, ym, q[0], tol / 4, depth + 1, forced - 1) +
           integrate(f, xm, x1, y0, ym, q[1], tol / 4, depth + 1, forced - 1) +
           integrate(f, x0, xm, ym, y1, q[2], tol / 4, depth + 1, forced - 1) +
           integrate(f, xm, x1, ym, y1, q[3], tol / 4, depth + 1, forced - 1);
}

struct ChiResult {
    double stat = 0, p = 0, pdf_integral = 0;
    int dof = 0;
    uint other = 0; // failed or delta samples
};

ChiResult chi_square(const SampleFn& sample, const PdfFn& pdf) {
    const double dx = 2.0 / kThetaBins, dy = 2.0 * kPi / kPhiBins;
    std::vector<double> expected(kThetaBins * kPhiBins + 1);
    std::vector<double> observed(expected.size(), 0.0);
    ChiResult r;
    for (int i = 0; i < kThetaBins; ++i)
        for (int j = 0; j < kPhiBins; ++j) {
            const double z0 = -1.0 + i * dx, z1 = z0 + dx, y0 = j * dy;
            const CellIntegrand f{&pdf, z0 >= 0.0};
            const double u0 = f.upper ? std::sqrt(1.0 - z1) : std::sqrt(1.0 + z0);
            const double u1 = f.upper ? std::sqrt(1.0 - z0) : std::sqrt(1.0 + z1);
            const double v =
                integrate(f, u0, u1, y0, y0 + dy, gauss3(f, u0, u1, y0, y0 + dy), 1e-10, 0, 1);
            expected[i * kPhiBins + j] = v * kChiSamples;
            r.pdf_integral += v;
        }
    expected.back() = std::max(0.0, 1.0 - r.pdf_integral) * kChiSamples;
    for (uint s = 0; s < kChiSamples; ++s) {
        float3 wo;
        if (!sample(s, &wo)) {
            ++r.other;
            observed.back() += 1.0;
            continue;
        }
        const double z = std::min(1.0, std::max(-1.0, (double)wo.z));
        double phi = std::atan2((double)wo.y, (double)wo.x);
        if (phi < 0.0) phi += 2.0 * kPi;
        const int i = std::min(kThetaBins - 1, (int)((z + 1.0) / dx));
        const int j = std::min(kPhiBins - 1, (int)(phi / dy));
        observed[i * kPhiBins + j] += 1.0;
    }
    // Pearson's statistic, pooling the cells that expect fewer than 5 samples.
    std::vector<int> order(expected.size());
    for (size_t i = 0; i < order.size(); ++i)
        order[i] = (int)i;
    std::sort(order.begin(), order.end(), [&](int a, int b) { return expected[a] < expected[b]; });
    double pool_e = 0.0, pool_o = 0.0;
    for (int c : order) {
        if (expected[c] < 5.0) {
            pool_e += expected[c];
            pool_o += observed[c];
            if (pool_e < 5.0) continue;
            r.stat += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
            pool_e = pool_o = 0.0;
        } else {
            r.stat += (observed[c] - expected[c]) * (observed[c] - expected[c]) / expected[c];
        }
        ++r.dof;
    }
    if (pool_e > 0.0 || pool_o > 0.0) { // the leftover pool, a cell of its own
        r.stat += (pool_o - pool_e) * (pool_o - pool_e) / std::max(pool_e, 1e-12);
        ++r.dof;
    }
    r.dof = std::max(1, r.dof - 1);
    r.p = gamma_q(0.5 * r.dof, 0.5 * r.stat);
    return r;
}

/// A non-delta sampling routine under test: a material, its albedo and wi.
struct ChiCase {
    std::string name;
    Material m;
    float3 albedo;
    float3 wi;
};

std::vector<ChiCase> chi_cases() {
    std::vector<ChiCase> cases;
    char buf[96];
    for (float th : kThetas) {
        std::snprintf(buf, sizeof buf, "diffuse wi=%g", th);
        cases.push_back({buf, diffuse(), {0.3f, 0.6f, 0.9f}, dir(th)});
        for (float a : {0.05f, 0.3f, 1.0f}) {
            std::snprintf(buf, sizeof buf, "roughconductor a=%g wi=%g", a, th);
            cases.push_back({buf, roughconductor(a, kGoldEta, kGoldK), kWhite, dir(th)});
        }
        std::snprintf(buf, sizeof buf, "roughplastic a=0.05 eta=1.5 wi=%g", th);
        cases.push_back({buf, roughplastic(0.05f, 1.5f, kWhite), {0.5f, 0.3f, 0.2f}, dir(th)});
        std::snprintf(buf, sizeof buf, "roughplastic a=0.3 eta=1.5 wi=%g", th);
        cases.push_back({buf, roughplastic(0.3f, 1.5f, kWhite), {0.5f, 0.3f, 0.2f}, dir(th)});
        std::snprintf(buf, sizeof buf, "roughplastic a=1 eta=1.9 nonlinear wi=%g", th);
        cases.push_back(
            {buf, roughplastic(1.0f, 1.9f, {0.6f, 0.6f, 0.6f}, true), {0.9f, 0.9f, 0.9f}, dir(th)});
        std::snprintf(buf, sizeof buf, "roughplastic a=0.3 eta=1.33 black base wi=%g", th);
        cases.push_back({buf, roughplastic(0.3f, 1.33f, kWhite), {0.0f, 0.0f, 0.0f}, dir(th)});
    }
    return cases;
}

/// Significance per chi-square test: 1% for the whole suite of positive tests (Bonferroni).
double chi_alpha() {
    return 0.01 / (double)chi_cases().size();
}

SampleFn generic_sampler(const ChiCase& c, uint stream) {
    return [c, stream](uint i, float3* wo) {
        const Draw d = draw(c.m, c.albedo, c.wi, 7u, stream, i);
        *wo = d.wo;
        return d.pdf > 0.0f && !d.delta;
    };
}
PdfFn generic_pdf(const ChiCase& c) {
    return [c](float3 wo) { return bsdf_pdf(tables(), &c.m, c.albedo, c.wi, wo); };
}


} // namespace

TEST_SUITE("bsdf") {

    TEST_CASE("chi-square p-values: the incomplete gamma function against closed forms") {
        // 2 degrees of freedom: Q(1, x/2) = exp(-x/2); 1 degree: Q(1/2, x/2) = erfc(sqrt(x/2)).
        for (double x : {0.1, 1.0, 5.0, 30.0}) {
            CHECK(gamma_q(1.0, 0.5 * x) == doctest::Approx(std::exp(-0.5 * x)).epsilon(1e-10));
            CHECK(gamma_q(0.5, 0.5 * x) ==
                  doctest::Approx(std::erfc(std::sqrt(0.5 * x))).epsilon(1e-9));
        }
        // 2000 degrees of freedom: the 0.999 quantile is 2158.4 (Wilson-Hilferty, accurate here to
        // 0.1).
        CHECK(gamma_q(1000.0, 0.5 * 2158.4) == doctest::Approx(1e-3).epsilon(0.05));
    }

    TEST_CASE("chi-square: every non-delta sampler follows its pdf") {
        const std::vector<ChiCase> cases = chi_cases();
        const double alpha = chi_alpha();
        std::printf("chi-square, %u samples, 32x64 cells + failures, reject p < %.2e\n",
                    kChiSamples, alpha);
        uint stream = 0;
        for (const ChiCase& c : cases) {
            const ChiResult r = chi_square(generic_sampler(c, stream++), generic_pdf(c));
            std::printf("  %-45s stat %8.1f dof %4d p %.3f  int pdf %.6f  fail %u\n",
                        c.name.c_str(), r.stat, r.dof, r.p, r.pdf_integral, r.other);
            INFO(c.name << ": stat " << r.stat << ", dof " << r.dof << ", p " << r.p);
            CHECK(r.p >= alpha);
            CHECK(r.pdf_integral <= 1.0 + 1e-5);
            if (c.wi.z == 1.0f) { // closed forms of the pdf's integral at normal incidence
                const float a = c.m.alpha, a_vis = 1.0f / (1.0f + a * a);
                double want = 1.0;
                if (c.m.type == MATERIAL_ROUGHCONDUCTOR) want = a_vis;
                if (c.m.type == MATERIAL_ROUGHPLASTIC) {
                    const float p = roughplastic_specular_prob(c.albedo, xyz(c.m.specular),
                                                               plastic_t(c.m, 1.0f));
                    want = p * a_vis + (1.0 - p);
                }
                CHECK(std::fabs(r.pdf_integral - want) <= 1e-5);
            }
        }
    }

    TEST_CASE("chi-square: wrong pdfs and samplers are rejected") {
        const double alpha = chi_alpha();
        const ChiCase base{"roughconductor a=0.3 wi=45", roughconductor(0.3f, kGoldEta, kGoldK),
                           kWhite, dir(45.0f)};
        const PdfFn right = generic_pdf(base);
        struct Bad {
            const char* what;
            SampleFn sample;
            PdfFn pdf;
        };
        const ChiCase dif{"diffuse", diffuse(), kWhite, dir(45.0f)};
        const ChiCase pla{
            "roughplastic", roughplastic(0.3f, 1.5f, kWhite), {0.5f, 0.5f, 0.5f}, dir(45.0f)};
        const float p_spec =
            roughplastic_specular_prob(pla.albedo, kWhite, plastic_t(pla.m, pla.wi.z));
        const Bad bad[] = {
            {"diffuse pdf * 1.1", generic_sampler(dif, 900),
             [&](float3 wo) { return 1.1f * bsdf_pdf(tables(), &dif.m, kWhite, dif.wi, wo); }},
            {"roughconductor pdf * 1.1", generic_sampler(base, 901),
             [&](float3 wo) { return 1.1f * right(wo); }},
            {"roughconductor pdf with alpha * 1.1", generic_sampler(base, 902),
             [&](float3 wo) { return bsdf_roughconductor_pdf(0.33f, base.wi, wo); }},
            {"roughplastic lobe weights off by 10%", generic_sampler(pla, 903),
             [&](float3 wo) {
                 const float p = 1.1f * p_spec;
                 return wo.z <= 0.0f ? 0.0f
                                     : p * bsdf_roughconductor_pdf(0.3f, pla.wi, wo) +
                                           (1.0f - p) * wo.z / kPi;
             }},
            {"normals drawn from D cos instead of the visible normals",
             [&](uint i, float3* wo) {
                 const float u1 = rng_uniform(7u, 904u, i, 1u), u2 = rng_uniform(7u, 904u, i, 2u);
                 const float t2 = 0.09f * u1 / (1.0f - u1), c = 1.0f / std::sqrt(1.0f + t2);
                 const float s = std::sqrt(std::max(0.0f, 1.0f - c * c)), phi = 2.0f * kPi * u2;
                 *wo = vreflect(base.wi, make_float3(s * std::cos(phi), s * std::sin(phi), c));
                 return wo->z > 0.0f ? 1 : 0;
             },
             right},
        };
        for (const Bad& b : bad) {
            const ChiResult r = chi_square(b.sample, b.pdf);
            std::printf("  negative control %-52s stat %10.1f dof %4d p %.2e\n", b.what, r.stat,
                        r.dof, r.p);
            INFO(b.what << ": stat " << r.stat << ", dof " << r.dof << ", p " << r.p);
            CHECK(r.p < alpha);
        }
    }

    TEST_CASE("energy: white BSDFs reflect at most what they receive") {
        const uint n = 1u << 17;
        struct E {
            std::string name;
            Material m;
        };
        std::vector<E> cases;
        cases.push_back({"diffuse", diffuse()});
        cases.push_back(
            {"conductor none", material(MATERIAL_CONDUCTOR, 0, kWhite, kNoneEta, kNoneK)});
        cases.push_back(
            {"conductor gold", material(MATERIAL_CONDUCTOR, 0, kWhite, kGoldEta, kGoldK)});
        for (float a : {1e-4f, 0.05f, 0.3f, 1.0f}) {
            const std::string as = " a=" + std::to_string(a).substr(0, 6);
            cases.push_back({"roughconductor none" + as, roughconductor(a, kNoneEta, kNoneK)});
            cases.push_back({"roughconductor gold" + as, roughconductor(a, kGoldEta, kGoldK)});
            for (float eta : {1.5f, 1.9f})
                for (bool nl : {false, true})
                    cases.push_back({"roughplastic" + as +
                                         " eta=" + std::to_string(eta).substr(0, 4) +
                                         (nl ? " nonlinear" : ""),
                                     roughplastic(a, eta, kWhite, nl)});
        }
        uint stream = 1000;
        for (const E& e : cases)
            for (float th : kThetas) {
                const float3 wi = dir(th);
                const bool plastic = e.m.type == MATERIAL_ROUGHPLASTIC;
                Mean est, uni, fres;
                for (uint i = 0; i < n; ++i) {
                    est.add(draw(e.m, kWhite, wi, 3u, stream, i).w.x);
                    // independent estimate: uniform directions on the hemisphere, pdf 1 / (2 pi)
                    const float3 u = sample_uniform_sphere(0.5f * rng_uniform(3u, stream, i, 3u),
                                                           rng_uniform(3u, stream, i, 4u));
                    uni.add(bsdf_eval(tables(), &e.m, kWhite, wi, u).x * 2.0 * kPi);
                    // plastic: E[F(wi.m)] over the visible normals bounds the coating's albedo
                    if (plastic)
                        fres.add(fresnel_dielectric_r(
                            vdot(wi,
                                 ggx_sample_visible(e.m.alpha, wi, rng_uniform(3u, stream, i, 5u),
                                                    rng_uniform(3u, stream, i, 6u))),
                            e.m.eta.x));
                }
                ++stream;
                const double mean = est.mean(), se = est.se(), umean = uni.mean(), use = uni.se();
                double bound = 1.0, bound_se = 0.0;
                if (plastic) { // coating + base t_i T_o / (eta^2 (1 - r)) <= E[F] + t_i <= 1
                    const float eta = e.m.eta.x;
                    const double base = plastic_t_average(e.m) / ((double)eta * eta) /
                                        (1.0 - (double)plastic_r(e.m));
                    CHECK(base <= 1.0); // the base passes on at most what enters it
                    bound = fres.mean() + plastic_t(e.m, wi.z) * base;
                    bound_se = fres.se();
                }
                INFO(e.name << " wi=" << th << ": albedo " << mean << " +- " << se << ", uniform "
                            << umean << " +- " << use << ", bound " << bound);
                CHECK(mean <= bound + 4.0 * std::sqrt(se * se + bound_se * bound_se) + 1e-5);
                CHECK(mean > 0.0);
                if (e.m.type == MATERIAL_DIFFUSE) CHECK(mean == doctest::Approx(1.0).epsilon(1e-6));
                const bool broad = e.m.type == MATERIAL_DIFFUSE || e.m.alpha >= 0.3f;
                if (broad)
                    CHECK(std::fabs(mean - umean) <= 4.0 * std::sqrt(se * se + use * use) + 1e-6);
                if (th == 45.0f)
                    std::printf("  energy %-38s wi=45: %.5f +- %.5f (bound %.5f)\n", e.name.c_str(),
                                mean, se, bound);
            }
    }

    TEST_CASE("energy: a white roughplastic reflects Mitsuba's albedo, at most 1") {
        // White furnace: specular 1, diffuse 1. Mitsuba's model predicts the albedo
        // R(wi) + t_i T_o / (eta^2 (1 - r)): the coating reflects R = E[F(wi.m) G1(wo)] over the
        // visible normals (eval_reflectance, here by the host's double quadrature, 128 x 128),
        // the base passes t_i into the layer and T_o / (eta^2 (1 - r)) of it out (T_o = 2 int t mu
        // dmu). Estimated with the BSDF's own sampling (N = 2^17), within 4 standard errors +
        // 2e-4 (the quadrature, the table's r); and at most 1 by the same margin.
        const uint n = 1u << 17;
        uint stream = 1500;
        for (float eta : {1.33f, 1.5f})
            for (float a : {0.05f, 0.3f, 1.0f})
                for (float th : kThetas) {
                    const Material m = roughplastic(a, eta, kWhite);
                    const float3 wi = dir(th);
                    Mean est;
                    for (uint i = 0; i < n; ++i)
                        est.add(draw(m, kWhite, wi, 21u, stream, i).w.x);
                    ++stream;
                    const double coating = tandem::rough_dielectric_reflectance(a, wi.z, eta, 128);
                    const double base = plastic_t(m, wi.z) * plastic_t_average(m) /
                                        ((double)eta * eta) / (1.0 - plastic_r(m));
                    const double mean = est.mean(), se = est.se();
                    INFO("eta " << eta << " alpha " << a << " wi=" << th << ": albedo " << mean
                                << " +- " << se << ", Mitsuba's " << coating << " + " << base);
                    CHECK(std::fabs(mean - (coating + base)) <= 4.0 * se + 2e-4);
                    CHECK(mean <= 1.0 + 4.0 * se);
                    CHECK(coating + base <= 1.0);
                    if (th == 45.0f)
                        std::printf("  white roughplastic eta %.2f alpha %.2f wi=45: %.5f +- %.5f, "
                                    "Mitsuba's %.5f + %.5f\n",
                                    eta, a, mean, se, coating, base);
                }
    }

    TEST_CASE("roughplastic: as alpha -> 0 the base tends to the smooth interface's") {
        // The base with specular 0 against Mitsuba's formula for a smooth interface,
        // diff t0(cos_i) t0(cos_o) cos_o / (pi eta^2), diff = diffuse / (1 - r0): t0 linear
        // between 1 - F at the 64 nodes, r0 the 64-node mean of 2 F(mu) mu from inside. Within
        // 2e-4 relative at GGX_ALPHA_MIN for cosines >= 0.1 (measured 6e-5: the table's
        // quadrature; the interface still scatters at grazing cosines below ~alpha), and further
        // off as alpha grows.
        const float eta = 1.5f;
        auto t0 = [&](double mu) {
            const double x = mu * 63.0;
            const int k = std::min(62, (int)x);
            const double f0 = 1.0 - fresnel_dielectric_r(std::max(1e-6f, k / 63.0f), eta),
                         f1 = 1.0 - fresnel_dielectric_r((k + 1) / 63.0f, eta);
            return f0 + (f1 - f0) * (x - k);
        };
        double r0 = 0.0;
        for (int k = 0; k < 64; ++k) {
            const float mu = std::max(1e-6f, k / 63.0f);
            r0 += 2.0 * fresnel_dielectric_r(mu, 1.0f / eta) * mu / 64.0;
        }
        double prev = 0.0;
        for (float a : {GGX_ALPHA_MIN, 0.01f, 0.1f}) {
            const Material m = roughplastic(a, eta, {0.0f, 0.0f, 0.0f});
            double worst = 0.0;
            for (float ci : {1.0f, 0.8f, 0.5f, 0.3f, 0.1f})
                for (float co : {1.0f, 0.7f, 0.4f, 0.1f}) {
                    const float3 wi = make_float3(std::sqrt(1.0f - ci * ci), 0.0f, ci);
                    const float3 wo = make_float3(0.0f, std::sqrt(1.0f - co * co), co);
                    const double f = bsdf_eval(tables(), &m, kWhite, wi, wo).x;
                    const double smooth = t0(ci) * t0(co) * co / (kPi * eta * eta) / (1.0 - r0);
                    worst = std::max(worst, rel_diff(f, smooth));
                }
            std::printf("  roughplastic base vs smooth interface, alpha %g: worst relative "
                        "difference %.2e\n",
                        a, worst);
            if (a == GGX_ALPHA_MIN) CHECK(worst <= 2e-4);
            CHECK(worst >= prev); // and it grows with alpha
            prev = worst;
        }
    }

    TEST_CASE("energy: roughplastic's diffuse base against its closed form") {
        // Specular 0: only the base, sampled by the cosine. Mitsuba's formula integrates to
        // diff t_i T_o / eta^2, T_o = 2 int t(mu) mu dmu (the table as looked up), with diff the
        // linear or nonlinear rescaling of the diffuse reflectance by the table's r.
        const uint n = 1u << 16;
        uint stream = 2000;
        for (float eta : {1.33f, 1.5f, 1.9f})
            for (bool nl : {false, true})
                for (float th : kThetas) {
                    const Material m = roughplastic(0.3f, eta, {0.0f, 0.0f, 0.0f}, nl);
                    const float3 wi = dir(th), albedo = {0.5f, 0.5f, 0.5f};
                    Mean est;
                    for (uint i = 0; i < n; ++i)
                        est.add(draw(m, albedo, wi, 5u, stream, i).w.x);
                    ++stream;
                    const double r = plastic_r(m);
                    const double diff = nl ? 0.5 / (1.0 - 0.5 * r) : 0.5 / (1.0 - r);
                    const double want =
                        diff * plastic_t(m, wi.z) * plastic_t_average(m) / (eta * eta);
                    const double mean = est.mean(), se = est.se();
                    INFO("eta " << eta << (nl ? " nonlinear" : "") << " wi=" << th << ": " << mean
                                << " +- " << se << " want " << want);
                    CHECK(std::fabs(mean - want) <= 4.0 * se + 1e-5);
                }
    }

    TEST_CASE("reciprocity: f(wi, wo) = f(wo, wi) for the non-delta BSDFs") {
        const auto cases = nondelta_cases({1e-4f, 0.05f, 0.3f, 1.0f});
        uint stream = 3000, checked = 0;
        double worst = 0.0;
        for (const auto& [m, albedo] : cases) {
            for (uint i = 0; i < 4000; ++i) {
                const float3 wi = sample_cosine_hemisphere(rng_uniform(9u, stream, i, 0u),
                                                           rng_uniform(9u, stream, i, 1u));
                float3 wo = sample_uniform_sphere(0.5f * rng_uniform(9u, stream, i, 2u),
                                                  rng_uniform(9u, stream, i, 3u));
                // half of the pairs near the specular peak, where D is large
                if (i % 2) wo = draw(m, albedo, wi, 19u, stream, i).wo;
                if (wi.z <= 0.0f || wo.z <= 0.0f) continue;
                const float3 f1 = bsdf_eval(tables(), &m, albedo, wi, wo),
                             f2 = bsdf_eval(tables(), &m, albedo, wo, wi);
                const float a1[3] = {f1.x, f1.y, f1.z}, a2[3] = {f2.x, f2.y, f2.z};
                for (int c = 0; c < 3; ++c) {
                    const double x = a1[c] / (double)wo.z, y = a2[c] / (double)wi.z;
                    const double d = rel_diff(x, y);
                    worst = std::max(worst, d);
                    ++checked;
                    if (!(d <= 1e-4)) {
                        INFO("type " << m.type << " alpha " << m.alpha << " wi " << wi.x << ","
                                     << wi.y << "," << wi.z << " wo " << wo.x << "," << wo.y << ","
                                     << wo.z << ": " << x << " vs " << y);
                        CHECK(d <= 1e-4);
                    }
                }
            }
            ++stream;
        }
        std::printf("reciprocity: %u values, worst relative difference %.2e\n", checked, worst);
        CHECK(checked > 100000);
    }

    TEST_CASE("consistency: sample weights and pdfs agree with eval and pdf") {
        const auto cases = nondelta_cases({1e-4f, 0.01f, 0.05f, 0.3f, 1.0f});
        uint stream = 4000, checked = 0;
        double worst_w = 0.0, worst_p = 0.0;
        for (const auto& [m, albedo] : cases)
            for (float th : {0.0f, 30.0f, 60.0f, 85.0f, 89.0f, 89.99f}) {
                const float3 wi = dir(th);
                for (uint i = 0; i < 4000; ++i) {
                    const auto [w, wo, pdf, delta] = draw(m, albedo, wi, 11u, stream, i);
                    if (!(pdf > 0.0f)) {
                        CHECK(max_component(w) == 0.0f);
                        continue;
                    }
                    CHECK(delta == 0);
                    const float p = bsdf_pdf(tables(), &m, albedo, wi, wo);
                    const float3 f = bsdf_eval(tables(), &m, albedo, wi, wo);
                    const double dp = rel_diff(pdf, p);
                    worst_p = std::max(worst_p, dp);
                    if (!(dp <= 1e-5)) CHECK(dp <= 1e-5);
                    if (p <= 1e-3f) continue;
                    const float fw[3] = {f.x, f.y, f.z}, ww[3] = {w.x, w.y, w.z};
                    for (int c = 0; c < 3; ++c) {
                        const double d = rel_diff(ww[c], fw[c] / (double)p);
                        worst_w = std::max(worst_w, d);
                        ++checked;
                        if (!(d <= 1e-3)) {
                            INFO("type " << m.type << " alpha " << m.alpha << " wi=" << th
                                         << ": weight " << ww[c] << " eval/pdf " << fw[c] / p);
                            CHECK(d <= 1e-3);
                        }
                    }
                }
                ++stream;
            }
        std::printf("consistency: %u weights, worst relative difference %.2e (pdf %.2e)\n", checked,
                    worst_w, worst_p);
        CHECK(checked > 300000);
    }

    TEST_CASE("stability: finite outputs for extreme inputs, zero from behind") {
        // Random alpha (log-uniform 1e-4..1), IORs, colours; wi from the normal to 89.99 deg plus
        // exact normal, grazing, tiny and backfacing cosines; wo random, along the normal or the
        // mirror; u at 0 and 0.99999994.
        const float u_max = 0.99999994f;
        const float tiny_z[] = {0.0f, 1e-7f, 1e-20f, 1e-40f, 1.7e-4f};
        const uint types[] = {MATERIAL_DIFFUSE, MATERIAL_CONDUCTOR, MATERIAL_ROUGHCONDUCTOR,
                              MATERIAL_DIELECTRIC, MATERIAL_ROUGHPLASTIC};
        uint bad = 0, backfacing = 0, successes = 0;
        for (uint t = 0; t < 5; ++t)
            for (uint i = 0; i < 10000; ++i) {
                auto u = [&](uint d) { return rng_uniform(17u, t, i, d); };
                const float alpha = std::pow(10.0f, -4.0f * u(0));
                // dielectric IORs from a few values, as each roughplastic IOR builds a table
                const float etas[] = {1.0f, 1.1f, 1.33f, 1.5f, 2.0f, 3.0f};
                const float eta_c = 3.0f * u(1), k_c = 10.0f * u(2), eta_d = etas[i % 6];
                Material m = material(
                    types[t], alpha, {u(4), u(5), 1.0f},
                    types[t] == MATERIAL_CONDUCTOR || types[t] == MATERIAL_ROUGHCONDUCTOR
                        ? float3{eta_c, 1.0f, 0.0f}
                        : float3{i % 7 == 0 ? 1.0f : (i % 2 ? eta_d : 1.0f / eta_d), 1.0f, 1.0f},
                    {k_c, 0.0f, 30.0f}, i % 2 ? MATERIAL_FLAG_NONLINEAR : 0u);
                const float3 albedo = {u(6), i % 3 == 0 ? 0.0f : 1.0f, 0.5f};
                float3 wi = dir(89.99f * u(7), 2.0f * kPi * u(8));
                const float z = tiny_z[(i / 8) % 5];
                if (i % 8 == 0) wi = make_float3(0.0f, 0.0f, 1.0f);
                if (i % 8 == 1) wi = make_float3(std::sqrt(1.0f - z * z), 0.0f, z);
                if (i % 8 == 2) wi.z = -wi.z;
                float3 wo = sample_uniform_sphere(u(9), u(10));
                if (i % 5 == 0) wo = make_float3(0.0f, 0.0f, 1.0f);
                if (i % 5 == 1) wo = make_float3(-wi.x, -wi.y, wi.z);
                const float us[3] = {0.0f, u_max, u(11)};
                const float u_lobe = us[i % 3], u1 = us[(i / 3) % 3], u2 = us[(i / 9) % 3];

                const float3 f = bsdf_eval(tables(), &m, albedo, wi, wo);
                const float p = bsdf_pdf(tables(), &m, albedo, wi, wo);
                float3 ws;
                float ps;
                int delta;
                const float3 w =
                    bsdf_sample(tables(), &m, albedo, wi, u_lobe, u1, u2, &ws, &ps, &delta);
                const bool ok = finite3(f) && f.x >= 0 && f.y >= 0 && f.z >= 0 &&
                                std::isfinite(p) && p >= 0 && finite3(w) && w.x >= 0 && w.y >= 0 &&
                                w.z >= 0 && std::isfinite(ps) && ps >= 0 && finite3(ws) &&
                                (delta == 0 || delta == 1) && !(delta && ps != 0.0f) &&
                                (ps > 0.0f || delta || max_component(w) == 0.0f) &&
                                (!(ps > 0.0f || delta) || std::fabs(vlength(ws) - 1.0f) <= 1e-3f);
                if (!ok) {
                    ++bad;
                    INFO("type " << m.type << " alpha " << alpha << " wi " << wi.x << "," << wi.y
                                 << "," << wi.z << " wo " << wo.x << "," << wo.y << "," << wo.z
                                 << " u " << u_lobe << "," << u1 << "," << u2 << ": eval " << f.x
                                 << " pdf " << p << " weight " << w.x << " spdf " << ps << " wo' "
                                 << ws.x << "," << ws.y << "," << ws.z);
                    CHECK(ok);
                }
                successes += ps > 0.0f || delta;
                if (wi.z < 0.0f && m.type != MATERIAL_DIELECTRIC) { // one-sided: black from behind
                    ++backfacing;
                    CHECK(max_component(f) == 0.0f);
                    CHECK(p == 0.0f);
                    CHECK((ps == 0.0f && delta == 0 && max_component(w) == 0.0f));
                }
            }
        std::printf("stability: 50000 inputs, %u non-finite, %u backfacing, %u samples succeeded\n",
                    bad, backfacing, successes);
        CHECK(bad == 0);
        CHECK(backfacing > 4000);
        CHECK(successes > 30000);
    }

} // TEST_SUITE("bsdf")
