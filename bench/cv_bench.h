// `tandem bench cv`: the cost of the fused two-state kernel against a primal render (and of the
// two-launch CV-PSS fallback), and, on an unchanging scene, the effective sample count and the
// per-pixel bias of the recursive control variate for each variance form ("Recursive Control
// Variates for Inverse Rendering", Sec. 3.2: there the CV image should approach the mean of all
// iterations).
#pragma once

#include "runtime/tuning.h"

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace tandem {

struct CvBenchOptions {
    std::string scene = TANDEM_BENCH_SCENE_DIR "/indirect-room.xml";
    std::vector<std::string> changing{"painting.reflectance", "floor.reflectance"};
    int cost_size = 256;  ///< square resolution of the cost runs
    int cost_repeats = 5; ///< interleaved timed rounds (best kept)
    std::vector<std::pair<std::string, std::string>> defines; ///< scene defines (-D)
    int steady_size = 32;     ///< square resolution of the steady-state runs
    int steady_runs = 64;     ///< independent runs whose spread gives the variances and the bias
    int reference_spp = 4096; ///< spp of the render the bias is measured against
    std::vector<int> steady_iterations{16, 64, 256};
    std::vector<std::string> variances{"consistent", "reference"}; ///< cv_variance forms
    std::string device;
    Tuning tuning; ///< the switches, as the entry point read them (runtime/tuning.h)
    bool progress = false;
};

struct CvBenchResult {
    std::string scene, device;
    int cost_size = 0, steady_size = 0, steady_runs = 0;
    double primal_seconds = 0, fused_seconds = 0, pss_seconds = 0; ///< best device times, 1 spp
    double fused_cost_ratio = 0, pss_cost_ratio = 0;
    int reference_spp = 0;
    std::vector<int> iterations;
    /// Per-pixel bias of C_n: z = (mean over runs - reference) / its standard error, over the
    /// elements with a nonzero standard error.
    struct Bias {
        double mean_abs_z = 0; ///< E|z| = 0.80 for unbiased normal errors
        double beyond_3 = 0;   ///< fraction with |z| > 3: 0.0027 for unbiased normal errors
    };
    struct Form {
        std::string variance;              ///< "consistent" or "reference"
        std::vector<double> effective_spp; ///< Var[F] / Var[C_n], summed over pixels and channels
        std::vector<double> mean_alpha;
        std::vector<Bias> bias;
    };
    std::vector<Form> forms;
    /// The bias measure applied to the plain mean of the same samples (exactly unbiased): what
    /// the measure reads on this scene without any bias.
    std::vector<Bias> running_mean_bias;
    nlohmann::json to_json() const;
    std::string to_table() const;
};

CvBenchResult run_cv_bench(const CvBenchOptions& options);

} // namespace tandem
