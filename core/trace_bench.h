// `tandem bench trace`: rays per second of the device traversal against Embree on the same rays.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace tandem {

struct TraceBenchOptions {
    std::string mesh;            ///< mesh file (OBJ or PLY)
    std::size_t rays = 1 << 20;  ///< rays per ray set
    std::string device;          ///< device spec, see select_device()
    int threads = 0;             ///< Embree host threads; 0 = all hardware threads
    int repeats = 3;             ///< timed repetitions; the best is reported
    int bvh_width = 4;           ///< device BVH layout: 2 or 4
    bool progress = false;       ///< print phases to stderr
};

/// One ray set: device rays/s from kernel event time, Embree rays/s from wall time (best mode).
struct TraceBenchRow {
    std::string name;        ///< "coherent", "incoherent" or "shadow"
    std::string query;       ///< "closest" or "any"
    double tandem_mrays_s = 0;
    double embree_mrays_s = 0;
    double ratio = 0;        ///< tandem / embree
    std::string embree_mode; ///< the fastest Embree entry point
    double upload_s = 0;     ///< ray upload time (not counted in tandem_mrays_s)
    double download_s = 0;   ///< result download time (not counted)
    std::size_t mismatches = 0; ///< rays whose hit/miss differs from Embree (sanity check)
};

struct TraceBenchResult {
    std::string mesh, device;
    std::size_t triangles = 0, rays = 0, bvh_nodes = 0;
    int bvh_depth = 0, bvh_width = 0, embree_threads = 0;
    double bvh_build_s = 0, bvh_upload_s = 0;
    std::vector<TraceBenchRow> rows;

    nlohmann::json to_json() const;
    std::string to_table() const;
};

TraceBenchResult run_trace_bench(const TraceBenchOptions& options);

} // namespace tandem
