// The MPI job (cli/mpi_job.h).
#include "cli/mpi_job.h"

#include <algorithm>
#include <chrono>
#include <cstdlib>

#include "cli/commands.h"
#include "runtime/device.h"
#include "runtime/error.h"

#if TANDEM_MPI
#include <mpi.h>

#include "shared/fixed_point.h"
#endif

namespace tandem::cli {

std::unique_ptr<MpiJob> join_mpi_job(const Tuning& tuning) {
    if (!tuning.mpi_launched) return nullptr;
    return std::make_unique<MpiJob>();
}

std::string device_for_rank(unsigned local_rank) {
    std::vector<int> gpus;
    for (const DeviceInfo& d : list_devices())
        if (d.type == "GPU") gpus.push_back(d.index);
    if (gpus.empty()) return {};
    return std::to_string(gpus[local_rank % gpus.size()]);
}

std::string process_device(const GlobalOptions& global) {
    if (!global.device.empty() || !global.tuning.device.empty() || !global.mpi ||
        global.mpi->size() == 1)
        return global.device; // (Context::create falls back to TANDEM_DEVICE, then the default)
    return device_for_rank(global.mpi->local_rank());
}

#if TANDEM_MPI

namespace {

void check(int status, const char* what) {
    if (status == MPI_SUCCESS) return;
    char text[MPI_MAX_ERROR_STRING];
    int length = 0;
    MPI_Error_string(status, text, &length);
    throw Error(std::string("MPI: ") + what + " failed: " + std::string(text, std::size_t(length)));
}

/// The element-wise fixed_merge of GRAD_WORDS-word slots: an exact, commutative and associative
/// reduction (kernels/shared/fixed_point.h), so any reduction tree gives the one sum.
void merge_slots(void* in, void* inout, int* length, MPI_Datatype*) {
    const auto* from = static_cast<const std::uint32_t*>(in);
    auto* into = static_cast<std::uint32_t*>(inout);
    for (int i = 0; i < *length; ++i) gpu::fixed_merge(into + GRAD_WORDS * i, from + GRAD_WORDS * i);
}

MPI_Datatype slot_type() {
    static MPI_Datatype type = [] {
        MPI_Datatype t;
        check(MPI_Type_contiguous(int(GRAD_WORDS), MPI_UINT32_T, &t), "MPI_Type_contiguous");
        check(MPI_Type_commit(&t), "MPI_Type_commit");
        return t;
    }();
    return type;
}

MPI_Op merge_op() {
    static MPI_Op op = [] {
        MPI_Op o;
        check(MPI_Op_create(&merge_slots, 1, &o), "MPI_Op_create");
        return o;
    }();
    return op;
}

/// MPI counts are ints: large buffers go in pieces of at most this many elements.
constexpr std::size_t k_piece = std::size_t(1) << 30;

} // namespace

MpiJob::MpiJob() {
    int initialized = 0;
    MPI_Initialized(&initialized);
    if (!initialized) check(MPI_Init(nullptr, nullptr), "MPI_Init");
    // errors come back as codes (check() makes them an Error), not as an abort inside MPI
    MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
    int r = 0, n = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &r);
    MPI_Comm_size(MPI_COMM_WORLD, &n);
    m_rank = unsigned(r);
    m_size = unsigned(n);
    MPI_Comm node;
    check(MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, r, MPI_INFO_NULL, &node),
          "MPI_Comm_split_type");
    int local = 0;
    MPI_Comm_rank(node, &local);
    MPI_Comm_free(&node);
    m_local_rank = unsigned(local);
    char name[MPI_MAX_PROCESSOR_NAME];
    int length = 0;
    MPI_Get_processor_name(name, &length);
    m_host.assign(name, std::size_t(length));
}

MpiJob::~MpiJob() {
    int finalized = 0;
    MPI_Finalized(&finalized);
    if (!finalized) MPI_Finalize();
}

template <class F> void MpiJob::exchange(std::size_t bytes, F&& f) {
    if (!m_timing) {
        f();
        return;
    }
    using Clock = std::chrono::steady_clock;
    const auto t0 = Clock::now();
    check(MPI_Barrier(MPI_COMM_WORLD), "a barrier");
    const auto t1 = Clock::now();
    f();
    m_costs.wait_seconds += std::chrono::duration<double>(t1 - t0).count();
    m_costs.exchange_seconds += std::chrono::duration<double>(Clock::now() - t1).count();
    m_costs.bytes += bytes;
}

void MpiJob::sum_fixed(std::vector<std::uint32_t>& words) {
    if (words.size() % GRAD_WORDS != 0) throw Error("MPI: a gradient of partial slots");
    exchange(words.size() * 4, [&] {
        for (std::size_t at = 0; at < words.size(); at += GRAD_WORDS * k_piece) {
            const std::size_t slots = std::min(k_piece, (words.size() - at) / GRAD_WORDS);
            check(MPI_Allreduce(MPI_IN_PLACE, words.data() + at, int(slots), slot_type(),
                                merge_op(), MPI_COMM_WORLD),
                  "the gradient's all-reduce");
        }
    });
}

void MpiJob::or_bits(std::vector<std::uint32_t>& words) {
    exchange(words.size() * 4, [&] {
        for (std::size_t at = 0; at < words.size(); at += k_piece)
            check(MPI_Allreduce(MPI_IN_PLACE, words.data() + at,
                                int(std::min(k_piece, words.size() - at)), MPI_UINT32_T, MPI_BOR,
                                MPI_COMM_WORLD),
                  "an exchange of values");
    });
}

std::uint64_t MpiJob::sum(std::uint64_t value) {
    std::uint64_t total = 0;
    exchange(8, [&] {
        check(MPI_Allreduce(&value, &total, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD),
              "a counter's sum");
    });
    return total;
}

void MpiJob::to_root(unsigned from, std::string& bytes) {
    if (from == 0 || from >= m_size) return;
    for (std::size_t at = 0; at < bytes.size(); at += k_piece) {
        const int count = int(std::min(k_piece, bytes.size() - at));
        if (m_rank == from)
            check(MPI_Send(bytes.data() + at, count, MPI_BYTE, 0, 1, MPI_COMM_WORLD),
                  "sending a view's state");
        else if (m_rank == 0)
            check(MPI_Recv(bytes.data() + at, count, MPI_BYTE, int(from), 1, MPI_COMM_WORLD,
                           MPI_STATUS_IGNORE),
                  "receiving a view's state");
    }
}

std::vector<std::string> MpiJob::gather(const std::string& line) {
    const int length = int(line.size());
    std::vector<int> lengths(m_rank == 0 ? m_size : 0), offsets(lengths.size());
    check(MPI_Gather(&length, 1, MPI_INT, lengths.data(), 1, MPI_INT, 0, MPI_COMM_WORLD),
          "gathering lines");
    int total = 0;
    for (std::size_t i = 0; i < lengths.size(); ++i) {
        offsets[i] = total;
        total += lengths[i];
    }
    std::string all(std::size_t(total), '\0');
    check(MPI_Gatherv(line.data(), length, MPI_CHAR, all.data(), lengths.data(), offsets.data(),
                      MPI_CHAR, 0, MPI_COMM_WORLD),
          "gathering lines");
    std::vector<std::string> lines;
    for (std::size_t i = 0; i < lengths.size(); ++i)
        lines.push_back(all.substr(std::size_t(offsets[i]), std::size_t(lengths[i])));
    return lines;
}

void MpiJob::set_device(const std::string& device) {
    const std::vector<std::string> lines =
        gather("rank " + std::to_string(m_rank) + " on " + m_host + " (local rank " +
               std::to_string(m_local_rank) + "): " + device);
    m_described.clear();
    for (const std::string& l : lines) m_described += (m_described.empty() ? "" : "; ") + l;
}

void MpiJob::abort(int code) {
    MPI_Abort(MPI_COMM_WORLD, code);
    std::_Exit(code); // (MPI_Abort does not return)
}

#else // built without MPI

MpiJob::MpiJob() {
    throw Error("started by an MPI launcher, but this tandem was built without MPI "
                "(TANDEM_MPI=OFF; scripts/setup-debian.sh installs Open MPI): run it alone");
}
MpiJob::~MpiJob() = default;
void MpiJob::sum_fixed(std::vector<std::uint32_t>&) {}
void MpiJob::or_bits(std::vector<std::uint32_t>&) {}
std::uint64_t MpiJob::sum(std::uint64_t value) { return value; }
void MpiJob::to_root(unsigned, std::string&) {}
std::vector<std::string> MpiJob::gather(const std::string& line) { return {line}; }
void MpiJob::set_device(const std::string& device) { m_described = device; }
void MpiJob::abort(int code) { std::_Exit(code); }

#endif

} // namespace tandem::cli
