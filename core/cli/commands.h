// Subcommands of the `tandem` executable. Each registers its options on the CLI11 app and runs
// from a callback; errors propagate as tandem::Error to main(), which prints one line.
#pragma once

#include <CLI/CLI.hpp>

namespace tandem::cli {

/// Options every subcommand shares.
struct GlobalOptions {
    std::string device; ///< --device: index or name substring (else $TANDEM_DEVICE)
    bool verbose = false;
};

void add_devices_command(CLI::App& app, GlobalOptions& global);
void add_bench_command(CLI::App& app, GlobalOptions& global);
void add_render_command(CLI::App& app, GlobalOptions& global);
void add_params_command(CLI::App& app, GlobalOptions& global);

} // namespace tandem::cli
