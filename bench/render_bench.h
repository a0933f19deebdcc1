// `tandem bench render`: path-tracer throughput (samples/s) and error against time (RMSE of
// renders at growing spp against a high-spp reference, and its log-log slope).
#pragma once

#include "runtime/tuning.h"

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace tandem {

struct RenderBenchOptions {
    std::string scene;                    ///< Mitsuba XML scene
    std::string device;                   ///< device spec, see select_device()
    Tuning tuning; ///< the switches, as the entry point read them (runtime/tuning.h)
    std::vector<int> throughput_sizes{256, 512}; ///< square resolutions of the throughput runs
    int throughput_spp = 16;              ///< spp of the throughput runs
    int size = 128;                       ///< square resolution of the convergence runs
    int reference_spp = 1024;             ///< spp of the reference image
    int max_spp = 0;                      ///< largest convergence spp; 0 = reference_spp / 16
    int repeats = 4;                      ///< independent renders per convergence spp
    int math_repeats = 5; ///< interleaved renders per variant of the deterministic-math cost
    bool progress = false;                ///< print phases to stderr
};

/// One throughput render (after an untimed warm-up render on the same DeviceScene).
struct RenderThroughput {
    int width = 0, height = 0, spp = 0;
    double seconds = 0;            ///< wall time of the render passes and the download
    double kernel_seconds = 0;     ///< device time of the render passes (OpenCL events)
    double samples_per_second = 0; ///< width * height * spp / seconds
    double kernel_samples_per_second = 0; ///< width * height * spp / kernel_seconds
};

/// One convergence point: `repeats` renders at `spp`, each with its own seed.
struct RenderConvergence {
    int spp = 0;
    double seconds = 0;        ///< best (least) wall time of the repeats
    double kernel_seconds = 0; ///< best (least) device time of the repeats
    double rmse = 0;           ///< sqrt of the MSE against the reference, averaged over repeats
    double rel_mse = 0;        ///< mean of (x - ref)^2 / (ref^2 + 0.01), averaged over repeats
};

struct RenderBenchResult {
    std::string scene, device;
    int size = 0, reference_spp = 0, repeats = 0;
    double reference_seconds = 0;
    std::uint64_t nan_guards = 0; ///< over every render of the benchmark
    std::vector<RenderThroughput> throughput;
    std::vector<RenderConvergence> convergence;
    /// What the deterministic transcendentals (kernels/shared/det_math.h) cost: the best kernel
    /// time of throughput_spp renders at `size`, with them (DET_MATH=1, what Tandem builds) and
    /// with the implementation's built-ins (DET_MATH=0), interleaved; cost = det / builtin - 1.
    double det_math_seconds = 0, builtin_math_seconds = 0, det_math_cost = 0;
    double slope = 0;     ///< least-squares slope of log(rmse) against log(seconds)
    double slope_spp = 0; ///< the same against log(spp); -0.5 in expectation
    double total_seconds = 0;

    nlohmann::json to_json() const;
    std::string to_table() const;
    /// The convergence table as CSV: spp,seconds,kernel_seconds,rmse,rel_mse.
    std::string convergence_csv() const;
};

RenderBenchResult run_render_bench(const RenderBenchOptions& options);

} // namespace tandem
