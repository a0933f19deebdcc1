// Host driver of the image losses (kernels/loss.cl): per-element terms and delta = dloss/dimage
// on the device, optionally through the recursive control variate, then a reduction in a fixed
// order, so the loss is the same bits every run.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "runtime/kernel_source.h"
#include "runtime/launch.h"
#include "shared/cv.h"
#include "shared/loss.h"

namespace tandem {

/// The loss named `name` ("mean", "l1", "l2" or "rl2"); throws Error for another name.
unsigned loss_kind(const std::string& name);

/// The loss of several evaluations (the views of a batch): their losses added in order, in float.
inline float sum_losses(const std::vector<float>& losses) {
    float total = 0.0f;
    for (float v : losses) total += v;
    return total;
}

class ImageLoss {
public:
    ImageLoss(Context& ctx, const KernelLibrary& lib);
    ~ImageLoss();
    ImageLoss(const ImageLoss&) = delete;
    ImageLoss& operator=(const ImageLoss&) = delete;
    /// Enqueues the loss of `image` against `reference` (same size; ignored for LOSS_MEAN) as the
    /// mean over all elements, and dloss/dimage into `delta`. With `mask` (one weight in [0, 1]
    /// per pixel: a photograph's), each pixel's terms and delta are weighed by it (0 leaves the
    /// pixel out; the mean is still over all elements). Read the value with value(); with `add`,
    /// value() is the sum of this loss and those of the evaluations before it (the views of a
    /// batch), else this one's alone.
    void evaluate(unsigned kind, const Buffer<float>& image, const Buffer<float>& reference,
                  Buffer<float>& delta, const Buffer<float>* mask = nullptr, bool add = false);
    /// Enqueues the recursive control variate of iteration `config.iteration` (shared/cv.h),
    /// which updates `state` (one CvState per element) from h = <F_{n-1}>_n and f = <F_n>_n,
    /// then the loss of the control-variate estimate against `reference` and its delta; `mask`
    /// and `add` as evaluate()'s.
    void evaluate_cv(unsigned kind, const Buffer<float>& f, const Buffer<float>& h,
                     Buffer<gpu::CvState>& state, const gpu::CvConfig& config,
                     const Buffer<float>& reference, Buffer<float>& delta,
                     const Buffer<float>* mask = nullptr, bool add = false);
    /// The loss of the last evaluation, or the sum of the last evaluations' losses in order
    /// (evaluate's `add`): finishes the queue (whatever else is in it; a no-op when the caller
    /// has finished it), then adds each one's chunk sums in order.
    float value();
    /// The losses value() adds (sum_losses), each evaluation's in order (waits like value()).
    std::vector<float> values();
    Context& context() { return m_ctx; }
    /// Enqueues alpha[i] = state[i].alpha, the control weights, for metrics and images.
    void cv_alpha(const Buffer<gpu::CvState>& state, Buffer<float>& alpha);
    /// Elements summed per work item in the fixed-order reduction.
    static constexpr unsigned k_chunk = 4096;

private:
    Context& m_ctx;
    Program m_program;
    Kernel m_terms, m_cv_terms, m_sum, m_alpha, m_mask;
    Buffer<float> m_term_buf; ///< scratch, reallocated only when the size changes
    /// One evaluation's chunk sums, read without blocking, and its element count.
    struct Pending {
        Buffer<float> partial;
        std::vector<float> host;
        unsigned count = 0;
    };
    std::vector<std::unique_ptr<Pending>> m_pending; ///< the evaluations value() adds
    std::vector<std::unique_ptr<Pending>> m_spare;   ///< their buffers, kept for reuse
    Buffer<float>& terms(unsigned n);
    /// Weighs the terms and delta by `mask` (if any), then enqueues the chunk sums of the terms
    /// and their read, after the earlier ones with `add`, else alone.
    void reduce(unsigned n, Buffer<float>& delta, const Buffer<float>* mask, bool add);
};

} // namespace tandem
