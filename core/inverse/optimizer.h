// Adam or gradient descent on the device (kernels/optim.cl), over the flat parameter layout, with
// per-element learning rates and valid ranges. The moments and the step count live in the
// parameter state; this holds only the method and the kernels.
#pragma once

#include "core/inverse/param_state.h"
#include "runtime/kernel_source.h"
#include "runtime/launch.h"
#include "shared/optim.h"

namespace tandem {

struct OptimizerConfig {
    enum class Method { adam, sgd } method = Method::adam;
    float beta1 = 0.9f, beta2 = 0.999f, epsilon = 1e-8f; ///< Adam
};

class Optimizer {
public:
    Optimizer(Context& ctx, const KernelLibrary& lib, const OptimizerConfig& config);

    /// One step on `state`: theta <- update(theta, gradient), clamped to [lower, upper] per
    /// element; counts the step. Enqueued.
    void step(ParamState& state);
    /// The update on explicit buffers (all of one size), as step t (1-based) of Adam.
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

} // namespace tandem
