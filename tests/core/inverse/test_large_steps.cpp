// Large Steps (core/inverse/large_steps.h): the matrix against one written out by hand, the solves
// against a dense reference, and a step in u against the explicit formula; a texture's grid
// Laplacian likewise.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "core/inverse/large_step_params.h"
#include "core/inverse/large_steps.h"
#include "runtime/error.h"
#include "support.h"

using namespace tandem;

namespace {

// A square of two triangles whose vertex 4 repeats vertex 2's position (as a cube's split
// vertices do): points 0, 1, 2, 3; edges 0-1, 1-2, 2-0, 2-3, 3-0 (the diagonal 0-2 shared).
const std::vector<float> positions = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 1, 1, 0};
const std::vector<unsigned> triangles = {0, 1, 2, 4, 3, 0};

/// Solves A y = b by Gaussian elimination with partial pivoting, in double (the reference).
std::vector<double> dense_solve(std::vector<double> a, std::vector<double> b, std::size_t n) {
    for (std::size_t c = 0; c < n; ++c) {
        std::size_t pivot = c;
        for (std::size_t r = c + 1; r < n; ++r)
            if (std::abs(a[r * n + c]) > std::abs(a[pivot * n + c])) pivot = r;
        for (std::size_t k = 0; k < n; ++k) std::swap(a[c * n + k], a[pivot * n + k]);
        std::swap(b[c], b[pivot]);
        for (std::size_t r = c + 1; r < n; ++r) {
            const double f = a[r * n + c] / a[c * n + c];
            for (std::size_t k = c; k < n; ++k) a[r * n + k] -= f * a[c * n + k];
            b[r] -= f * b[c];
        }
    }
    std::vector<double> y(n);
    for (std::size_t r = n; r-- > 0;) {
        double s = b[r];
        for (std::size_t k = r + 1; k < n; ++k) s -= a[r * n + k] * y[k];
        y[r] = s / a[r * n + r];
    }
    return y;
}

} // namespace

TEST_CASE("large steps: I + lambda L of a welded mesh, written out") {
    const LargeSteps ls(positions, triangles, 2.0);
    REQUIRE(ls.vertices() == 5);
    REQUIRE(ls.points() == 4);
    // degrees: point 0: 3 (1, 2, 3), 1: 2, 2: 3, 3: 2
    const std::vector<double> expected = {7, -2, -2, -2,  -2, 5, -2, 0,
                                          -2, -2, 7, -2,  -2, 0, -2, 5};
    CHECK(ls.dense_matrix() == expected);
}

TEST_CASE("large steps: the solves match a dense reference, and u round-trips") {
    const LargeSteps ls(positions, triangles, 19.0);
    const std::size_t n = ls.points();
    const std::vector<double> a = ls.dense_matrix();
    const std::vector<float> g = {0.3f, -1.0f, 0.2f, 0.5f, 0.25f, -0.75f, -0.1f, 0.4f,
                                  1.0f, 0.6f, -0.2f, 0.05f, 0.1f, 0.1f, 0.1f};
    const std::vector<float> gu = ls.gradient(g);
    for (int c = 0; c < 3; ++c) {
        // the copies' gradients add (vertices 2 and 4 are one point)
        std::vector<double> b = {g[0 + c], g[3 + c], g[6 + c] + double(g[12 + c]), g[9 + c]};
        const std::vector<double> y = dense_solve(a, b, n);
        for (std::size_t p = 0; p < n; ++p) CHECK(gu[3 * p + c] == doctest::Approx(y[p]).epsilon(1e-6));
    }
    const std::vector<float> u = ls.to_differential(positions);
    const std::vector<float> x = ls.from_differential(u);
    for (std::size_t i = 0; i < x.size(); ++i) CHECK(x[i] == doctest::Approx(positions[i]).epsilon(1e-6));
    CHECK(x[6] == x[12]); // the copies of a point stay together
    CHECK_THROWS_AS(LargeSteps(positions, triangles, -1.0), Error);
    CHECK_THROWS_AS(LargeSteps(positions, {0, 1, 9}, 1.0), Error);
}

TEST_CASE("large steps: a gradient step in u is the explicit formula") {
    // u' = u - eta gu  =>  x' = M^-1 (M x - eta M^-1 g) = x - eta M^-2 g
    const LargeSteps ls(positions, triangles, 19.0);
    const std::size_t n = ls.points();
    const std::vector<double> a = ls.dense_matrix();
    const std::vector<float> g = {1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}; // vertex 0, x
    const float eta = 0.5f;
    std::vector<float> u = ls.to_differential(positions);
    const std::vector<float> gu = ls.gradient(g);
    for (std::size_t i = 0; i < u.size(); ++i) u[i] -= eta * gu[i];
    const std::vector<float> x = ls.from_differential(u);
    const std::vector<double> once = dense_solve(a, {1, 0, 0, 0}, n);
    const std::vector<double> twice = dense_solve(a, once, n);
    const unsigned point_of_vertex[5] = {0, 1, 2, 3, 2};
    for (std::size_t v = 0; v < 5; ++v)
        CHECK(x[3 * v] == doctest::Approx(positions[3 * v] - eta * twice[point_of_vertex[v]]).epsilon(1e-6));
    // the step moves every point, not only the one with a gradient: smooth, as the paper's Fig. 3
    for (std::size_t p = 0; p < n; ++p) CHECK(twice[p] > 0.0);
}

TEST_CASE("large steps: a texture's grid Laplacian, written out, and its solves") {
    // 3 x 2 texels, numbered by rows: 0 1 2 / 3 4 5; each joined to its four neighbours
    const LargeSteps ls = LargeSteps::image(3, 2, 3, 2.0);
    REQUIRE(ls.points() == 6);
    REQUIRE(ls.channels() == 3);
    const std::vector<double> expected = {
        5, -2, 0, -2, 0, 0,  -2, 7, -2, 0, -2, 0,  0, -2, 5, 0, 0, -2,
        -2, 0, 0, 5, -2, 0,  0, -2, 0, -2, 7, -2,  0, 0, -2, 0, -2, 5};
    CHECK(ls.dense_matrix() == expected);
    // per channel, the gradient's solve against the dense reference (rgb interleaved per texel)
    std::vector<float> g(18);
    for (std::size_t i = 0; i < g.size(); ++i) g[i] = float(std::sin(1.7 * double(i) + 0.3));
    const std::vector<float> gu = ls.gradient(g);
    for (int c = 0; c < 3; ++c) {
        std::vector<double> b(6);
        for (std::size_t t = 0; t < 6; ++t) b[t] = g[3 * t + std::size_t(c)];
        const std::vector<double> y = dense_solve(expected, b, 6);
        for (std::size_t t = 0; t < 6; ++t)
            CHECK(gu[3 * t + std::size_t(c)] == doctest::Approx(y[t]).epsilon(1e-6));
    }
    const std::vector<float> x = ls.from_differential(ls.to_differential(g));
    for (std::size_t i = 0; i < x.size(); ++i) CHECK(x[i] == doctest::Approx(g[i]).epsilon(1e-5));
    CHECK_THROWS_AS(LargeSteps::image(0, 2, 3, 1.0), Error);
    CHECK_THROWS_AS(LargeSteps::image(2, 2, 3, -1.0), Error);
}

// Large Steps on a bitmap texture in an optimize job (core/inverse/large_step_params.h): with SGD,
// x' = M^-1 (M x - eta M^-1 g) = x - eta M^-2 g, M = I + lambda L of the texel grid. Checked
// without solving: M applied twice by hand (the four-neighbour stencil) to (x - x') / eta must give
// g back. The bound: x' carries a few float roundings of values near 0.5 (u = M x stored, the
// update, the solve back: about 4 ulp(0.5) = 2.4e-7), which M^2 (infinity norm (1 + 8 lambda)^2 =
// 81 for lambda 1) and 1 / eta amplify to 81 * 2.4e-7 / 0.05 = 3.9e-4; a step without the
// preconditioning misses by M^2 g - g, about 1 at this g's peaks. A large step clamps to the
// range, both ways.
TEST_CASE("large steps on a texture: an SGD step is x - eta M^-2 g, clamped to the range") {
    TANDEM_REQUIRE_DEVICE(ctx);
    const RenderScene scene = build_render_scene(
        load_scene(std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/grad-texture.xml"));
    const Parameter& p = scene.params.find("paint.reflectance");
    REQUIRE(p.kind == Parameter::Kind::texture);
    const int w = p.width, h = p.height;
    const double lambda = 1.0;
    OptimizerConfig sgd;
    sgd.method = OptimizerConfig::Method::sgd;
    const auto job = [&](float lr) {
        OptimizeConfig config;
        config.path = "job.json";
        OptimizedParam q;
        q.name = p.name;
        q.lr = lr;
        q.large_steps = lambda;
        config.params = {q};
        return config;
    };
    std::vector<float> g(scene.params.values().size(), 0.0f);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c)
                g[p.offset + 3 * std::size_t(y * w + x) + std::size_t(c)] =
                    float(0.3 * std::sin(0.9 * x + c) * std::cos(0.7 * y));
    for (float eta : {0.05f, 100.0f}) {
        INFO("eta " << eta);
        ParamState state(*ctx, scene.params);
        LargeStepParams steps(state, KernelLibrary::from_environment(), job(eta), scene, sgd);
        CHECK(steps.plan().find(std::to_string(w * h) + " texels") != std::string::npos);
        std::vector<float> values = scene.params.values();
        std::fill_n(values.begin() + std::ptrdiff_t(p.offset), p.size, 0.5f);
        steps.start(values);
        for (std::size_t i = 0; i < p.size; ++i) REQUIRE(std::fabs(values[p.offset + i] - 0.5f) < 1e-6f);
        state.theta().upload(values);
        state.gradient().value.upload(g);
        steps.step(0);
        const std::vector<float> after = state.theta().download();
        for (std::size_t i = 0; i < values.size(); ++i)
            if (i < p.offset || i >= p.offset + p.size) REQUIRE(after[i] == values[i]);
        if (eta > 1.0f) { // far past the range both ways: clamped there
            std::size_t low = 0, high = 0;
            for (std::size_t i = p.offset; i < p.offset + p.size; ++i) {
                REQUIRE((after[i] >= p.lower && after[i] <= p.upper));
                low += after[i] == p.lower, high += after[i] == p.upper;
            }
            CHECK(low > p.size / 4);
            CHECK(high > p.size / 4);
            continue;
        }
        // r = M (M d), d = (x - x') / eta, per channel
        const auto apply = [&](const std::vector<double>& v) {
            std::vector<double> out(v.size());
            for (int y = 0; y < h; ++y)
                for (int x = 0; x < w; ++x)
                    for (int c = 0; c < 3; ++c) {
                        const auto at = [&](int i, int j) { return v[3 * std::size_t(j * w + i) + std::size_t(c)]; };
                        double sum = at(x, y), degree = 0.0, neighbours = 0.0;
                        for (const auto& [i, j] : {std::pair{x - 1, y}, {x + 1, y}, {x, y - 1}, {x, y + 1}})
                            if (i >= 0 && i < w && j >= 0 && j < h) degree += 1.0, neighbours += at(i, j);
                        out[3 * std::size_t(y * w + x) + std::size_t(c)] =
                            sum + lambda * (degree * at(x, y) - neighbours);
                    }
            return out;
        };
        std::vector<double> d(p.size);
        for (std::size_t i = 0; i < p.size; ++i) d[i] = (double(values[p.offset + i]) - after[p.offset + i]) / eta;
        const std::vector<double> r = apply(apply(d));
        double worst = 0.0;
        for (std::size_t i = 0; i < p.size; ++i) worst = std::max(worst, std::fabs(r[i] - g[p.offset + i]));
        CHECK(worst < 3.9e-4);
    }
}

// A texel held at a bound takes no gradient pulling it further out: from every texel at 0, a step
// down leaves u where it was (M^-1 of a constant is that constant), so a step up of the same size
// then lifts every texel to eta exactly; were u let past the bound, that step would only bring it
// back to 0.
TEST_CASE("large steps on a texture: a texel held at a bound does not drift past it") {
    TANDEM_REQUIRE_DEVICE(ctx);
    const RenderScene scene = build_render_scene(
        load_scene(std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/grad-texture.xml"));
    const Parameter& p = scene.params.find("paint.reflectance");
    OptimizeConfig config;
    config.path = "job.json";
    OptimizedParam q;
    q.name = p.name;
    q.lr = 0.125f;
    q.large_steps = 4.0;
    config.params = {q};
    OptimizerConfig sgd;
    sgd.method = OptimizerConfig::Method::sgd;
    ParamState state(*ctx, scene.params);
    LargeStepParams steps(state, KernelLibrary::from_environment(), config, scene, sgd);
    std::vector<float> values = scene.params.values();
    std::fill_n(values.begin() + std::ptrdiff_t(p.offset), p.size, 0.0f);
    steps.start(values);
    state.theta().upload(values);
    for (int it = 0; it < 2; ++it) {
        std::vector<float> g(values.size(), 0.0f);
        std::fill_n(g.begin() + std::ptrdiff_t(p.offset), p.size, it == 0 ? 1.0f : -1.0f);
        state.gradient().value.upload(g);
        steps.step(it);
    }
    const std::vector<float> x = state.theta().download();
    for (std::size_t i = p.offset; i < p.offset + p.size; ++i)
        REQUIRE(x[i] == doctest::Approx(0.125).epsilon(1e-5));
}

TEST_CASE("large steps: refused on a parameter that is neither vertex positions nor a texture") {
    TANDEM_REQUIRE_DEVICE(ctx);
    const RenderScene scene = build_render_scene(
        load_scene(std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/grad-texture.xml"));
    OptimizeConfig config;
    config.path = "job.json";
    OptimizedParam q;
    q.name = "sky.radiance";
    q.large_steps = 19.0;
    config.params = {q};
    ParamState state(*ctx, scene.params);
    CHECK_THROWS_WITH_AS(LargeStepParams(state, KernelLibrary::from_environment(), config, scene,
                                         OptimizerConfig{}),
                         "job.json: params.sky.radiance: 'large_steps' is for a mesh's vertex "
                         "positions or a bitmap texture, and this is a rgb parameter",
                         Error);
}
