// The secondary term's guide tables (core/render/boundary_guide.h): the cells of directions, the
// slots of edges, the blur, the CDFs and the edge choice, against values worked out by hand.
#include <doctest/doctest.h>

#include <cmath>

#include "core/render/boundary_guide.h"
#include "runtime/error.h"

using namespace tandem;

namespace {

/// The probability of cell c in the CDF of slot `slot`.
double cell_p(const SecondaryGuideTables& t, unsigned slot, unsigned c) {
    const std::size_t cells = std::size_t(t.guide.dir_res) * t.guide.dir_res;
    const float* cdf = t.cdf.data() + slot * cells;
    return double(cdf[c]) - (c > 0 ? double(cdf[c - 1]) : 0.0);
}

} // namespace

TEST_CASE("guide: a direction's cell is the cell of uniform_sphere's square it came from") {
    for (unsigned n : {4u, 64u})
        for (unsigned i = 0; i < n; ++i)
            for (unsigned j = 0; j < n; ++j) {
                // the centre of cell (i, j) of the (u1, u2) square
                float w[3];
                gpu::uniform_sphere((float(i) + 0.5f) / float(n), (float(j) + 0.5f) / float(n), w);
                CHECK(gpu::secondary_guide_cell(gpu::make_float3(w[0], w[1], w[2]), n) == i * n + j);
            }
    // the poles and the seam of phi stay inside the table
    CHECK(gpu::secondary_guide_cell(gpu::make_float3(0, 0, 1), 8) == 0u * 8u + 0u);
    CHECK(gpu::secondary_guide_cell(gpu::make_float3(0, 0, -1), 8) / 8u == 7u);
    CHECK(gpu::secondary_guide_cell(gpu::make_float3(1, -1e-7f, 0), 8) % 8u == 7u);
}

TEST_CASE("guide: one sample's cell, blurred, and the bins an edge keeps") {
    SecondaryGuideShape shape;
    shape.bins = 2;
    shape.dir_res = 4;
    shape.max_slots = 4; // two edges of two bins
    // edge 1: weight 3 at t = 0.25 (bin 0), cell (1, 0); edge 0: weight 1 at t = 0.9 (bin 1),
    // cell (0, 2); edge 2: weight 0.5, beyond max_slots; a sample of weight 0 counts nothing
    const std::vector<gpu::float4> samples = {gpu::make_float4(0.25f, 3.0f, 0, 0),
                                              gpu::make_float4(0.9f, 1.0f, 0, 0),
                                              gpu::make_float4(0.5f, 0.5f, 0, 0),
                                              gpu::make_float4(0.5f, 0.0f, 0, 0)};
    const std::vector<unsigned> cells = {1 * 4 + 0, 0 * 4 + 2, 5, 5};
    const std::vector<unsigned> edges = {1, 0, 2, 0};
    const SecondaryGuideTables t = build_secondary_guide(samples, cells, edges, 3, shape);
    CHECK(t.guide.fraction == shape.fraction);
    CHECK(t.guide.slots == 4u);
    CHECK(t.edge_slot[1] == 0u); // the heavier edge first
    CHECK(t.edge_slot[0] == 2u);
    CHECK(t.edge_slot[2] == GUIDE_NO_SLOT);
    CHECK(t.edge_weight == std::vector<double>{1.0, 3.0, 0.5});
    // edge 1, bin 0: cell (1, 0) blurred by [1 2 1]^2 / 16, phi wrapping: rows 0..2, columns
    // 3, 0, 1; all of the mass inside the table, so the weights are those of the kernel
    const double k[3] = {1, 2, 1};
    for (unsigned i = 0; i < 4; ++i)
        for (unsigned j = 0; j < 4; ++j) {
            const int di = int(i) - 1, dj = (int(j) + 1) % 4 - 1; // j = 3 is dj = -1
            const double expect =
                std::abs(di) <= 1 && std::abs(dj) <= 1 ? k[di + 1] * k[dj + 1] / 16.0 : 0.0;
            CHECK(cell_p(t, 0, i * 4 + j) == doctest::Approx(expect).epsilon(1e-6));
        }
    // bin 1 of edge 1 saw nothing: it takes the edge's whole histogram, the same density
    for (unsigned c = 0; c < 16; ++c) CHECK(cell_p(t, 1, c) == doctest::Approx(cell_p(t, 0, c)));
    // edge 0's sample is in bin 1; at row 0, theta does not wrap: the row above is lost and the
    // rest renormalised (kernel rows 1, 2 of weights 2 and 1, columns 1..3)
    CHECK(cell_p(t, 3, 0 * 4 + 2) == doctest::Approx(4.0 / 12.0).epsilon(1e-6));
    CHECK(cell_p(t, 3, 1 * 4 + 1) == doctest::Approx(1.0 / 12.0).epsilon(1e-6));
    CHECK(cell_p(t, 3, 2 * 4 + 2) == 0.0);
    for (unsigned s = 0; s < 4; ++s) CHECK(t.cdf[s * 16 + 15] == 1.0f);
}

TEST_CASE("guide: nothing learnt is no guide, the edge choice mixes length and weight, bad shapes are refused") {
    const SecondaryGuideShape shape;
    const SecondaryGuideTables none =
        build_secondary_guide({gpu::make_float4(0.5f, 0.0f, 0, 0)}, {0}, {0}, 2, shape);
    CHECK(none.guide.fraction == 0.0f);
    CHECK(none.guide.slots == 0u);
    CHECK(none.cdf.empty());

    std::vector<gpu::SecondaryEdge> edges(2);
    edges[0].n0.w = 0.75f;
    edges[1].n0.w = 0.25f;
    guide_edge_choice(none, shape, edges); // no weight: as they were
    CHECK(edges[0].n0.w == 0.75f);
    SecondaryGuideTables learnt;
    learnt.edge_weight = {0.0, 2.0};
    guide_edge_choice(learnt, shape, edges);
    const double f = shape.edge_fraction;
    CHECK(edges[0].n0.w == doctest::Approx((1 - f) * 0.75));
    CHECK(edges[1].n0.w == doctest::Approx((1 - f) * 0.25 + f));

    SecondaryGuideShape bad;
    bad.dir_res = 0;
    CHECK_THROWS_AS(build_secondary_guide({}, {}, {}, 0, bad), Error);
    bad.dir_res = 1024;
    bad.max_slots = 4096; // 2^32 cells: past the kernels' 32-bit index
    CHECK_THROWS_AS(build_secondary_guide({}, {}, {}, 0, bad), Error);

    CHECK(secondary_guide_mode("auto", "x") == -1);
    CHECK(secondary_guide_mode("on", "x") == 1);
    CHECK(secondary_guide_mode("off", "x") == 0);
    CHECK_THROWS_WITH_AS(secondary_guide_mode("yes", "--secondary-guide"),
                         doctest::Contains("--secondary-guide: 'yes'"), Error);
}
