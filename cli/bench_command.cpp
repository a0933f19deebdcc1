// `tandem bench trace [--mesh FILE] [--rays N] [--json]`: device traversal against Embree.
// `tandem bench render [--scene FILE] [--json] [--csv FILE]`: path-tracer samples/s and error
// against time.
// `tandem bench grad [--scene FILE] [--param NAME] [--sizes N,...] [--json]`: time per inverse
// rendering iteration, split into primal, adjoint and other.
#include <cstdio>
#include <fstream>
#include <iostream>
#include <unistd.h>

#include "bench/cv_bench.h"
#include "bench/grad_bench.h"
#include "bench/render_bench.h"
#include "bench/trace_bench.h"
#include "cli/commands.h"
#include "core/io/atomic_file.h"
#include "runtime/error.h"

namespace tandem::cli {

namespace {

void add_render_bench(CLI::App& bench, GlobalOptions& global) {
    CLI::App* render = bench.add_subcommand(
        "render", "Samples/s of the path tracer, and RMSE against time versus a reference");
    auto opt = std::make_shared<RenderBenchOptions>();
    auto json = std::make_shared<bool>(false);
    auto csv = std::make_shared<std::string>();
    opt->scene = TANDEM_DEFAULT_SCENE;
    render->add_option("--scene", opt->scene, "scene file (Mitsuba 3 XML subset)")
        ->capture_default_str()
        ->check(CLI::ExistingFile);
    render->add_option("--spp", opt->throughput_spp, "spp of the throughput renders")
        ->capture_default_str()
        ->check(CLI::Range(1, 1 << 16));
    render->add_option("--size", opt->size, "square resolution of the convergence renders")
        ->capture_default_str()
        ->check(CLI::Range(1, 1 << 14));
    render->add_option("--ref-spp", opt->reference_spp, "spp of the reference image")
        ->capture_default_str()
        ->check(CLI::Range(2, 1 << 20));
    render
        ->add_option("--max-spp", opt->max_spp,
                     "largest convergence spp (powers of two from 1); default: ref-spp / 16")
        ->check(CLI::Range(1, 1 << 20));
    render->add_option("--repeats", opt->repeats, "independent renders per convergence spp")
        ->capture_default_str()
        ->check(CLI::Range(1, 100));
    render->add_option("--device", global.device, "OpenCL device: index or name substring");
    render->add_flag("--json", *json, "print JSON");
    render->add_option("--csv", *csv, "write the convergence table to this CSV file");
    render->callback([opt, json, csv, &global] {
        opt->device = global.device;
        opt->progress = isatty(STDERR_FILENO) != 0;
        const RenderBenchResult result = run_render_bench(*opt);
        if (!csv->empty()) write_file_atomic(*csv, result.convergence_csv());
        if (*json)
            std::cout << result.to_json().dump(2) << std::endl;
        else
            std::cout << result.to_table();
    });
}

} // namespace

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
    trace
        ->add_option("--bvh-width", opt->bvh_width,
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
    add_render_bench(*bench, global);

    CLI::App* cv = bench->add_subcommand("cv", "Fused two-state kernel cost over a primal render, "
                                               "and the CV's steady-state effective spp and bias");
    auto copt = std::make_shared<CvBenchOptions>();
    auto cjson = std::make_shared<bool>(false);
    cv->add_option("--scene", copt->scene, "scene file")
        ->capture_default_str()
        ->check(CLI::ExistingFile);
    cv->add_option("--changing", copt->changing, "parameters that differ between the two states")
        ->capture_default_str();
    cv->add_option("--size", copt->cost_size, "square resolution of the cost runs")
        ->capture_default_str();
    cv->add_option("--repeats", copt->cost_repeats, "interleaved timed rounds")
        ->capture_default_str();
    cv->add_option("--steady-size", copt->steady_size, "square resolution of the steady-state runs")
        ->capture_default_str();
    cv->add_option("--steady-runs", copt->steady_runs, "independent steady-state runs")
        ->capture_default_str()
        ->check(CLI::Range(2, 1000));
    cv->add_option("--iterations", copt->steady_iterations,
                   "steady-state iteration counts to measure at")
        ->capture_default_str()
        ->check(CLI::Range(2, 100000));
    cv->add_option("--reference-spp", copt->reference_spp,
                   "spp of the render the bias is measured against")
        ->capture_default_str()
        ->check(CLI::Range(1, 1 << 20));
    cv->add_option("--cv-variance", copt->variances, "variance forms to compare")
        ->capture_default_str()
        ->check(CLI::IsMember({"consistent", "reference"}));
    auto cdefines = std::make_shared<std::vector<std::string>>();
    cv->add_option("-D", *cdefines, "override a <default>: name=value (repeatable)");
    cv->add_option("--device", global.device, "OpenCL device: index or name substring");
    cv->add_flag("--json", *cjson, "print JSON");
    cv->callback([copt, cjson, cdefines, &global] {
        copt->device = global.device;
        copt->defines = parse_defines(*cdefines);
        copt->progress = isatty(STDERR_FILENO) != 0;
        const CvBenchResult result = run_cv_bench(*copt);
        if (*cjson)
            std::cout << result.to_json().dump(2) << std::endl;
        else
            std::cout << result.to_table();
    });

    CLI::App* grad = bench->add_subcommand(
        "grad", "Time per optimization iteration (PRB), split into primal, adjoint and other");
    auto gopt = std::make_shared<GradBenchOptions>();
    auto gjson = std::make_shared<bool>(false);
    grad->add_option("--scene", gopt->scene, "scene file (needs a <default name=\"res\">)")
        ->capture_default_str()
        ->check(CLI::ExistingFile);
    grad->add_option("--param", gopt->param, "the optimized parameter")->capture_default_str();
    grad->add_option("--sizes", gopt->sizes, "square resolutions")
        ->capture_default_str()
        ->delimiter(',');
    grad->add_option("--spp", gopt->spp, "spp of the primal and the adjoint")
        ->capture_default_str();
    grad->add_option("--iterations", gopt->iterations,
                     "timed iterations per size (after one warm-up)")
        ->capture_default_str()
        ->check(CLI::Range(1, 1000));
    grad->add_option("--device", global.device, "OpenCL device: index or name substring");
    grad->add_flag("--json", *gjson, "print JSON");
    grad->callback([gopt, gjson, &global] {
        gopt->device = global.device;
        gopt->progress = isatty(STDERR_FILENO) != 0;
        const GradBenchResult result = run_grad_bench(*gopt);
        if (*gjson)
            std::cout << result.to_json().dump(2) << std::endl;
        else
            std::cout << result.to_table();
    });
}

} // namespace tandem::cli
