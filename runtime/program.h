// Program build with explicit options, build errors mapped to kernels/<file>:<line>, and an on-disk
// binary cache keyed by (source, options, device, driver version).
#pragma once

#include <string>
#include <vector>

#include "runtime/context.h"
#include "runtime/kernel_source.h"

namespace tandem {

/// The options every program is built with on `device` by a context with `tuning`, set in this one
/// place: OpenCL C 1.2, and correctly rounded division and sqrt where the device offers them.
/// Never fast-math or mad-enable. (The tuning's measurement switches add -g, or defines that
/// change no code but keep the cache keys of their builds apart.)
std::string base_build_options(const DeviceInfo& device, const Tuning& tuning);

class Program {
public:
    /// Builds kernels/<file> (includes inlined) with base_build_options() followed by `options`
    /// (feature flags), through the binary cache in ctx.tuning().cache_dir (none when empty).
    /// Throws Error whose message is the first compiler error as "kernels/<file>:<line>: ...",
    /// with the full build log in Error::detail().
    static Program build(Context& ctx, const KernelLibrary& lib, const std::string& file,
                         const std::string& options);
    /// Builds a source string (base options first, like build()); `name` labels it in messages.
    /// No #include inlining.
    static Program build_source(Context& ctx, const std::string& name, const std::string& source,
                                const std::string& options);

    cl::Kernel kernel(const std::string& name) const;
    /// The names of the program's kernels (CL_PROGRAM_KERNEL_NAMES), in the implementation's order.
    std::vector<std::string> kernel_names() const;
    const std::string& name() const { return m_name; }
    /// True if this program came from the on-disk cache rather than the compiler.
    bool from_cache() const { return m_from_cache; }

private:
    cl::Program m_program;
    std::string m_name;
    bool m_from_cache = false;
};

} // namespace tandem
