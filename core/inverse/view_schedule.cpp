// The order of the views: shuffled epochs.
#include "core/inverse/view_schedule.h"

#include <algorithm>
#include <numeric>
#include <string>

#include "core/inverse/streams.h"
#include "runtime/error.h"

namespace tandem {

namespace {

/// Epoch e's permutation of `n` views before any straddle fix: Fisher-Yates, the swap partner of
/// position i (from the end) drawn as floor(u (i + 1) / 2^32) for a 32-bit hash u of (seed, e, i)
/// (a bias below (i + 1) / 2^32, nothing for a handful of views).
std::vector<unsigned> shuffled(unsigned n, std::uint32_t seed, std::uint64_t e) {
    std::vector<unsigned> p(n);
    std::iota(p.begin(), p.end(), 0u);
    const std::uint32_t epoch_seed = stream_seed(seed, static_cast<std::uint32_t>(e), Stream::view_order);
    for (unsigned i = n; i-- > 1;) {
        const std::uint32_t u = stream_seed(epoch_seed, i, Stream::view_order);
        const auto j = static_cast<unsigned>((std::uint64_t(u) * (i + 1)) >> 32);
        std::swap(p[i], p[j]);
    }
    return p;
}

} // namespace

ViewSchedule::ViewSchedule(unsigned views, unsigned batch, std::uint32_t seed)
    : m_views(views), m_batch(batch), m_seed(seed) {
    if (views == 0) throw Error("views: none to optimize against");
    if (batch == 0 || batch > views)
        throw Error("batch: " + std::to_string(batch) + " views per iteration out of " +
                    std::to_string(views) + " (1 to " + std::to_string(views) + ")");
    m_epoch_index = 0;
    m_epoch = batch == views ? shuffled(views, 0, 0) : shuffled(views, seed, 0);
    if (batch == views) std::iota(m_epoch.begin(), m_epoch.end(), 0u);
}

void ViewSchedule::seek(std::uint64_t e) {
    if (e < m_epoch_index) { // derived again from the first
        m_epoch_index = 0;
        m_epoch = shuffled(m_views, m_seed, 0);
    }
    while (m_epoch_index < e) {
        const std::uint64_t next = m_epoch_index + 1;
        std::vector<unsigned> p = shuffled(m_views, m_seed, next);
        // the batch that straddles the boundary took the tail of this epoch from `start` on
        const std::uint64_t boundary = next * m_views;
        const std::uint64_t start = boundary / m_batch * m_batch; // its first position
        if (start < boundary) {
            const auto first = static_cast<std::size_t>(start - m_epoch_index * m_views);
            const std::vector<unsigned> taken(m_epoch.begin() + std::ptrdiff_t(first), m_epoch.end());
            std::stable_partition(p.begin(), p.end(), [&](unsigned v) {
                return std::find(taken.begin(), taken.end(), v) == taken.end();
            });
        }
        m_epoch = std::move(p);
        m_epoch_index = next;
    }
}

std::vector<ViewSchedule::Visit> ViewSchedule::at(unsigned iteration) {
    std::vector<Visit> out;
    if (m_batch == m_views) { // every view, in order, every iteration
        for (unsigned v = 0; v < m_views; ++v) out.push_back({v, iteration});
        return out;
    }
    for (unsigned k = 0; k < m_batch; ++k) {
        const std::uint64_t p = std::uint64_t(iteration) * m_batch + k;
        const std::uint64_t e = p / m_views;
        seek(e);
        out.push_back({m_epoch[static_cast<std::size_t>(p - e * m_views)], static_cast<unsigned>(e)});
    }
    return out;
}

unsigned ViewSchedule::visits(unsigned view, unsigned iterations) {
    if (m_batch == m_views) return iterations;
    // once in each epoch before position P, and once more if it comes before P in P's epoch
    const std::uint64_t p = std::uint64_t(iterations) * m_batch, e = p / m_views;
    seek(e);
    const auto begin = m_epoch.begin(), end = begin + std::ptrdiff_t(p - e * m_views);
    return static_cast<unsigned>(e) + (std::find(begin, end, view) != end ? 1u : 0u);
}

} // namespace tandem
