// Derivatives of the BSDF values with respect to the material parameters
// (kernels/shared/bsdf_grad.h) on the host: against finite differences of the functions they
// differentiate (bsdf_eval; bsdf_sample's weight for the delta lobes), exact zeros where the eval
// is zero or alpha is clamped, homogeneity identities, negative controls (wrong formulas must be
// rejected), and finiteness under extreme inputs.
//
// Tolerances and how they were derived (u = 2^-24, float's unit roundoff):
// - Steps: each parameter x is stepped by h = 1e-2 times its natural scale: alpha itself for alpha
//   (D and G1 / cos are smooth functions of ln alpha with O(1) derivatives); max(|x|, 0.1) for the
//   colours, on which the values depend linearly, except the nonlinear plastic's albedo, whose
//   scale is also capped by the distance |1 - x r - 1e-3| / r to the eval's clamp (which lies
//   before the pole x = 1 / r; r the internal reflectance from the plastic's table), so the
//   stencil never straddles the clamp.
// - Central differences in double from float evaluations at the float-rounded points x +- h and
//   x +- 2h, divided by the exact float steps, combined by Richardson extrapolation
//   (4 D(h) - D(2h)) / 3: truncation error O((h / scale)^4) = 1e-8 relative to |f| / scale,
//   negligible against the rounding term below.
// - Rounding: one evaluation of f cos takes at most ~24 float roundings that differ between the
//   stencil points (D ~7, each G1 / cos ~6, the products ~4, the plastic's sum 1; the Fresnel
//   factors and cosines do not depend on the parameters and are bitwise equal across the
//   stencil; the plastic's table lookups in alpha take ~8 each, but its base and coating add
//   rather than multiply), so its error is <= 24 u |f|. D(h) then carries <= 24 u f_max / h, D(2h)
//   half that, and the extrapolation 4/3 * 24 + 1/3 * 12 = 36 u f_max / h; accepted: 48 u f_max / h
//   (f_max: the largest |f| on the stencil, per channel), plus 1e-5 |analytic| for the rounding of
//   the derivative itself (its cancellation in 2 t / b - 1 is absolute, ~u |f| / alpha, far inside
//   the first term). For alpha that is 2.9e-4 |f| / alpha, against derivatives ~|f| / alpha.
//   Measured: the worst |fd - analytic| / tolerance is ~0.15 (0.45 for the nonlinear albedo next
//   to the pole), i.e. the actual rounding is ~7 u f_max / h. The plastic's table is a cubic in
//   alpha^(1/4) per cell, C1 across its nodes: a stencil straddling a node sees a jump of the
//   second derivative, O(h) in the difference, measured far inside the tolerance (worst 0.15).
// - Skipped (counted, and at most 5% of the checks per parameter): stencils across which the set
//   of exactly-zero values changes (D flushed to zero by ggx_d, a one-sided cutoff), or with
//   nonzero values below 1e-30 (subnormal range, where the relative rounding bound fails). The
//   horizon needs no special care: the directions stay fixed, only the parameters move.
// - "Tight" checks are those whose tolerance is below 1% of the derivative; at least 80% of the
//   alpha checks of every roughconductor and roughplastic must be tight, so the comparison has
//   teeth (the plastic's base depends on alpha through its rough interface's table too).
// - Clamped alpha (< GGX_ALPHA_MIN): d_alpha exactly 0, and the central difference of the eval
//   exactly 0 too. At alpha = GGX_ALPHA_MIN, where the clamp starts, the derivative is the right
//   one: a second-order forward difference with h = 1e-3 alpha, truncation ~(h / alpha)^2 = 1e-6,
//   rounding (3 + 4 + 1) / 2 * 24 u f_max / h = 96 u f_max / h; accepted 128 u f_max / h
//   + 1e-4 |analytic|.
// - Homogeneity: f cos is linear in specular (conductor), in specular and albedo (diffuse, linear
//   plastic), and the delta weights in specular, so f = specular . d_specular + albedo . d_albedo
//   up to the few roundings of both sides: 1e-6 relative.
// - Negative controls: d ln D negated or its 4 t / (alpha b) term doubled, d ln(G1 / cos) negated
//   or dropped, the nonlinear plastic's 1 / (1 - x r)^2 replaced by 1 / (1 - x r), the linear
//   plastic's 1 / (1 - r) dropped, the plastic's base left out of d_alpha (its table's t and r
//   held fixed, as Mitsuba's detached table does), the conductor's F dropped from d_specular must
//   each fail the same comparison for a large share of the samples (thresholds below, each with a
//   wide margin under the measured share, 98-100% for all of them), while the unbroken derivative
//   rebuilt the same way must pass everywhere.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "bsdf_fixtures.h"
#include "shared/bsdf_grad.h"
#include "shared/rng.h"

using namespace tandem::gpu;
using namespace bsdf_fixtures;

namespace {

constexpr double kU = 5.9604644775390625e-8; // 2^-24
constexpr double kStepRel = 1e-2;            // h / natural scale
constexpr double kRoundFactor = 48.0;        // accepted rounding, in u f_max / h
constexpr double kRelTol = 1e-5;             // rounding of the analytic derivative
constexpr double kTight = 1e-2;              // a check is tight if its tolerance < 1% of the value
constexpr double kPlasticT = 1.5; // >= |d ln t / d ln alpha| of the plastic tables (extremes test)
constexpr double kPlasticR = 1.0; // >= |d r / d ln alpha| of the plastic tables

float get(float3 v, int c) {
    return c == 0 ? v.x : (c == 1 ? v.y : v.z);
}
void set(float3* v, int c, float x) {
    (c == 0 ? v->x : (c == 1 ? v->y : v->z)) = x;
}
bool finite3(float3 v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}
bool zero3(float3 v) {
    return v.x == 0.0f && v.y == 0.0f && v.z == 0.0f;
}
bool grad_zero(const BsdfGrad& g) {
    return zero3(g.d_albedo) && zero3(g.d_specular) && zero3(g.d_alpha);
}
bool grad_finite(const BsdfGrad& g) {
    return finite3(g.d_albedo) && finite3(g.d_specular) && finite3(g.d_alpha);
}
std::string str(float3 v) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "(%.9g, %.9g, %.9g)", v.x, v.y, v.z);
    return buf;
}

enum Param { kAlbedo = 0, kSpecular = 1, kAlpha = 2 };
const char* const kParamNames[] = {"albedo", "specular", "alpha"};

/// The value under test as a function of the material and the albedo (wi, wo bound by the caller).
using ValueFn = std::function<float3(const Material&, float3)>;

float get_param(const Material& m, float3 albedo, Param p, int c) {
    if (p == kAlbedo) return get(albedo, c);
    if (p == kSpecular) return get(xyz(m.specular), c);
    return m.alpha;
}
void set_param(Material* m, float3* albedo, Param p, int c, float x) {
    if (p == kAlbedo)
        set(albedo, c, x);
    else if (p == kSpecular)
        (c == 0 ? m->specular.x : (c == 1 ? m->specular.y : m->specular.z)) = x;
    else
        m->alpha = x;
}
float3 grad_of(const BsdfGrad& g, Param p) {
    return p == kAlbedo ? g.d_albedo : (p == kSpecular ? g.d_specular : g.d_alpha);
}

bool nonlinear_plastic(const Material& m) {
    return m.type == MATERIAL_ROUGHPLASTIC && (m.flags & MATERIAL_FLAG_NONLINEAR) != 0u;
}

/// Finite-difference step of parameter p at x: kStepRel times its natural scale (header comment).
double step(const Material& m, Param p, float x) {
    if (p == kAlpha) return kStepRel * (x > 0.0f ? (double)x : 0.1);
    double scale = std::max(std::fabs((double)x), 0.1);
    if (p == kAlbedo && nonlinear_plastic(m)) {
        const double r = plastic_r(m);
        if (r > 0.0) scale = std::min(scale, std::fabs(1.0 - x * r - 1e-3) / r);
    }
    return kStepRel * scale;
}

/// Richardson-extrapolated central difference of f at x per channel, and its rounding bound.
struct Fd {
    bool ok = true; // false: the zero pattern changes across the stencil, or values are subnormal
    double d[3] = {0, 0, 0};
    double bound[3] = {0, 0, 0}; // kRoundFactor u f_max / h
};
Fd central_difference(const std::function<float3(float)>& f, float x, double h) {
    Fd r;
    if (!(h > 0.0)) {
        r.ok = false;
        return r;
    }
    const double off[4] = {-2.0, -1.0, 1.0, 2.0};
    float xs[4];
    float3 v[4];
    for (int i = 0; i < 4; ++i) {
        xs[i] = (float)(x + off[i] * h);
        v[i] = f(xs[i]);
    }
    const float3 v0 = f(x);
    for (int c = 0; c < 3; ++c) {
        const bool zero0 = get(v0, c) == 0.0f;
        double fmax = std::fabs(get(v0, c));
        for (int i = 0; i < 4; ++i) {
            const float fi = get(v[i], c);
            if ((fi == 0.0f) != zero0 || !std::isfinite(fi) ||
                (fi != 0.0f && std::fabs(fi) < 1e-30f))
                r.ok = false;
            fmax = std::max(fmax, (double)std::fabs(fi));
        }
        const double d1 = ((double)get(v[2], c) - get(v[1], c)) / ((double)xs[2] - xs[1]);
        const double d2 = ((double)get(v[3], c) - get(v[0], c)) / ((double)xs[3] - xs[0]);
        r.d[c] = (4.0 * d1 - d2) / 3.0;
        r.bound[c] = kRoundFactor * kU * fmax / h;
    }
    return r;
}

/// Per-parameter tallies of the finite-difference comparison.
struct Stats {
    uint checked = 0, skipped = 0, tight = 0, failed = 0;
    double worst = 0.0; // largest |fd - analytic| / tolerance
    void add(const Stats& o) {
        checked += o.checked, skipped += o.skipped, tight += o.tight, failed += o.failed;
        worst = std::max(worst, o.worst);
    }
};

/// Compares g with central differences of `value` at (m, albedo) for every parameter and channel:
/// a colour channel c perturbs output c by g's diagonal entry and the others not at all; alpha
/// perturbs every channel. Returns a bit mask of the parameters that failed; a description of the
/// first failure goes to *why.
int check_point(const ValueFn& value, const Material& m, float3 albedo, const BsdfGrad& g,
                Stats st[3], std::string* why) {
    int failed = 0;
    for (int pi = 0; pi < 3; ++pi) {
        const Param p = (Param)pi;
        const float3 an = grad_of(g, p);
        for (int c = 0; c < (p == kAlpha ? 1 : 3); ++c) {
            const float x = get_param(m, albedo, p, c);
            const double h = step(m, p, x);
            const Fd fd = central_difference(
                [&](float v) {
                    Material mm = m;
                    float3 aa = albedo;
                    set_param(&mm, &aa, p, c, v);
                    return value(mm, aa);
                },
                x, h);
            if (!fd.ok) {
                ++st[p].skipped;
                continue;
            }
            ++st[p].checked;
            bool bad = false;
            for (int k = 0; k < 3; ++k) {
                const bool diag = p == kAlpha || k == c;
                const double want = diag ? get(an, k) : 0.0;
                const double tol = kRelTol * std::fabs(want) + fd.bound[k];
                const double err = std::fabs(fd.d[k] - want);
                st[p].worst = std::max(st[p].worst, err / tol);
                if (p == kAlpha ? k == 0 : k == c) st[p].tight += tol < kTight * std::fabs(want);
                if (!(err <= tol)) {
                    if (!bad && why && why->empty()) {
                        char buf[256];
                        std::snprintf(buf, sizeof buf,
                                      "d/d %s[%d] channel %d: analytic %.9g, finite difference "
                                      "%.9g, tolerance %.3g (h %.3g)",
                                      kParamNames[p], c, k, want, fd.d[k], tol, h);
                        *why = buf;
                    }
                    bad = true;
                }
            }
            if (bad) {
                ++st[p].failed;
                failed |= 1 << p;
            }
        }
    }
    return failed;
}

/// A material under test with its albedo.
struct Case {
    std::string name;
    Material m;
    float3 albedo;
};

const float3 kSpec = {0.9f, 0.7f, 0.5f};

/// The non-delta families of the finite-difference test.
std::vector<Case> eval_cases() {
    std::vector<Case> cases = {{"diffuse", diffuse(), {0.3f, 0.6f, 0.9f}}};
    char buf[96];
    for (float a : {0.05f, 0.3f, 0.8f}) {
        std::snprintf(buf, sizeof buf, "roughconductor gold a=%g", a);
        Material rc = roughconductor(a, kGoldEta, kGoldK);
        rc.specular = make_float4(kSpec.x, kSpec.y, kSpec.z, 0.0f);
        cases.push_back({buf, rc, kWhite});
    }
    for (float a : {0.05f, 0.2f, 0.5f, 0.8f}) {
        std::snprintf(buf, sizeof buf, "roughplastic eta=1.5 a=%g", a);
        cases.push_back({buf, roughplastic(a, 1.5f, {0.8f, 0.9f, 1.0f}), {0.5f, 0.3f, 0.2f}});
        std::snprintf(buf, sizeof buf, "roughplastic eta=1.9 nonlinear a=%g", a);
        cases.push_back({buf, roughplastic(a, 1.9f, {0.6f, 0.7f, 0.8f}, true), {0.9f, 0.5f, 0.1f}});
    }
    cases.push_back({"roughplastic eta=1.33 nonlinear a=0.1",
                     roughplastic(0.1f, 1.33f, kSpec, true),
                     {0.95f, 0.7f, 0.05f}});
    cases.push_back({"roughplastic eta=10 nonlinear a=0.3 (clamped denominator)",
                     roughplastic(0.3f, 10.0f, kSpec, true),
                     {0.5f, 0.995f, 1.2f}});
    return cases;
}

/// Direction pair i of a case: wi cosine-distributed (every 16th grazing at 89.9 deg, every 16th
/// at normal incidence), wo uniform on the upper hemisphere or (odd i) drawn by bsdf_sample, so
/// that half of the pairs sit in the specular peak.
void directions(const Case& cs, uint stream, uint i, float3* wi, float3* wo) {
    auto u = [&](uint d) { return rng_uniform(23u, stream, i, d); };
    *wi = sample_cosine_hemisphere(u(0), u(1));
    if (i % 16 == 2) *wi = dir(89.9f, 2.0f * kPi * u(2));
    if (i % 16 == 4) *wi = make_float3(0.0f, 0.0f, 1.0f);
    *wo = sample_uniform_sphere(0.5f * u(3), u(4));
    if (i % 2) {
        const Draw d = draw(cs.m, cs.albedo, *wi, 29u, stream, i);
        if (d.pdf > 0.0f) *wo = d.wo;
    }
}

ValueFn eval_fn(float3 wi, float3 wo) {
    return [wi, wo](const Material& m, float3 albedo) {
        return bsdf_eval(tables(), &m, albedo, wi, wo);
    };
}

/// Runs the finite-difference comparison over n direction pairs of a case, with the analytic
/// derivatives of `grad` (the header's by default; the negative controls substitute wrong ones).
using GradFn = std::function<BsdfGrad(const Material&, float3, float3, float3)>;
BsdfGrad header_grad(const Material& m, float3 albedo, float3 wi, float3 wo) {
    return bsdf_eval_grad(tables(), &m, albedo, wi, wo);
}
void run_eval_case(const Case& cs, uint stream, uint n, const GradFn& grad, Stats st[3],
                   bool report) {
    for (uint i = 0; i < n; ++i) {
        float3 wi, wo;
        directions(cs, stream, i, &wi, &wo);
        if (wi.z <= 0.0f || wo.z <= 0.0f) { // on the horizon: not a pair of this test
            for (int p = 0; p < 3; ++p)
                ++st[p].skipped;
            continue;
        }
        std::string why;
        const int failed =
            check_point(eval_fn(wi, wo), cs.m, cs.albedo, grad(cs.m, cs.albedo, wi, wo), st, &why);
        if (failed && report) {
            INFO(cs.name << " wi " << str(wi) << " wo " << str(wo) << ": " << why);
            CHECK(failed == 0);
        }
    }
}

/// Prints and checks the tallies of one case; min_tight: the share of tight alpha checks required.
void report_stats(const std::string& name, const Stats st[3], double min_tight) {
    std::printf("  %-66s", name.c_str());
    for (int p = 0; p < 3; ++p)
        std::printf(" %s %u/%u tight %u worst %.3f%s", kParamNames[p], st[p].checked,
                    st[p].checked + st[p].skipped, st[p].tight, st[p].worst, p < 2 ? "," : "\n");
    for (int p = 0; p < 3; ++p) {
        INFO(name << ": " << kParamNames[p] << " checked " << st[p].checked << " skipped "
                  << st[p].skipped << " tight " << st[p].tight);
        CHECK(st[p].failed == 0);
        CHECK(st[p].checked >= 0.95 * (st[p].checked + st[p].skipped));
    }
    INFO(name << ": alpha checks " << st[kAlpha].checked << ", tight " << st[kAlpha].tight);
    CHECK(st[kAlpha].tight >= min_tight * st[kAlpha].checked);
}

constexpr uint kPairs = 3000;

} // namespace

TEST_SUITE("bsdf_grad") {

    TEST_CASE("bsdf grad: eval derivatives match finite differences") {
        std::printf("bsdf grad vs finite differences (%u pairs per case; checked/total, tight, "
                    "worst error / tolerance):\n",
                    kPairs);
        uint stream = 0;
        Stats total[3];
        for (const Case& cs : eval_cases()) {
            Stats st[3];
            run_eval_case(cs, stream++, kPairs, header_grad, st, true);
            report_stats(cs.name, st,
                         cs.m.type == MATERIAL_ROUGHCONDUCTOR || cs.m.type == MATERIAL_ROUGHPLASTIC
                             ? 0.8
                             : 0.0);
            for (int p = 0; p < 3; ++p)
                total[p].add(st[p]);
        }
        CHECK(total[kAlpha].checked > 30000);
        CHECK(total[kAlbedo].checked > 100000);
    }

    TEST_CASE("bsdf grad: delta weights match finite differences of bsdf_sample") {
        // The value differentiated is bsdf_sample's weight for the same lobe and direction; a
        // perturbed parameter that changed the lobe or the direction would make it NaN (caught).
        struct DeltaCase {
            std::string name;
            Material m;
            bool sphere; // wi on the whole sphere (dielectric) or the upper hemisphere
        };
        std::vector<DeltaCase> cases = {
            {"conductor gold", material(MATERIAL_CONDUCTOR, 0.0f, kSpec, kGoldEta, kGoldK), false},
            {"conductor none", material(MATERIAL_CONDUCTOR, 0.0f, kSpec, kNoneEta, kNoneK), false},
            {"dielectric eta=1.5",
             material(MATERIAL_DIELECTRIC, 0.0f, kSpec, {1.5f, 1.5f, 1.5f}, kWhite), true},
            {"dielectric eta=1/1.33",
             material(MATERIAL_DIELECTRIC, 0.0f, kSpec, {1.0f / 1.33f, 1.0f, 1.0f}, kWhite), true},
        };
        const float3 albedo = {0.4f, 0.5f, 0.6f};
        uint stream = 100, reflected = 0, refracted = 0;
        for (const DeltaCase& dc : cases) {
            Stats st[3];
            for (uint i = 0; i < kPairs; ++i) {
                auto u = [&](uint d) { return rng_uniform(31u, stream, i, d); };
                const float3 wi = dc.sphere ? sample_uniform_sphere(u(0), u(1))
                                            : sample_cosine_hemisphere(u(0), u(1));
                const float u_lobe = i % 2 ? 0.99999994f : 0.0f; // refraction unless TIR
                float3 wo;
                float pdf;
                int delta;
                bsdf_sample(tables(), &dc.m, albedo, wi, u_lobe, 0.5f, 0.5f, &wo, &pdf, &delta);
                if (!delta) {
                    for (int p = 0; p < 3; ++p)
                        ++st[p].skipped;
                    continue;
                }
                const bool refr = (wi.z > 0.0f) != (wo.z > 0.0f);
                (refr ? refracted : reflected) += 1;
                const ValueFn weight = [&](const Material& m, float3 a) {
                    float3 w2;
                    float p2;
                    int d2;
                    const float3 w =
                        bsdf_sample(tables(), &m, a, wi, u_lobe, 0.5f, 0.5f, &w2, &p2, &d2);
                    const bool same = d2 && w2.x == wo.x && w2.y == wo.y && w2.z == wo.z;
                    return same ? w : make_float3(NAN, NAN, NAN);
                };
                std::string why;
                const BsdfGrad g = bsdf_delta_weight_grad(&dc.m, wi, wo);
                const int failed = check_point(weight, dc.m, albedo, g, st, &why);
                if (failed) {
                    INFO(dc.name << " wi " << str(wi) << " wo " << str(wo) << ": " << why);
                    CHECK(failed == 0);
                }
                CHECK(zero3(g.d_albedo));
                CHECK(zero3(g.d_alpha));
            }
            ++stream;
            report_stats(dc.name, st, 0.0);
        }
        std::printf("  delta lobes: %u reflections, %u refractions\n", reflected, refracted);
        CHECK(reflected > 5000);
        CHECK(refracted > 1500);
    }

    TEST_CASE("bsdf grad: homogeneity, f = specular . d_specular + albedo . d_albedo") {
        // Holds exactly in the linear parameters: diffuse, roughconductor, linear roughplastic,
        // conductor and dielectric-reflection weights.
        std::vector<Case> cases = {{"diffuse", diffuse(), {0.3f, 0.6f, 0.9f}}};
        for (float a : {1e-4f, 0.05f, 0.3f, 1.0f}) {
            Material rc = roughconductor(a, kGoldEta, kGoldK);
            rc.specular = make_float4(kSpec.x, kSpec.y, kSpec.z, 0.0f);
            cases.push_back({"roughconductor", rc, kWhite});
            cases.push_back(
                {"roughplastic", roughplastic(a, 1.5f, {0.8f, 0.9f, 1.0f}), {0.5f, 0.3f, 0.2f}});
        }
        uint stream = 200, checked = 0;
        double worst = 0.0;
        for (const Case& cs : cases) {
            for (uint i = 0; i < kPairs; ++i) {
                float3 wi, wo;
                directions(cs, stream, i, &wi, &wo);
                const float3 f = bsdf_eval(tables(), &cs.m, cs.albedo, wi, wo);
                const BsdfGrad g = bsdf_eval_grad(tables(), &cs.m, cs.albedo, wi, wo);
                const float3 spec = xyz(cs.m.specular);
                for (int c = 0; c < 3; ++c) {
                    const double lin = (double)get(spec, c) * get(g.d_specular, c) +
                                       (double)get(cs.albedo, c) * get(g.d_albedo, c);
                    const double d = std::fabs(lin - get(f, c));
                    const double rel = d / std::max((double)std::fabs(get(f, c)), 1e-30);
                    if (get(f, c) != 0.0f) worst = std::max(worst, rel);
                    ++checked;
                    if (!(d <= 1e-6 * std::fabs(get(f, c)))) {
                        INFO(cs.name << " a=" << cs.m.alpha << " wi " << str(wi) << " wo "
                                     << str(wo) << " channel " << c << ": f " << get(f, c) << " vs "
                                     << lin);
                        CHECK(d <= 1e-6 * std::fabs(get(f, c)));
                    }
                }
            }
            ++stream;
        }
        // Delta weights: conductor specular * F, dielectric reflection specular.
        const Material cond = material(MATERIAL_CONDUCTOR, 0.0f, kSpec, kGoldEta, kGoldK);
        const Material diel =
            material(MATERIAL_DIELECTRIC, 0.0f, kSpec, {1.5f, 1.5f, 1.5f}, kWhite);
        for (uint i = 0; i < kPairs; ++i) {
            const float3 wi =
                sample_uniform_sphere(rng_uniform(37u, 0u, i, 0u), rng_uniform(37u, 0u, i, 1u));
            for (const Material* m : {&cond, &diel}) {
                float3 wo;
                float pdf;
                int delta;
                const float3 w =
                    bsdf_sample(tables(), m, kWhite, wi, 0.0f, 0.5f, 0.5f, &wo, &pdf, &delta);
                const float3 ds = bsdf_delta_weight_grad(m, wi, wo).d_specular;
                for (int c = 0; c < 3; ++c) {
                    const double lin = (double)get(kSpec, c) * get(ds, c);
                    ++checked;
                    CHECK(std::fabs(lin - get(w, c)) <= 1e-6 * std::fabs(get(w, c)));
                }
            }
        }
        std::printf("homogeneity: %u values, worst relative difference %.2e\n", checked, worst);
        CHECK(checked > 90000);
    }

    TEST_CASE("bsdf grad: exactly zero where the eval is zero, and for clamped alpha") {
        std::vector<Case> cases = {{"diffuse", diffuse(), {0.3f, 0.6f, 0.9f}}};
        for (float a : {0.0f, 5e-5f, 1e-4f, 0.05f, 0.3f, 1.0f}) {
            cases.push_back({"roughconductor", roughconductor(a, kGoldEta, kGoldK), kWhite});
            cases.push_back(
                {"roughplastic", roughplastic(a, 1.5f, {0.8f, 0.9f, 1.0f}), {0.5f, 0.3f, 0.2f}});
            cases.push_back({"roughplastic nonlinear",
                             roughplastic(a, 1.9f, kWhite, true),
                             {0.9f, 0.5f, 0.1f}});
        }
        cases.push_back(
            {"conductor", material(MATERIAL_CONDUCTOR, 0.0f, kSpec, kGoldEta, kGoldK), kWhite});
        cases.push_back({"dielectric",
                         material(MATERIAL_DIELECTRIC, 0.3f, kSpec, {1.5f, 1.5f, 1.5f}, kWhite),
                         kWhite});
        uint stream = 300, below = 0, flushed = 0, clamped = 0, delta_types = 0;
        for (const Case& cs : cases) {
            const bool rough =
                cs.m.type == MATERIAL_ROUGHCONDUCTOR || cs.m.type == MATERIAL_ROUGHPLASTIC;
            for (uint i = 0; i < 2000; ++i) {
                float3 wi, wo;
                directions(cs, stream, i, &wi, &wo);
                // below the surface: either direction, including a signed zero cosine
                if (i % 4 == 1) wi.z = -wi.z;
                if (i % 4 == 2) wo.z = -wo.z;
                if (i % 8 == 3) wo.z = -0.0f;
                if (i % 8 == 7) wi.z = 0.0f;
                // both grazing, 90 deg apart: m.z ~ 1e-25, D m.z < 1e-20 and ggx_d flushes D to 0
                if (i % 8 == 5) {
                    const float z = 1e-25f * (1.0f + rng_uniform(43u, stream, i, 0u));
                    wi = make_float3(1.0f, 0.0f, z);
                    wo = make_float3(0.0f, 1.0f, z);
                }
                const float3 f = bsdf_eval(tables(), &cs.m, cs.albedo, wi, wo);
                const BsdfGrad g = bsdf_eval_grad(tables(), &cs.m, cs.albedo, wi, wo);
                INFO(cs.name << " a=" << cs.m.alpha << " wi " << str(wi) << " wo " << str(wo));
                if (wi.z <= 0.0f || wo.z <= 0.0f) {
                    ++below;
                    CHECK(zero3(f));
                    CHECK(grad_zero(g));
                }
                if (cs.m.type == MATERIAL_CONDUCTOR || cs.m.type == MATERIAL_DIELECTRIC) {
                    ++delta_types;
                    CHECK(grad_zero(g));
                }
                if (cs.m.type == MATERIAL_ROUGHCONDUCTOR && zero3(f)) { // incl. D flushed to 0
                    flushed += wi.z > 0.0f && wo.z > 0.0f;
                    CHECK(grad_zero(g));
                }
                if (!rough) continue;
                // the coating's share vanishes with D: so do d_specular and the coating's d_alpha
                // (a plastic's base still depends on alpha: its d_alpha is the base's alone, that
                // of the same material without a coating, bit for bit)
                float3 m;
                if (wi.z > 0.0f && wo.z > 0.0f &&
                    (!half_vector(wi, wo, &m) || ggx_d(ggx_alpha(cs.m.alpha), m) == 0.0f)) {
                    CHECK(zero3(g.d_specular));
                    float3 base = {0.0f, 0.0f, 0.0f};
                    if (cs.m.type == MATERIAL_ROUGHPLASTIC) {
                        Material uncoated = cs.m;
                        uncoated.specular = make_float4(0.0f, 0.0f, 0.0f, 0.0f);
                        base = bsdf_eval_grad(tables(), &uncoated, cs.albedo, wi, wo).d_alpha;
                    }
                    CHECK(
                        (g.d_alpha.x == base.x && g.d_alpha.y == base.y && g.d_alpha.z == base.z));
                }
                if (cs.m.alpha < GGX_ALPHA_MIN) { // clamped: exactly zero, as is the eval's FD
                    ++clamped;
                    CHECK(zero3(g.d_alpha));
                    CHECK(std::signbit(g.d_alpha.x) == 0);
                    Material lo = cs.m, hi = cs.m;
                    lo.alpha = cs.m.alpha * 0.5f;
                    hi.alpha = cs.m.alpha * 1.5f;
                    const float3 flo = bsdf_eval(tables(), &lo, cs.albedo, wi, wo),
                                 fhi = bsdf_eval(tables(), &hi, cs.albedo, wi, wo);
                    CHECK((flo.x == fhi.x && flo.y == fhi.y && flo.z == fhi.z));
                }
            }
            ++stream;
        }
        // Non-delta types have zero delta-weight derivatives.
        for (const Case& cs : cases)
            if (cs.m.type != MATERIAL_CONDUCTOR && cs.m.type != MATERIAL_DIELECTRIC)
                CHECK(grad_zero(bsdf_delta_weight_grad(&cs.m, dir(30.0f), dir(30.0f, 3.84f))));
        // The conductor fails (zero weight) from behind: so does its derivative.
        CHECK(grad_zero(bsdf_delta_weight_grad(&cases[cases.size() - 2].m,
                                               make_float3(0.0f, 0.6f, -0.8f),
                                               make_float3(0.0f, -0.6f, -0.8f))));
        std::printf("zeros: %u below the surface, %u with D flushed, %u with clamped alpha, %u "
                    "delta-only\n",
                    below, flushed, clamped, delta_types);
        CHECK(below > 20000);
        CHECK(flushed > 100);
        CHECK(clamped > 5000);
    }

    TEST_CASE("bsdf grad: at alpha = GGX_ALPHA_MIN, the right derivative") {
        // Second-order forward difference (-3 f(a) + 4 f(a + h) - f(a + 2 h)) / (2 h), h = 1e-3 a.
        const float a = GGX_ALPHA_MIN;
        Material rc = roughconductor(a, kGoldEta, kGoldK);
        rc.specular = make_float4(kSpec.x, kSpec.y, kSpec.z, 0.0f);
        const std::vector<Case> cases = {
            {"roughconductor", rc, kWhite},
            {"roughplastic", roughplastic(a, 1.5f, {0.8f, 0.9f, 1.0f}), {0.5f, 0.3f, 0.2f}}};
        uint stream = 400, checked = 0, nonzero = 0;
        double worst = 0.0;
        for (const Case& cs : cases) {
            for (uint i = 0; i < kPairs; ++i) {
                float3 wi, wo;
                directions(cs, stream, i, &wi, &wo);
                if (wi.z <= 0.0f || wo.z <= 0.0f) continue;
                const double h = 1e-3 * a;
                const float xs[3] = {a, (float)(a + h), (float)(a + 2.0 * h)};
                float3 v[3];
                for (int k = 0; k < 3; ++k) {
                    Material m = cs.m;
                    m.alpha = xs[k];
                    v[k] = bsdf_eval(tables(), &m, cs.albedo, wi, wo);
                }
                const BsdfGrad g = bsdf_eval_grad(tables(), &cs.m, cs.albedo, wi, wo);
                for (int c = 0; c < 3; ++c) {
                    const float f0 = get(v[0], c), f1 = get(v[1], c), f2 = get(v[2], c);
                    if ((f0 == 0.0f) != (f1 == 0.0f) || (f0 == 0.0f) != (f2 == 0.0f) ||
                        std::fabs(f0) < 1e-30f)
                        continue;
                    // exact float steps h1 = xs[1] - a, h2 = xs[2] - a (nearly h and 2 h): the
                    // quadratic through the three points, differentiated at a
                    const double h1 = (double)xs[1] - a, h2 = (double)xs[2] - a;
                    const double d = ((f1 - (double)f0) * h2 * h2 - (f2 - (double)f0) * h1 * h1) /
                                     (h1 * h2 * (h2 - h1));
                    const double fmax = std::max({std::fabs(f0), std::fabs(f1), std::fabs(f2)});
                    const double want = get(g.d_alpha, c);
                    const double tol = 1e-4 * std::fabs(want) + 128.0 * kU * fmax / h;
                    worst = std::max(worst, std::fabs(d - want) / tol);
                    ++checked;
                    nonzero += want != 0.0;
                    if (!(std::fabs(d - want) <= tol)) {
                        INFO(cs.name << " wi " << str(wi) << " wo " << str(wo) << " channel " << c
                                     << ": analytic " << want << " forward difference " << d);
                        CHECK(std::fabs(d - want) <= tol);
                    }
                }
            }
            ++stream;
        }
        std::printf("alpha = GGX_ALPHA_MIN: %u forward differences, %u nonzero, worst error / "
                    "tolerance %.3f\n",
                    checked, nonzero, worst);
        CHECK(checked > 2000);
        CHECK(nonzero > 2000);
    }

    TEST_CASE("bsdf grad: wrong derivatives are rejected (negative controls)") {
        // Each variant is the header's derivative with one factor broken, rebuilt from the
        // header's own pieces; it must fail the comparison for a large share of the pairs.
        struct Variant {
            const char* what;
            Param param;
            std::vector<Case> cases;
            std::function<BsdfGrad(const Material&, float3, float3, float3)> grad;
            double min_share; // of the checked pairs that must fail; < 0: none may (control)
        };
        std::vector<Case> rcs, lin, nonlin;
        for (float a : {0.05f, 0.3f, 0.8f}) {
            Material rc = roughconductor(a, kGoldEta, kGoldK);
            rc.specular = make_float4(kSpec.x, kSpec.y, kSpec.z, 0.0f);
            rcs.push_back({"roughconductor", rc, kWhite});
            lin.push_back(
                {"roughplastic", roughplastic(a, 1.5f, {0.8f, 0.9f, 1.0f}), {0.5f, 0.3f, 0.2f}});
            nonlin.push_back({"roughplastic nonlinear",
                              roughplastic(a, 1.9f, kWhite, true),
                              {0.9f, 0.5f, 0.1f}});
        }
        // d_alpha = f * dlog with dlog rebuilt from (weights of) its three terms.
        auto alpha_variant = [](double w_d, double w_g, double w_t) {
            return [=](const Material& m, float3 albedo, float3 wi, float3 wo) {
                BsdfGrad g = bsdf_eval_grad(tables(), &m, albedo, wi, wo);
                const float3 f = bsdf_eval(tables(), &m, albedo, wi, wo);
                float3 h;
                if (!half_vector(wi, wo, &h)) return g;
                const float a = ggx_alpha(m.alpha);
                const double t = (h.x * h.x + h.y * h.y) / ((double)a * a),
                             b = t + (double)h.z * h.z;
                // d ln D / d a = -2 / a + w_t 4 t / (a b)
                const double dd = -2.0 / a + w_t * 4.0 * t / (a * b);
                const double dlog = w_d * dd + w_g * (ggx_g1_over_cos_dlog_alpha(a, wi) +
                                                      ggx_g1_over_cos_dlog_alpha(a, wo));
                g.d_alpha = f * (float)dlog;
                return g;
            };
        };
        const std::vector<Variant> variants = {
            {"none: d_alpha rebuilt unbroken (control of the rebuild)", kAlpha, rcs,
             alpha_variant(1.0, 1.0, 1.0), -1.0},
            {"d ln D negated", kAlpha, rcs, alpha_variant(-1.0, 1.0, 1.0), 0.9},
            {"d ln D with 8 t / (a b) for 4 t / (a b)", kAlpha, rcs, alpha_variant(1.0, 1.0, 2.0),
             0.8},
            {"d ln(G1 / cos) negated", kAlpha, rcs, alpha_variant(1.0, -1.0, 1.0), 0.7},
            {"d ln(G1 / cos) dropped", kAlpha, rcs, alpha_variant(1.0, 0.0, 1.0), 0.5},
            {"conductor d_specular without F", kSpecular, rcs,
             [](const Material& m, float3 albedo, float3 wi, float3 wo) {
                 BsdfGrad g = bsdf_eval_grad(tables(), &m, albedo, wi, wo);
                 float3 h;
                 if (!half_vector(wi, wo, &h)) return g;
                 const float3 fr = fresnel_conductor3(vdot(wi, h), xyz(m.eta), xyz(m.k));
                 g.d_specular = make_float3(g.d_specular.x / fr.x, g.d_specular.y / fr.y,
                                            g.d_specular.z / fr.z);
                 return g;
             },
             0.9},
            {"linear plastic d_albedo without 1 / (1 - r)", kAlbedo, lin,
             [](const Material& m, float3 albedo, float3 wi, float3 wo) {
                 BsdfGrad g = bsdf_eval_grad(tables(), &m, albedo, wi, wo);
                 g.d_albedo = g.d_albedo * (1.0f - plastic_r(m));
                 return g;
             },
             0.9},
            {"nonlinear plastic d_albedo 1 / (1 - x r) for 1 / (1 - x r)^2", kAlbedo, nonlin,
             [](const Material& m, float3 albedo, float3 wi, float3 wo) {
                 BsdfGrad g = bsdf_eval_grad(tables(), &m, albedo, wi, wo);
                 const float r = plastic_r(m);
                 g.d_albedo = make_float3(g.d_albedo.x * (1.0f - albedo.x * r),
                                          g.d_albedo.y * (1.0f - albedo.y * r),
                                          g.d_albedo.z * (1.0f - albedo.z * r));
                 return g;
             },
             0.6},
            {"plastic d_alpha without the base's (the table's t and r held fixed)", kAlpha, lin,
             [](const Material& m, float3 albedo, float3 wi, float3 wo) {
                 BsdfGrad g = bsdf_eval_grad(tables(), &m, albedo, wi, wo);
                 const float3 none = {0.0f, 0.0f, 0.0f}; // no base: the coating's d_alpha
                 g.d_alpha = bsdf_eval_grad(tables(), &m, none, wi, wo).d_alpha;
                 return g;
             },
             0.9},
        };
        uint stream = 500;
        for (const Variant& v : variants) {
            Stats st[3];
            for (const Case& cs : v.cases)
                run_eval_case(cs, stream++, 1000, v.grad, st, false);
            const double share = (double)st[v.param].failed / st[v.param].checked;
            std::printf("  negative control %-62s rejected at %5.1f%% of %u checks\n", v.what,
                        100.0 * share, st[v.param].checked);
            INFO(v.what << ": rejected " << st[v.param].failed << " of " << st[v.param].checked);
            if (v.min_share < 0.0)
                CHECK(st[v.param].failed == 0);
            else
                CHECK(share >= v.min_share);
        }
    }

    TEST_CASE("bsdf grad: finite, signed and bounded for extreme inputs") {
        // alpha log-uniform in [1e-5, 1] plus exactly GGX_ALPHA_MIN, grazing and tiny cosines
        // (down to subnormal), IORs from 1/3 to 10 (plastic; a few values, as each builds a
        // table) and 0..3 + i 0..10 (conductor), albedos 0..1.5 (the nonlinear plastic's clamp).
        // d_albedo and d_specular are >= 0 (the values grow with them), |d_alpha| <= 4 / alpha *
        // f (|d ln(D G G)| <= 4 / alpha, f >= coating), except for the plastic's base B = f - f
        // (albedo 0), whose share is bounded by its table terms: |d ln B / d ln alpha| <=
        // 2 kT + kR L, kT >= |d ln t / d ln alpha| and kR >= |d r / d ln alpha| over the whole
        // table for eta >= 1 (tests/core/scene/test_plastic_table.cpp), L = d ln diff / d r =
        // 1 / (1 - r) (linear) or x / max(1 - x r, 1e-3) (nonlinear).
        const float tiny_z[] = {0.0f, 1e-7f, 1e-20f, 1e-40f, 1.7e-4f};
        const uint types[] = {MATERIAL_DIFFUSE, MATERIAL_CONDUCTOR, MATERIAL_ROUGHCONDUCTOR,
                              MATERIAL_DIELECTRIC, MATERIAL_ROUGHPLASTIC};
        uint bad = 0, nonzero_alpha = 0;
        for (uint t = 0; t < 5; ++t)
            for (uint i = 0; i < 20000; ++i) {
                auto u = [&](uint d) { return rng_uniform(41u, t, i, d); };
                const float alpha = i % 10 == 0 ? GGX_ALPHA_MIN : std::pow(10.0f, -5.0f * u(0));
                const float eta_c = 3.0f * u(1), k_c = 10.0f * u(2);
                const float etas[] = {1.33f, 1.5f, 2.0f, 3.0f};
                const float eta_d = i % 13 == 0 ? 10.0f : etas[(i / 2) % 4];
                const Material m = material(
                    types[t], alpha, {u(4), u(5), 1.0f},
                    types[t] == MATERIAL_CONDUCTOR || types[t] == MATERIAL_ROUGHCONDUCTOR
                        ? float3{eta_c, 1.0f, 0.0f}
                        : float3{i % 7 == 0 ? 1.0f : (i % 2 ? eta_d : 1.0f / eta_d), 1.0f, 1.0f},
                    {k_c, 0.0f, 30.0f}, i % 2 ? MATERIAL_FLAG_NONLINEAR : 0u);
                const float3 albedo = {u(6), i % 3 == 0 ? 0.0f : 1.0f, 1.5f * u(12)};
                float3 wi = dir(89.99f * u(7), 2.0f * kPi * u(8));
                const float z = tiny_z[(i / 8) % 5];
                if (i % 8 == 0) wi = make_float3(0.0f, 0.0f, 1.0f);
                if (i % 8 == 1) wi = make_float3(std::sqrt(1.0f - z * z), 0.0f, z);
                if (i % 8 == 2) wi.z = -wi.z;
                float3 wo = sample_uniform_sphere(u(9), u(10));
                if (i % 5 == 0) wo = make_float3(0.0f, 0.0f, 1.0f);
                if (i % 5 == 1) wo = make_float3(-wi.x, -wi.y, wi.z);
                if (i % 5 == 2) wo = make_float3(0.0f, std::sqrt(1.0f - z * z), z);
                const float3 f = bsdf_eval(tables(), &m, albedo, wi, wo);
                const BsdfGrad g = bsdf_eval_grad(tables(), &m, albedo, wi, wo);
                float3 ws;
                float ps;
                int delta;
                bsdf_sample(tables(), &m, albedo, wi, u(11), 0.5f, 0.5f, &ws, &ps, &delta);
                const BsdfGrad gd = bsdf_delta_weight_grad(&m, wi, ws);
                const float bound = 4.0f / ggx_alpha(alpha) * (1.0f + 1e-5f);
                bool ok = grad_finite(g) && grad_finite(gd) && g.d_albedo.x >= 0.0f &&
                          g.d_albedo.y >= 0.0f && g.d_albedo.z >= 0.0f && g.d_specular.x >= 0.0f &&
                          g.d_specular.y >= 0.0f && g.d_specular.z >= 0.0f &&
                          gd.d_specular.x >= 0.0f && gd.d_specular.y >= 0.0f &&
                          gd.d_specular.z >= 0.0f;
                float3 f_coat = f, d_coat = g.d_alpha; // the plastic's coating alone
                const bool plastic = m.type == MATERIAL_ROUGHPLASTIC;
                if (plastic) {
                    const float3 none = {0.0f, 0.0f, 0.0f};
                    f_coat = bsdf_eval(tables(), &m, none, wi, wo);
                    d_coat = bsdf_eval_grad(tables(), &m, none, wi, wo).d_alpha;
                }
                for (int c = 0; c < 3; ++c) {
                    ok = ok && std::fabs(get(d_coat, c)) <= bound * std::fabs(get(f_coat, c));
                    if (!plastic || m.eta.x < 1.0f) continue; // eta < 1: see the table test
                    const double x = get(albedo, c), r = plastic_r(m);
                    const double lever = m.flags & MATERIAL_FLAG_NONLINEAR
                                             ? x / std::max(1.0 - x * r, 1e-3)
                                             : 1.0 / (1.0 - r);
                    const double base = (double)get(f, c) - get(f_coat, c);
                    const double d_base = (double)get(g.d_alpha, c) - get(d_coat, c);
                    ok = ok && std::fabs(d_base) <=
                                   (2.0 * kPlasticT + kPlasticR * lever) / ggx_alpha(alpha) *
                                           std::fabs(base) * (1.0 + 1e-4) +
                                       1e-6 * std::fabs(get(f, c)) + 1e-30; // 1e-30: subnormals
                }
                nonzero_alpha += !zero3(g.d_alpha);
                if (!ok) {
                    ++bad;
                    INFO("type " << m.type << " alpha " << alpha << " eta " << m.eta.x << " wi "
                                 << str(wi) << " wo " << str(wo) << ": f " << str(f) << " d_albedo "
                                 << str(g.d_albedo) << " d_specular " << str(g.d_specular)
                                 << " d_alpha " << str(g.d_alpha) << " delta d_specular "
                                 << str(gd.d_specular));
                    CHECK(ok);
                }
            }
        std::printf("extremes: 100000 inputs, %u bad, %u with nonzero d_alpha\n", bad,
                    nonzero_alpha);
        CHECK(bad == 0);
        CHECK(nonzero_alpha > 5000);
    }

} // TEST_SUITE("bsdf_grad")
