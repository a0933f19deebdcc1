// Optimizer driver.
#include "core/inverse/optimizer.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <vector>

#include "runtime/error.h"

namespace tandem {

namespace {

std::string free_name(const ParamState& state, const std::string& name) {
    if (!name.empty()) return name;
    for (unsigned i = 0;; ++i) {
        const std::string candidate = "optimizer" + std::to_string(i);
        if (!state.has_buffer(candidate + ".m")) return candidate;
    }
}

} // namespace

OptimizerConfig::Method optimizer_method(const std::string& name) {
    if (name == "adam") return OptimizerConfig::Method::adam;
    if (name == "sgd") return OptimizerConfig::Method::sgd;
    throw Error("optimizer method '" + name + "': expected 'adam' or 'sgd'");
}

Optimizer::Optimizer(ParamState& state, const KernelLibrary& lib, const OptimizerConfig& config,
                     const std::string& name)
    : m_state(state), m_name(free_name(state, name)), m_update(state.context(), lib, config) {
    m_m = &state.add_buffer(m_name + ".m", state.size(), 0.0f);
    try {
        m_v = &state.add_buffer(m_name + ".v", state.size(), 0.0f);
    } catch (...) {
        state.remove_buffer(m_name + ".m");
        throw;
    }
}

Optimizer::~Optimizer() {
    m_state.remove_buffer(m_name + ".m");
    m_state.remove_buffer(m_name + ".v");
}

void Optimizer::set_rates(const std::vector<std::pair<const Parameter*, float>>& rates) {
    std::vector<float> lr(m_state.size(), 0.0f);
    for (const auto& [p, rate] : rates) {
        if (!std::isfinite(rate) || rate < 0.0f) {
            std::ostringstream m;
            m << p->name << ": learning rate " << rate << " must be finite and >= 0";
            throw Error(m.str());
        }
        std::fill(lr.begin() + std::ptrdiff_t(p->offset),
                  lr.begin() + std::ptrdiff_t(p->offset + p->size), rate);
    }
    m_rates = Buffer<float>(m_state.context(), "learning rates", lr);
}

unsigned Optimizer::steps() const {
    return m_name == k_state_optimizer ? m_state.steps() : m_steps;
}

OptimizerUpdate::OptimizerUpdate(Context& ctx, const KernelLibrary& lib,
                                 const OptimizerConfig& config)
    : m_ctx(ctx), m_config(config), m_program(Program::build(ctx, lib, "optim.cl", "")),
      m_adam(m_program, "adam_update"), m_sgd(m_program, "sgd_update") {}

void OptimizerUpdate::warm_up() {
    Buffer<float> p(m_ctx, "scratch", std::vector<float>(1, 0.5f)),
        g(m_ctx, "scratch", std::vector<float>(1, 0.0f));
    Buffer<float> lr(m_ctx, "scratch", std::vector<float>(1, 0.0f)),
        lo(m_ctx, "scratch", std::vector<float>(1, 0.0f));
    Buffer<float> hi(m_ctx, "scratch", std::vector<float>(1, 1.0f)), m(m_ctx, "scratch", 1),
        v(m_ctx, "scratch", 1);
    update(p, g, m, v, lr, lo, hi, 1);
    m_ctx.finish();
}

void Optimizer::step(const Buffer<float>* gradient) {
    if (m_name == k_state_optimizer)
        m_state.count_step();
    else
        ++m_steps;
    ParamState& s = m_state;
    m_update.update(s.theta(), gradient ? *gradient : s.gradient().value, moment1(), moment2(),
                    m_rates.size() ? m_rates : s.learning_rates(), s.lower(), s.upper(), steps());
}

void OptimizerUpdate::update(Buffer<float>& params, const Buffer<float>& grads, Buffer<float>& m,
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
