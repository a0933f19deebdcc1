// The MPI job a `tandem` process was launched in (mpirun, srun, ...): its ranks, the device each
// renders on, and the exact exchanges of core/inverse/ranks.h over MPI. Only the command line
// links MPI (TANDEM_MPI); a build without it refuses to run under any MPI launcher rather than run
// the whole job once per rank.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/inverse/ranks.h"
#include "runtime/tuning.h"

namespace tandem::cli {

class MpiJob final : public Ranks {
public:
    /// Joins the job (MPI_Init). Throws Error where MPI is not built in.
    MpiJob();
    ~MpiJob() override; ///< MPI_Finalize
    MpiJob(const MpiJob&) = delete;
    MpiJob& operator=(const MpiJob&) = delete;

    unsigned rank() const override { return m_rank; }
    unsigned size() const override { return m_size; }
    std::string describe() const override { return m_described; }
    void sum_fixed(std::vector<std::uint32_t>& words) override;
    void or_bits(std::vector<std::uint32_t>& words) override;
    std::uint64_t sum(std::uint64_t value) override;
    void to_root(unsigned from, std::string& bytes) override;

    void set_timing(bool on) override { m_timing = on; }
    Costs costs() const override { return m_costs; }

    /// This process's rank among those of its node (one GPU each).
    unsigned local_rank() const { return m_local_rank; }
    const std::string& host() const { return m_host; }
    /// Every rank's `line`, in rank order, at rank 0 (empty elsewhere). Collective.
    std::vector<std::string> gather(const std::string& line);
    /// Records the device this rank renders on: describe() then lists every rank's. Collective.
    void set_device(const std::string& device);
    /// Ends every rank of the job with `code` (MPI_Abort): a failure on one rank must not leave
    /// the others waiting in an exchange.
    [[noreturn]] void abort(int code);

private:
    /// Runs the exchange `f` of `bytes`, timed (after a timed barrier) where timing is on.
    template <class F> void exchange(std::size_t bytes, F&& f);

    unsigned m_rank = 0, m_size = 1, m_local_rank = 0;
    bool m_timing = false;
    Costs m_costs;
    std::string m_host, m_described;
};

/// The job of a process an MPI launcher started (Tuning::mpi_launched), else null.
std::unique_ptr<MpiJob> join_mpi_job(const Tuning& tuning);

/// The device a rank renders on where neither --device nor TANDEM_DEVICE names one: the GPU
/// local_rank modulo the node's GPUs (one per local rank), else the default device (PoCL's CPU
/// device, shared).
std::string device_for_rank(unsigned local_rank);

} // namespace tandem::cli
