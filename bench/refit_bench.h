// `tandem bench refit`: a BVH rebuilt (Embree) against the same tree refit (core/bvh/bvh_refit.h)
// after a shape step moved every vertex, by mesh size: the time of each, and the SAH cost the refit
// tree pays for keeping its old topology (what tracing through it costs more).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace tandem {

struct RefitBenchOptions {
    std::vector<unsigned> grids{32, 64, 128, 256, 512, 1024}; ///< height fields of n x n quads
    int repeats = 5;      ///< timed repetitions; the best is kept
    /// The step: every vertex moved by this fraction of the grid's extent along a smooth field
    /// (a shape step of an optimization: neighbours move together).
    float step = 0.01f;
    int steps = 10; ///< steps taken before the SAH cost is compared (a refit tree drifts)
};

struct RefitBenchRow {
    std::size_t triangles = 0;
    std::string layout;       ///< "bvh2" or "bvh8_tri4"
    double build_ms = 0, refit_ms = 0;
    double sah_one = 0;       ///< SAH cost of the tree refit after one step, over a new build's
    double sah_many = 0;      ///< the same after `steps` steps
};

struct RefitBenchResult {
    unsigned threads = 0; ///< Embree's build threads (all hardware threads)
    RefitBenchOptions options;
    std::vector<RefitBenchRow> rows;
    std::string to_table() const;
    nlohmann::json to_json() const;
};

RefitBenchResult run_refit_bench(const RefitBenchOptions& options);

} // namespace tandem
