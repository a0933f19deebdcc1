// Kernel sources: embedded into the binary at build time (cmake/embed_kernels.cmake), or read from
// a directory (Tuning::kernel_dir, $TANDEM_KERNEL_DIR) so kernels can be edited without a
// rebuild. Includes are inlined with #line markers, so compiler messages name the real
// kernels/<file>:<line>.
#pragma once

#include <cstddef>
#include <string>

#include "runtime/tuning.h"

namespace tandem {

/// One file of the kernels/ tree, as embedded by the build. `path` is relative to kernels/.
struct EmbeddedFile {
    const char* path;
    const char* text;
};

/// The files embedded at build time (defined in the generated kernel_sources_embedded.cpp).
const EmbeddedFile* embedded_kernel_files(std::size_t* count);

class KernelLibrary {
public:
    /// Files from tuning.kernel_dir when it names one, otherwise the embedded copy.
    static KernelLibrary from_tuning(const Tuning& tuning);
    /// from_tuning(tuning_from_environment()): for entry points (the tests, a Python session).
    static KernelLibrary from_environment();
    /// Files read from a directory laid out like kernels/.
    static KernelLibrary from_directory(std::string dir);
    /// The embedded copy.
    static KernelLibrary embedded();
    /// This library with `count` more files: read() takes a path from them where the library itself
    /// (embedded, or its directory) has no such file. For the programs only the tests and the
    /// benchmarks build (tests/kernels/probes, bench/kernels), which the product does not embed;
    /// a kernel directory may still replace them. `files` must outlive the library (generated
    /// arrays do).
    KernelLibrary with_files(const EmbeddedFile* files, std::size_t count) const;

    /// Text of one file (path relative to kernels/). Throws Error if it does not exist.
    std::string read(const std::string& path) const;
    /// The file with every `#include "..."` inlined once, each piece preceded by a #line marker
    /// naming kernels/<path>. Throws Error naming the including file and line if one is missing.
    std::string preprocess(const std::string& path) const;
    /// "embedded" or the directory the files come from, for messages.
    const std::string& origin() const { return m_dir.empty() ? k_embedded : m_dir; }

private:
    inline static const std::string k_embedded = "embedded";
    std::string m_dir; // empty: embedded
    const EmbeddedFile* m_extra = nullptr; ///< with_files(): looked up after the rest
    std::size_t m_extra_count = 0;
};

} // namespace tandem
