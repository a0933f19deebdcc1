// The random streams of a run: every seed a pass is launched with is derived here, from the
// run's seed, the iteration and what the stream is for. Two streams of different purposes are
// independent; the same (seed, iteration, purpose) always gives the same seed, so a resumed run,
// the CLI and the Python module draw the same samples.
#pragma once

#include <cstdint>

namespace tandem {

/// What a stream is for. The numbering of the iteration streams is part of every recorded output
/// (docs/method.md): append new purposes, never renumber.
enum class Stream : std::uint32_t {
    primal = 0,               ///< the primal image(s) of an iteration
    adjoint = 1,              ///< the adjoint (PRB replay) of an iteration
    restir = 2,               ///< the adjoint chain's resampling pass
    restir_burn_in_paths = 3, ///< the camera paths of its burn-in pass b (iteration b)
    restir_burn_in = 4,       ///< the resampling of its burn-in pass b
    restir_primal = 5,        ///< the primal chain's resampling pass
    restir_primal_burn_in_paths = 6,
    restir_primal_burn_in = 7,
    view_order = 8, ///< the shuffle of the views' epoch e (the "iteration" is e)
    view = 9,       ///< a sensor's own streams (view_seed; the "iteration" is the sensor)
    /// The target render of `tandem optimize` (the iteration is not used: one render per run).
    target = 0x100,
    /// The every-K re-renders that image_error measures (the iteration is not used: they all
    /// share one stream, so two milestones compare parameters, not noise).
    evaluation = 0x101,
};

/// The seed of stream `purpose` of a run seeded with `seed` at iteration `iteration`: a hash of
/// the three (a bijection of each for fixed others).
std::uint32_t stream_seed(std::uint32_t seed, std::uint32_t iteration, Stream purpose);

/// The seed of sensor `sensor`'s passes drawn from stream seed `stream`: the stream's own for
/// sensor 0 (a scene with one sensor draws what it always drew), else an independent one.
inline std::uint32_t view_seed(std::uint32_t stream, unsigned sensor) {
    return sensor == 0 ? stream : stream_seed(stream, sensor, Stream::view);
}

/// Shorthands of stream_seed, as the Python module and the tests name them.
inline std::uint32_t primal_seed(std::uint32_t seed, std::uint32_t iteration) {
    return stream_seed(seed, iteration, Stream::primal);
}
inline std::uint32_t adjoint_seed(std::uint32_t seed, std::uint32_t iteration) {
    return stream_seed(seed, iteration, Stream::adjoint);
}
inline std::uint32_t restir_seed(std::uint32_t seed, std::uint32_t iteration) {
    return stream_seed(seed, iteration, Stream::restir);
}
inline std::uint32_t restir_primal_seed(std::uint32_t seed, std::uint32_t iteration) {
    return stream_seed(seed, iteration, Stream::restir_primal);
}

} // namespace tandem
