// The processes an optimization runs on, and the few exchanges between them that keep every
// process's parameters the same bits as one process's would be.
//
// Each process (an MPI rank) owns the views v with v mod size == rank: it renders and
// back-propagates them when a batch holds them, and keeps their control variate and reservoirs.
// Everything a step needs from the views of other processes is exchanged exactly:
//   - the fixed-point gradient words: integer sums (fixed_merge: exact in any grouping, so the
//     total is the one accumulator's of a single process, wrap counts included);
//   - values that one process computed for its own views (the chunk sums of |delta| that choose
//     the gradient scale, each view's loss and mean control weight): every process holds its own
//     and zero bits for the others', and a bitwise OR gives every process all of them, bit for
//     bit, to be combined in the batch's order as one process combines them;
//   - counters (guards): integer sums.
// The MPI implementation is the command line's (cli/mpi_job.h), so that the core and the Python
// module do not depend on MPI; OneProcess is the trivial one.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

namespace tandem {

class Ranks {
public:
    virtual ~Ranks() = default;
    virtual unsigned rank() const = 0;
    virtual unsigned size() const = 0;
    /// The device this process renders on, for the log ("rank R of N: DEVICE"); empty: unknown.
    virtual std::string describe() const { return {}; }

    /// words (GRAD_WORDS per element: lo, hi, wraps) <- the exact sum of every process's words
    /// (fixed_merge, element-wise). Collective.
    virtual void sum_fixed(std::vector<std::uint32_t>& words) = 0;
    /// words <- the bitwise OR of every process's words. Collective.
    virtual void or_bits(std::vector<std::uint32_t>& words) = 0;
    /// The sum of every process's `value`. Collective.
    virtual std::uint64_t sum(std::uint64_t value) = 0;
    /// Rank `from`'s `bytes` arrive in rank 0's `bytes` (of the same size; other ranks' are left
    /// alone). Collective: every rank calls it with the same `from`.
    virtual void to_root(unsigned from, std::string& bytes) = 0;

    /// What the exchanges cost this process so far, measured where timing is on: the wall time
    /// spent waiting for the other processes to arrive (a barrier before each exchange: the
    /// imbalance of their work), the time of the exchanges themselves, and their bytes.
    struct Costs {
        double wait_seconds = 0.0, exchange_seconds = 0.0;
        std::uint64_t bytes = 0;
    };
    virtual void set_timing(bool) {}
    virtual Costs costs() const { return {}; }

    bool root() const { return rank() == 0; }
    /// Whether every process passed the same `value` (a fingerprint: the iteration a resume
    /// starts at and the digests of its inputs, a device's name). Collective. Two ranks agree
    /// exactly when their values do; more may, with values that differ, only where the sums
    /// collide mod 2^64.
    bool agree(std::uint64_t value) { return sum(value) == value * size(); }
    /// Whether this process renders view `view` (and keeps its state).
    bool owns(unsigned view) const { return view % size() == rank(); }

    /// values <- every process's values where each held its own and zeros elsewhere (or_bits
    /// on their bits): exact for any value, NaN included.
    template <class T> void gather_values(std::vector<T>& values) {
        static_assert(std::is_trivially_copyable<T>::value && sizeof(T) % 4 == 0,
                      "gather_values takes 32- or 64-bit values");
        if (size() == 1 || values.empty()) return;
        std::vector<std::uint32_t> words(values.size() * sizeof(T) / 4);
        std::memcpy(words.data(), values.data(), words.size() * 4);
        or_bits(words);
        std::memcpy(values.data(), words.data(), words.size() * 4);
    }
};

/// One process: it owns every view, and the exchanges change nothing.
class OneProcess final : public Ranks {
public:
    unsigned rank() const override { return 0; }
    unsigned size() const override { return 1; }
    void sum_fixed(std::vector<std::uint32_t>&) override {}
    void or_bits(std::vector<std::uint32_t>&) override {}
    std::uint64_t sum(std::uint64_t value) override { return value; }
    void to_root(unsigned, std::string&) override {}
};

} // namespace tandem
