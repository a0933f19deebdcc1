// `tandem checkpoint FILE [--json]`: verifies a checkpoint of `tandem optimize` (every section's
// checksum) and says what it holds: the iteration, the sections, the inputs of its run.
#include <iomanip>
#include <iostream>

#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "core/inverse/checkpoint.h"
#include "core/io/digest.h"

namespace tandem::cli {

void add_checkpoint_command(CLI::App& app, GlobalOptions&) {
    CLI::App* cmd = app.add_subcommand(
        "checkpoint", "Verify an optimize checkpoint and list its sections and inputs");
    auto file = std::make_shared<std::string>();
    auto json = std::make_shared<bool>(false);
    cmd->add_option("file", *file, "checkpoint.bin of an optimize output folder")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_flag("--json", *json, "print it as JSON");
    cmd->callback([file, json] {
        const CheckpointSummary s = inspect_checkpoint(*file); // throws, naming the damage
        if (*json) {
            nlohmann::json j{{"file", *file}, {"iteration", s.iterations_done}};
            for (const auto& sec : s.sections)
                j["sections"].push_back(
                    {{"name", sec.name}, {"bytes", sec.bytes}, {"xxh3", digest_hex(sec.digest)}});
            for (const auto& f : s.inputs.files)
                j["inputs"]["files"].push_back({{"path", f.path}, {"xxh3", digest_hex(f.digest)}});
            for (const auto& st : s.inputs.settings)
                j["inputs"]["settings"][st.key] = st.value;
            std::cout << j.dump(2) << std::endl;
            return;
        }
        std::cout << *file << ": iteration " << s.iterations_done << ", " << s.sections.size()
                  << " sections, every checksum holds\n";
        for (const auto& sec : s.sections)
            std::cout << "  section " << std::left << std::setw(28) << sec.name << std::right
                      << std::setw(12) << sec.bytes << " bytes  xxh3 " << digest_hex(sec.digest)
                      << "\n";
        for (const auto& f : s.inputs.files)
            std::cout << "  input " << f.path << "  xxh3 " << digest_hex(f.digest) << "\n";
        for (const auto& st : s.inputs.settings)
            std::cout << "  setting " << st.key << " = " << st.value << "\n";
    });
}

} // namespace tandem::cli
