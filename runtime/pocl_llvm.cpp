// PoCL's work-group method, and LLVM's SLP vectoriser off for the kernels PoCL compiles inside a
// scope (pocl_llvm.h).
#include "runtime/pocl_llvm.h"

#include <dlfcn.h>
#include <link.h>

#include <cctype>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <string>

namespace tandem {

namespace {

using ParseOptions = void (*)(int, const char* const*, const char*);

/// The path of the loaded libLLVM with a major version in [15, 19], or empty.
std::string loaded_llvm() {
    std::string found;
    dl_iterate_phdr(
        [](dl_phdr_info* info, std::size_t, void* data) {
            const char* name = info->dlpi_name;
            const char* base = name ? std::strrchr(name, '/') : nullptr;
            base = base ? base + 1 : name;
            // Debian: libLLVM-15.so.1; upstream: libLLVM.so.18.1 or libLLVM-17.so
            if (!base || std::strncmp(base, "libLLVM", 7) != 0) return 0;
            const char* digits = std::strpbrk(base + 7, "0123456789");
            const int major = digits ? std::atoi(digits) : 0;
            if (major < 15 || major > 19) return 0;
            *static_cast<std::string*>(data) = name;
            return 1;
        },
        &found);
    return found;
}

/// LLVMParseCommandLineOptions of PoCL's LLVM, looked up once (the library stays loaded: PoCL
/// holds it for the life of the process), or null.
ParseOptions parse_options() {
    static std::once_flag once;
    static ParseOptions parse = nullptr;
    std::call_once(once, [] {
        const std::string path = loaded_llvm();
        if (path.empty()) return;
        void* lib = dlopen(path.c_str(), RTLD_NOW | RTLD_NOLOAD);
        if (!lib) return;
        parse = reinterpret_cast<ParseOptions>(dlsym(lib, "LLVMParseCommandLineOptions"));
        dlclose(lib); // the reference RTLD_NOLOAD took; PoCL's keeps it loaded
    });
    return parse;
}

void set_slp_threshold(ParseOptions parse, const char* option) {
    static std::mutex mutex; // LLVM's option parser is not thread-safe
    const std::lock_guard<std::mutex> lock(mutex);
    const char* argv[] = {"tandem", option};
    parse(2, argv, "");
}

} // namespace

bool is_pocl(const DeviceInfo& device) {
    return device.platform == "Portable Computing Language";
}

bool pocl_widens_gathers(const DeviceInfo& device) {
    if (!is_pocl(device) || device.type != "CPU") return false;
    // LLVM's names of the x86 CPUs with AVX-512 (LLVM 15 to 19), as PoCL puts them in the name
    static const char* const avx512_targets[] = {
        "avx512",     "cascadelake", "cooperlake",     "cannonlake",    "icelake",
        "rocketlake", "tigerlake",   "sapphirerapids", "graniterapids", "emeraldrapids",
        "knl",        "knm",         "znver4",         "znver5",        "x86-64-v4"};
    std::string name = device.name;
    for (char& c : name)
        c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    for (const char* target : avx512_targets)
        if (name.find(target) != std::string::npos) return true;
    return false;
}

const char* pocl_work_group_method(const DeviceInfo& device, const char* user) {
    if (user) return nullptr;
    if (!is_pocl(device) || device.type != "CPU" || pocl_widens_gathers(device)) return nullptr;
    return "workitemloops";
}

WorkGroupMethod pocl_work_group_method_in_effect(const DeviceInfo& device, const Tuning& tuning) {
    if (!is_pocl(device)) return {};
    if (tuning.pocl_work_group_method)
        return {*tuning.pocl_work_group_method, "POCL_WORK_GROUP_METHOD"};
    if (const char* chosen = pocl_work_group_method(device, nullptr)) return {chosen, "Tandem"};
    return {"loopvec", "PoCL's default"};
}

namespace {

/// The method pocl_choose_work_group_method set for the process (empty: none), under its mutex.
std::mutex g_chosen_mutex;
std::string g_chosen;

} // namespace

void pocl_choose_work_group_method(const DeviceInfo& device, const Tuning& tuning) {
    // contexts made at once choose one after the other
    const std::lock_guard<std::mutex> lock(g_chosen_mutex);
    const char* user =
        tuning.pocl_work_group_method ? tuning.pocl_work_group_method->c_str() : nullptr;
    if (!g_chosen.empty() || user) return; // the process's first choice, or the user's, holds
    if (const char* method = pocl_work_group_method(device, nullptr)) {
        setenv("POCL_WORK_GROUP_METHOD", method, 0);
        g_chosen = method;
    }
}

std::string pocl_work_group_method_for_builds(const DeviceInfo& device, const Tuning& tuning) {
    if (!is_pocl(device)) return {};
    if (tuning.pocl_work_group_method) return *tuning.pocl_work_group_method;
    const std::lock_guard<std::mutex> lock(g_chosen_mutex);
    return g_chosen;
}

PoclSlpOff::PoclSlpOff(const DeviceInfo& device, const Tuning& tuning) {
    if (!is_pocl(device) || tuning.pocl_slp) return;
    if (const ParseOptions parse = parse_options()) {
        set_slp_threshold(parse, "-slp-threshold=1000000");
        m_active = true;
    }
}

PoclSlpOff::~PoclSlpOff() {
    if (m_active) set_slp_threshold(parse_options(), "-slp-threshold=0");
}

} // namespace tandem
