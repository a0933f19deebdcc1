// Stratified pixel positions (kernels/shared/pixel_sample.h): every sample alone is uniform over
// its pixel, and every four consecutive samples of a pixel take its four quadrants. The kernels
// place their camera rays with these functions (path_camera_ray, render_pass's packets,
// wf_generate), and tests/core/render compares those three paths bit for bit.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "shared/pixel_sample.h"

using namespace tandem;

namespace {

/// Sample `sample` of pixel `pixel` under `seed`, as the kernels place it: (x, y) in [0, 1]².
std::array<float, 2> position(std::uint32_t seed, std::uint32_t pixel, std::uint32_t sample) {
    const std::uint32_t q = gpu::pixel_quadrant(sample, gpu::pixel_quadrant_offset(seed, pixel));
    return {gpu::pixel_stratified(gpu::rng_uniform(seed, pixel, sample, 0u), q & 1u),
            gpu::pixel_stratified(gpu::rng_uniform(seed, pixel, sample, 1u), q >> 1u)};
}

/// Pearson's chi-square of `counts` against equal expected counts.
double chi_square(const std::vector<int>& counts) {
    double n = 0.0;
    for (int c : counts)
        n += c;
    const double expected = n / (double)counts.size();
    double x2 = 0.0;
    for (int c : counts)
        x2 += (c - expected) * (c - expected) / expected;
    return x2;
}

/// The chi-square bound used below: the mean plus 5 standard deviations (df degrees of freedom).
double chi_square_bound(int df) {
    return df + 5.0 * std::sqrt(2.0 * df);
}

} // namespace

TEST_CASE("pixel positions: every four consecutive samples of a pixel take its four quadrants") {
    for (std::uint32_t seed : {0u, 7u, 0xffffffffu})
        for (std::uint32_t pixel = 0; pixel < 4096; ++pixel)
            for (std::uint32_t k0 : {0u, 1u, 6u, 4096u, 0xfffffffcu}) {
                const std::uint32_t offset = gpu::pixel_quadrant_offset(seed, pixel);
                REQUIRE(offset < 4u);
                unsigned seen = 0u;
                for (std::uint32_t j = 0; j < 4u; ++j) {
                    const std::array<float, 2> p = position(seed, pixel, k0 + j);
                    const unsigned q = (p[0] >= 0.5f ? 1u : 0u) | (p[1] >= 0.5f ? 2u : 0u);
                    CHECK(q == gpu::pixel_quadrant(k0 + j, offset));
                    seen |= 1u << q;
                }
                CHECK(seen == 15u);
            }
}

TEST_CASE("pixel positions: each sample alone is uniform over its pixel") {
    // For a fixed sample index, positions over many pixels: an 8 x 8 histogram (the quadrant
    // comes from the per-pixel offset, the place inside it from the sample's own numbers).
    const std::uint32_t pixels = 1u << 16;
    for (std::uint32_t sample : {0u, 1u, 3u, 13u}) {
        CAPTURE(sample);
        std::vector<int> bins(64, 0), offsets(4, 0);
        for (std::uint32_t pixel = 0; pixel < pixels; ++pixel) {
            const std::array<float, 2> p = position(3u, pixel, sample);
            REQUIRE(p[0] >= 0.0f);
            REQUIRE(p[0] <= 1.0f);
            REQUIRE(p[1] >= 0.0f);
            REQUIRE(p[1] <= 1.0f);
            const int bx = std::min(7, (int)(p[0] * 8.0f)), by = std::min(7, (int)(p[1] * 8.0f));
            ++bins[by * 8 + bx];
            ++offsets[gpu::pixel_quadrant_offset(3u, pixel)];
        }
        CHECK(chi_square(bins) < chi_square_bound(63));
        CHECK(chi_square(offsets) < chi_square_bound(3));
    }
}

TEST_CASE("pixel positions: four samples measure a pixel's half exactly, one sample does not") {
    // The fraction of samples left of the pixel's centre: 1/2 for every four consecutive samples
    // (stratified), while a single sample's indicator has variance 1/4 (it is uniform).
    double single_sum = 0.0, single_sq = 0.0;
    const int pixels = 20000;
    for (int pixel = 0; pixel < pixels; ++pixel) {
        int left = 0;
        for (std::uint32_t k = 0; k < 4u; ++k)
            left += position(5u, (std::uint32_t)pixel, k)[0] < 0.5f;
        CHECK(left == 2);
        const double one = position(5u, (std::uint32_t)pixel, 0u)[0] < 0.5f ? 1.0 : 0.0;
        single_sum += one;
        single_sq += one * one;
    }
    const double mean = single_sum / pixels, var = single_sq / pixels - mean * mean;
    CHECK(mean == doctest::Approx(0.5).epsilon(0.02));
    CHECK(var == doctest::Approx(0.25).epsilon(0.02));
}

TEST_CASE("pixel positions: the edges of the random numbers' range stay in their half") {
    const float u_max = 1.0f - 0x1p-24f; // the largest value rng_uniform returns
    CHECK(gpu::pixel_stratified(0.0f, 0u) == 0.0f);
    CHECK(gpu::pixel_stratified(u_max, 0u) == 0.5f - 0x1p-25f);
    CHECK(gpu::pixel_stratified(0.0f, 1u) == 0.5f);
    CHECK(gpu::pixel_stratified(u_max, 1u) == 1.0f); // 1 + u_max rounds to 2: the pixel's edge
}
