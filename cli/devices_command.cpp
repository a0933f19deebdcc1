// `tandem devices [--json]`: lists OpenCL platforms and devices.
#include <iomanip>
#include <iostream>

#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/mpi_job.h"
#include "runtime/device.h"
#include "runtime/pocl_llvm.h"

namespace tandem::cli {

void add_devices_command(CLI::App& app, GlobalOptions& global) {
    CLI::App* cmd = app.add_subcommand("devices", "List OpenCL platforms and devices");
    auto json = std::make_shared<bool>(false);
    cmd->add_flag("--json", *json, "print JSON instead of a table");
    cmd->callback([json, &global] {
        const std::vector<DeviceInfo> devices = list_devices();
        // in an MPI job: rank 0 lists the devices, and which one each rank renders on
        std::vector<std::string> ranks;
        if (global.mpi) {
            const std::string spec = process_device(global);
            const DeviceInfo d = select_device(spec.empty() ? global.tuning.device : spec);
            ranks = global.mpi->gather("rank " + std::to_string(global.mpi->rank()) + " on " +
                                       global.mpi->host() + " (local rank " +
                                       std::to_string(global.mpi->local_rank()) + "): [" +
                                       std::to_string(d.index) + "] " + d.name);
            if (!global.mpi->root()) return;
        }
        if (*json) {
            nlohmann::json out = nlohmann::json::array();
            const auto or_null = [](const std::string& v) {
                return v.empty() ? nlohmann::json(nullptr) : nlohmann::json(v);
            };
            for (const DeviceInfo& d : devices) {
                const auto [method, by] = pocl_work_group_method_in_effect(d, global.tuning);
                out.push_back({{"index", d.index},
                               {"platform", d.platform},
                               {"platform_version", d.platform_version},
                               {"name", d.name},
                               {"vendor", d.vendor},
                               {"type", d.type},
                               {"compute_units", d.compute_units},
                               {"native_float_width", d.native_float_width},
                               {"global_mem_bytes", d.global_mem_bytes},
                               {"max_alloc_bytes", d.max_alloc_bytes},
                               {"opencl_c_version", d.opencl_c_version},
                               {"driver_version", d.driver_version},
                               {"correctly_rounded_divide_sqrt", d.correctly_rounded_divide_sqrt},
                               {"denormals", d.denormals},
                               {"hardware_fma", d.hardware_fma},
                               {"reproducible", d.reproducible()},
                               {"pocl_work_group_method", or_null(method)},
                               {"pocl_work_group_method_by", or_null(by)}});
            }
            if (global.mpi) out = {{"devices", out}, {"ranks", ranks}};
            std::cout << out.dump(2) << std::endl;
            return;
        }
        std::string platform;
        for (const DeviceInfo& d : devices) {
            if (d.platform != platform) {
                platform = d.platform;
                std::cout << "platform: " << d.platform << " (" << d.platform_version << ")\n";
            }
            std::cout << "  [" << d.index << "] " << d.name << "\n"
                      << "      type " << d.type << ", " << d.compute_units << " compute units, "
                      << d.native_float_width << "-wide native float vectors, " << std::fixed
                      << std::setprecision(1) << d.global_mem_bytes / (1024.0 * 1024.0 * 1024.0)
                      << " GiB global memory, " << d.opencl_c_version << ", driver "
                      << d.driver_version << "\n"
                      << "      reproducible: "
                      << (d.reproducible() ? "yes (the same bits as every reproducible device)"
                                           : "no: " + d.reproducibility_note())
                      << "\n";
            if (!d.hardware_fma)
                std::cout
                    << "      fma: no CL_FP_FMA, likely in software (the same bits, slower)\n";
            if (const auto [method, by] = pocl_work_group_method_in_effect(d, global.tuning); !method.empty())
                std::cout << "      PoCL work-group method: " << method << " (" << by << ")\n";
        }
        if (global.mpi) {
            std::cout << "MPI: " << ranks.size() << (ranks.size() == 1 ? " rank\n" : " ranks\n");
            for (const std::string& r : ranks) std::cout << "  " << r << "\n";
        }
    });
}

} // namespace tandem::cli
