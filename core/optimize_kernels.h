// Host drivers of the image loss (kernels/loss.cl) and the optimizers (kernels/optim.cl). Both
// work on flat float buffers and are deterministic: the loss is reduced in a fixed order.
#pragma once

#include <string>

#include "runtime/kernel_source.h"
#include "runtime/launch.h"
#include "shared/cv.h"
#include "shared/loss.h"
#include "shared/optim.h"

namespace tandem {

/// The loss named `name` ("mean", "l1", "l2" or "rl2"); throws Error for another name.
unsigned loss_kind(const std::string& name);

class ImageLoss {
public:
    ImageLoss(Context& ctx, const KernelLibrary& lib);
    /// Loss of `image` against `reference` (same size; ignored for LOSS_MEAN) as the mean over all
    /// elements, and dloss/dimage into `delta`. Blocks until the value is read back.
    float evaluate(unsigned kind, const Buffer<float>& image, const Buffer<float>& reference,
                   Buffer<float>& delta);
    /// The recursive control variate of iteration `config.iteration` (shared/cv.h) updates `state`
    /// (one CvState per element) from h = <F_{n-1}>_n and f = <F_n>_n, then the loss of the
    /// control-variate estimate against `reference` and its delta, as evaluate().
    float evaluate_cv(unsigned kind, const Buffer<float>& f, const Buffer<float>& h,
                      Buffer<gpu::CvState>& state, const gpu::CvConfig& config,
                      const Buffer<float>& reference, Buffer<float>& delta);
    /// Elements summed per work item in the fixed-order reduction.
    static constexpr unsigned k_chunk = 4096;

private:
    Context& m_ctx;
    Program m_program;
    Kernel m_terms, m_cv_terms, m_sum;
    Buffer<float> m_term_buf, m_partial; ///< scratch, reallocated only when the size changes
    Buffer<float>& terms(unsigned n);
    float reduce(unsigned n);
};

/// Adam or gradient descent over a flat parameter buffer, with per-element learning rates and
/// valid ranges. Moments live on the device between steps.
class Optimizer {
public:
    enum class Method { adam, sgd };
    Optimizer(Context& ctx, const KernelLibrary& lib, Method method, std::size_t count,
              float beta1 = 0.9f, float beta2 = 0.999f, float epsilon = 1e-8f);

    /// One step: params <- update(params, grads), clamped to [lower, upper] per element.
    void step(Buffer<float>& params, const Buffer<float>& grads, const Buffer<float>& lr,
              const Buffer<float>& lower, const Buffer<float>& upper);
    unsigned steps_taken() const { return m_step; }
    /// Launches the update kernel once on scratch data (PoCL compiles on first launch).
    void warm_up();
    /// The moments, for checkpoints.
    Buffer<float>& first_moment() { return m_m; }
    Buffer<float>& second_moment() { return m_v; }
    void set_steps_taken(unsigned t) { m_step = t; }

private:
    Context& m_ctx;
    Method m_method;
    std::size_t m_count;
    float m_beta1, m_beta2, m_epsilon;
    unsigned m_step = 0;
    Buffer<float> m_m, m_v;
    Program m_program;
    Kernel m_adam, m_sgd;
};

} // namespace tandem
