// Every switch of Tandem in one value: filled once, where a program starts (the CLI, the Python
// module, the test and fuzz harnesses), from the environment (tuning_from_environment) and the
// program's options, then passed down. Nothing below the entry points reads the environment: the
// Context carries its Tuning (Context::tuning), the device policy (core/render/policy.h) reads the
// render fields from there, and the runtime its own.
//
// The runtime knows nothing of rendering: the render fields are plain data here, and their
// meaning is the policy's. Unset optional fields leave the choice to the policy; every choice
// they force gives the same bits (docs/tuning.md).
#pragma once

#include <optional>
#include <string>

namespace tandem {

/// The fault hooks of runtime/fault.h: which event fails or kills the process (0 or empty: none).
struct FaultHooks {
    /// TANDEM_FAIL_ALLOCATION=N: the N-th device buffer allocation of the process (from 1) fails
    /// as on CL_MEM_OBJECT_ALLOCATION_FAILURE.
    unsigned long fail_allocation = 0;
    /// TANDEM_FAIL_WRITE=N: the N-th whole-file write of the process (from 1) fails as on a full
    /// disk, part of the file written.
    unsigned long fail_write = 0;
    /// TANDEM_KILL_AT=WHERE:N: the point `kill_point` (fault::kill_point's names) whose N-th
    /// passage `kill_count` kills the process with SIGKILL.
    std::string kill_point;
    unsigned long kill_count = 0;
};

/// The most bounces whose hits the megakernel adjoint records (its default), and the most that
/// Tuning::hit_record_bounces may ask for: a choice of the host, the kernels take any count.
constexpr unsigned k_max_hit_record_bounces = 32;
/// The most bounces Tuning::wavefront_record_bounces may ask the wavefront adjoint to record.
constexpr unsigned k_max_wavefront_record_bounces = 999999;

struct Tuning {
    // ---- Device, kernels and their cache (user-facing) ----

    /// TANDEM_DEVICE: the OpenCL device when a program names none (its index or a substring of
    /// "platform device"); empty: the first GPU, else the first device.
    std::string device;
    /// TANDEM_KERNEL_DIR: read the kernels from this directory, laid out like kernels/, instead of
    /// the copy embedded at build time (to edit kernels without a rebuild); empty: embedded.
    std::string kernel_dir;
    /// Where program binaries are cached: TANDEM_CACHE_DIR, else $XDG_CACHE_HOME/tandem, else
    /// $HOME/.cache/tandem; empty (TANDEM_NO_CACHE=1, or none of them set): no cache.
    std::string cache_dir;

    /// Started by an MPI launcher (mpirun, srun...): OMPI_COMM_WORLD_SIZE, PMIX_RANK or PMI_SIZE is
    /// set. `tandem` then joins the MPI job (cli/mpi_job.h; of its commands only `optimize` and
    /// `devices` run across several ranks); started alone, it does not initialise MPI at all.
    bool mpi_launched = false;

    // ---- PoCL (runtime/pocl_llvm.h) ----

    /// POCL_WORK_GROUP_METHOD as the user set it (PoCL reads it; Tandem chooses one only where it
    /// is unset, and names it in the programs' cache keys). Unset: Tandem's choice.
    std::optional<std::string> pocl_work_group_method;
    /// TANDEM_POCL_SLP=1: keep LLVM's SLP vectoriser on for the kernels PoclSlpOff would compile
    /// without it (the wavefront's shading stages), to measure what turning it off buys.
    bool pocl_slp = false;
    /// TANDEM_KERNEL_DEBUG=1: build the kernels with -g (line tables, for a profiler).
    bool kernel_debug = false;

    // ---- The render policy's overrides (core/render/policy.h; measurements and tests) ----

    /// TANDEM_BVH_WIDTH: the BVH layout, 2, 4 or 8; 0: the policy's.
    int bvh_width = 0;
    /// TANDEM_BVH_LEAVES: four- and eight-wide trees' leaves as BvhTri4 blocks (tri4: true) or a
    /// record per triangle (records: false); unset: the policy's.
    std::optional<bool> bvh_tri4_leaves;
    /// TANDEM_BVH_PREFETCH=0/1: the eight-wide traversal prefetches the children a ray enters;
    /// unset: the policy's.
    std::optional<bool> bvh_prefetch;
    /// TANDEM_CAMERA_PACKETS=0/1: the render pass traces camera rays as packets of eight, where
    /// the tree allows it; unset: the policy's.
    std::optional<bool> camera_packets;
    /// TANDEM_BVH_REPACK=0 keeps Embree's leaves as it built them (core/bvh/leaf_repack.h), to
    /// compare; 1 (the default) repacks them.
    bool bvh_repack = true;
    /// TANDEM_WAVEFRONT=0/1: the passes run as the wavefront (1) or the megakernels (0) wherever
    /// the wavefront covers the scene; unset: the policy's choice.
    std::optional<bool> wavefront;
    /// TANDEM_SHADOW_RECORD=0: the adjoint's replay traces its NEE shadow rays again instead of
    /// reading the primal's record of them (to measure what the record saves).
    bool shadow_record = true;
    /// TANDEM_HIT_RECORD: the most bounces whose hits the megakernel adjoint records for its
    /// replay, 0 to k_max_hit_record_bounces (deeper bounces are traced again).
    unsigned hit_record_bounces = k_max_hit_record_bounces;
    /// TANDEM_WAVEFRONT_RECORD: the most bounces the wavefront adjoint records for its replay
    /// (0: every bounce traced again); unset: the policy's.
    std::optional<unsigned> wavefront_record_bounces;

    // ---- Fault injection (tests) ----

    /// TANDEM_FAIL_ALLOCATION, TANDEM_FAIL_WRITE, TANDEM_KILL_AT.
    FaultHooks faults;
};

/// A Tuning from the process's environment: every variable of docs/tuning.md, each checked. Throws
/// Error naming the first variable with a value it does not take, and what it takes
/// ("TANDEM_BVH_WIDTH='3': expected the BVH width 2, 4 or 8"). The one place Tandem reads its
/// environment.
Tuning tuning_from_environment();

} // namespace tandem
