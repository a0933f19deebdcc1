// Subcommands of the `tandem` executable. Each registers its options on the CLI11 app and runs
// from a callback; errors propagate as tandem::Error to main(), which prints one line.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

#include "core/scene/scene.h"
#include "runtime/tuning.h"

namespace tandem::cli {

class MpiJob;

/// Options every subcommand shares.
struct GlobalOptions {
    std::string device; ///< --device: index or name substring (else tuning.device)
    bool verbose = false;
    /// Every switch, from the environment: filled once by main before the command runs, and
    /// passed to what the command makes (Context::create(device, tuning)).
    Tuning tuning;
    /// The MPI job this process was launched in (cli/mpi_job.h), else null: set by main.
    MpiJob* mpi = nullptr;
};

/// The device of this process: --device, else TANDEM_DEVICE, else in an MPI job of several
/// ranks the GPU of its local rank (device_for_rank), else the default.
std::string process_device(const GlobalOptions& global);

/// "-D name=value" overrides as pairs; throws Error for an entry without '='.
std::vector<std::pair<std::string, std::string>> parse_defines(const std::vector<std::string>& ds);

/// A one-line progress bar on stderr, redrawn in place: "[####    ] done/total unit".
void draw_progress(int done, int total, const char* unit);

/// The sensors `--sensor KEY` chooses: one (an index or an id: find_sensor), or every one for
/// "all". Throws Error naming the sensors there are for another key.
std::vector<unsigned> chosen_sensors(const std::vector<Camera>& sensors, const std::string& key);

/// The file of sensor k among several (`--sensor all`): `path` with "_K" before its extension
/// (render.exr -> render_3.exr); `path` itself for one sensor.
std::string sensor_path(const std::string& path, unsigned k, bool several);

void add_devices_command(CLI::App& app, GlobalOptions& global);
void add_bench_command(CLI::App& app, GlobalOptions& global);
void add_render_command(CLI::App& app, GlobalOptions& global);
void add_params_command(CLI::App& app, GlobalOptions& global);
void add_grad_command(CLI::App& app, GlobalOptions& global);
void add_optimize_command(CLI::App& app, GlobalOptions& global);
void add_checkpoint_command(CLI::App& app, GlobalOptions& global);

} // namespace tandem::cli
