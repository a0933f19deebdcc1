// The deterministic transcendentals (kernels/shared/det_math.h): accuracy against long double on
// the host, and the same bits on the device as on the host.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "probes/probes.h"
#include "runtime/launch.h"
#include "shared/det_math.h"
#include "support.h"

using namespace tandem;

namespace {

// The bounds kernels/shared/det_math.h documents, in ulps against long double: the largest error
// at every float argument (sin and cos for |x| < 8192, acos and the quarter-pi pair on [-1, 1]),
// rounded up in the last digit shown; atan2's, a function of two arguments, is the largest of 10^9
// random pairs (1.486), rounded up. Each test asserts them on its own samples, which are subsets.
constexpr double k_sin_ulps = 1.533, k_cos_ulps = 1.529;
constexpr double k_quarter_pi_sin_ulps = 0.966, k_quarter_pi_cos_ulps = 1.290;
constexpr double k_acos_ulps = 1.513, k_atan2_ulps = 1.49;

/// |got - exact| in units of the float ulp at `exact` (at `floor` where |exact| is smaller).
double ulps(float got, long double exact, float floor = 0.0f) {
    if (std::isnan(got) || std::isnan(double(exact))) return std::isnan(got) == std::isnan(double(exact)) ? 0.0 : 1e30;
    const float e = std::max(std::fabs(float(exact)), floor);
    const float ulp = std::nextafter(std::fabs(e), std::numeric_limits<float>::infinity()) - std::fabs(e);
    return double(std::fabs(double(got) - double(exact))) / double(ulp);
}

struct Worst {
    double ulps = 0.0;
    float at = 0.0f;
    void add(double u, float x) {
        if (u > ulps) ulps = u, at = x;
    }
};

std::vector<float> sweep(float lo, float hi, int n) {
    std::vector<float> v;
    for (int i = 0; i <= n; ++i) v.push_back(lo + (hi - lo) * float(i) / float(n));
    return v;
}

uint32_t bits(float f) {
    uint32_t u;
    std::memcpy(&u, &f, 4);
    return u;
}

} // namespace

TEST_CASE("det_math: det_floor is floor, bit for bit, zeros and large values included") {
    auto same = [](float x) {
        const float a = gpu::det_floor(x), b = std::floor(x);
        std::uint32_t ua, ub;
        std::memcpy(&ua, &a, 4);
        std::memcpy(&ub, &b, 4);
        return ua == ub;
    };
    std::size_t checked = 0, wrong = 0;
    // Every 61st bit pattern of both signs (70 million values over all exponents), and every
    // float near the integers and half-integers up to 2^12 and near +-2^23, where the rule changes.
    for (std::uint64_t bits = 0; bits < (1ull << 32); bits += 61) {
        float x;
        const std::uint32_t b = static_cast<std::uint32_t>(bits);
        std::memcpy(&x, &b, 4);
        if (!std::isfinite(x)) continue;
        ++checked;
        wrong += !same(x);
    }
    for (int i = -4096; i <= 4096; ++i)
        for (const float base : {float(i), i + 0.5f, float(i) * 2048.0f + 8388608.0f * (i < 0 ? -1 : 1)}) {
            float x = base;
            for (int k = 0; k < 4; ++k) x = std::nextafter(x, -INFINITY);
            for (int k = 0; k < 9; ++k, x = std::nextafter(x, INFINITY)) {
                ++checked;
                wrong += !same(x);
            }
        }
    for (const float x : {0.0f, -0.0f, 8388608.0f, -8388608.0f, 8388607.5f, -8388607.5f,
                          std::numeric_limits<float>::max(), -std::numeric_limits<float>::max(),
                          std::numeric_limits<float>::denorm_min(), -std::numeric_limits<float>::denorm_min()}) {
        ++checked;
        wrong += !same(x);
    }
    INFO(checked << " values");
    CHECK(wrong == 0);
}

TEST_CASE("det_math: sin and cos within their documented ulps on |x| < 8192") {
    Worst s, c;
    std::mt19937 rng(7);
    std::vector<float> xs = sweep(-7.0f, 7.0f, 400000);
    std::uniform_real_distribution<float> wide(-8192.0f, 8192.0f);
    for (int i = 0; i < 400000; ++i) xs.push_back(wide(rng));
    for (float x : xs) {
        float sv, cv;
        gpu::det_sincos(x, &sv, &cv);
        const long double es = std::sin((long double)x), ec = std::cos((long double)x);
        // near a zero of the function (x near a multiple of pi/2) the result is accurate to
        // the reduction's absolute error, not relative: ulps of a value at least 2^-6 there
        s.add(ulps(sv, es, 0x1p-6f), x);
        c.add(ulps(cv, ec, 0x1p-6f), x);
    }
    MESSAGE("sin: worst " << s.ulps << " ulp at " << s.at << "; cos: worst " << c.ulps << " ulp at " << c.at);
    CHECK(s.ulps <= k_sin_ulps);
    CHECK(c.ulps <= k_cos_ulps);
    float sv, cv;
    gpu::det_sincos(0.0f, &sv, &cv);
    CHECK(sv == 0.0f);
    CHECK(cv == 1.0f);
    gpu::det_sincos(std::numeric_limits<float>::infinity(), &sv, &cv);
    CHECK(std::isnan(sv));
    CHECK(std::isnan(cv));
}

TEST_CASE("det_math: sin and cos of (pi/4) a within their documented ulps on [-1, 1]") {
    Worst s, c;
    std::vector<float> as = sweep(-1.0f, 1.0f, 400000);
    for (float a : {0x1p-20f, -0x1p-20f, 1e-30f, 1.0f, -1.0f}) as.push_back(a);
    const long double quarter_pi = 0.785398163397448309615660845819875721L;
    for (float a : as) {
        float sv, cv;
        gpu::det_sincos_quarter_pi(a, &sv, &cv);
        s.add(ulps(sv, std::sin(quarter_pi * a)), a);
        c.add(ulps(cv, std::cos(quarter_pi * a)), a);
    }
    MESSAGE("sin: worst " << s.ulps << " ulp at " << s.at << "; cos: worst " << c.ulps << " ulp at " << c.at);
    CHECK(s.ulps <= k_quarter_pi_sin_ulps);
    CHECK(c.ulps <= k_quarter_pi_cos_ulps);
    float sv, cv;
    gpu::det_sincos_quarter_pi(0.0f, &sv, &cv);
    CHECK(sv == 0.0f);
    CHECK(cv == 1.0f);
}

TEST_CASE("det_math: acos within its documented ulps on [-1, 1]") {
    Worst a;
    for (float x : sweep(-1.0f, 1.0f, 2000000)) a.add(ulps(gpu::det_acos(x), std::acos((long double)x)), x);
    for (float x : {-1.0f, -0.5f, 0.0f, 0.5f, 1.0f, std::nextafter(1.0f, 0.0f), std::nextafter(-1.0f, 0.0f)})
        a.add(ulps(gpu::det_acos(x), std::acos((long double)x)), x);
    MESSAGE("acos: worst " << a.ulps << " ulp at " << a.at);
    CHECK(a.ulps <= k_acos_ulps);
    CHECK(gpu::det_acos(1.0f) == 0.0f);
    CHECK(std::isnan(gpu::det_acos(1.0001f)));
    CHECK(std::isnan(gpu::det_acos(std::numeric_limits<float>::quiet_NaN())));
}

TEST_CASE("det_math: atan2 within its documented ulps, with atan2's zeros and infinities") {
    Worst a;
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f), e(-20.0f, 20.0f);
    for (int i = 0; i < 1000000; ++i) {
        const float y = u(rng) * std::exp2(e(rng)), x = u(rng) * std::exp2(e(rng));
        a.add(ulps(gpu::det_atan2(y, x), std::atan2((long double)y, (long double)x)), y / x);
    }
    MESSAGE("atan2: worst " << a.ulps << " ulp at y/x = " << a.at);
    CHECK(a.ulps <= k_atan2_ulps);
    // The far ends of the float range, where the reduction's denominator x + c y would overflow
    // or round among denormals without its scaling, and ratios on either side of each interval's
    // boundary (7/16, 11/16, 19/16, 39/16), where the reduced argument is largest.
    Worst far;
    const float fmax_ = std::numeric_limits<float>::max(),
                tiny = std::numeric_limits<float>::denorm_min();
    std::uniform_real_distribution<float> ratio(0.3f, 3.0f);
    for (const int e : {-149, -140, -127, -126, -101, -100, -99, 99, 100, 101, 126, 127}) {
        for (int i = 0; i < 20000; ++i) {
            const float x = std::ldexp(0.5f + 0.5f * std::fabs(u(rng)), e);
            const float y = x * ratio(rng);
            if (!std::isfinite(y) || y == 0.0f || x == 0.0f) continue;
            far.add(
                ulps(gpu::det_atan2(y, x), std::atan2((long double)y, (long double)x), 0x1p-126f),
                y / x);
            far.add(ulps(gpu::det_atan2(-x, -y), std::atan2(-(long double)x, -(long double)y),
                         0x1p-126f),
                    x / y);
        }
    }
    for (const float c : {7.0f / 16.0f, 11.0f / 16.0f, 19.0f / 16.0f, 39.0f / 16.0f})
        for (const float x : {1.0f, 3.7f, 1e-30f, 1e30f, fmax_ / 4.0f, 1e-39f, 1000.0f * tiny}) {
            float y = c * x;
            for (int k = 0; k < 4; ++k)
                y = std::nextafter(y, 0.0f);
            for (int k = 0; k < 9; ++k, y = std::nextafter(y, INFINITY))
                far.add(ulps(gpu::det_atan2(y, x), std::atan2((long double)y, (long double)x),
                             0x1p-126f),
                        y / x);
        }
    for (const auto& c : {std::array<float, 2>{fmax_, fmax_},
                          {fmax_, fmax_ / 2.0f},
                          {fmax_ / 2.0f, fmax_},
                          {fmax_, 0.4375f * fmax_},
                          {tiny, tiny},
                          {3.0f * tiny, 5.0f * tiny},
                          {fmax_, tiny},
                          {tiny, fmax_}})
        far.add(ulps(gpu::det_atan2(c[0], c[1]), std::atan2((long double)c[0], (long double)c[1]),
                     0x1p-126f),
                c[0] / c[1]);
    MESSAGE("atan2 at the ends of the range and at the intervals' boundaries: worst "
            << far.ulps << " ulp at y/x = " << far.at);
    CHECK(far.ulps <= k_atan2_ulps);
    const float inf = std::numeric_limits<float>::infinity();
    const float cases[][2] = {{0.0f, 1.0f},  {-0.0f, 1.0f}, {0.0f, -1.0f}, {-0.0f, -1.0f},
                              {0.0f, -0.0f}, {-0.0f, 0.0f}, {1.0f, 0.0f},  {-1.0f, -0.0f},
                              {inf, 1.0f},   {1.0f, inf},   {1.0f, -inf},  {inf, -inf},
                              {-inf, inf},   {2.0f, 2.0f},  {-3.0f, -3.0f}};
    for (const auto& c : cases) {
        INFO("atan2(" << c[0] << ", " << c[1] << ")");
        const float got = gpu::det_atan2(c[0], c[1]), want = std::atan2(c[0], c[1]);
        CHECK(ulps(got, (long double)want) <= 1.0);
        CHECK(std::signbit(got) == std::signbit(want));
    }
    CHECK(std::isnan(gpu::det_atan2(std::numeric_limits<float>::quiet_NaN(), 1.0f)));
}

TEST_SUITE("device") {
    TEST_CASE("det_math: the device computes the host's bits") {
        TANDEM_REQUIRE_DEVICE(ctx);
        std::vector<float> x, y;
        std::mt19937 rng(3);
        std::uniform_real_distribution<float> u(-1.0f, 1.0f), e(-12.0f, 12.0f);
        for (float v : sweep(-10.0f, 10.0f, 20000)) x.push_back(v), y.push_back(u(rng));
        for (float v : sweep(-1.0f, 1.0f, 20000)) x.push_back(v), y.push_back(u(rng) * std::exp2(e(rng)));
        for (int i = 0; i < 20000; ++i)
            x.push_back(u(rng) * std::exp2(e(rng))), y.push_back(u(rng) * std::exp2(e(rng)));
        const float special[] = {0.0f, -0.0f, 1.0f, -1.0f, std::numeric_limits<float>::infinity(),
                                 -std::numeric_limits<float>::infinity(),
                                 std::numeric_limits<float>::quiet_NaN(), 1e-40f, 8191.9f,
                                 // det_floor's edges: past 2^23 every float is an integer, and a
                                 // negative denormal floors to -1
                                 -1e-40f, 8388607.5f, -8388607.5f, 8388608.0f, -8388609.0f, 1e30f,
                                 -1e30f,
                                 // atan2's scaling of its operands: near overflow, and tiny
                                 std::numeric_limits<float>::max(), -1.5e38f, 0x1p101f, 0x1p-101f,
                                 -0x1p-120f};
        for (float a : special)
            for (float b : special) x.push_back(a), y.push_back(b);
        const auto n = unsigned(x.size());
        const Program program =
            Program::build(*ctx, probe_library(), "probes/math_probe.cl", "");
        Kernel probe(program, "det_math_probe");
        Buffer<float> bx(*ctx, "x", x), by(*ctx, "y", y), out(*ctx, "out", 7 * x.size());
        probe.launch(*ctx, "det math probe", n, bx, by, out, n);
        const std::vector<float> device = out.download();
        std::size_t differ = 0;
        for (unsigned i = 0; i < n; ++i) {
            float s, c;
            gpu::det_sincos(x[i], &s, &c);
            float sq = 0.0f, cq = 0.0f;
            if (std::fabs(y[i]) <= 1.0f) gpu::det_sincos_quarter_pi(y[i], &sq, &cq);
            const float host[7] = {s, c, gpu::det_acos(x[i]), gpu::det_atan2(y[i], x[i]),
                                    gpu::det_floor(x[i]), sq, cq};
            for (int k = 0; k < 7; ++k) {
                const bool same = bits(host[k]) == bits(device[7 * i + k]) ||
                                  (std::isnan(host[k]) && std::isnan(device[7 * i + k]));
                if (!same && differ++ < 5)
                    MESSAGE("function " << k << " at x = " << x[i] << ", y = " << y[i] << ": host "
                                        << host[k] << ", device " << device[7 * i + k]);
            }
        }
        CHECK(differ == 0);
    }
}

// det_log and det_exp (the free flights and the transmittance of media): their largest errors
// against long double over every 7th positive float (log) and every 3rd float in (-87.3, 88.7)
// (exp), a one-off sweep, were 0.8226 and 1.0103 ulp; rounded up here.
TEST_CASE("det_math: log and exp within their measured ulps, and their special values") {
    constexpr double k_log_ulps = 0.823, k_exp_ulps = 1.011;
    Worst l, e;
    std::mt19937 rng(11);
    std::uniform_int_distribution<uint32_t> positive(1u, 0x7f7fffffu);
    std::uniform_real_distribution<float> exps(-87.3f, 88.7f);
    for (int i = 0; i < 1000000; ++i) {
        const uint32_t b = positive(rng);
        float x;
        std::memcpy(&x, &b, 4);
        l.add(ulps(gpu::det_log(x), std::log((long double)x)), x);
        const float y = exps(rng);
        e.add(ulps(gpu::det_exp(y), std::exp((long double)y)), y);
    }
    for (float u : sweep(0.0f, 0.99999994f, 100000)) // free flights take log(1 - u)
        l.add(ulps(gpu::det_log(1.0f - u), std::log((long double)(1.0f - u)), 0x1p-24f), 1.0f - u);
    MESSAGE("log: worst " << l.ulps << " ulp at " << l.at << "; exp: worst " << e.ulps << " at " << e.at);
    CHECK(l.ulps <= k_log_ulps);
    CHECK(e.ulps <= k_exp_ulps);
    CHECK(gpu::det_log(1.0f) == 0.0f);
    CHECK(gpu::det_log(0.0f) == -std::numeric_limits<float>::infinity());
    CHECK(std::isnan(gpu::det_log(-1.0f)));
    CHECK(gpu::det_log(std::numeric_limits<float>::infinity()) == std::numeric_limits<float>::infinity());
    CHECK(gpu::det_exp(0.0f) == 1.0f);
    CHECK(gpu::det_exp(-100.0f) == 0.0f);
    CHECK(gpu::det_exp(100.0f) == std::numeric_limits<float>::infinity());
    CHECK(std::isnan(gpu::det_exp(std::nanf(""))));
}
