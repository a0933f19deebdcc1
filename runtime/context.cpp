// OpenCL context, queue and stage timing.
#include "runtime/context.h"

#include <algorithm>

#include "runtime/error.h"
#include "runtime/fault.h"
#include "runtime/pocl_llvm.h"

namespace tandem {

Context::Context(DeviceInfo device, Tuning tuning)
    : m_device(std::move(device)), m_tuning(std::move(tuning)) {
    fault::configure(m_tuning.faults);
    // before any kernel of the process is compiled
    pocl_choose_work_group_method(m_device, m_tuning);
    try {
        m_context = cl::Context(m_device.device);
        m_queue = cl::CommandQueue(m_context, m_device.device, CL_QUEUE_PROFILING_ENABLE);
    } catch (const cl::Error& e) {
        throw DeviceError("cannot create an OpenCL context on '" + m_device.name +
                          "': " + e.what() + " (" + cl_error_name(e.err()) + ")");
    }
}

Context::~Context() {
    if (!m_queue()) return; // moved from
    try {
        m_queue.finish();
    } catch (...) {
        // a lost device: nothing to wait for, and a destructor must not throw
    }
}

void Context::record(const std::string& stage, const cl::Event& event) {
    if (m_timing) m_events.emplace_back(stage, event);
}

std::vector<StageTime> Context::stage_times() {
    std::vector<StageTime> out = stage_times_since(0);
    m_events.clear();
    return out;
}

std::vector<StageTime> Context::stage_times_since(std::size_t mark) {
    finish();
    std::vector<StageTime> out;
    for (std::size_t i = std::min(mark, m_events.size()); i < m_events.size(); ++i) {
        const auto& [stage, event] = m_events[i];
        const cl_ulong start = event.getProfilingInfo<CL_PROFILING_COMMAND_START>();
        const cl_ulong end = event.getProfilingInfo<CL_PROFILING_COMMAND_END>();
        StageTime* slot = nullptr;
        for (StageTime& s : out)
            if (s.stage == stage) slot = &s;
        if (!slot) {
            out.push_back(StageTime{stage, 0.0, 0});
            slot = &out.back();
        }
        slot->seconds += static_cast<double>(end - start) * 1e-9;
        slot->count += 1;
    }
    return out;
}

double stage_seconds(const std::vector<StageTime>& times, const std::string& stage) {
    for (const StageTime& s : times)
        if (s.stage == stage) return s.seconds;
    return 0.0;
}

} // namespace tandem
