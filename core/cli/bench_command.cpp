// `tandem bench trace [--mesh FILE] [--rays N] [--json]`: device traversal against Embree.
#include <iostream>
#include <unistd.h>

#include "core/cli/commands.h"
#include "bench/trace_bench.h"

namespace tandem::cli {

void add_bench_command(CLI::App& app, GlobalOptions& global) {
    CLI::App* bench = app.add_subcommand("bench", "Benchmarks (ratios measured in one run)");
    bench->require_subcommand(1);
    CLI::App* trace = bench->add_subcommand(
        "trace", "Rays/s of the OpenCL closest-hit and any-hit kernels against Embree");
    auto opt = std::make_shared<TraceBenchOptions>();
    auto json = std::make_shared<bool>(false);
    opt->mesh = TANDEM_DEFAULT_MESH;
    trace->add_option("--mesh", opt->mesh, "OBJ or PLY mesh")->capture_default_str();
    trace->add_option("--rays", opt->rays, "rays per ray set")
        ->capture_default_str()
        ->check(CLI::Range(std::size_t{1}, std::size_t{1} << 28));
    trace->add_option("--threads", opt->threads, "Embree host threads (0: all)")
        ->capture_default_str();
    trace->add_option("--repeats", opt->repeats, "timed repetitions (best is kept)")
        ->capture_default_str()
        ->check(CLI::Range(1, 100));
    trace->add_option("--bvh-width", opt->bvh_width,
                      "headline BVH layout: 2 (BvhNode) or 4 (Bvh4Node); default: the device's "
                      "preferred (4 on CPUs, 2 on GPUs). Both are always measured.")
        ->check(CLI::IsMember({2, 4}));
    trace->add_option("--device", global.device, "OpenCL device: index or name substring");
    trace->add_flag("--json", *json, "print JSON");
    trace->callback([opt, json, &global] {
        opt->device = global.device;
        opt->progress = isatty(STDERR_FILENO) != 0;
        const TraceBenchResult result = run_trace_bench(*opt);
        if (*json)
            std::cout << result.to_json().dump(2) << std::endl;
        else
            std::cout << result.to_table();
    });
}

} // namespace tandem::cli
