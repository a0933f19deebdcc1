// `tandem bench cv`: the cost of the fused two-state kernel against a primal render (and of the
// two-launch CV-PSS fallback), and the steady-state effective sample count of the recursive
// control variate ("Recursive Control Variates for Inverse Rendering", Sec. 3.2: on an unchanging scene the CV image approaches the mean
// of all iterations).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace tandem {

struct CvBenchOptions {
    std::string scene = TANDEM_BENCH_SCENE_DIR "/indirect-room.xml";
    std::vector<std::string> changing{"painting.reflectance", "floor.reflectance"};
    int cost_size = 256;  ///< square resolution of the cost runs
    int cost_repeats = 5; ///< interleaved timed rounds (best kept)
    int steady_size = 64; ///< square resolution of the steady-state runs
    int steady_runs = 8;  ///< independent runs whose spread gives the variances
    std::vector<int> steady_iterations{16, 64, 256};
    std::string device;
    bool progress = false;
};

struct CvBenchResult {
    std::string scene, device;
    int cost_size = 0, steady_size = 0, steady_runs = 0;
    double primal_seconds = 0, fused_seconds = 0, pss_seconds = 0; ///< best device times, 1 spp
    double fused_cost_ratio = 0, pss_cost_ratio = 0;
    std::vector<int> iterations;
    std::vector<double> effective_spp; ///< Var[F] / Var[C_n], summed over pixels and channels
    std::vector<double> mean_alpha;
    nlohmann::json to_json() const;
    std::string to_table() const;
};

CvBenchResult run_cv_bench(const CvBenchOptions& options);

} // namespace tandem
