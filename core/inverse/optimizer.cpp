// Optimizer driver.
#include "core/inverse/optimizer.h"

#include <cmath>
#include <vector>

#include "runtime/error.h"

namespace tandem {

Optimizer::Optimizer(Context& ctx, const KernelLibrary& lib, const OptimizerConfig& config)
    : m_ctx(ctx), m_config(config), m_program(Program::build(ctx, lib, "optim.cl", "")),
      m_adam(m_program, "adam_update"), m_sgd(m_program, "sgd_update") {}

void Optimizer::warm_up() {
    Buffer<float> p(m_ctx, "scratch", std::vector<float>(1, 0.5f)),
        g(m_ctx, "scratch", std::vector<float>(1, 0.0f));
    Buffer<float> lr(m_ctx, "scratch", std::vector<float>(1, 0.0f)),
        lo(m_ctx, "scratch", std::vector<float>(1, 0.0f));
    Buffer<float> hi(m_ctx, "scratch", std::vector<float>(1, 1.0f)), m(m_ctx, "scratch", 1),
        v(m_ctx, "scratch", 1);
    update(p, g, m, v, lr, lo, hi, 1);
    m_ctx.finish();
}

void Optimizer::step(ParamState& s) {
    s.count_step();
    update(s.theta(), s.gradient().value, s.moment1(), s.moment2(), s.learning_rates(), s.lower(),
           s.upper(), s.steps());
}

void Optimizer::update(Buffer<float>& params, const Buffer<float>& grads, Buffer<float>& m,
                       Buffer<float>& v, const Buffer<float>& lr, const Buffer<float>& lower,
                       const Buffer<float>& upper, unsigned t) {
    const std::size_t count = params.size();
    for (const std::size_t size :
         {grads.size(), m.size(), v.size(), lr.size(), lower.size(), upper.size()})
        if (size != count)
            throw Error("optimizer: a buffer has " + std::to_string(size) + " elements, not " +
                        std::to_string(count));
    const auto n = static_cast<unsigned>(count);
    if (m_config.method == OptimizerConfig::Method::sgd) {
        m_sgd.launch(m_ctx, "optimizer", n, params, grads, lr, lower, upper, n);
        return;
    }
    gpu::AdamConfig c{};
    c.beta1 = m_config.beta1;
    c.beta2 = m_config.beta2;
    c.epsilon = m_config.epsilon;
    c.correction1 = static_cast<float>(1.0 - std::pow(double(m_config.beta1), double(t)));
    c.correction2 = static_cast<float>(1.0 - std::pow(double(m_config.beta2), double(t)));
    m_adam.launch(m_ctx, "optimizer", n, params, grads, m, v, lr, lower, upper, c, n);
}

} // namespace tandem
