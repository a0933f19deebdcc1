// The order in which an optimization visits its views: shuffled epochs, derived from the run's
// seed alone, so that a resumed run (or another process) takes the same batches.
//
// The views form an endless sequence of epochs; each epoch is a permutation of all of them,
// shuffled (Fisher-Yates) by the stream Stream::view_order of (seed, epoch). Iteration n takes
// positions [n B, (n + 1) B) of the sequence. Where B does not divide the number of views, a batch
// straddles two epochs; the views it already took from the first are then moved, in their order,
// to the end of the second's permutation, so that no batch holds a view twice and every epoch is
// still a permutation. A view at position p is in epoch p / N, so it has been visited exactly
// p / N times before: its control variate's iteration. With B = N (every view every
// iteration), the epochs are not shuffled: each batch is the views in their order.
#pragma once

#include <cstdint>
#include <vector>

namespace tandem {

class ViewSchedule {
public:
    /// One view of a batch: its index among the views, and how often it was visited before.
    struct Visit {
        unsigned view = 0, visit = 0;
    };

    /// `views` views (>= 1), `batch` of them per iteration (1 <= batch <= views; throws Error
    /// otherwise), shuffled with `seed`.
    ViewSchedule(unsigned views, unsigned batch, std::uint32_t seed);

    unsigned views() const { return m_views; }
    unsigned batch() const { return m_batch; }
    /// The batch of iteration `iteration`, in the order of the sequence. Any iteration, in any
    /// order: the epochs are derived again from the first when one before the cached one is asked.
    std::vector<Visit> at(unsigned iteration);
    /// How often view `view` is visited in iterations [0, iterations): its control variate's
    /// iteration after them.
    unsigned visits(unsigned view, unsigned iterations);

private:
    /// Makes m_epoch the permutation of epoch `e`.
    void seek(std::uint64_t e);

    unsigned m_views, m_batch;
    std::uint32_t m_seed;
    std::uint64_t m_epoch_index = 0;
    std::vector<unsigned> m_epoch; ///< the permutation of epoch m_epoch_index
};

} // namespace tandem
