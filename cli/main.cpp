// The `tandem` command line: subcommand dispatch and one-line error reporting.
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "cli/mpi_job.h"
#include "runtime/error.h"
#include "runtime/fault.h"

namespace {

/// CLI11's message for a bad command line, except where a subcommand is missing and something
/// else was given in its place: then that is named (`tandem rendr`: the subcommands there are;
/// `tandem --bogus`: an unknown option), where CLI11 would only say that a subcommand is required.
std::string parse_error_message(CLI::App& app, const CLI::ParseError& e) {
    CLI::App* level = &app; // the deepest subcommand given
    for (std::vector<CLI::App*> given = level->get_subcommands(); !given.empty();
         given = level->get_subcommands())
        level = given.front();
    const std::vector<std::string> extra = level->remaining();
    const std::vector<CLI::App*> known = level->get_subcommands({});
    if (extra.empty() || known.empty()) return e.what();
    if (extra.front().rfind('-', 0) == 0) return "unknown option '" + extra.front() + "'";
    std::string names;
    for (const CLI::App* sub : known)
        names += (names.empty() ? "" : ", ") + sub->get_name();
    return "unknown subcommand '" + extra.front() + "' (one of: " + names + ")";
}

} // namespace

int main(int argc, char** argv) {
    CLI::App app{"Tandem: a portable inverse path tracer (OpenCL)", "tandem"};
    app.require_subcommand(1);
    tandem::cli::GlobalOptions global;
    app.add_option("--device", global.device,
                   "OpenCL device: index or name substring (default: $TANDEM_DEVICE, else the "
                   "first GPU, else the first device)");
    app.add_flag("-v,--verbose", global.verbose, "print full build logs on kernel errors");
    tandem::cli::add_devices_command(app, global);
    tandem::cli::add_render_command(app, global);
    tandem::cli::add_params_command(app, global);
    tandem::cli::add_grad_command(app, global);
    tandem::cli::add_optimize_command(app, global);
    tandem::cli::add_checkpoint_command(app, global);
    tandem::cli::add_bench_command(app, global);
    std::unique_ptr<tandem::cli::MpiJob> mpi;
    // In an MPI job of several ranks, an error on one rank ends them all (MPI_Abort), so that
    // none waits for it in an exchange; each says which rank it is.
    // One write per line (std::cerr is unbuffered: pieces of the ranks' lines would interleave).
    const auto fail = [&](const std::string& line, const std::string& detail = {}) {
        const std::string rank =
            mpi ? "rank " + std::to_string(mpi->rank()) + " of " + std::to_string(mpi->size()) + ": "
                : std::string();
        std::cerr << ("tandem: error: " + rank + line + "\n" + (detail.empty() ? "" : detail + "\n"))
                  << std::flush;
        if (mpi && mpi->size() > 1) mpi->abort(1);
        return 1;
    };
    try {
        // every switch read once, before anything runs (a bad value is the command's error)
        global.tuning = tandem::tuning_from_environment();
        tandem::fault::configure(global.tuning.faults);
        mpi = tandem::cli::join_mpi_job(global.tuning);
        global.mpi = mpi.get();
        if (mpi && mpi->size() > 1) { // the others would run once per rank, each the whole of it
            // the subcommand: the first argument that is neither an option nor --device's value
            std::string command;
            for (int i = 1; i < argc && command.empty(); ++i) {
                const std::string arg = argv[i];
                if (arg == "--device") ++i;
                else if (arg.rfind('-', 0) != 0) command = arg;
            }
            if (!command.empty() && command != "optimize" && command != "devices")
                throw tandem::Error("`tandem " + command + "` runs as one process: only `tandem " +
                                    "optimize` (and `devices`) run across ranks");
        }
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        // --help and friends exit 0 with CLI11's own output; a bad command line is an error like
        // any other: one line, status 1 (CLI11's own codes, 100 and up, would read as crashes).
        if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) return app.exit(e);
        return fail(parse_error_message(app, e) + " (see --help)");
    } catch (const tandem::Error& e) {
        return fail(e.what(), global.verbose ? e.detail() : std::string());
    } catch (const std::exception& e) {
        return fail(e.what());
    }
    return 0;
}
