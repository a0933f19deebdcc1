// `tandem optimize`: gradient descent on scene parameters against a target image, with metrics,
// periodic images, checkpoints that resume bit-identically, and a convergence plot.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "core/inverse/optimize_config.h"
#include "core/inverse/ranks.h"
#include "runtime/context.h"
#include "runtime/kernel_source.h"

namespace tandem {

struct OptimizeOptions {
    std::string out_dir = "optimize-out";
    /// Continue from out_dir/checkpoint.bin (or, when it is damaged, checkpoint.prev.bin); without
    /// one (a run killed before its first checkpoint), start from iteration 0.
    bool resume = false;
    /// With resume: continue even when an input changed since the checkpoint (the first change
    /// is said on stderr, and metrics.csv marks the rows from then on: inputs_changed).
    bool force = false;
    int until = 0; ///< > 0: stop after this iteration (as if interrupted)
    std::string device;
    bool stage_timing = false; ///< measure device time per stage (summary *_seconds)
    /// Called after every iteration with (iteration, iterations, loss).
    std::function<void(int, int, float)> progress;
    /// The processes the views are spread over (an MPI job: cli/mpi_job.h); null: this one.
    /// Rank 0 writes the folder; every rank takes the same steps on the same bits.
    Ranks* ranks = nullptr;
};

struct OptimizeSummary {
    int iterations_done = 0;
    float final_loss = 0.0f;
    double param_error = -1.0; ///< last measured; -1 without a reference scene
    double image_error = -1.0; ///< last measured
    double alpha_mean = -1.0;  ///< last iteration's mean control weight; -1 without a CV
    std::string cv_plan;       ///< the scheduler's choice and why
    std::string cv_variance;   ///< the control weight's variance estimate (config cv_variance)
    double seconds = 0.0;
    /// Summed over iterations, with OptimizeOptions::stage_timing (else 0); restir_seconds are
    /// the resampling passes that ran on their own (burn-in, and a wavefront adjoint's): a pass
    /// fused into the kernel of the paths that read it (docs/restir.md, "One pass fewer")
    /// counts in primal_seconds or adjoint_seconds.
    double primal_seconds = 0.0, adjoint_seconds = 0.0, restir_seconds = 0.0, other_seconds = 0.0;
    /// Which ReSTIR chains ran: "none", "adjoint", "primal" or "primal+adjoint".
    std::string restir = "none";
    /// Non-finite samples, saturated gradient contributions and wrapped gradient sums dropped or
    /// clamped over the run (resumed runs included), in the iterations and the every-K re-renders.
    std::uint64_t guards = 0;
    /// Checkpoints written by this run, and the wall time they took (the state's download, its
    /// checksums, the write, its flush to the disk and the renames): outside `seconds`.
    int checkpoints = 0;
    double checkpoint_seconds = 0.0;
    /// Resumed with OptimizeOptions::force over changed inputs, in this run or an earlier part.
    bool inputs_changed = false;
    /// The processes of the run (an MPI job: OptimizeOptions::ranks), and with stage_timing what
    /// rank 0's exchanges with the others cost (Ranks::Costs: waiting for them, the exchanges).
    unsigned ranks = 1;
    Ranks::Costs exchanges;
};

/// Runs the optimization of `config`, writing into options.out_dir:
///   metrics.csv       iteration, seconds, loss, param_error, image_error, alpha_mean (blank when
///                     not measured), inputs_changed (1 from a resume forced over changed
///                     inputs on); rewritten atomically after every iteration. `seconds` is
///                     the wall time of the iterations themselves (render, loss, adjoint, step,
///                     and the values they read back for the metrics), without the every-K
///                     measurements (re-renders, state downloads) and output writes.
///                     Row i: the loss of iteration i's render (the parameters before its
///                     step); param_error and image_error of the parameters after it
///   alpha_NNNN.exr, variance_NNNN.exr  every K iterations with a control variate: the control
///                     weight and the variance estimate of the CV image, Var[C_n] (eq. 10),
///                     per element
///   target.exr        the target image
///   iter_NNNN.exr     every K iterations: the re-render that image_error measures
///   params.json       final values of the optimized parameters (textures: file names)
///   <param>.exr       final textures
///   convergence.png   loss, param_error and image_error against iteration
///   checkpoint.bin    every K iterations: everything needed to resume bit-identically, in
///                     checksummed sections, with the run's inputs (core/inverse/checkpoint.h)
///   checkpoint.prev.bin  the checkpoint before it, which --resume falls back to when the
///                     newest is damaged
///   .tandem.lock      the lock that keeps a second writer out while the run lasts
///                     (core/io/folder_lock.h)
OptimizeSummary run_optimization(Context& ctx, const KernelLibrary& lib,
                                 const OptimizeConfig& config, const OptimizeOptions& options);

/// The summary as JSON text (`tandem optimize --json`, Python's tandem.optimize): iterations,
/// loss, param_error, image_error, seconds, the *_seconds of the stages, alpha_mean, guards,
/// cv_plan, cv_variance, restir, checkpoints, checkpoint_seconds, inputs_changed and out
/// (`out_dir`).
std::string optimize_summary_json(const OptimizeSummary& summary, const std::string& out_dir);

} // namespace tandem
