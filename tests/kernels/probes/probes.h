// The probe kernels (this folder): programs only the tests build, to compare the device
// compiler's struct layouts and the device's arithmetic with the host's. They are embedded into
// the test binaries alone (tests/CMakeLists.txt), not into the product's kernel sources.
#pragma once

#include <cstddef>

#include "runtime/kernel_source.h"

namespace tandem {

/// The files of tests/kernels/probes, named "probes/<file>" (generated at build time).
const EmbeddedFile* probe_kernel_files(std::size_t* count);

/// The kernel library the tests use with the probes in front, so that "probes/layout.cl" and
/// "probes/math_probe.cl" build (and include the product's kernels/shared headers).
inline KernelLibrary probe_library() {
    std::size_t count = 0;
    const EmbeddedFile* files = probe_kernel_files(&count);
    return KernelLibrary::from_environment().with_files(files, count);
}

} // namespace tandem
