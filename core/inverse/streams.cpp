// The random streams of a run.
#include "core/inverse/streams.h"

namespace tandem {

namespace {

/// A 32-bit finaliser (lowbias32, Wellons' hash prospector): a bijection with good avalanche.
std::uint32_t mix32(std::uint32_t x) {
    x ^= x >> 16;
    x *= 0x7feb352dU;
    x ^= x >> 15;
    x *= 0x846ca68bU;
    x ^= x >> 16;
    return x;
}

/// The hash of (seed, iteration, stream number).
std::uint32_t hash3(std::uint32_t seed, std::uint32_t iteration, std::uint32_t stream) {
    return mix32(mix32(mix32(seed) ^ iteration) ^ (0x9e3779b9U * (stream + 1U)));
}

} // namespace

std::uint32_t stream_seed(std::uint32_t seed, std::uint32_t iteration, Stream purpose) {
    switch (purpose) {
    // The once-per-run renders: the primal stream of a scrambled seed at an iteration no run
    // reaches, so that they share no samples with any iteration.
    case Stream::target:
        return hash3(seed ^ 0x5bd1e995u, 0xFFFFFFFFu, 0);
    case Stream::evaluation:
        return hash3(seed ^ 0x68e31da4u, 0xFFFFFFFFu, 0);
    default:
        return hash3(seed, iteration, static_cast<std::uint32_t>(purpose));
    }
}

} // namespace tandem
