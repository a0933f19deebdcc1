// One step of inverse rendering: primal render -> image loss and its adjoint -> PRB gradient, all
// on the device (papers/000 eq. 12-13: the primal image that feeds the loss and the adjoint pass
// use independent seeds, so the product of their estimates is unbiased).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/control_variate.h"
#include "core/optimize_kernels.h"
#include "core/renderer.h"

namespace tandem {

/// The seeds of iteration `iteration` of a run seeded with `seed`: distinct, decorrelated
/// streams for the primal render and the adjoint pass (a hash of (seed, iteration, stream)).
std::uint32_t primal_seed(std::uint32_t seed, std::uint32_t iteration);
std::uint32_t adjoint_seed(std::uint32_t seed, std::uint32_t iteration);

/// How the primal images of an iteration are produced (papers/000 Sec. 5):
///   none  plain PRB: one render of theta_n
///   pss   recursive control variate, primary sample space: theta_n and theta_{n-1} rendered by
///         two launches with the same seed
///   ps    recursive control variate, path space: one fused two-state launch (CV-PS)
enum class CvMode { none, pss, ps };

/// "none", "pss" or "ps"; throws Error otherwise.
CvMode cv_mode(const std::string& name);
const char* cv_mode_name(CvMode mode);

/// The scheduler's fusion decision: the two primal renders of an iteration (theta_n and
/// theta_{n-1}, same seed) fuse into the two-state kernel when every changing parameter leaves
/// geometry and sampling valid for both states, else they run as two launches (CV-PSS).
/// Every parameter kind today (reflectance, texels, specular, roughness, radiance) changes only
/// what a path sees, never where it goes: light sampling uses a fixed table, and BSDF sampling is
/// re-weighted by the two-state path. `reason` says why, for the log.
CvMode plan_cv(CvMode requested, const std::vector<const Parameter*>& changing, std::string* reason);

struct StepTimes {
    double primal = 0.0, loss = 0.0, adjoint = 0.0; ///< device seconds
};

class GradientStep {
public:
    /// `reference`: the target image (rgb, the scene's film size); empty for LOSS_MEAN. Throws
    /// Error when its size does not match the film.
    GradientStep(Context& ctx, const KernelLibrary& lib, Renderer& renderer, unsigned loss,
                 const std::vector<float>& reference);

    /// Renders `params` at (seed_primal, spp), evaluates the loss, and writes the PRB gradient
    /// (seed_adjoint, spp_grad) to gradient(). Returns the loss. Counts dropped samples and
    /// saturated gradient contributions in guards().
    float evaluate(const Buffer<float>& params, std::uint32_t seed_primal, int spp,
                   std::uint32_t seed_adjoint, int spp_grad);

    /// Launches every kernel an iteration uses once, on scratch data (PoCL compiles a kernel on its
    /// first launch), so that timed iterations measure rendering, not compilation. Leaves the
    /// gradient, images and control-variate state as they were meant to be: call before the run.
    void warm_up(const Buffer<float>& params);

    /// Switches on the recursive control variate (mode pss or ps): evaluate_cv() then keeps a
    /// CvState per image element.
    void enable_cv(CvMode mode);
    /// Iteration `iteration` with the control variate: the primal images of `params` (theta_n)
    /// and `params_old` (theta_{n-1}) with seed_primal, the CV estimate, its loss and delta, and
    /// the PRB gradient at theta_n. Returns the loss of the CV estimate.
    float evaluate_cv(const Buffer<float>& params, const Buffer<float>& params_old,
                      unsigned iteration, std::uint32_t seed_primal, int spp,
                      std::uint32_t seed_adjoint, int spp_grad);
    Buffer<gpu::CvState>& cv_state() { return m_cv_state; }
    Buffer<float>& image_old() { return m_image_old; }
    CvMode cv() const { return m_cv; }

    Buffer<float>& gradient() { return m_grad; }
    Buffer<float>& image() { return m_image; }
    Buffer<float>& delta() { return m_delta; }
    std::uint64_t guards() const { return m_guards; }
    const StepTimes& times() const { return m_times; }

private:
    Context& m_ctx;
    Renderer& m_renderer;
    unsigned m_loss;
    ImageLoss m_image_loss;
    Buffer<float> m_reference, m_image, m_delta, m_grad;
    CvMode m_cv = CvMode::none;
    Buffer<float> m_image_old;
    Buffer<gpu::CvState> m_cv_state;
    std::uint64_t m_guards = 0;
    StepTimes m_times;
};

} // namespace tandem
