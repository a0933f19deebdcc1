// `tandem optimize CONFIG.json [--out DIR] [--resume [--force]] [--until N] [--json]`: inverse
// rendering by gradient descent (core/inverse/optimize.h).
#include <functional>
#include <iostream>
#include <unistd.h>

#include "cli/commands.h"
#include "cli/mpi_job.h"
#include "core/inverse/optimize.h"
#include "runtime/error.h"

namespace tandem::cli {

void add_optimize_command(CLI::App& app, GlobalOptions& global) {
    CLI::App* cmd = app.add_subcommand(
        "optimize", "Recover scene parameters from a target image (PRB + Adam or SGD)");
    auto config = std::make_shared<std::string>();
    auto opt = std::make_shared<OptimizeOptions>();
    auto json = std::make_shared<bool>(false);
    cmd->add_option("config", *config, "optimization config (JSON; see README)")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("--out", opt->out_dir, "output directory")->capture_default_str();
    CLI::Option* resume =
        cmd->add_flag("--resume", opt->resume, "continue from DIR/checkpoint.bin, bit-identically");
    cmd->add_flag("--force", opt->force,
                  "with --resume: continue even if an input (scene, mesh, texture, target, config) "
                  "changed since the checkpoint; metrics.csv marks the rows after it")
        ->needs(resume);
    cmd->add_option("--until", opt->until,
                    "stop after this iteration (continue later with --resume)")
        ->check(CLI::Range(1, 1 << 30));
    cmd->add_option("--device", global.device, "OpenCL device: index or name substring");
    cmd->add_flag("--json", *json, "print a JSON summary");
    cmd->callback([config, opt, json, &global] {
        const OptimizeConfig c = load_optimize_config(*config);
        Context ctx = Context::create(process_device(global), global.tuning);
        OptimizeOptions o = *opt;
        o.stage_timing = *json; // primal_seconds, adjoint_seconds, restir_seconds, other_seconds
        const bool root = !global.mpi || global.mpi->root();
        if (global.mpi) {
            const DeviceInfo& d = ctx.device();
            global.mpi->set_device(d.name);
            o.ranks = global.mpi;
            // the same bits as one process need the same device everywhere, or reproducible ones
            const std::string kind = d.platform + "/" + d.name + "/" + d.driver_version;
            const bool same = global.mpi->agree(std::hash<std::string>{}(kind));
            if (!global.mpi->agree(d.reproducible() ? 1 : 0) || (!same && !d.reproducible()))
                throw Error("the ranks render on different devices, not all of them reproducible "
                            "(`tandem devices`): their gradients would not be one process's; "
                            "name one kind with --device");
            if (!same && root)
                std::cerr << "tandem optimize: the ranks render on different devices, all "
                             "reproducible: the same bits as one process\n";
        }
        const bool tty = isatty(STDERR_FILENO);
        if (root) o.progress = [tty](int it, int total, float loss) {
            if (tty) {
                const int width = 30, filled = width * it / total;
                std::cerr << "\r[" << std::string(filled, '#') << std::string(width - filled, ' ')
                          << "] " << it << "/" << total << " loss " << loss
                          << (it == total ? "\n" : "   ") << std::flush;
            } else if (it % 10 == 0 || it == total) {
                std::cerr << "iteration " << it << "/" << total << ": loss " << loss << "\n";
            }
        };
        const OptimizeSummary s =
            run_optimization(ctx, KernelLibrary::from_tuning(global.tuning), c, o);
        if (!root) return; // rank 0 reports for the job
        if (*json) {
            std::cout << optimize_summary_json(s, o.out_dir) << std::endl;
        } else {
            std::cout << o.out_dir << ": " << s.iterations_done << " iterations in " << s.seconds
                      << " s, loss " << s.final_loss;
            if (s.param_error >= 0) std::cout << ", parameter RMSE " << s.param_error;
            if (s.image_error >= 0) std::cout << ", image RMSE " << s.image_error;
            if (s.alpha_mean >= 0) std::cout << ", mean alpha " << s.alpha_mean;
            if (s.inputs_changed) std::cout << " (resumed over changed inputs: --force)";
            std::cout << "\n";
        }
        if (s.guards)
            std::cerr
                << "warning: " << s.guards
                << " non-finite samples, saturated gradient contributions or wrapped gradient "
                   "sums were dropped or clamped\n";
    });
}

} // namespace tandem::cli
