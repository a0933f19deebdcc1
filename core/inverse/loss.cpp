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
      m_sum(m_program, "sum_chunks"), m_alpha(m_program, "cv_alpha_image"),
      m_mask(m_program, "mask_terms") {}

ImageLoss::~ImageLoss() {
    try {
        m_ctx.finish(); // a pending read of the chunk sums writes into m_partial_host
    } catch (...) {
    }
}

Buffer<float>& ImageLoss::terms(unsigned n) {
    if (m_term_buf.size() < n) m_term_buf = Buffer<float>(m_ctx, "loss terms", n);
    return m_term_buf;
}

void ImageLoss::reduce(unsigned n, Buffer<float>& delta, const Buffer<float>* mask, bool add) {
    if (mask) {
        if (std::size_t(3) * mask->size() != n) throw Error("loss: a mask of the wrong size");
        m_mask.launch(m_ctx, "loss", n, m_term_buf, delta, *mask, n);
    }
    if (!add) { // (a read still pending into a spare's host vector keeps its order in the queue)
        for (auto& p : m_pending) m_spare.push_back(std::move(p));
        m_pending.clear();
    }
    const unsigned chunks = (n + k_chunk - 1) / k_chunk;
    std::unique_ptr<Pending> p;
    for (auto it = m_spare.begin(); it != m_spare.end(); ++it)
        if ((*it)->partial.size() == chunks) {
            p = std::move(*it);
            m_spare.erase(it);
            break;
        }
    if (!p) {
        p = std::make_unique<Pending>();
        p->partial = Buffer<float>(m_ctx, "loss partial sums", chunks);
        p->host.assign(chunks, 0.0f);
    }
    p->count = n;
    m_sum.launch(m_ctx, "loss", chunks, m_term_buf, p->partial, k_chunk, n);
    p->partial.enqueue_read(0, chunks, p->host.data());
    m_pending.push_back(std::move(p));
}

std::vector<float> ImageLoss::values() {
    if (m_pending.empty()) throw Error("loss: nothing has been evaluated");
    m_ctx.finish();
    std::vector<float> means; // each evaluation's partial sums in order, then its mean
    for (const auto& p : m_pending) {
        float sum = 0.0f;
        for (float v : p->host)
            sum += v;
        means.push_back(sum / static_cast<float>(p->count));
    }
    return means;
}

float ImageLoss::value() { return sum_losses(values()); }

void ImageLoss::evaluate_cv(unsigned kind, const Buffer<float>& f, const Buffer<float>& h,
                            Buffer<gpu::CvState>& state, const gpu::CvConfig& config,
                            const Buffer<float>& reference, Buffer<float>& delta,
                            const Buffer<float>* mask, bool add) {
    const auto n = static_cast<unsigned>(f.size());
    if (h.size() != f.size() || state.size() != f.size() || delta.size() != f.size())
        throw Error("control variate: image, state and delta buffers differ in size");
    if (kind != LOSS_MEAN && reference.size() != f.size())
        throw Error("loss: the reference has " + std::to_string(reference.size()) +
                    " elements, the image " + std::to_string(f.size()));
    m_cv_terms.launch(m_ctx, "loss", n, f, h, state, reference, terms(n), delta, kind, n, config);
    reduce(n, delta, mask, add);
}

void ImageLoss::evaluate(unsigned kind, const Buffer<float>& image, const Buffer<float>& reference,
                         Buffer<float>& delta, const Buffer<float>* mask, bool add) {
    const auto n = static_cast<unsigned>(image.size());
    if (kind != LOSS_MEAN && reference.size() != image.size())
        throw Error("loss: the reference has " + std::to_string(reference.size()) +
                    " elements, the image " + std::to_string(image.size()));
    if (delta.size() != image.size()) throw Error("loss: delta buffer of the wrong size");
    m_terms.launch(m_ctx, "loss", n, image, reference, terms(n), delta, kind, n);
    reduce(n, delta, mask, add);
}

void ImageLoss::cv_alpha(const Buffer<gpu::CvState>& state, Buffer<float>& alpha) {
    if (alpha.size() != state.size())
        throw Error("control variate: alpha buffer of the wrong size");
    const auto n = static_cast<unsigned>(state.size());
    m_alpha.launch(m_ctx, "metrics", n, state, alpha, n);
}

} // namespace tandem
