// The `tandem` command line: subcommand dispatch and one-line error reporting.
#include <iostream>

#include "cli/commands.h"
#include "runtime/error.h"

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
    tandem::cli::add_bench_command(app, global);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e);
    } catch (const tandem::Error& e) {
        std::cerr << "tandem: error: " << e.what() << std::endl;
        if (global.verbose && !e.detail().empty()) std::cerr << e.detail() << std::endl;
        return 1;
    } catch (const std::exception& e) {
        std::cerr << "tandem: error: " << e.what() << std::endl;
        return 1;
    }
    return 0;
}
