// Loss and optimizer drivers.
#include "core/optimize_kernels.h"

#include <cmath>
#include <vector>

#include "runtime/error.h"

namespace tandem {

unsigned loss_kind(const std::string& name) {
    if (name == "mean") return LOSS_MEAN;
    if (name == "l1") return LOSS_L1;
    if (name == "l2") return LOSS_L2;
    if (name == "rl2") return LOSS_RL2;
    throw Error("unknown loss '" + name + "' (mean, l1, l2, rl2)");
}

ImageLoss::ImageLoss(Context& ctx, const KernelLibrary& lib)
    : m_ctx(ctx), m_program(Program::build(ctx, lib, "loss.cl", "")),
      m_terms(m_program, "loss_terms"), m_cv_terms(m_program, "cv_loss_terms"),
      m_sum(m_program, "sum_chunks") {}

Buffer<float>& ImageLoss::terms(unsigned n) {
    if (m_term_buf.size() != n) {
        m_term_buf = Buffer<float>(m_ctx, "loss terms", n);
        m_partial = Buffer<float>(m_ctx, "loss partial sums", (n + k_chunk - 1) / k_chunk);
    }
    return m_term_buf;
}

float ImageLoss::reduce(unsigned n) {
    const unsigned chunks = (n + k_chunk - 1) / k_chunk;
    m_sum.launch(m_ctx, "loss", chunks, m_term_buf, m_partial, k_chunk, n);
    float sum = 0.0f; // the partial sums in order, then the mean
    for (float p : m_partial.download()) sum += p;
    return sum / static_cast<float>(n);
}

float ImageLoss::evaluate_cv(unsigned kind, const Buffer<float>& f, const Buffer<float>& h,
                             Buffer<gpu::CvState>& state, const gpu::CvConfig& config,
                             const Buffer<float>& reference, Buffer<float>& delta) {
    const auto n = static_cast<unsigned>(f.size());
    if (h.size() != f.size() || state.size() != f.size() || delta.size() != f.size())
        throw Error("control variate: image, state and delta buffers differ in size");
    if (kind != LOSS_MEAN && reference.size() != f.size())
        throw Error("loss: the reference has " + std::to_string(reference.size()) +
                    " elements, the image " + std::to_string(f.size()));
    m_cv_terms.launch(m_ctx, "loss", n, f, h, state, reference, terms(n), delta, kind, n, config);
    return reduce(n);
}

float ImageLoss::evaluate(unsigned kind, const Buffer<float>& image, const Buffer<float>& reference,
                          Buffer<float>& delta) {
    const auto n = static_cast<unsigned>(image.size());
    if (kind != LOSS_MEAN && reference.size() != image.size())
        throw Error("loss: the reference has " + std::to_string(reference.size()) +
                    " elements, the image " + std::to_string(image.size()));
    if (delta.size() != image.size()) throw Error("loss: delta buffer of the wrong size");
    m_terms.launch(m_ctx, "loss", n, image, reference, terms(n), delta, kind, n);
    return reduce(n);
}

Optimizer::Optimizer(Context& ctx, const KernelLibrary& lib, Method method, std::size_t count,
                     float beta1, float beta2, float epsilon)
    : m_ctx(ctx), m_method(method), m_count(count), m_beta1(beta1), m_beta2(beta2),
      m_epsilon(epsilon), m_m(ctx, "adam m", std::vector<float>(count, 0.0f)),
      m_v(ctx, "adam v", std::vector<float>(count, 0.0f)),
      m_program(Program::build(ctx, lib, "optim.cl", "")), m_adam(m_program, "adam_update"),
      m_sgd(m_program, "sgd_update") {}

void Optimizer::warm_up() {
    Buffer<float> p(m_ctx, "scratch", std::vector<float>(1, 0.5f)), g(m_ctx, "scratch", std::vector<float>(1, 0.0f));
    Buffer<float> lr(m_ctx, "scratch", std::vector<float>(1, 0.0f)), lo(m_ctx, "scratch", std::vector<float>(1, 0.0f));
    Buffer<float> hi(m_ctx, "scratch", std::vector<float>(1, 1.0f)), m(m_ctx, "scratch", 1), v(m_ctx, "scratch", 1);
    gpu::AdamConfig c{};
    c.beta1 = m_beta1;
    c.beta2 = m_beta2;
    c.epsilon = m_epsilon;
    c.correction1 = c.correction2 = 1.0f;
    if (m_method == Method::sgd)
        m_sgd.launch(m_ctx, "optimizer", 1, p, g, lr, lo, hi, 1u);
    else
        m_adam.launch(m_ctx, "optimizer", 1, p, g, m, v, lr, lo, hi, c, 1u);
    m_ctx.finish();
}

void Optimizer::step(Buffer<float>& params, const Buffer<float>& grads, const Buffer<float>& lr,
                     const Buffer<float>& lower, const Buffer<float>& upper) {
    for (const std::size_t size : {params.size(), grads.size(), lr.size(), lower.size(), upper.size()})
        if (size != m_count)
            throw Error("optimizer: a buffer has " + std::to_string(size) + " elements, not " +
                        std::to_string(m_count));
    const auto n = static_cast<unsigned>(m_count);
    ++m_step;
    if (m_method == Method::sgd) {
        m_sgd.launch(m_ctx, "optimizer", n, params, grads, lr, lower, upper, n);
        return;
    }
    gpu::AdamConfig c{};
    c.beta1 = m_beta1;
    c.beta2 = m_beta2;
    c.epsilon = m_epsilon;
    c.correction1 = static_cast<float>(1.0 - std::pow(double(m_beta1), double(m_step)));
    c.correction2 = static_cast<float>(1.0 - std::pow(double(m_beta2), double(m_step)));
    m_adam.launch(m_ctx, "optimizer", n, params, grads, m_m, m_v, lr, lower, upper, c, n);
}

} // namespace tandem
