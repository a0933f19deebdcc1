// `tandem bench refit` (bench/refit_bench.h): build and refit timed alternately, repetition by
// repetition, so that machine noise hits both alike.
#include "bench/refit_bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

#include "core/bvh/bvh_refit.h"

namespace tandem {

namespace {

/// A height field of n x n quads over [0, 1]^2 (two triangles each), gently rolling.
TriangleMesh grid(unsigned n) {
    TriangleMesh mesh;
    mesh.source = "grid " + std::to_string(n);
    for (unsigned j = 0; j <= n; ++j)
        for (unsigned i = 0; i <= n; ++i) {
            const float x = float(i) / float(n), z = float(j) / float(n);
            mesh.positions.emplace_back(x, 0.05f * std::sin(6.0f * x) * std::cos(5.0f * z), z);
        }
    for (unsigned j = 0; j < n; ++j)
        for (unsigned i = 0; i < n; ++i) {
            const unsigned a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
            mesh.triangles.emplace_back(a, b, d);
            mesh.triangles.emplace_back(a, d, c);
        }
    return mesh;
}

/// One step: every vertex moved by `step` along a smooth field that varies with the step count.
void take_step(TriangleMesh& mesh, float step, int k) {
    for (glm::vec3& p : mesh.positions)
        p += step * glm::vec3(std::sin(7.0f * p.z + float(k)), std::cos(9.0f * p.x - float(k)),
                              std::sin(8.0f * p.x + 5.0f * p.z));
}

double ms_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

} // namespace

RefitBenchResult run_refit_bench(const RefitBenchOptions& options) {
    RefitBenchResult result;
    result.options = options;
    result.threads = std::max(1u, std::thread::hardware_concurrency());
    EmbreeDevice embree;
    for (unsigned n : options.grids)
        for (int layout : {2, 9}) { // 9: eight-wide with blocks of four
            const int width = layout & ~1;
            const LeafFormat leaves = layout % 2 ? LeafFormat::tri4 : LeafFormat::records;
            RefitBenchRow row;
            row.layout = layout == 2 ? "bvh2" : "bvh8_tri4";
            const TriangleMesh mesh = grid(n);
            row.triangles = mesh.triangle_count();
            const FlatBvh built = build_bvh(embree, mesh, width, leaves);
            TriangleMesh moved = mesh;
            take_step(moved, options.step, 0);
            row.build_ms = row.refit_ms = INFINITY;
            for (int r = 0; r < options.repeats; ++r) {
                auto t0 = std::chrono::steady_clock::now();
                const FlatBvh rebuilt = build_bvh(embree, moved, width, leaves);
                row.build_ms = std::min(row.build_ms, ms_since(t0));
                FlatBvh refit = built;
                t0 = std::chrono::steady_clock::now();
                refit_bvh(refit, moved);
                row.refit_ms = std::min(row.refit_ms, ms_since(t0));
                if (r == 0) row.sah_one = bvh_sah_cost(refit) / bvh_sah_cost(rebuilt);
            }
            FlatBvh refit = built;
            for (int k = 1; k < options.steps; ++k) take_step(moved, options.step, k);
            refit_bvh(refit, moved);
            row.sah_many = bvh_sah_cost(refit) / bvh_sah_cost(build_bvh(embree, moved, width, leaves));
            result.rows.push_back(row);
        }
    return result;
}

std::string RefitBenchResult::to_table() const {
    std::string out;
    char line[256];
    std::snprintf(line, sizeof line,
                  "BVH refit against rebuild (Embree, %u threads), a step of %g of the extent; "
                  "best of %d\n%10s %-10s %10s %10s %8s %10s %10s\n",
                  threads, options.step, options.repeats, "triangles", "layout", "build ms",
                  "refit ms", "speedup", "SAH 1", "SAH many");
    out += line;
    for (const RefitBenchRow& r : rows) {
        std::snprintf(line, sizeof line, "%10zu %-10s %10.3f %10.3f %8.2f %10.3f %10.3f\n",
                      r.triangles, r.layout.c_str(), r.build_ms, r.refit_ms,
                      r.build_ms / r.refit_ms, r.sah_one, r.sah_many);
        out += line;
    }
    std::snprintf(line, sizeof line,
                  "SAH 1, SAH many: the refit tree's SAH cost over a new build's after one step and "
                  "after %d\n",
                  options.steps);
    return out + line;
}

nlohmann::json RefitBenchResult::to_json() const {
    nlohmann::json j;
    j["threads"] = threads;
    j["step"] = options.step;
    j["steps"] = options.steps;
    j["repeats"] = options.repeats;
    for (const RefitBenchRow& r : rows)
        j["rows"].push_back({{"triangles", r.triangles}, {"layout", r.layout},
                             {"build_ms", r.build_ms}, {"refit_ms", r.refit_ms},
                             {"sah_one", r.sah_one}, {"sah_many", r.sah_many}});
    return j;
}

} // namespace tandem
