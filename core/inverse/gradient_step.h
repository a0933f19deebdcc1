// One gradient evaluation of inverse rendering, all on the device: primal image(s) -> image loss
// and its adjoint (through the recursive control variate when enabled) -> PRB gradient into the
// parameter state. The primal image that feeds the loss and the adjoint pass use independent
// seeds, so the product of their estimates is unbiased ("Recursive Control Variates for Inverse
// Rendering", Nicolet et al. 2023, Sec. 4; docs/method.md).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/inverse/control_variate.h"
#include "core/inverse/loss.h"
#include "core/inverse/param_state.h"
#include "core/inverse/restir.h"
#include "core/inverse/streams.h"
#include "core/render/passes.h"
#include "core/render/schedule.h"

namespace tandem {

/// Device seconds of the stages of an evaluation (with Context::set_stage_timing on).
struct StepTimes {
    double primal = 0.0, loss = 0.0, adjoint = 0.0, restir = 0.0;
    /// From Context::stage_times(): "render", "loss", "adjoint" and "restir" (the resampling
    /// passes of both chains).
    static StepTimes from(const std::vector<StageTime>& stages);
};

class GradientStep {
public:
    /// The control variate's per-element statistics, a named buffer of the parameter state.
    static constexpr const char* k_cv_state = ControlVariate::k_state;

    /// `reference`: the target image (3 floats per pixel of the scene's film); empty for
    /// LOSS_MEAN. With cv pss or ps, each evaluation also renders theta_prev and runs the
    /// recursive control variate.
    GradientStep(DeviceScene& scene, const KernelLibrary& lib, unsigned loss,
                 const std::vector<float>& reference, CvMode cv = CvMode::none,
                 CvVariance cv_variance = CvVariance::consistent);

    /// Reuses light samples across evaluations (ReSTIR, core/inverse/restir.h): in the adjoint
    /// for `spp_grad` samples per pixel where config.adjoint, and in a chain of its own in the
    /// primal image for `spp` where config.primal (without a control variate and with spp >= 1
    /// only: throws Error otherwise). The scene must be built with restir_features(). Call before
    /// attach().
    void enable_restir(const RestirConfig& config, int spp_grad, int spp = 0);
    /// The seeds of one iteration's resampling passes (restir_seed, restir_primal_seed).
    struct RestirSeeds {
        std::uint32_t adjoint = 0, primal = 0;
    };
    Restir* restir() { return m_restir.get(); }               ///< the adjoint's chain, or null
    Restir* restir_primal() { return m_restir_primal.get(); } ///< the primal's chain, or null

    /// Registers what `state` must carry for this evaluation (the CV statistics, the
    /// reservoirs): call once before the first evaluate() on it, and before restoring a
    /// checkpoint into it. The control variate keeps its statistics there from then on.
    void attach(ParamState& state);

    /// Enqueues iteration `iteration` at state.theta(): the primal image(s) at (seed_primal,
    /// spp), the loss and its delta, and the PRB gradient (seed_adjoint, spp_grad) into
    /// state.gradient(). With the control variate, theta_prev is the previous state. With
    /// ReSTIR, each adjoint path first refreshes its reservoir at its first hit (the pass's seed
    /// restir->adjoint: restir_seed), from the previous iteration's, whose domain is theta_prev,
    /// and reads it; with the primal chain, each primal path does the same with its own
    /// (restir->primal: restir_primal_seed). ReSTIR needs its seeds (throws Error without).
    /// Read the loss with loss().
    void evaluate(ParamState& state, unsigned iteration, std::uint32_t seed_primal, int spp,
                  std::uint32_t seed_adjoint, int spp_grad,
                  std::optional<RestirSeeds> restir = std::nullopt);
    /// The loss of the last evaluate() (of the control-variate estimate with a CV); waits.
    float loss() { return m_loss.value(); }

    /// Launches every kernel an evaluation uses once, on scratch data (PoCL compiles a kernel on
    /// its first launch), so that timed iterations measure rendering, not compilation. Leaves
    /// the state as it was.
    void warm_up(ParamState& state);

    CvMode cv() const { return m_cv; }
    CvVariance cv_variance() const { return m_cv_variance; }
    /// The control variate (its alpha and variance images), or null without one.
    ControlVariate* control_variate() { return m_control.get(); }
    DeviceScene& scene() { return m_scene; }
    Buffer<float>& image() { return m_image; }         ///< <F_n>_n of the last evaluation
    Buffer<float>& image_old() { return m_image_old; } ///< <F_{n-1}>_n (control variate)
    Buffer<float>& delta() { return m_delta; }         ///< dloss/dimage of the last evaluation

private:
    DeviceScene& m_scene;
    unsigned m_kind;
    CvMode m_cv;
    CvVariance m_cv_variance;
    ImageLoss m_loss;
    Buffer<float> m_reference, m_image, m_image_old, m_delta;
    std::unique_ptr<ControlVariate> m_control; ///< with a CvMode other than none
    std::unique_ptr<Restir> m_restir, m_restir_primal;
};

} // namespace tandem
