// Large Steps (core/inverse/large_steps.h): the matrix against one written out by hand, the solves
// against a dense reference, and a step in u against the explicit formula.
#include <doctest/doctest.h>

#include <cmath>
#include <vector>

#include "core/inverse/large_steps.h"
#include "runtime/error.h"

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
