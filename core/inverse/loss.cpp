// Image loss driver.
#include "core/inverse/loss.h"

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
      m_sum(m_program, "sum_chunks"), m_alpha(m_program, "cv_alpha_image") {}

ImageLoss::~ImageLoss() {
    try {
        m_ctx.finish(); // a pending read of the chunk sums writes into m_partial_host
    } catch (...) {
    }
}

Buffer<float>& ImageLoss::terms(unsigned n) {
    if (m_term_buf.size() != n) {
        m_ctx.finish(); // as above, before m_partial_host is reallocated
        m_term_buf = Buffer<float>(m_ctx, "loss terms", n);
        m_partial = Buffer<float>(m_ctx, "loss partial sums", (n + k_chunk - 1) / k_chunk);
        m_partial_host.assign(m_partial.size(), 0.0f);
    }
    return m_term_buf;
}

void ImageLoss::reduce(unsigned n) {
    const unsigned chunks = (n + k_chunk - 1) / k_chunk;
    m_sum.launch(m_ctx, "loss", chunks, m_term_buf, m_partial, k_chunk, n);
    m_partial.enqueue_read(0, chunks, m_partial_host.data());
    m_count = n;
}

float ImageLoss::value() {
    if (m_count == 0) throw Error("loss: nothing has been evaluated");
    m_ctx.finish();
    float sum = 0.0f; // the partial sums in order, then the mean
    for (float p : m_partial_host)
        sum += p;
    return sum / static_cast<float>(m_count);
}

void ImageLoss::evaluate_cv(unsigned kind, const Buffer<float>& f, const Buffer<float>& h,
                            Buffer<gpu::CvState>& state, const gpu::CvConfig& config,
                            const Buffer<float>& reference, Buffer<float>& delta) {
    const auto n = static_cast<unsigned>(f.size());
    if (h.size() != f.size() || state.size() != f.size() || delta.size() != f.size())
        throw Error("control variate: image, state and delta buffers differ in size");
    if (kind != LOSS_MEAN && reference.size() != f.size())
        throw Error("loss: the reference has " + std::to_string(reference.size()) +
                    " elements, the image " + std::to_string(f.size()));
    m_cv_terms.launch(m_ctx, "loss", n, f, h, state, reference, terms(n), delta, kind, n, config);
    reduce(n);
}

void ImageLoss::evaluate(unsigned kind, const Buffer<float>& image, const Buffer<float>& reference,
                         Buffer<float>& delta) {
    const auto n = static_cast<unsigned>(image.size());
    if (kind != LOSS_MEAN && reference.size() != image.size())
        throw Error("loss: the reference has " + std::to_string(reference.size()) +
                    " elements, the image " + std::to_string(image.size()));
    if (delta.size() != image.size()) throw Error("loss: delta buffer of the wrong size");
    m_terms.launch(m_ctx, "loss", n, image, reference, terms(n), delta, kind, n);
    reduce(n);
}

void ImageLoss::cv_alpha(const Buffer<gpu::CvState>& state, Buffer<float>& alpha) {
    if (alpha.size() != state.size())
        throw Error("control variate: alpha buffer of the wrong size");
    const auto n = static_cast<unsigned>(state.size());
    m_alpha.launch(m_ctx, "metrics", n, state, alpha, n);
}

} // namespace tandem
