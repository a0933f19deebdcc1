// Image losses and optimizers on the device against the shared host reference (bit for bit, since
// the reduction order is fixed and the device divides correctly rounded), plus their closed forms.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "core/inverse/loss.h"
#include "core/inverse/optimize_outputs.h"
#include "core/inverse/optimizer.h"
#include "shared/rng.h"
#include "support.h"

using namespace tandem;

namespace {

std::vector<float> random_values(std::size_t n, unsigned seed, float scale) {
    std::vector<float> v(n);
    for (std::size_t i = 0; i < n; ++i) v[i] = scale * gpu::rng_uniform(seed, unsigned(i), 0, 0);
    return v;
}

/// Adam and SGD written out in double (Kingma and Ba 2015, algorithm 1; the bias corrections
/// 1 - beta^t from the step count), independent of kernels/shared/optim.h, and the rounding bound
/// that a float implementation must meet on each step. One step starts from the float
/// implementation's state, so that the bound is one step's, and fails past it.
struct ReferenceStep {
    static constexpr double u = 0x1p-24; // unit roundoff of float: one rounding is within u
    int failures = 0;
    int clamped = 0;    // steps the range stopped
    double worst = 0.0; // largest |float - double| / bound seen

    void compare(const char* what, double got, double want, double bound, int t, std::size_t i) {
        const double r = got == want ? 0.0 : std::fabs(got - want) / bound;
        worst = std::max(worst, r);
        if (!(r <= 1.0) && failures++ < 5)
            MESSAGE(std::string(what) << " of element " << i << " at step " << t << ": " << got
                                      << ", double " << want << " (bound " << bound << ")");
    }

    /// Checks Adam's step t from (p, m, v) with gradient g to the float result (p1, m1, v1).
    void adam(double beta1, double beta2, double eps, int t, double p, double g, double lr,
              double lo, double hi, double m, double v, double p1, double m1, double v1,
              std::size_t i) {
        // m: b1 m, (1 - b1) g and their sum each round once (1 - b1 is exact in float: Sterbenz)
        const double m_ref = beta1 * m + (1.0 - beta1) * g;
        compare("m", m1, m_ref, 3.0 * u * (beta1 * std::fabs(m) + (1.0 - beta1) * std::fabs(g)), t,
                i);
        // v: b2 v, (1 - b2) g, times g, and the sum
        const double v_ref = beta2 * v + (1.0 - beta2) * g * g;
        compare("v", v1, v_ref, 4.0 * u * (beta2 * v + (1.0 - beta2) * g * g), t, i);
        // p from the float moments: the corrections rounded to float (u each), m / c1 and v / c2
        // (u each), sqrt (u, plus half of v_hat's 2u), + eps, lr times, the division: 7u of the
        // step s, then p - s rounds once (u of the result); the clamp is exact. Twice the
        // result's u covers the second-order terms.
        const double s = lr * (m1 / (1.0 - std::pow(beta1, t))) /
                         (std::sqrt(v1 / (1.0 - std::pow(beta2, t))) + eps);
        const double p_ref = std::min(std::max(p - s, lo), hi);
        clamped += p_ref != p - s;
        compare("p", p1, p_ref, 8.0 * u * std::fabs(s) + 2.0 * u * std::fabs(p_ref), t, i);
    }

    /// Checks one gradient-descent step: lr g and p - lr g round once each.
    void sgd(int t, double p, double g, double lr, double lo, double hi, double p1, std::size_t i) {
        const double p_ref = std::min(std::max(p - lr * g, lo), hi);
        clamped += p_ref != p - lr * g;
        compare("p", p1, p_ref, 2.0 * u * (std::fabs(lr * g) + std::fabs(p_ref)), t, i);
    }
};

/// Element i's gradient at step t: both signs, magnitudes from 1e-4 to 10, some exactly zero,
/// and a run of one sign, so that the moments grow, shrink and cancel.
float test_gradient(std::size_t i, int t) {
    if ((i + unsigned(t)) % 11 == 0) return 0.0f;
    const float sign =
        (i % 3 == 0 || gpu::rng_uniform(7, unsigned(i), unsigned(t), 0) < 0.5f) ? 1.0f : -1.0f;
    return sign * std::pow(10.0f, -4.0f + 5.0f * gpu::rng_uniform(8, unsigned(i), unsigned(t), 0));
}

} // namespace

TEST_SUITE("optimize") {
    TEST_CASE("loss elements: values and derivatives of every loss") {
        float d;
        CHECK(gpu::loss_element(LOSS_L1, 3.0f, 1.0f, 0.5f, &d) == 2.0f);
        CHECK(d == 0.5f);
        CHECK(gpu::loss_element(LOSS_L1, 1.0f, 3.0f, 0.5f, &d) == 2.0f);
        CHECK(d == -0.5f);
        CHECK(gpu::loss_element(LOSS_L2, 3.0f, 1.0f, 0.5f, &d) == 4.0f);
        CHECK(d == 2.0f);
        CHECK(gpu::loss_element(LOSS_RL2, 3.0f, 1.0f, 1.0f, &d) == doctest::Approx(4.0f / 1.01f));
        CHECK(d == doctest::Approx(4.0f / 1.01f));
        CHECK(gpu::loss_element(LOSS_MEAN, 3.0f, 0.0f, 0.25f, &d) == 3.0f);
        CHECK(d == 0.25f);
        // derivatives against central differences of the value
        for (unsigned kind : {LOSS_L2, LOSS_RL2}) {
            const float x = 0.7f, r = 0.3f, h = 1e-3f;
            float unused;
            const float fd = (gpu::loss_element(kind, x + h, r, 1.0f, &unused) -
                              gpu::loss_element(kind, x - h, r, 1.0f, &unused)) / (2 * h);
            gpu::loss_element(kind, x, r, 1.0f, &d);
            CHECK(d == doctest::Approx(fd).epsilon(1e-3));
        }
    }

    TEST_CASE("adam: the first step moves every parameter by lr against its gradient's sign") {
        gpu::AdamConfig c{0.9f, 0.999f, 1e-8f, 1.0f - 0.9f, 1.0f - 0.999f, 0, 0, 0};
        float m = 0, v = 0;
        // with bias correction, the first step is lr * g / (|g| + eps)
        CHECK(gpu::adam_step(0.5f, 3.0f, 0.01f, 0.0f, 1.0f, c, &m, &v) == doctest::Approx(0.49f));
        m = v = 0;
        CHECK(gpu::adam_step(0.5f, -1e-3f, 0.01f, 0.0f, 1.0f, c, &m, &v) == doctest::Approx(0.51f));
        m = v = 0;
        CHECK(gpu::adam_step(0.995f, -5.0f, 0.01f, 0.0f, 1.0f, c, &m, &v) == 1.0f); // clamped
        CHECK(gpu::sgd_step(0.5f, 2.0f, 0.1f, 0.0f, 1.0f) == doctest::Approx(0.3f));
        CHECK(gpu::sgd_step(0.05f, 2.0f, 0.1f, 0.0f, 1.0f) == 0.0f);
    }

    TEST_CASE("adam and sgd: every step of 30 equals a double-precision Adam and SGD to rounding") {
        // Two sets of betas: the default, and 0.5 / 0.9, whose bias corrections change over the
        // whole run (1 - 0.9^30 = 0.96; 1 - 0.999^30 = 0.03). Learning rates 0.001 to 0.5 over
        // [0, 1], so that some steps clamp.
        const std::size_t n = 96;
        for (const auto betas : {std::array<float, 2>{0.9f, 0.999f}, {0.5f, 0.9f}}) {
            INFO("beta1 " << betas[0] << ", beta2 " << betas[1]);
            ReferenceStep adam, sgd;
            std::vector<float> p(n), q(n), m(n, 0.0f), v(n, 0.0f), lr(n);
            for (std::size_t i = 0; i < n; ++i) {
                p[i] = q[i] = gpu::rng_uniform(5, unsigned(i), 0, 0);
                lr[i] = 0.001f * std::pow(500.0f, gpu::rng_uniform(6, unsigned(i), 0, 0));
            }
            for (int t = 1; t <= 30; ++t) {
                gpu::AdamConfig c{};
                c.beta1 = betas[0];
                c.beta2 = betas[1];
                c.epsilon = 1e-8f;
                c.correction1 = float(1.0 - std::pow(double(betas[0]), t));
                c.correction2 = float(1.0 - std::pow(double(betas[1]), t));
                for (std::size_t i = 0; i < n; ++i) {
                    const float g = test_gradient(i, t);
                    float m1 = m[i], v1 = v[i];
                    const float p1 = gpu::adam_step(p[i], g, lr[i], 0.0f, 1.0f, c, &m1, &v1);
                    adam.adam(betas[0], betas[1], 1e-8f, t, p[i], g, lr[i], 0.0, 1.0, m[i], v[i],
                              p1, m1, v1, i);
                    p[i] = p1, m[i] = m1, v[i] = v1;
                    const float q1 = gpu::sgd_step(q[i], g, lr[i], 0.0f, 1.0f);
                    sgd.sgd(t, q[i], g, lr[i], 0.0, 1.0, q1, i);
                    q[i] = q1;
                }
            }
            MESSAGE("worst error over its rounding bound: adam "
                    << adam.worst << ", sgd " << sgd.worst << "; clamped " << adam.clamped << ", "
                    << sgd.clamped);
            CHECK(adam.failures == 0);
            CHECK(sgd.failures == 0);
            CHECK(adam.clamped > 0);
            CHECK(sgd.clamped > 0);
        }
    }
}

TEST_SUITE("device") {
    TEST_CASE("device loss equals the host reference bit for bit, with its derivative") {
        TANDEM_REQUIRE_DEVICE(ctx);
        ImageLoss loss(*ctx, KernelLibrary::from_environment());
        const std::size_t n = 3 * 123 * 77; // not a multiple of the chunk
        const std::vector<float> image = random_values(n, 1, 2.0f), ref = random_values(n, 2, 2.0f);
        Buffer<float> dimage(*ctx, "image", image), dref(*ctx, "reference", ref), ddelta(*ctx, "delta", n);
        for (const char* name : {"mean", "l1", "l2", "rl2"}) {
            INFO(name);
            const unsigned kind = loss_kind(name);
            loss.evaluate(kind, dimage, dref, ddelta);
            const float value = loss.value();
            const std::vector<float> delta = ddelta.download();
            // host reference: the same element terms, chunk sums in order, then the mean
            std::vector<float> host_delta(n);
            float total = 0.0f;
            for (std::size_t begin = 0; begin < n; begin += ImageLoss::k_chunk) {
                float chunk = 0.0f;
                for (std::size_t i = begin; i < std::min(n, begin + ImageLoss::k_chunk); ++i)
                    chunk += gpu::loss_element(kind, image[i], kind == LOSS_MEAN ? 0.0f : ref[i],
                                               1.0f / float(n), &host_delta[i]);
                total += chunk;
            }
            CHECK(value == total / float(n));
            CHECK(test::same_bytes(delta, host_delta));
            // and against double precision, loosely
            double exact = 0;
            for (std::size_t i = 0; i < n; ++i) {
                const double e = double(image[i]) - ref[i];
                exact += kind == LOSS_MEAN ? image[i] : kind == LOSS_L1 ? std::fabs(e)
                         : kind == LOSS_L2 ? e * e : e * e / (double(ref[i]) * ref[i] + 1e-2);
            }
            CHECK(value == doctest::Approx(exact / n).epsilon(1e-5));
        }
        CHECK_THROWS_AS(loss_kind("l3"), Error);
    }

    TEST_CASE("device Adam and SGD equal the host reference over many steps, and converge") {
        TANDEM_REQUIRE_DEVICE(ctx);
        // Minimise sum (p - target)^2 with per-element learning rates and ranges.
        const std::size_t n = 1000;
        const std::vector<float> target = random_values(n, 3, 1.0f);
        std::vector<float> p(n, 0.5f), lr(n), lo(n, 0.0f), hi(n, 1.0f);
        for (std::size_t i = 0; i < n; ++i) lr[i] = 0.01f + 0.02f * gpu::rng_uniform(4, unsigned(i), 0, 0);
        using Method = OptimizerConfig::Method;
        for (Method method : {Method::adam, Method::sgd}) {
            OptimizerConfig config;
            config.method = method;
            OptimizerUpdate opt(*ctx, KernelLibrary::from_environment(), config);
            Buffer<float> dp(*ctx, "params", p), dlr(*ctx, "lr", lr), dlo(*ctx, "lower", lo),
                dhi(*ctx, "upper", hi), dg(*ctx, "grads", n), dm(*ctx, "m", std::vector<float>(n, 0.0f)),
                dv(*ctx, "v", std::vector<float>(n, 0.0f));
            std::vector<float> host = p, m(n, 0.0f), v(n, 0.0f);
            for (int t = 1; t <= 200; ++t) {
                std::vector<float> g(n);
                for (std::size_t i = 0; i < n; ++i) g[i] = 2.0f * (dp.download()[i] - target[i]);
                dg.upload(g);
                opt.update(dp, dg, dm, dv, dlr, dlo, dhi, unsigned(t));
                // the optimizer's bias corrections: 1 - beta^t in double, from the float betas
                gpu::AdamConfig c{0.9f, 0.999f, 1e-8f, float(1.0 - std::pow(double(0.9f), t)),
                                  float(1.0 - std::pow(double(0.999f), t)), 0, 0, 0};
                for (std::size_t i = 0; i < n; ++i) {
                    const float gh = 2.0f * (host[i] - target[i]);
                    host[i] = method == Method::adam
                                  ? gpu::adam_step(host[i], gh, lr[i], lo[i], hi[i], c, &m[i], &v[i])
                                  : gpu::sgd_step(host[i], gh, lr[i], lo[i], hi[i]);
                }
            }
            const std::vector<float> result = dp.download();
            std::size_t differ = 0;
            for (std::size_t i = 0; i < n; ++i) differ += result[i] != host[i];
            INFO((method == Method::adam ? "adam" : "sgd") << ": " << differ << " differ");
            CHECK(test::same_bytes(result, host));
            double err = 0;
            for (std::size_t i = 0; i < n; ++i) err = std::max(err, double(std::fabs(result[i] - target[i])));
            CHECK(err < 0.02);
        }
    }
}

TEST_SUITE("device") {
    TEST_CASE("device Adam and SGD: every step of 30 equals a double-precision Adam and SGD") {
        // The Optimizer's own bias corrections from the step count (core/inverse/optimizer.cpp)
        // and the kernels, each step checked from the device's state of the step before.
        TANDEM_REQUIRE_DEVICE(ctx);
        const std::size_t n = 96;
        using Method = OptimizerConfig::Method;
        for (const Method method : {Method::adam, Method::sgd})
            for (const auto betas : {std::array<float, 2>{0.9f, 0.999f}, {0.5f, 0.9f}}) {
                INFO((method == Method::adam ? "adam" : "sgd")
                     << ", beta1 " << betas[0] << ", beta2 " << betas[1]);
                OptimizerConfig config;
                config.method = method;
                config.beta1 = betas[0];
                config.beta2 = betas[1];
                OptimizerUpdate opt(*ctx, KernelLibrary::from_environment(), config);
                std::vector<float> p(n), lr(n), m(n, 0.0f), v(n, 0.0f);
                for (std::size_t i = 0; i < n; ++i) {
                    p[i] = gpu::rng_uniform(5, unsigned(i), 0, 0);
                    lr[i] = 0.001f * std::pow(500.0f, gpu::rng_uniform(6, unsigned(i), 0, 0));
                }
                Buffer<float> dp(*ctx, "params", p), dlr(*ctx, "lr", lr),
                    dlo(*ctx, "lower", std::vector<float>(n, 0.0f)),
                    dhi(*ctx, "upper", std::vector<float>(n, 1.0f)), dg(*ctx, "grads", n),
                    dm(*ctx, "m", m), dv(*ctx, "v", v);
                ReferenceStep check;
                for (int t = 1; t <= 30; ++t) {
                    std::vector<float> g(n);
                    for (std::size_t i = 0; i < n; ++i)
                        g[i] = test_gradient(i, t);
                    dg.upload(g);
                    opt.update(dp, dg, dm, dv, dlr, dlo, dhi, unsigned(t));
                    const std::vector<float> p1 = dp.download(), m1 = dm.download(),
                                             v1 = dv.download();
                    for (std::size_t i = 0; i < n; ++i)
                        if (method == Method::adam)
                            check.adam(betas[0], betas[1], config.epsilon, t, p[i], g[i], lr[i],
                                       0.0, 1.0, m[i], v[i], p1[i], m1[i], v1[i], i);
                        else
                            check.sgd(t, p[i], g[i], lr[i], 0.0, 1.0, p1[i], i);
                    p = p1, m = m1, v = v1;
                }
                MESSAGE("worst error over its rounding bound: " << check.worst);
                CHECK(check.failures == 0);
            }
    }
}

TEST_SUITE("optimizer") {
    TEST_CASE("a parameter with learning rate 0 is left exactly as it is, even outside its range") {
        gpu::AdamConfig c{};
        c.beta1 = 0.9f;
        c.beta2 = 0.999f;
        c.epsilon = 1e-8f;
        c.correction1 = 0.1f;
        c.correction2 = 0.001f;
        float m = 0.25f, v = 0.5f;
        CHECK(gpu::adam_step(1e-4f, 3.0f, 0.0f, 1e-3f, 1.0f, c, &m, &v) == 1e-4f);
        CHECK(m == 0.25f);
        CHECK(v == 0.5f);
        CHECK(gpu::sgd_step(1.5f, 3.0f, 0.0f, 0.0f, 1.0f) == 1.5f);
        CHECK(gpu::adam_step(0.5f, 1.0f, 0.1f, 0.0f, 1.0f, c, &m, &v) < 0.5f); // lr > 0 moves it
    }
}

TEST_CASE("a non-finite optimized value is named by its parameter, and a vertex by its index") {
    Parameter albedo, corners;
    albedo.name = "wall.reflectance";
    albedo.size = 3;
    corners.name = "light.vertex_positions";
    corners.kind = Parameter::Kind::vertices;
    corners.offset = 3;
    corners.size = 12;
    std::vector<float> values(15, 0.5f);
    const std::vector<const Parameter*> optimized{&albedo, &corners};
    CHECK(non_finite_note(optimized, values).empty());
    values[3 + 7] = INFINITY; // the second coordinate of the third corner
    CHECK(non_finite_note(optimized, values) == "light.vertex_positions: vertex 2 is not finite");
    values[1] = std::nanf("");
    CHECK(non_finite_note(optimized, values) == "wall.reflectance: element 1 is not finite");
}
