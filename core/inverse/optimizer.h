// Adam or gradient descent on the device (kernels/optim.cl), over the flat parameter layout of a
// parameter state, with per-element learning rates and valid ranges. The optimizer owns its
// moments, registered in the parameter state as named buffers so that checkpoints save them;
// `tandem optimize` and the Python module's Optimizer are this one class.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "core/inverse/param_state.h"
#include "runtime/kernel_source.h"
#include "runtime/launch.h"
#include "shared/optim.h"

namespace tandem {

struct OptimizerConfig {
    enum class Method { adam, sgd } method = Method::adam;
    float beta1 = 0.9f, beta2 = 0.999f, epsilon = 1e-8f; ///< Adam
};

/// "adam" or "sgd"; throws Error naming them otherwise.
OptimizerConfig::Method optimizer_method(const std::string& name);

/// The update kernels of a method, on explicit buffers.
class OptimizerUpdate {
public:
    OptimizerUpdate(Context& ctx, const KernelLibrary& lib, const OptimizerConfig& config);
    /// The update on explicit buffers (all of one size), as step t (1-based) of Adam. Enqueued.
    void update(Buffer<float>& params, const Buffer<float>& grads, Buffer<float>& m,
                Buffer<float>& v, const Buffer<float>& lr, const Buffer<float>& lower,
                const Buffer<float>& upper, unsigned t);
    /// Launches the update kernel once on scratch data (PoCL compiles on first launch).
    void warm_up();
    const OptimizerConfig& config() const { return m_config; }

private:
    Context& m_ctx;
    OptimizerConfig m_config;
    Program m_program;
    Kernel m_adam, m_sgd;
};

class Optimizer {
public:
    /// The name of the state's own optimizer: its moments are "adam.m" and "adam.v" and its step
    /// count is the state's (ParamState::steps), as checkpoints hold them.
    static constexpr const char* k_state_optimizer = "adam";

    /// Over `state` (which must outlive it), its moments zero in `state` under `name`.m and
    /// `name`.v. With `name` k_state_optimizer (the default) it is the state's own optimizer;
    /// with an empty name it takes the first free "optimizerN" and counts its steps itself, so
    /// that several optimizers over disjoint parameters of one state do not disturb each other.
    /// The learning rates are the state's (ParamState::learning_rates) unless set_rates() gives
    /// it its own. Throws Error if the name is taken.
    Optimizer(ParamState& state, const KernelLibrary& lib, const OptimizerConfig& config,
              const std::string& name = k_state_optimizer);
    /// Removes its moments from the state.
    ~Optimizer();
    Optimizer(const Optimizer&) = delete;
    Optimizer& operator=(const Optimizer&) = delete;

    /// Learning rates of its own: `rate` for every element of each parameter, 0 elsewhere.
    /// Throws Error for a negative or non-finite rate.
    void set_rates(const std::vector<std::pair<const Parameter*, float>>& rates);

    /// One step: theta <- update(theta, gradient), clamped to [lower, upper] per element, with
    /// the state's gradient (the adjoint's output), or `gradient` (one value per element); counts
    /// the step. Enqueued.
    void step(const Buffer<float>* gradient = nullptr);
    unsigned steps() const;
    /// Launches the update kernel once on scratch data (PoCL compiles on first launch).
    void warm_up() { m_update.warm_up(); }
    const OptimizerConfig& config() const { return m_update.config(); }
    const std::string& name() const { return m_name; }
    Buffer<float>& moment1() { return *m_m; } ///< the state's buffer `name`.m
    Buffer<float>& moment2() { return *m_v; } ///< the state's buffer `name`.v

private:
    ParamState& m_state;
    std::string m_name;
    OptimizerUpdate m_update;
    Buffer<float>* m_m = nullptr; ///< the moments, in the state
    Buffer<float>* m_v = nullptr;
    Buffer<float> m_rates; ///< set_rates()'s; empty: the state's
    unsigned m_steps = 0;  ///< steps of an optimizer other than the state's own
};

} // namespace tandem
