// `tandem bench grad`: wall time of one optimization iteration (primal render, loss, PRB adjoint,
// Adam step) at several resolutions, split into primal, adjoint and other (loss, optimizer,
// transfers and host work). Primal and adjoint are device times (OpenCL events).
#pragma once

#include "runtime/tuning.h"

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace tandem {

struct GradBenchOptions {
    std::string scene = TANDEM_BENCH_SCENE_DIR "/cbox-wall.xml";
    std::string param = "wall.reflectance";
    std::vector<int> sizes{64, 128, 256, 512};
    int spp = 4; ///< primal and adjoint
    int iterations = 5;
    std::string device;
    Tuning tuning; ///< the switches, as the entry point read them (runtime/tuning.h)
    bool progress = false;
};

struct GradBenchRow {
    int size = 0;
    double iteration = 0, primal = 0, adjoint = 0, other = 0; ///< mean seconds per iteration
};

struct GradBenchResult {
    std::string scene, param, device;
    int spp = 0, iterations = 0;
    std::vector<GradBenchRow> rows;
    nlohmann::json to_json() const;
    std::string to_table() const;
};

GradBenchResult run_grad_bench(const GradBenchOptions& options);

} // namespace tandem
