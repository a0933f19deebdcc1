// Kernel source lookup and #include inlining with #line markers (LuxCore's approach).
#include "runtime/kernel_source.h"

#include <fstream>
#include <set>
#include <sstream>

#include "runtime/error.h"

namespace tandem {

KernelLibrary KernelLibrary::from_tuning(const Tuning& tuning) {
    if (!tuning.kernel_dir.empty()) return from_directory(tuning.kernel_dir);
    return embedded();
}

KernelLibrary KernelLibrary::from_environment() {
    return from_tuning(tuning_from_environment());
}

KernelLibrary KernelLibrary::from_directory(std::string dir) {
    KernelLibrary lib;
    while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
    lib.m_dir = std::move(dir);
    return lib;
}

KernelLibrary KernelLibrary::embedded() { return KernelLibrary{}; }

KernelLibrary KernelLibrary::with_files(const EmbeddedFile* files, std::size_t count) const {
    KernelLibrary lib = *this;
    lib.m_extra = files;
    lib.m_extra_count = count;
    return lib;
}

std::string KernelLibrary::read(const std::string& path) const {
    const auto extra = [&]() -> const char* {
        for (std::size_t i = 0; i < m_extra_count; ++i)
            if (path == m_extra[i].path) return m_extra[i].text;
        return nullptr;
    };
    if (m_dir.empty()) {
        std::size_t count = 0;
        const EmbeddedFile* files = embedded_kernel_files(&count);
        for (std::size_t i = 0; i < count; ++i)
            if (path == files[i].path) return files[i].text;
        if (const char* text = extra()) return text;
        throw Error("kernel source kernels/" + path + " is not embedded in this build");
    }
    const std::string full = m_dir + "/" + path;
    std::ifstream in(full, std::ios::binary);
    if (!in) {
        if (const char* text = extra()) return text;
        throw Error("cannot read kernel source " + full + " (TANDEM_KERNEL_DIR)");
    }
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
}

namespace {

/// Returns the quoted file name if `line` is an #include "..." directive, else an empty string.
std::string include_target(const std::string& line) {
    std::size_t i = line.find_first_not_of(" \t");
    if (i == std::string::npos || line[i] != '#') return {};
    i = line.find_first_not_of(" \t", i + 1);
    if (i == std::string::npos || line.compare(i, 7, "include") != 0) return {};
    const std::size_t open = line.find('"', i + 7);
    if (open == std::string::npos) return {};
    const std::size_t close = line.find('"', open + 1);
    if (close == std::string::npos) return {};
    return line.substr(open + 1, close - open - 1);
}

void inline_file(const KernelLibrary& lib, const std::string& path, std::set<std::string>& seen,
                 std::ostringstream& out) {
    seen.insert(path);
    std::istringstream in(lib.read(path));
    out << "#line 1 \"kernels/" << path << "\"\n";
    std::string line;
    int number = 0;
    while (std::getline(in, line)) {
        ++number;
        const std::string target = include_target(line);
        if (target.empty()) {
            out << line << '\n';
            continue;
        }
        if (!seen.count(target)) {
            try {
                inline_file(lib, target, seen, out);
            } catch (const Error& e) {
                throw Error("kernels/" + path + ":" + std::to_string(number) + ": " + e.what());
            }
        }
        out << "#line " << number + 1 << " \"kernels/" << path << "\"\n";
    }
}

} // namespace

std::string KernelLibrary::preprocess(const std::string& path) const {
    std::set<std::string> seen;
    std::ostringstream out;
    inline_file(*this, path, seen, out);
    return out.str();
}

} // namespace tandem
