// `tandem optimize`: gradient descent on scene parameters against a target image, with metrics,
// periodic images, checkpoints that resume bit-identically, and a convergence plot.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "runtime/context.h"
#include "runtime/kernel_source.h"

namespace tandem {

/// One optimized parameter: its name (see `tandem params`), learning rate, and optionally a
/// starting value that replaces the scene's for every element (e.g. a flat grey texture).
struct OptimizedParam {
    std::string name;
    float lr = 0.01f;
    std::vector<float> init; ///< empty: the scene's value; 1 value: every element; 3: rgb per texel
};

/// The JSON config of `tandem optimize` (docs: README "Inverse rendering"). Relative paths are
/// relative to the config file.
struct OptimizeConfig {
    std::string path; ///< the config file itself
    std::string scene;
    std::vector<std::pair<std::string, std::string>> defines;
    // target: an image, or a reference scene rendered at target_spp
    std::string target_image, target_scene;
    std::vector<std::pair<std::string, std::string>> target_defines;
    int target_spp = 256;
    std::vector<OptimizedParam> params;
    std::string optimizer = "adam";
    float beta1 = 0.9f, beta2 = 0.999f, epsilon = 1e-8f;
    int iterations = 100, spp = 4, spp_grad = 4;
    std::string loss = "l1";
    std::uint32_t seed = 0;
    int checkpoint_every = 10; ///< K: checkpoint, image and image_error every K iterations
    int image_error_spp = 64;  ///< spp of the re-render that image_error measures
    std::string cv = "ps";     ///< recursive control variate: "none", "pss" or "ps" (papers/000)
};

/// Reads and validates `path`. Throws Error "PATH: ..." on malformed JSON (with the position),
/// unknown keys, wrong types and out-of-range values.
OptimizeConfig load_optimize_config(const std::string& path);

struct OptimizeOptions {
    std::string out_dir = "optimize-out";
    bool resume = false; ///< continue from out_dir/checkpoint.bin
    int until = 0;       ///< > 0: stop after this iteration (as if interrupted)
    std::string device;
    /// Called after every iteration with (iteration, iterations, loss).
    std::function<void(int, int, float)> progress;
};

struct OptimizeSummary {
    int iterations_done = 0;
    float final_loss = 0.0f;
    double param_error = -1.0; ///< last measured; -1 without a reference scene
    double image_error = -1.0; ///< last measured
    double alpha_mean = -1.0;  ///< last iteration's mean control weight; -1 without a CV
    std::string cv_plan;       ///< the scheduler's choice and why
    double seconds = 0.0;
    double primal_seconds = 0.0, adjoint_seconds = 0.0, other_seconds = 0.0; ///< summed over iterations
};

/// Runs the optimization of `config`, writing into options.out_dir:
///   metrics.csv       iteration, seconds, loss, param_error, image_error, alpha_mean (blank when
///                     not measured); rewritten atomically after every iteration. `seconds` is
///                     the wall time of the iterations themselves (render, loss, adjoint, step),
///                     without the measurements (re-renders, downloads) and output writes.
///                     Row i: the loss of iteration i's render (the parameters before its
///                     step); param_error and image_error of the parameters after it
///   alpha_NNNN.exr, variance_NNNN.exr  every K iterations with a control variate: the control
///                     weight and the variance estimate of eq. 10, per pixel and channel
///   target.exr        the target image
///   iter_NNNN.exr     every K iterations: the re-render that image_error measures
///   params.json       final values of the optimized parameters (textures: file names)
///   <param>.exr       final textures
///   convergence.png   loss, param_error and image_error against iteration
///   checkpoint.bin    every K iterations: everything needed to resume bit-identically
OptimizeSummary run_optimization(Context& ctx, const KernelLibrary& lib, const OptimizeConfig& config,
                                 const OptimizeOptions& options);

} // namespace tandem
