// An OpenCL context and in-order profiling queue on one device, with per-stage event timing.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "runtime/device.h"
#include "runtime/tuning.h"

namespace tandem {

/// Accumulated device time of one named stage.
struct StageTime {
    std::string stage;
    double seconds = 0.0; ///< sum of (end - start) of the stage's events
    int count = 0;        ///< number of enqueued commands
};

class Context {
public:
    /// Creates a context and an in-order queue with profiling on the device, which works as
    /// `tuning` says (its builds, its device scenes' policy). Arms the fault hooks from it, and
    /// chooses PoCL's work-group method (pocl_choose_work_group_method).
    Context(DeviceInfo device, Tuning tuning);
    /// Context on select_device(device_spec), else on select_device(tuning.device).
    static Context create(const std::string& device_spec, const Tuning& tuning) {
        return Context(select_device(device_spec.empty() ? tuning.device : device_spec), tuning);
    }
    /// create(device_spec, tuning_from_environment()): for an entry point that takes the
    /// environment as it is when it opens a context (a Python session, a benchmark program).
    static Context create(const std::string& device_spec = {}) {
        return create(device_spec, tuning_from_environment());
    }
    /// Waits for the queue before releasing it. A command still enqueued when the process exits
    /// (the caller threw after a launch) may be running on a driver thread, or, on PoCL, compiling
    /// its work-group function with LLVM, while exit() destroys LLVM's statics: a crash after
    /// main has returned.
    ~Context();
    Context(Context&&) = default;
    Context& operator=(Context&&) = delete;

    const DeviceInfo& device() const { return m_device; }
    /// The switches this context works with: what Program::build and the device scenes made on
    /// it read (never the environment).
    const Tuning& tuning() const { return m_tuning; }
    /// Replaces them for what is built or made on the context from now on (tests that compare
    /// policies on one context); the work-group method and the fault hooks stay as they were.
    void set_tuning(Tuning tuning) { m_tuning = std::move(tuning); }
    cl::Context& cl_context() { return m_context; }
    cl::CommandQueue& queue() { return m_queue; }

    /// Device timing is on request: while off (the default), record() keeps nothing, so a long
    /// run neither grows a list of events nor waits for them.
    void set_stage_timing(bool on) {
        m_timing = on;
        if (!on) m_events.clear();
    }
    bool stage_timing() const { return m_timing; }
    /// Records an enqueued command under a stage name (callers record only with timing on).
    void record(const std::string& stage, const cl::Event& event);
    /// A mark in the recorded stages, for stage_times_since().
    std::size_t stage_mark() const { return m_events.size(); }
    /// Waits for the queue, then returns the device time of every stage recorded after `mark`,
    /// leaving the record as it is (for a caller that times its own work inside a longer one).
    std::vector<StageTime> stage_times_since(std::size_t mark);
    /// Waits for the queue, then returns the device time of every stage recorded since the last
    /// call (in order of first appearance) and forgets them. Empty while timing is off.
    std::vector<StageTime> stage_times();
    /// Blocks until every enqueued command has completed.
    void finish() { m_queue.finish(); }

private:
    DeviceInfo m_device;
    Tuning m_tuning;
    cl::Context m_context;
    cl::CommandQueue m_queue;
    std::vector<std::pair<std::string, cl::Event>> m_events;
    bool m_timing = false;
};

/// Waits for the queue when it goes out of scope (errors ignored): keeps host memory that
/// non-blocking reads write into alive until they are done, whatever way the scope is left.
class FinishOnExit {
public:
    explicit FinishOnExit(Context& ctx) : m_ctx(ctx) {}
    FinishOnExit(const FinishOnExit&) = delete;
    FinishOnExit& operator=(const FinishOnExit&) = delete;
    ~FinishOnExit() {
        try {
            m_ctx.finish();
        } catch (...) {
        }
    }

private:
    Context& m_ctx;
};

/// Seconds of `stage` in `times`, 0 if absent.
double stage_seconds(const std::vector<StageTime>& times, const std::string& stage);

} // namespace tandem
