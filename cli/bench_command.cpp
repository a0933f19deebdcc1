// `tandem bench trace [--mesh FILE] [--rays N] [--json]`: device traversal against Embree.
// `tandem bench render [--scene FILE] [--json] [--csv FILE]`: path-tracer samples/s and error
// against time.
// `tandem bench grad [--scene FILE] [--param NAME] [--sizes N,...] [--json]`: time per inverse
// rendering iteration, split into primal, adjoint and other.
// `tandem bench restir [--scene FILE] [--param NAME] [--res N] [--seeds K] [--ablations] [--json]`:
// adjoint noise of ReSTIR light-sample reuse against plain PRB and RIS at equal device time.
// `tandem bench soak [--iterations N] [--scene F] [--json] [--csv FILE]`: memory, device
// allocations and time per iteration over a long optimization run, and their slopes.
// `tandem bench refit [--grids N,...] [--json]`: BVH rebuild against refit after a shape step, by
// mesh size.
#include <cstdio>
#include <fstream>
#include <iostream>
#include <unistd.h>

#include "bench/cv_bench.h"
#include "bench/grad_bench.h"
#include "bench/refit_bench.h"
#include "bench/render_bench.h"
#include "bench/restir_bench.h"
#include "bench/soak_bench.h"
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
        opt->tuning = global.tuning;
        opt->progress = isatty(STDERR_FILENO) != 0;
        if (!csv->empty()) check_output_file(*csv); // before the work
        const RenderBenchResult result = run_render_bench(*opt);
        if (!csv->empty()) write_file_atomic(*csv, result.convergence_csv());
        if (*json)
            std::cout << result.to_json().dump(2) << std::endl;
        else
            std::cout << result.to_table();
    });
}

void add_restir_bench(CLI::App& bench, GlobalOptions& global) {
    CLI::App* cmd = bench.add_subcommand(
        "restir", "Adjoint noise of ReSTIR light-sample reuse against plain PRB and RIS, at "
                  "equal device time (relMSE against a high-spp PRB gradient)");
    auto o = std::make_shared<RestirBenchOptions>();
    auto json = std::make_shared<bool>(false);
    auto progress = std::make_shared<bool>(false);
    auto defines = std::make_shared<std::vector<std::string>>();
    cmd->add_option("--scene", o->scene, "scene file")
        ->capture_default_str()
        ->check(CLI::ExistingFile);
    cmd->add_option("--param", o->param, "the optimized parameter")->capture_default_str();
    cmd->add_option("-D", *defines, "override a <default> of --scene: name=value (repeatable)");
    cmd->add_option("--control-scene", o->control_scene,
                    "the negative control's scene (default: scenes/indirect-room.xml, where light "
                    "reaches the parameter indirectly; for vertex positions "
                    "scenes/shadow-one-light.xml, one large light)")
        ->check(CLI::ExistingFile);
    cmd->add_option("--control-param", o->control_param,
                    "the negative control's parameter (default: painting.reflectance; for vertex "
                    "positions --param)");
    cmd->add_option("--shape-offset", o->shape_offset,
                    "vertex positions: the mesh's trajectory starts this times its bounding "
                    "box's diagonal away along +x")
        ->capture_default_str()
        ->check(CLI::Range(0.0f, 1.0f));
    cmd->add_option("--boundary-reuse", o->boundary_reuse,
                    "vertex positions: ReSTIR reuses the secondary boundary term's light vertices "
                    "too (0: the interior alone)")
        ->capture_default_str()
        ->check(CLI::Range(0, 1));
    cmd->add_option("--boundary-candidates", o->boundary.candidates,
                    "fresh light points per secondary boundary sample")
        ->capture_default_str()
        ->check(CLI::Range(1, 64));
    cmd->add_option("--boundary-neighbours", o->boundary.neighbours,
                    "previous reservoirs of the boundary point's cell to combine with")
        ->capture_default_str()
        ->check(CLI::Range(0, 8));
    cmd->add_option("--boundary-visibility", o->boundary.visibility,
                    "the boundary reservoirs' target weighs down light points that neither side "
                    "of the edge sees (1: one or two rays per target) or not (0)")
        ->capture_default_str()
        ->check(CLI::Range(0, 1));
    cmd->add_option("--boundary-receiver", o->boundary.receiver,
                    "the boundary reservoirs' target weighs down receivers the camera does not "
                    "see (1) or not (0)")
        ->capture_default_str()
        ->check(CLI::Range(0, 1));
    cmd->add_option("--boundary-cell", o->boundary.cell,
                    "the boundary reservoirs' grid cell, as a fraction of the edges' extent")
        ->capture_default_str()
        ->check(CLI::Range(1e-4f, 1.0f));
    cmd->add_option("--deep-depth", o->deep_depth,
                    "max_depth of the second case on --scene (0: none)")
        ->capture_default_str()
        ->check(CLI::Range(0, 64));
    cmd->add_flag("--headline-only", o->headline_only,
                  "measure --scene as it is only (no deeper case, no negative control)");
    cmd->add_option("--res", o->res, "square film resolution")
        ->capture_default_str()
        ->check(CLI::Range(4, 4096));
    cmd->add_option("--seeds", o->seeds, "independent seeds per estimator")
        ->capture_default_str()
        ->check(CLI::Range(1, 1000));
    cmd->add_option("--spp-grad", o->spp_grad, "ReSTIR's adjoint samples per pixel")
        ->capture_default_str()
        ->check(CLI::Range(1, 1024));
    cmd->add_option("--iterations", o->iterations,
                    "iterations t of the trajectory to measure at (the other cases: the last)")
        ->capture_default_str()
        ->delimiter(',')
        ->check(CLI::Range(1, 100000));
    cmd->add_option("--lr", o->lr, "Adam's learning rate of the trajectory")->capture_default_str();
    cmd->add_option("--target-spp", o->target_spp, "spp of the target image")
        ->capture_default_str()
        ->check(CLI::Range(1, 1 << 20));
    cmd->add_option("--delta-spp", o->delta_spp, "spp of the primal render that fixes delta_t")
        ->capture_default_str()
        ->check(CLI::Range(1, 1 << 20));
    cmd->add_option("--reference-factor", o->reference_factor,
                    "reference spp over the largest estimator spp")
        ->capture_default_str()
        ->check(CLI::Range(1, 1 << 16));
    cmd->add_option("--direct", o->direct,
                    "the share of the first vertex's direct light ReSTIR and RIS estimate: auto, "
                    "all or mis (docs/restir.md)")
        ->check(CLI::IsMember({"auto", "all", "mis"}))
        ->capture_default_str();
    cmd->add_option("--reference-min-spp", o->reference_min_spp,
                    "the reference's fewest spp, whatever the estimators' spp")
        ->capture_default_str()
        ->check(CLI::Range(1, 1 << 20));
    cmd->add_option("--reference-chunks", o->reference_chunks,
                    "independent passes of the reference (their spread is its noise)")
        ->capture_default_str()
        ->check(CLI::Range(1, 1024));
    cmd->add_flag("--ablations", o->ablations,
                  "also vary visibility, spatial, m_cap, candidates and burn_in at the last t");
    cmd->add_option("--ablation-seeds", o->ablation_seeds, "seeds per ablation (0: --seeds)")
        ->capture_default_str()
        ->check(CLI::Range(0, 1000));
    cmd->add_option("--device", global.device, "OpenCL device: index or name substring");
    cmd->add_flag("--json", *json, "print JSON");
    cmd->add_flag("--progress", *progress, "report progress on stderr (default: on a terminal)");
    cmd->callback([o, json, progress, defines, &global] {
        o->device = global.device;
        o->tuning = global.tuning;
        o->defines = parse_defines(*defines);
        o->progress = *progress || isatty(STDERR_FILENO) != 0;
        const RestirBenchResult result = run_restir_bench(*o);
        if (*json)
            std::cout << result.to_json().dump(2) << std::endl;
        else
            std::cout << result.to_table();
    });
}

void add_soak_bench(CLI::App& bench, GlobalOptions& global) {
    CLI::App* cmd = bench.add_subcommand(
        "soak", "A long tandem optimize run (PRB + CV-PS + Adam, ReSTIR where supported): host "
                "memory, live device buffers and time per iteration, and their slopes");
    auto o = std::make_shared<SoakBenchOptions>();
    auto json = std::make_shared<bool>(false);
    auto csv = std::make_shared<std::string>();
    cmd->add_option("--iterations", o->iterations, "optimization iterations")
        ->capture_default_str()
        ->check(CLI::Range(2, 10000000));
    cmd->add_option("--sample-every", o->sample_every, "iterations between samples")
        ->capture_default_str()
        ->check(CLI::Range(1, 1000000));
    cmd->add_option("--scene", o->scene, "scene file (needs a <default name=\"res\">)")
        ->capture_default_str()
        ->check(CLI::ExistingFile);
    cmd->add_option("--param", o->param, "the optimized parameter")->capture_default_str();
    cmd->add_option("--res", o->res, "square film resolution")
        ->capture_default_str()
        ->check(CLI::Range(1, 4096));
    cmd->add_option("--spp", o->spp, "spp of the primal and the adjoint")
        ->capture_default_str()
        ->check(CLI::Range(1, 1024));
    cmd->add_option("--checkpoint-every", o->checkpoint_every,
                    "iterations between checkpoints, re-renders and images")
        ->capture_default_str()
        ->check(CLI::Range(1, 10000000));
    cmd->add_option("--restir", o->restir, "light-sample reuse in the adjoint")
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "on", "off"}));
    cmd->add_option("--device", global.device, "OpenCL device: index or name substring");
    cmd->add_flag("--json", *json, "print JSON (the samples and the slopes)");
    cmd->add_option("--csv", *csv, "write the samples to this CSV file");
    cmd->callback([o, json, csv, &global] {
        o->device = global.device;
        o->tuning = global.tuning;
        o->progress = isatty(STDERR_FILENO) != 0;
        if (!csv->empty()) check_output_file(*csv); // before the work
        const SoakBenchResult result = run_soak_bench(*o);
        if (!csv->empty()) write_file_atomic(*csv, result.samples_csv());
        if (*json)
            std::cout << result.to_json().dump(2) << std::endl;
        else
            std::cout << result.to_table();
    });
}

void add_refit_bench(CLI::App& bench) {
    CLI::App* cmd = bench.add_subcommand(
        "refit", "BVH rebuild (Embree) against refit after a shape step, by mesh size");
    auto opt = std::make_shared<RefitBenchOptions>();
    auto json = std::make_shared<bool>(false);
    cmd->add_option("--grids", opt->grids, "height fields of N x N quads")
        ->capture_default_str()
        ->delimiter(',')
        ->check(CLI::Range(1u, 4096u));
    cmd->add_option("--repeats", opt->repeats, "timed repetitions (best is kept)")
        ->capture_default_str()
        ->check(CLI::Range(1, 100));
    cmd->add_option("--step", opt->step, "each step's motion, a fraction of the extent")
        ->capture_default_str()
        ->check(CLI::Range(0.0f, 1.0f));
    cmd->add_option("--steps", opt->steps, "steps before the second SAH comparison")
        ->capture_default_str()
        ->check(CLI::Range(1, 100000));
    cmd->add_flag("--json", *json, "print JSON");
    cmd->callback([opt, json] {
        const RefitBenchResult result = run_refit_bench(*opt);
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
        ->capture_default_str()
        ->check(CLI::Range(0, 4096));
    trace->add_option("--repeats", opt->repeats, "timed repetitions (best is kept)")
        ->capture_default_str()
        ->check(CLI::Range(1, 100));
    trace
        ->add_option(
            "--bvh-width", opt->bvh_width,
            "headline BVH layout: 2 (BvhNode), 4 (Bvh4Node) or 8 (Bvh8Node); default: "
            "the device's preferred (CPUs: 8 with 8-wide float vectors, else 4; GPUs: 2). All "
            "are always measured.")
        ->check(CLI::IsMember({2, 4, 8}));
    trace->add_option("--device", global.device, "OpenCL device: index or name substring");
    trace->add_flag("--json", *json, "print JSON");
    trace->callback([opt, json, &global] {
        opt->device = global.device;
        opt->tuning = global.tuning;
        opt->progress = isatty(STDERR_FILENO) != 0;
        const TraceBenchResult result = run_trace_bench(*opt);
        if (*json)
            std::cout << result.to_json().dump(2) << std::endl;
        else
            std::cout << result.to_table();
    });
    add_render_bench(*bench, global);
    add_restir_bench(*bench, global);
    add_soak_bench(*bench, global);
    add_refit_bench(*bench);

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
        ->capture_default_str()
        ->check(CLI::Range(1, 1 << 14));
    cv->add_option("--repeats", copt->cost_repeats, "interleaved timed rounds")
        ->capture_default_str()
        ->check(CLI::Range(1, 100));
    cv->add_option("--steady-size", copt->steady_size, "square resolution of the steady-state runs")
        ->capture_default_str()
        ->check(CLI::Range(1, 1 << 14));
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
        copt->tuning = global.tuning;
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
        ->delimiter(',')
        ->check(CLI::Range(1, 1 << 14));
    grad->add_option("--spp", gopt->spp, "spp of the primal and the adjoint")
        ->capture_default_str()
        ->check(CLI::Range(1, 1 << 16));
    grad->add_option("--iterations", gopt->iterations,
                     "timed iterations per size (after one warm-up)")
        ->capture_default_str()
        ->check(CLI::Range(1, 1000));
    grad->add_option("--device", global.device, "OpenCL device: index or name substring");
    grad->add_flag("--json", *gjson, "print JSON");
    grad->callback([gopt, gjson, &global] {
        gopt->device = global.device;
        gopt->tuning = global.tuning;
        gopt->progress = isatty(STDERR_FILENO) != 0;
        const GradBenchResult result = run_grad_bench(*gopt);
        if (*gjson)
            std::cout << result.to_json().dump(2) << std::endl;
        else
            std::cout << result.to_table();
    });
}

} // namespace tandem::cli
