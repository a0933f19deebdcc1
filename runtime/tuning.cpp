// The environment, read once into a Tuning: the one place Tandem calls getenv.
#include "runtime/tuning.h"

#include <cstdlib>
#include <cstring>
#include <string>

#include "runtime/error.h"

namespace tandem {

namespace {

/// The variable's value, or null where it is unset.
const char* env(const char* name) {
    return std::getenv(name);
}

/// Whether `name` is set to exactly "1" (the on/off measurement switches, where any other value
/// is off).
bool is_one(const char* name) {
    const char* value = env(name);
    return value && std::string(value) == "1";
}

/// A 0/1 switch: unset, or the value it says. Throws Error on any other value.
std::optional<bool> switch_value(const char* name) {
    const char* value = env(name);
    if (!value) return std::nullopt;
    const std::string text(value);
    if (text != "0" && text != "1")
        throw Error(std::string(name) + "='" + text + "': expected 0 or 1");
    return text == "1";
}

/// A count from 0 to `max`: unset, or its value. Throws Error, naming the variable and saying
/// that it counts `what`, on any other value.
std::optional<unsigned> count_value(const char* name, unsigned max, const char* what) {
    const char* value = env(name);
    if (!value) return std::nullopt;
    const std::string text(value);
    if (text.empty() || text.size() > 9 ||
        text.find_first_not_of("0123456789") != std::string::npos || std::stoul(text) > max)
        throw Error(std::string(name) + "='" + text + "': expected " + what + " (0 to " +
                    std::to_string(max) + ")");
    return static_cast<unsigned>(std::stoul(text));
}

/// The count a fault hook's decimal number names (from 1); 0 (never) for an empty or malformed
/// one: the hooks are for tests, which set them right.
unsigned long hook_count(const char* text) {
    if (text == nullptr || *text == '\0') return 0;
    char* end = nullptr;
    const unsigned long n = std::strtoul(text, &end, 10);
    return *end == '\0' ? n : 0;
}

FaultHooks faults_from_environment() {
    FaultHooks f;
    f.fail_allocation = hook_count(env("TANDEM_FAIL_ALLOCATION"));
    f.fail_write = hook_count(env("TANDEM_FAIL_WRITE"));
    if (const char* target = env("TANDEM_KILL_AT")) {
        if (const char* colon = std::strrchr(target, ':')) {
            f.kill_point = std::string(target, colon);
            f.kill_count = hook_count(colon + 1);
        }
    }
    return f;
}

std::string cache_dir_from_environment() {
    if (is_one("TANDEM_NO_CACHE")) return {};
    if (const char* dir = env("TANDEM_CACHE_DIR"); dir && *dir) return dir;
    if (const char* xdg = env("XDG_CACHE_HOME"); xdg && *xdg) return std::string(xdg) + "/tandem";
    if (const char* home = env("HOME"); home && *home) return std::string(home) + "/.cache/tandem";
    return {};
}

} // namespace

Tuning tuning_from_environment() {
    Tuning t;
    if (const char* device = env("TANDEM_DEVICE")) t.device = device;
    if (const char* dir = env("TANDEM_KERNEL_DIR")) t.kernel_dir = dir;
    t.cache_dir = cache_dir_from_environment();

    if (const char* method = env("POCL_WORK_GROUP_METHOD")) t.pocl_work_group_method = method;
    t.pocl_slp = is_one("TANDEM_POCL_SLP");
    t.kernel_debug = is_one("TANDEM_KERNEL_DEBUG");

    if (const char* value = env("TANDEM_BVH_WIDTH")) {
        const std::string text(value);
        if (text != "2" && text != "4" && text != "8")
            throw Error("TANDEM_BVH_WIDTH='" + text + "': expected the BVH width 2, 4 or 8");
        t.bvh_width = std::stoi(text);
    }
    if (const char* value = env("TANDEM_BVH_LEAVES")) {
        const std::string text(value);
        if (text != "records" && text != "tri4")
            throw Error("TANDEM_BVH_LEAVES='" + text +
                        "': expected the BVH leaf format records or tri4");
        t.bvh_tri4_leaves = text == "tri4";
    }
    t.bvh_repack = switch_value("TANDEM_BVH_REPACK").value_or(true);
    t.bvh_prefetch = switch_value("TANDEM_BVH_PREFETCH");
    t.camera_packets = switch_value("TANDEM_CAMERA_PACKETS");
    t.wavefront = switch_value("TANDEM_WAVEFRONT");
    t.shadow_record = switch_value("TANDEM_SHADOW_RECORD").value_or(true);
    t.hit_record_bounces =
        count_value("TANDEM_HIT_RECORD", k_max_hit_record_bounces,
                    "the number of bounces whose hits the adjoint records, an integer")
            .value_or(k_max_hit_record_bounces);
    t.wavefront_record_bounces = count_value("TANDEM_WAVEFRONT_RECORD",
                                             k_max_wavefront_record_bounces,
                                             "the number of bounces the adjoint records");

    // Open MPI's mpirun, PMIx launchers (Open MPI 5, Slurm's srun) and MPICH's Hydra set these
    t.mpi_launched = env("OMPI_COMM_WORLD_SIZE") || env("PMIX_RANK") || env("PMI_SIZE");
    t.faults = faults_from_environment();
    return t;
}

} // namespace tandem
