// Host driver of the image losses (kernels/loss.cl): per-element terms and delta = dloss/dimage
// on the device, optionally through the recursive control variate, then a reduction in a fixed
// order, so the loss is the same bits every run.
#pragma once

#include <string>
#include <vector>

#include "runtime/kernel_source.h"
#include "runtime/launch.h"
#include "shared/cv.h"
#include "shared/loss.h"

namespace tandem {

/// The loss named `name` ("mean", "l1", "l2" or "rl2"); throws Error for another name.
unsigned loss_kind(const std::string& name);

class ImageLoss {
public:
    ImageLoss(Context& ctx, const KernelLibrary& lib);
    ~ImageLoss();
    ImageLoss(const ImageLoss&) = delete;
    ImageLoss& operator=(const ImageLoss&) = delete;
    /// Enqueues the loss of `image` against `reference` (same size; ignored for LOSS_MEAN) as the
    /// mean over all elements, and dloss/dimage into `delta`. Read the value with value().
    void evaluate(unsigned kind, const Buffer<float>& image, const Buffer<float>& reference,
                  Buffer<float>& delta);
    /// Enqueues the recursive control variate of iteration `config.iteration` (shared/cv.h),
    /// which updates `state` (one CvState per element) from h = <F_{n-1}>_n and f = <F_n>_n,
    /// then the loss of the control-variate estimate against `reference` and its delta.
    void evaluate_cv(unsigned kind, const Buffer<float>& f, const Buffer<float>& h,
                     Buffer<gpu::CvState>& state, const gpu::CvConfig& config,
                     const Buffer<float>& reference, Buffer<float>& delta);
    /// The loss of the last evaluation: finishes the queue (whatever else is in it; a no-op when
    /// the caller has finished it), then adds the chunk sums in order.
    float value();
    Context& context() { return m_ctx; }
    /// Enqueues alpha[i] = state[i].alpha, the control weights, for metrics and images.
    void cv_alpha(const Buffer<gpu::CvState>& state, Buffer<float>& alpha);
    /// Elements summed per work item in the fixed-order reduction.
    static constexpr unsigned k_chunk = 4096;

private:
    Context& m_ctx;
    Program m_program;
    Kernel m_terms, m_cv_terms, m_sum, m_alpha;
    Buffer<float> m_term_buf, m_partial; ///< scratch, reallocated only when the size changes
    std::vector<float> m_partial_host;   ///< the chunk sums, read without blocking
    unsigned m_count = 0;                ///< elements of the last evaluation
    Buffer<float>& terms(unsigned n);
    /// Enqueues the chunk sums of the terms and their read into m_partial_host.
    void reduce(unsigned n);
};

} // namespace tandem
