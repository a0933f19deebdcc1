// `tandem bench trace`: rays per second of the device traversal against Embree on the same rays.
#pragma once

#include "runtime/tuning.h"

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace tandem {

struct TraceBenchOptions {
    std::string mesh;            ///< mesh file (OBJ or PLY)
    std::size_t rays = 1 << 20;  ///< rays per ray set
    std::string device;          ///< device spec, see select_device()
    Tuning tuning; ///< the switches, as the entry point read them (runtime/tuning.h)
    int threads = 0;             ///< Embree host threads; 0 = all hardware threads
    int repeats = 5;             ///< timed repetitions; the best is reported
    int bvh_width = 0;           ///< headline device layout: 2, 4, 8, or 0 = the device's preferred
    bool progress = false;       ///< print phases to stderr
};

/// One timed variant: a device BVH layout, or an Embree entry point.
struct TraceTiming {
    std::string name;    ///< "bvh2", "bvh4", "bvh4_tri4", "bvh8", "bvh8_tri4", "rtcIntersect1", ...
    double mrays_s = 0;  ///< best of the repeats, millions of rays per second
};

/// One ray set. Device rates count kernel (event) time only; Embree rates count wall time of
/// the whole batch on the host threads.
struct TraceBenchRow {
    std::string name;           ///< "coherent", "incoherent" or "shadow"
    std::string query;          ///< "closest" or "any"
    double tandem_mrays_s = 0;  ///< the headline layout
    double embree_mrays_s = 0;  ///< Embree's fastest entry point
    double ratio = 0;           ///< tandem / embree
    std::string embree_mode;    ///< that fastest entry point
    std::vector<TraceTiming> layouts, embree_modes; ///< every variant, side by side
    double upload_s = 0;        ///< ray upload time (not counted in the rates)
    double download_s = 0;      ///< result download time (not counted)
    std::size_t mismatches = 0; ///< rays whose hit/miss differs from Embree (sanity check)
    /// rays on which some layout's result differs from the headline layout's in any bit (every
    /// layout must report the same hits: closest, then lowest primitive id)
    std::size_t layout_mismatches = 0;
};

struct TraceBenchResult {
    std::string mesh, device;
    std::size_t triangles = 0, rays = 0;
    int bvh_width = 0, embree_threads = 0;
    /// the headline layout: "bvh2", "bvh4", "bvh4_tri4", "bvh8", "bvh8_tri4" or "bvh8_tri4_pf"
    /// (the eight-wide tree of blocks with BVH_PREFETCH)
    std::string layout;
    /// Whether the headline layout is traced with BVH_PREFETCH (prefers_prefetch, core/render/policy.h,
    /// where an eight-wide tree of blocks is the headline); either way "bvh8_tri4_pf" is timed
    /// with it and "bvh8_tri4" without. Prefetches are issued only where the kernel compiler is
    /// Clang for x86 with AVX.
    bool prefetch = false;
    double bvh_build_s = 0, bvh_upload_s = 0;
    std::vector<std::pair<std::string, std::size_t>> bvh_nodes; ///< (layout, node count)
    std::vector<TraceBenchRow> rows;

    nlohmann::json to_json() const;
    std::string to_table() const;
};

TraceBenchResult run_trace_bench(const TraceBenchOptions& options);

} // namespace tandem
