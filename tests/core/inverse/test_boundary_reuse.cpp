// The secondary boundary term's reuse of light vertices across iterations
// (core/render/boundary_reuse.h, kernels/path/boundary_reuse.h): the buckets by which a pass finds
// the previous reservoirs, worked out by hand; under three small lights with a moving occluder,
// the gradient after a chain of iterations with reuse has the plain estimator's mean; and a chain
// run twice gives the same bits. The combine's arithmetic is the interior's (shared/reservoir.h),
// whose 1-D models (tests/kernels/shared/test_reservoir.cpp) also model this chain over edge
// points, with its deliberate errors.
#include <doctest/doctest.h>

#include <array>
#include <cmath>

#include "core/inverse/session.h"
#include "core/render/boundary_reuse.h"
#include "inverse_fixtures.h"
#include "support.h"

using namespace tandem;

namespace {

std::string test_scene(const char* name) {
    return std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/" + name;
}

/// A session whose kernels compile the reuse (RESTIR=1).
SessionOptions reuse_build() {
    SessionOptions o;
    o.restir = true;
    return o;
}

gpu::BoundaryReservoir reservoir(unsigned cell, unsigned light) {
    gpu::BoundaryReservoir r{};
    r.cell = cell;
    r.light = light;
    r.W = light == NO_EMISSIVE ? 0.0f : 1.0f;
    return r;
}

/// The secondary term alone (no primary term; the interior at 1 spp, the same for the same seed)
/// of occluder.vertex_positions under three lights (shape-lights.xml), as the x of its
/// translation, at the last of `iterations` iterations along which the occluder moves toward where
/// the scene has it (0.02 per iteration along -x), each iteration with seed `seed` * iterations +
/// n. With `reuse`, every iteration runs with it (its reservoirs carried on); without, only the
/// last runs.
struct Chain {
    Session& session;
    const Parameter& p;
    std::vector<float> xyz;
    int spp;

    double run(int iterations, std::uint32_t seed, SecondaryReservoirs* reuse,
               std::vector<float>* gradient = nullptr) {
        double x = 0.0;
        for (int n = reuse ? 0 : iterations - 1; n < iterations; ++n) {
            std::vector<float> v = xyz;
            for (std::size_t i = 0; i < v.size(); i += 3) v[i] += 0.02f * float(iterations - 1 - n);
            session.set_value(p, FloatSpan{v.data(), v.size()});
            BoundarySamples b;
            b.primary = 0;
            b.secondary = spp;
            b.reuse = reuse;
            session.set_boundary_samples(b);
            const std::vector<float> g =
                session.grad("mean", {}, {&p}, 4, 1, seed * std::uint32_t(iterations) + n).gradient;
            if (n == iterations - 1) {
                for (std::size_t i = 0; i < p.size; i += 3) x += g[p.offset + i];
                if (gradient) *gradient = g;
            }
        }
        session.set_value(p, FloatSpan{xyz.data(), xyz.size()});
        return x;
    }
};

} // namespace

TEST_CASE("boundary reuse: buckets list every reservoir of a cell's low bits, in slot order") {
    // four reservoirs: 8 buckets (a power of two at least twice their count)
    const std::vector<gpu::BoundaryReservoir> r{reservoir(9, 3), reservoir(1, NO_EMISSIVE),
                                                reservoir(17, 0), reservoir(4, 2)};
    const SecondaryReservoirs::Buckets b = SecondaryReservoirs::bucket(r);
    REQUIRE(b.first.size() == 9);
    // cells 9, 1 and 17 share bucket 1 (the empty one too: kept by its point, not its sample)
    CHECK(b.first == std::vector<unsigned>{0, 0, 3, 3, 3, 4, 4, 4, 4});
    CHECK(b.slots == std::vector<unsigned>{0, 1, 2, 3});
    CHECK(SecondaryReservoirs::bucket({}).first == std::vector<unsigned>{0, 0});
}

TEST_CASE("boundary reuse: a bad setting is refused, naming its field") {
    SecondaryReuseConfig c;
    c.neighbours = 9;
    CHECK_THROWS_WITH_AS(validate_secondary_reuse(c, "here"),
                         doctest::Contains("here: neighbours"), Error);
    c = {};
    c.cell = 0.0f;
    CHECK_THROWS_WITH_AS(validate_secondary_reuse(c, "here"), doctest::Contains("here: cell"),
                         Error);
    // a scene whose kernels were built without the reuse
    Context* ctx = test::device_context();
    Session session(*ctx, KernelLibrary::from_environment(), test_scene("shape-lights.xml"), {});
    const Parameter& p = session.parameter("occluder.vertex_positions");
    SecondaryReservoirs reuse(*ctx, SecondaryReuseConfig{});
    BoundarySamples b;
    b.reuse = &reuse;
    session.set_boundary_samples(b);
    CHECK_THROWS_WITH_AS(session.grad("mean", {}, {&p}, 1, 1, 0),
                         doctest::Contains("not built with RESTIR=1"), Error);
}

namespace {

/// Reuse changes where the secondary term's light vertices go, not what they estimate: with the
/// occluder moving, the gradient after three iterations of reuse against the plain estimator's at
/// the same parameters and seed (paired: the interior term is the same), over `seeds` seeds, the mean
/// of the differences within 4 standard errors of 0, and that standard error below 5 % of the
/// value, so that a bias of that size is caught (and heavy tails, which would widen it).
void check_moving_occluder(const char* file, int spp, int seeds, bool visibility) {
    Context* ctx = test::device_context();
    Session session(*ctx, KernelLibrary::from_environment(), test_scene(file), {}, reuse_build());
    const Parameter& p = session.parameter("occluder.vertex_positions");
    Chain chain{session, p, session.value(p), spp};
    // fewer candidates and neighbours than the defaults: the same arithmetic, a cheaper test
    SecondaryReuseConfig config;
    config.candidates = 4;
    config.neighbours = 2;
    config.visibility = visibility;
    test::Stat plain, reused, diff;
    for (std::uint32_t seed = 0; seed < std::uint32_t(seeds); ++seed) {
        SecondaryReservoirs reuse(*ctx, config);
        const double a = chain.run(3, seed, nullptr), b = chain.run(3, seed, &reuse);
        plain.add(a);
        reused.add(b);
        diff.add(b - a);
    }
    MESSAGE(std::string(file) << ", moving occluder: plain " << plain.mean() << " +- " << plain.se()
                 << ", reused " << reused.mean() << " +- " << reused.se() << ", difference "
                 << diff.mean() << " +- " << diff.se());
    CHECK(std::abs(diff.mean()) <= 4.0 * diff.se());
    CHECK(diff.se() < 0.05 * std::abs(plain.mean()));
}

} // namespace

// Three square lamps, one-sided.
TEST_CASE("boundary reuse: the secondary term keeps its mean along a moving occluder") {
    check_moving_occluder("shape-lights.xml", 64, 16, false);
}

// Three sphere lights: a light point may lie on a closed light's far side, which its direction
// meets behind the near side (a target that gave those points the floor's value spiked: this
// case's standard error caught it). With the target's visibility, which traces what the
// direction meets.
TEST_CASE("boundary reuse: the same under closed lights") {
    check_moving_occluder("shape-sphere-lights.xml", 256, 64, true);
}

// Small enough for Oclgrind (tests/CMakeLists.txt: oclgrind.boundary_reuse): 81 pixels, a last
// work-group partly filled.
TEST_CASE("boundary reuse: a chain run twice gives the same bits") {
    Context* ctx = test::device_context();
    Session session(*ctx, KernelLibrary::from_environment(), test_scene("shape-sphere-lights.xml"),
                    {{"res", "9"}}, reuse_build());
    const Parameter& p = session.parameter("occluder.vertex_positions");
    Chain chain{session, p, session.value(p), 4};
    std::vector<float> g[2];
    SecondaryReuseConfig config; // with the target's rays: every path of the kernel
    config.visibility = true;
    for (int k = 0; k < 2; ++k) {
        SecondaryReservoirs reuse(*ctx, config);
        chain.run(3, 7, &reuse, &g[k]);
    }
    CHECK(g[0] == g[1]);
    // and the reuse is there: without it the same seed gives other bits
    std::vector<float> plain;
    chain.run(3, 7, nullptr, &plain);
    CHECK(plain != g[0]);
}
