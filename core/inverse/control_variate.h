// The recursive control variate ("Recursive Control Variates for Inverse Rendering", Nicolet et
// al. 2023; kernels/shared/cv.h; docs/method.md) as one object: its per-element statistics, the
// constants of each iteration, its evaluation (fused with the image loss, kernels/loss.cl), and
// the images it reports: the control weights alpha and the variance estimate of C_n. `tandem
// optimize` (through GradientStep) and the Python module's ControlVariate use it alike.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "core/inverse/loss.h"
#include "core/inverse/param_state.h"
#include "shared/cv.h"

namespace tandem {

/// How the control weight's Var[C_{n-1}] is estimated (kernels/shared/cv.h): "consistent" (the
/// default) or "reference" (the paper's eq. 10, to reproduce its behaviour).
enum class CvVariance : unsigned {
    reference = CV_VARIANCE_REFERENCE,
    consistent = CV_VARIANCE_CONSISTENT,
};

/// "reference" or "consistent"; anything else throws Error naming the accepted values.
CvVariance cv_variance(const std::string& name);
const char* cv_variance_name(CvVariance v);

/// The constants of iteration n (0-based) with `warmup` plain iterations (docs/method.md: default
/// 1) and decay rates beta1 (means) and beta2 (second moments): the statistics have been updated m
/// = max(n - 1, 0) times before iteration n, and the bias corrections are computed in double.
gpu::CvConfig make_cv_config(unsigned iteration, CvVariance variance = CvVariance::consistent,
                             unsigned warmup = 1, float beta1 = 0.9f, float beta2 = 0.999f);

/// The control variate's constants (make_cv_config).
struct CvSettings {
    CvVariance variance = CvVariance::consistent;
    unsigned warmup = 1;                ///< iterations that use C = F
    float beta1 = 0.9f, beta2 = 0.999f; ///< decay rates of the means and second moments
};

/// The recursive control variate of one film's images.
class ControlVariate {
public:
    /// The parameter state's named buffer of the statistics, once attach()ed (checkpoints save
    /// it).
    static constexpr const char* k_state = "cv.state";

    using Settings = CvSettings;

    /// Over images of `elements` floats (3 per pixel), its statistics zero in a buffer of its
    /// own; evaluated with `loss`'s kernels (which must outlive this object). Throws Error for
    /// betas outside (0, 1).
    ControlVariate(ImageLoss& loss, std::size_t elements, const Settings& settings = {});
    /// As above with an image loss of its own.
    ControlVariate(Context& ctx, const KernelLibrary& lib, std::size_t elements,
                   const Settings& settings = {});
    /// Waits for a pending read of the control weights.
    ~ControlVariate();
    ControlVariate(const ControlVariate&) = delete;
    ControlVariate& operator=(const ControlVariate&) = delete;

    /// Keeps the statistics in `state` under `name` (registered there, zero, unless they are
    /// already), so that checkpoints save and restore them; call before restoring a checkpoint
    /// into it. Each view of a scene with several sensors has its own (view_buffer).
    void attach(ParamState& state, const std::string& name = k_state);

    const Settings& settings() const { return m_settings; }
    std::size_t elements() const { return m_elements; }
    /// The constants of iteration `iteration` (make_cv_config with the settings).
    gpu::CvConfig config(unsigned iteration) const;

    /// Enqueues iteration `iteration`: updates the statistics from f = <F_n>_n and
    /// h = <F_{n-1}>_n, then the loss `kind` of the control-variate estimate against `reference`
    /// and its delta (read the loss from the ImageLoss).
    /// `mask` and `add` as ImageLoss::evaluate's.
    void evaluate(unsigned iteration, unsigned kind, const Buffer<float>& f, const Buffer<float>& h,
                  const Buffer<float>& reference, Buffer<float>& delta,
                  const Buffer<float>* mask = nullptr, bool add = false);

    /// Host images, for a caller without device buffers (the Python module): the next
    /// iteration (iteration() counts them) with F and H, returning C_n. Waits.
    std::vector<float> operator()(const float* f, const float* h);
    unsigned iteration() const { return m_iteration; }
    /// Statistics back to zero and the count to iteration 0.
    void reset();

    /// Enqueues the control weights of the last evaluation and their read into alpha_image()
    /// (valid once the queue is finished).
    void enqueue_alpha_read();
    const std::vector<float>& alpha_image() const { return m_alpha_host; }
    /// The mean of alpha_image(), summed in element order.
    double alpha_mean() const;
    /// The control weights, downloaded (waits).
    std::vector<float> alpha();
    /// The variance estimate of the CV image, Var[C_n] (eq. 10), per element, as iteration
    /// `next` (the one after the last evaluation) will weigh it. Waits for the statistics.
    std::vector<float> variance(unsigned next);

    Buffer<gpu::CvState>& statistics() { return *m_stats; }

private:
    ControlVariate(ImageLoss* loss, bool owned, std::size_t elements, const Settings& settings);

    std::unique_ptr<ImageLoss> m_own_loss;
    ImageLoss& m_loss;
    std::size_t m_elements;
    Settings m_settings;
    Buffer<gpu::CvState> m_own_stats;
    Buffer<gpu::CvState>* m_stats; ///< m_own_stats, or the parameter state's once attached
    unsigned m_iteration = 0;      ///< operator()'s count
    Buffer<float> m_alpha;
    std::vector<float> m_alpha_host;
    Buffer<float> m_f, m_h, m_delta; ///< operator()'s, allocated on first use
};

} // namespace tandem
