// One step of inverse rendering.
#include "core/inverse/gradient_step.h"

#include "core/inverse/control_variate.h"
#include "runtime/error.h"

namespace tandem {

StepTimes StepTimes::from(const std::vector<StageTime>& stages) {
    StepTimes t;
    t.primal = stage_seconds(stages, "render");
    t.loss = stage_seconds(stages, "loss");
    t.adjoint = stage_seconds(stages, "adjoint");
    t.restir = stage_seconds(stages, "restir");
    return t;
}

GradientStep::GradientStep(DeviceScene& scene, const KernelLibrary& lib, unsigned loss,
                           const std::vector<float>& reference, CvMode cv, CvVariance cv_variance)
    : m_scene(scene), m_kind(loss), m_cv(cv), m_cv_variance(cv_variance),
      m_loss(scene.context(), lib) {
    Context& ctx = scene.context();
    const std::size_t n = 3 * scene.pixels();
    if (loss != LOSS_MEAN && reference.size() != n)
        throw Error("the reference image has " + std::to_string(reference.size() / 3) +
                    " pixels, the scene renders " + std::to_string(n / 3));
    m_reference = Buffer<float>(ctx, "reference",
                                reference.empty() ? std::vector<float>(1, 0.0f) : reference);
    m_image = Buffer<float>(ctx, "image", n);
    m_image_old = Buffer<float>(ctx, "image (previous state)", cv == CvMode::none ? 1 : n);
    m_delta = Buffer<float>(ctx, "loss adjoint", n);
    if (cv != CvMode::none) {
        ControlVariate::Settings settings;
        settings.variance = cv_variance;
        m_control = std::make_unique<ControlVariate>(m_loss, n, settings);
    }
    prepare_passes(scene, cv == CvMode::ps, true); // compile now, not inside a timed iteration
}

void GradientStep::enable_restir(const RestirConfig& config, int spp_grad, int spp) {
    if (config.primal && m_cv != CvMode::none)
        throw Error("restir: reuse in the primal needs no control variate (its two states share "
                    "their paths; docs/restir.md)");
    if (config.primal && spp < 1)
        throw Error("restir: reuse in the primal needs the primal's samples per pixel");
    m_restir.reset();
    m_restir_primal.reset();
    if (config.adjoint) m_restir = std::make_unique<Restir>(m_scene, config, spp_grad);
    if (config.primal)
        m_restir_primal = std::make_unique<Restir>(m_scene, config, spp, RestirChain::primal);
}

void GradientStep::attach(ParamState& state) {
    if (m_control) m_control->attach(state);
    if (m_restir) m_restir->attach(state);
    if (m_restir_primal) m_restir_primal->attach(state);
}

void GradientStep::evaluate(ParamState& state, unsigned iteration, std::uint32_t seed_primal,
                            int spp, std::uint32_t seed_adjoint, int spp_grad,
                            std::optional<RestirSeeds> restir) {
    if ((m_restir || m_restir_primal) && !restir)
        throw Error("restir: an evaluation with reservoirs needs the seeds of its passes");
    if (m_restir && m_restir->spp() != spp_grad)
        throw Error("restir: the reservoirs are for " + std::to_string(m_restir->spp()) +
                    " adjoint samples per pixel, not " + std::to_string(spp_grad));
    if (m_restir_primal && m_restir_primal->spp() != spp)
        throw Error("restir: the primal's reservoirs are for " +
                    std::to_string(m_restir_primal->spp()) + " samples per pixel, not " +
                    std::to_string(spp));
    const Buffer<float>& theta = state.theta();
    switch (m_cv) {
    case CvMode::none:
        if (m_restir_primal) {
            render(m_scene, theta, seed_primal, spp, m_image,
                   m_restir_primal->resampled_by_paths(state, restir->primal));
            m_restir_primal->commit(state);
        } else {
            render(m_scene, theta, seed_primal, spp, m_image);
        }
        m_loss.evaluate(m_kind, m_image, m_reference, m_delta);
        break;
    case CvMode::ps:
    case CvMode::pss:
        if (m_cv == CvMode::ps) {
            render_two_state(m_scene, theta, state.theta_prev(), seed_primal, spp, m_image,
                             m_image_old);
        } else {
            render(m_scene, theta, seed_primal, spp, m_image);
            render(m_scene, state.theta_prev(), seed_primal, spp, m_image_old);
        }
        if (!state.has_buffer(k_cv_state))
            throw Error("parameter state: no buffer named '" + std::string(k_cv_state) + "'");
        m_control->attach(state); // its statistics are the state's
        m_control->evaluate(iteration, m_kind, m_image, m_image_old, m_reference, m_delta);
        break;
    }
    if (!m_restir) {
        backward(m_scene, theta, seed_adjoint, spp_grad, m_delta, state.gradient());
        return;
    }
    backward(m_scene, theta, seed_adjoint, spp_grad, m_delta, state.gradient(),
             m_restir->resampled_by_paths(state, restir->adjoint));
    m_restir->commit(state);
}

void GradientStep::warm_up(ParamState& state) {
    Context& ctx = m_scene.context();
    const Buffer<float>& theta = state.theta();
    render(m_scene, theta, 0xFFFFFFFFu, 1, m_image);
    if (m_cv == CvMode::ps)
        render_two_state(m_scene, theta, theta, 0xFFFFFFFFu, 1, m_image, m_image_old);
    m_loss.evaluate(m_kind, m_image, m_reference, m_delta);
    Buffer<gpu::CvState> scratch(ctx, "scratch state",
                                 std::vector<gpu::CvState>(m_image.size(), gpu::cv_state_zero()));
    m_loss.evaluate_cv(m_kind, m_image, m_image, scratch, make_cv_config(0, m_cv_variance),
                       m_reference, m_delta);
    Buffer<float> alpha(ctx, "scratch alpha", m_image.size());
    m_loss.cv_alpha(scratch, alpha);
    // the gradient of the warm-up goes to scratch buffers, not to the state's
    GradientBuffers grad(ctx, m_scene.param_count());
    backward(m_scene, theta, 0xFFFFFFFFu, 1, m_delta, grad);
    // Each chain's pass on its own (as burn-in runs it) and fused into its paths (as an iteration
    // does): PoCL compiles a kernel at its first launch, which must not fall into the timed
    // burn-in. They write the chain's scratch reservoirs only; the state's are read.
    if (m_restir) {
        m_restir->resample(state, 0xFFFFFFFFu, 0xFFFFFFFFu);
        backward(m_scene, theta, 0xFFFFFFFFu, m_restir->spp(), m_delta, grad,
                 m_restir->resampled_by_paths(state, 0xFFFFFFFFu));
    }
    if (m_restir_primal) {
        m_restir_primal->resample(state, 0xFFFFFFFFu, 0xFFFFFFFFu);
        render(m_scene, theta, 0xFFFFFFFFu, m_restir_primal->spp(), m_image,
               m_restir_primal->resampled_by_paths(state, 0xFFFFFFFFu));
    }
    ctx.finish();
    m_scene.reset_guards();
}

} // namespace tandem
