// Kernel launch: a variadic argument setter, a fixed local size, and a stage name on every enqueue.
#pragma once

#include <string>
#include <type_traits>
#include <utility>

#include "runtime/buffer.h"
#include "runtime/program.h"

namespace tandem {

/// Work-group size of every launch. Fixed, so results never depend on the driver's choice; kernels
/// guard `get_global_id(0) < count` because the global size is rounded up to a multiple of it.
constexpr std::size_t k_local_size = 64;

class Kernel {
public:
    Kernel() = default;
    Kernel(const Program& program, const std::string& name)
        : m_kernel(program.kernel(name)), m_name(name) {}

    /// Sets every argument in order (Buffer<T> or a trivially copyable scalar/struct), enqueues
    /// `global_size` work items under `stage`, and records its event when stage timing is on.
    /// Does not wait for completion.
    template <class... Args>
    void launch(Context& ctx, const std::string& stage, std::size_t global_size,
                const Args&... args) {
        cl_uint index = 0;
        (set_arg(index++, args), ...);
        const std::size_t rounded = (global_size + k_local_size - 1) / k_local_size * k_local_size;
        if (rounded == 0) return;
        cl::Event event; // only with stage timing on: no event otherwise
        try {
            ctx.queue().enqueueNDRangeKernel(m_kernel, cl::NullRange, cl::NDRange(rounded),
                                             cl::NDRange(k_local_size), nullptr,
                                             ctx.stage_timing() ? &event : nullptr);
        } catch (const cl::Error& e) {
            throw DeviceError("launch of kernel '" + m_name + "' (" + stage +
                              ") failed: " + cl_error_name(e.err()));
        }
        if (ctx.stage_timing()) ctx.record(stage, event);
    }

private:
    template <class T> void set_arg(cl_uint index, const Buffer<T>& buffer) {
        m_kernel.setArg(index, buffer.cl());
    }
    template <class T> void set_arg(cl_uint index, const T& value) {
        static_assert(std::is_trivially_copyable_v<T>, "kernel arguments must be plain data");
        m_kernel.setArg(index, sizeof(T), &value);
    }

    cl::Kernel m_kernel;
    std::string m_name;
};

} // namespace tandem
