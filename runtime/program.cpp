// Program build and on-disk binary cache.
#include "runtime/program.h"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <fcntl.h>
#include <unistd.h>

#include "runtime/error.h"
#include "runtime/pocl_llvm.h"
#include "runtime/stderr_redirect.h"

namespace tandem {

namespace fs = std::filesystem;

namespace {

constexpr const char* k_cache_magic = "tandem-program-cache-v1";

std::uint64_t fnv1a64(const std::string& s) {
    std::uint64_t h = 1469598103934665603ull;
    for (unsigned char c : s) {
        h ^= c;
        h *= 1099511628211ull;
    }
    return h;
}

/// The first line of the log that carries "error", or the first non-empty line.
std::string first_error_line(const std::string& log) {
    std::istringstream in(log);
    std::string line, first;
    while (std::getline(in, line)) {
        if (first.empty() && !line.empty()) first = line;
        if (line.find("error") != std::string::npos) return line;
    }
    return first.empty() ? "no build log" : first;
}

std::string build_log(const cl::Program& program, const cl::Device& device) {
    try {
        return program.getBuildInfo<CL_PROGRAM_BUILD_LOG>(device);
    } catch (const cl::Error&) {
        return {};
    }
}

/// Cache file contents: magic, key length and key (the full key is compared, so a hash collision
/// cannot return a wrong binary), binary length and binary.
std::string read_cached(const fs::path& file, const std::string& key) {
    std::ifstream in(file, std::ios::binary);
    if (!in) return {};
    std::string magic;
    std::getline(in, magic);
    std::uint64_t key_len = 0, bin_len = 0;
    in.read(reinterpret_cast<char*>(&key_len), sizeof key_len);
    if (!in || magic != k_cache_magic || key_len != key.size()) return {};
    std::string stored(key_len, '\0');
    in.read(stored.data(), static_cast<std::streamsize>(key_len));
    if (!in || stored != key) return {};
    in.read(reinterpret_cast<char*>(&bin_len), sizeof bin_len);
    std::error_code ec;
    const std::uintmax_t file_size = fs::file_size(file, ec);
    if (!in || ec || bin_len == 0 || bin_len > file_size) return {}; // damaged entry: rebuild
    std::string binary(bin_len, '\0');
    in.read(binary.data(), static_cast<std::streamsize>(bin_len));
    return in ? binary : std::string{};
}

void write_cached(const fs::path& file, const std::string& key, const std::string& binary) {
    std::error_code ec;
    fs::create_directories(file.parent_path(), ec);
    if (ec) return; // the cache is an optimisation: an unwritable cache directory is not an error
    // Unique per process and per call, so concurrent writers never share a temporary file.
    static std::atomic<unsigned> counter{0};
    const fs::path tmp =
        file.string() + ".tmp" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
    {
        std::ofstream out(tmp, std::ios::binary);
        if (!out) return;
        const std::uint64_t key_len = key.size(), bin_len = binary.size();
        out << k_cache_magic << '\n';
        out.write(reinterpret_cast<const char*>(&key_len), sizeof key_len);
        out.write(key.data(), static_cast<std::streamsize>(key.size()));
        out.write(reinterpret_cast<const char*>(&bin_len), sizeof bin_len);
        out.write(binary.data(), static_cast<std::streamsize>(binary.size()));
        if (!out) {
            fs::remove(tmp, ec);
            return;
        }
    }
    fs::rename(tmp, file, ec); // atomic: readers see the old file or the whole new one
    if (ec) fs::remove(tmp, ec);
}

void build_quietly(cl::Program& program, const cl::Device& device, const std::string& options) {
    StderrRedirect quiet(StderrRedirect::discard);
    program.build({device}, options.c_str());
}

} // namespace

std::string base_build_options(const DeviceInfo& device, const Tuning& tuning) {
    std::string options = "-cl-std=CL1.2";
    if (device.correctly_rounded_divide_sqrt) options += " -cl-fp32-correctly-rounded-divide-sqrt";
    // Line tables in the device code, so a profiler can split kernel time by source line
    // (scripts/profile_kernels.py: perf on PoCL's JIT objects). On PoCL 3.1 the machine code is the
    // same (checked); elsewhere -g may change it. The cache key differs.
    if (tuning.kernel_debug) options += " -g";
    // PoCL's SLP vectoriser kept on where PoclSlpOff would turn it off (pocl_llvm.h), to measure
    // what that buys. The define changes no code, only the cache keys (PoCL's and ours), so that
    // the two builds are not taken for each other.
    if (tuning.pocl_slp) options += " -D TANDEM_POCL_SLP=1";
    // PoCL's work-group method (pocl_choose_work_group_method), likewise only in the cache keys:
    // PoCL 3.1 leaves it out of its own, and would take a kernel compiled with one method for
    // the other.
    std::string name;
    for (char c : pocl_work_group_method_for_builds(device, tuning))
        if (std::isalnum(static_cast<unsigned char>(c))) name += c;
    if (!name.empty()) options += " -D TANDEM_POCL_WG_" + name;
    return options;
}

Program Program::build(Context& ctx, const KernelLibrary& lib, const std::string& file,
                       const std::string& options) {
    return build_source(ctx, "kernels/" + file, lib.preprocess(file), options);
}

Program Program::build_source(Context& ctx, const std::string& name, const std::string& source,
                              const std::string& extra_options) {
    const DeviceInfo& dev = ctx.device();
    const std::string options =
        base_build_options(dev, ctx.tuning()) + (extra_options.empty() ? "" : " ") + extra_options;
    Program p;
    p.m_name = name;
    const std::string key = std::string(k_cache_magic) + "\nplatform: " + dev.platform + " " +
                            dev.platform_version + "\ndevice: " + dev.name +
                            "\ndriver: " + dev.driver_version + "\noptions: " + options +
                            "\nsource:\n" + source;
    const std::string& cache_dir = ctx.tuning().cache_dir;
    char hex[17];
    std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(fnv1a64(key)));
    const fs::path cache_file =
        cache_dir.empty() ? fs::path{} : fs::path(cache_dir) / (std::string(hex) + ".bin");

    // Step 1: a cached binary, if one matches the whole key and still builds.
    if (!cache_dir.empty()) {
        std::string binary;
        try {
            binary = read_cached(cache_file, key);
        } catch (const std::exception&) {
            binary.clear(); // an unreadable entry is rebuilt, never an error
        }
        if (!binary.empty()) {
            try {
                cl::Program::Binaries bins{
                    std::vector<unsigned char>(binary.begin(), binary.end())};
                p.m_program = cl::Program(ctx.cl_context(), {dev.device}, bins);
                build_quietly(p.m_program, dev.device, options);
                p.m_from_cache = true;
                return p;
            } catch (const cl::Error&) {
                // stale or foreign binary: rebuild from source below
            }
        }
    }

    // Step 2: compile from source.
    try {
        p.m_program = cl::Program(ctx.cl_context(), source);
        build_quietly(p.m_program, dev.device, options);
    } catch (const cl::Error& e) {
        const std::string log = build_log(p.m_program, dev.device);
        throw DeviceError("kernel build of " + name + " failed on '" + dev.name +
                              "': " + first_error_line(log),
                          log.empty() ? std::string(cl_error_name(e.err())) : log);
    }

    // Step 3: store the binary for next time.
    if (!cache_dir.empty()) {
        try {
            const auto binaries = p.m_program.getInfo<CL_PROGRAM_BINARIES>();
            if (!binaries.empty() && !binaries.front().empty())
                write_cached(cache_file, key,
                             std::string(binaries.front().begin(), binaries.front().end()));
        } catch (const cl::Error&) {
            // a driver that cannot return binaries simply is not cached
        }
    }
    return p;
}

cl::Kernel Program::kernel(const std::string& kernel_name) const {
    // What the implementation prints while it creates the kernel is its reason when it fails
    // (Oclgrind prints why on stderr and returns CL_INVALID_KERNEL_NAME), and passed on otherwise.
    cl_int code = CL_SUCCESS;
    cl::Kernel k;
    StderrRedirect printed(StderrRedirect::capture);
    try {
        k = cl::Kernel(m_program, kernel_name.c_str());
    } catch (const cl::Error& e) {
        code = e.err();
    }
    const std::string message = printed.restore();
    if (code == CL_SUCCESS) {
        std::fputs(message.c_str(), stderr);
        return k;
    }
    std::vector<std::string> names;
    try {
        names = kernel_names();
    } catch (const cl::Error&) {
    }
    const std::string error = cl_error_name(code);
    // "Not found" only for what it means: the implementation says the name is wrong and the
    // program does not list it.
    if (code == CL_INVALID_KERNEL_NAME &&
        std::find(names.begin(), names.end(), kernel_name) == names.end()) {
        std::string known;
        for (const std::string& n : names)
            known += (known.empty() ? "" : ", ") + n;
        throw Error("kernel '" + kernel_name + "' not found in " + m_name + " (" + error +
                    (known.empty() ? "" : "; it has: " + known) + ")");
    }
    std::string device, log;
    try {
        const cl::Device dev = m_program.getInfo<CL_PROGRAM_DEVICES>().at(0);
        device = " on '" + std::string(dev.getInfo<CL_DEVICE_NAME>().c_str()) + "'";
        log = build_log(m_program, dev);
    } catch (const std::exception&) {
    }
    const std::string reason = one_line(message);
    throw Error("kernel '" + kernel_name + "' of " + m_name + " could not be created" + device +
                    " (" + error +
                    "): " + (reason.empty() ? "the implementation gave no reason" : reason),
                message + (log.empty() ? "" : "build log:\n" + log));
}

std::vector<std::string> Program::kernel_names() const {
    std::vector<std::string> out;
    std::string list = m_program.getInfo<CL_PROGRAM_KERNEL_NAMES>();
    list = list.c_str(); // some implementations count the terminating NUL
    std::size_t begin = 0;
    while (begin < list.size()) {
        const std::size_t end = std::min(list.find(';', begin), list.size());
        if (end > begin) out.push_back(list.substr(begin, end - begin));
        begin = end + 1;
    }
    return out;
}

} // namespace tandem
