// Surface distances (core/bvh/surface_distance.h) against closed forms on unit squares.
#include <doctest/doctest.h>

#include <cmath>

#include "core/bvh/surface_distance.h"
#include "runtime/error.h"

using namespace tandem;

namespace {

/// The square [x0, x0 + 1] x [0, 1] at height z, two triangles.
TriangleMesh square(double x0, double z) {
    TriangleMesh m;
    m.source = "square";
    const float a = float(x0), b = float(x0 + 1.0), h = float(z);
    m.positions = {{a, 0, h}, {b, 0, h}, {b, 1, h}, {a, 1, h}};
    m.triangles = {{0, 1, 2}, {0, 2, 3}};
    return m;
}

} // namespace

TEST_SUITE("bvh") {
    TEST_CASE("surface distance: points spread by area, distances exact, the two measures in closed form") {
        EmbreeDevice device;
        // samples: on the surface, spread evenly (a quarter of them in each quarter)
        const std::vector<glm::dvec3> s = surface_samples(square(0.0, 0.0), 10000);
        int quarter = 0;
        for (const glm::dvec3& p : s) {
            REQUIRE((p.x >= 0.0 && p.x <= 1.0 && p.y >= 0.0 && p.y <= 1.0 && p.z == 0.0));
            quarter += p.x < 0.5 && p.y < 0.5;
        }
        CHECK(std::abs(quarter - 2500) <= 25);
        // a point's distance to the nearest of the face, an edge or a corner
        const std::vector<double> d = distances_to_surface(
            device, square(0.0, 0.0), {{0.3, 0.6, 0.5}, {1.5, 0.5, 0.0}, {2.0, 2.0, 1.0}, {0.5, -0.25, -1.0}});
        CHECK(d[0] == doctest::Approx(0.5).epsilon(1e-6));
        CHECK(d[1] == doctest::Approx(0.5).epsilon(1e-6));
        CHECK(d[2] == doctest::Approx(std::sqrt(3.0)).epsilon(1e-6));
        CHECK(d[3] == doctest::Approx(std::sqrt(1.0625)).epsilon(1e-6));
        // parallel squares 0.25 apart: every distance is 0.25
        const SurfaceDistance lifted = surface_distance(device, square(0.0, 0.0), square(0.0, 0.25), 20000);
        CHECK(lifted.chamfer == doctest::Approx(0.25).epsilon(1e-6));
        CHECK(lifted.hausdorff == doctest::Approx(0.25).epsilon(1e-6));
        // squares overlapping by half: a point at x < 1/2 is 1/2 - x from the other, so each
        // one-sided mean is the integral of (1/2 - x) over [0, 1/2], 1/8; the largest tends to
        // 1/2. Quasi-random samples integrate this to about log(N)/N: 1e-3 is generous.
        const SurfaceDistance half = surface_distance(device, square(0.0, 0.0), square(0.5, 0.0), 100000);
        CHECK(std::abs(half.chamfer - 0.125) < 1e-3);
        CHECK(half.hausdorff <= 0.5 + 1e-7);
        CHECK(half.hausdorff > 0.499);
        // the same surface: zero, but for the rounding of the samples' interpolation
        CHECK(surface_distance(device, square(0.0, 0.0), square(0.0, 0.0), 1000).chamfer < 1e-15);
        TriangleMesh flat = square(0.0, 0.0);
        for (glm::vec3& p : flat.positions) p.y = 0.0f;
        CHECK_THROWS_AS(surface_samples(flat, 10), Error);
    }
}
