// The eight-lane hash (kernels/shared/rng.h): lane k of rng_uniform8 is rng_uniform of dimension
// dim0 + k, and lane k of rng_uniform8_samples that of sample b0 + k, bit for bit, on the host and
// on the device (whose compiler turns them into SIMD code on a CPU: kernels/path/random.h reads a
// path vertex's random numbers from rng_uniform8 there, and render_pass its camera rays' from
// rng_uniform8_samples).
#include <doctest/doctest.h>

#include <cstdint>
#include <cstring>
#include <random>
#include <vector>

#include "probes/probes.h"
#include "runtime/launch.h"
#include "shared/rng.h"
#include "support.h"

using namespace tandem;

namespace {

std::uint32_t bits(float x) {
    std::uint32_t b;
    std::memcpy(&b, &x, sizeof b);
    return b;
}

/// Keys (seed, a, b, dim0), four words each: random ones, and the edges of the words' range
/// (dimensions that wrap around 2^32 within the eight lanes among them).
std::vector<std::uint32_t> keys() {
    std::vector<std::uint32_t> k;
    std::mt19937 rng(11);
    for (int i = 0; i < 4096; ++i)
        for (int j = 0; j < 4; ++j)
            k.push_back(rng());
    const std::uint32_t edge[] = {0u,          1u,          2u,          7u,
                                  0x7fffffffu, 0x80000000u, 0xfffffff9u, 0xffffffffu};
    for (std::uint32_t a : edge)
        for (std::uint32_t d : edge)
            k.insert(k.end(), {a, d, a ^ d, d});
    return k;
}

/// rng_uniform of lane `lane` of rng_uniform8 (samples = false) or rng_uniform8_samples (true)
/// for key (seed, a, b, d).
float one_lane(const std::uint32_t* key, std::uint32_t lane, bool samples) {
    return samples ? gpu::rng_uniform(key[0], key[1], key[2] + lane, key[3])
                   : gpu::rng_uniform(key[0], key[1], key[2], key[3] + lane);
}

} // namespace

TEST_CASE(
    "rng_uniform8 and rng_uniform8_samples: lane k is rng_uniform of dimension or sample + k") {
    const std::vector<std::uint32_t> k = keys();
    for (const bool samples : {false, true}) {
        CAPTURE(samples);
        std::size_t differ = 0;
        for (std::size_t i = 0; i < k.size(); i += 4) {
            const gpu::float8 v =
                samples ? gpu::rng_uniform8_samples(k[i], k[i + 1], k[i + 2], k[i + 3])
                        : gpu::rng_uniform8(k[i], k[i + 1], k[i + 2], k[i + 3]);
            for (std::uint32_t lane = 0; lane < 8; ++lane) {
                const float one = one_lane(&k[i], lane, samples);
                if (bits((&v.s0)[lane]) != bits(one) && differ++ < 5)
                    MESSAGE("key " << i / 4 << ", lane " << lane << ": " << (&v.s0)[lane]
                                   << " against " << one);
            }
        }
        CHECK(differ == 0);
    }
}

TEST_SUITE("device") {
    TEST_CASE("rng_uniform8 and rng_uniform8_samples: the device computes rng_uniform's bits") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const std::vector<std::uint32_t> k = keys();
        const auto n = unsigned(k.size() / 4);
        const Program program =
            Program::build(*ctx, probe_library(), "probes/math_probe.cl", "");
        Kernel probe(program, "rng_probe");
        Buffer<std::uint32_t> key(*ctx, "keys", k);
        Buffer<float> out(*ctx, "out", 16 * std::size_t(n));
        probe.launch(*ctx, "rng probe", n, key, out, n);
        const std::vector<float> device = out.download();
        std::size_t differ = 0;
        for (unsigned i = 0; i < n; ++i)
            for (std::uint32_t lane = 0; lane < 16; ++lane) {
                const float host = one_lane(&k[4 * i], lane % 8, lane >= 8);
                if (bits(host) != bits(device[16 * i + lane]) && differ++ < 5)
                    MESSAGE("key " << i << ", " << (lane >= 8 ? "samples" : "dimensions")
                                   << ", lane " << lane % 8 << ": host " << host << ", device "
                                   << device[16 * i + lane]);
            }
        CHECK(differ == 0);
    }
}
