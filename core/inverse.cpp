// One step of inverse rendering.
#include "core/inverse.h"

#include "runtime/error.h"

namespace tandem {

namespace {

/// A 32-bit finaliser (lowbias32, Wellons' hash prospector): a bijection with good avalanche.
std::uint32_t mix32(std::uint32_t x) {
    x ^= x >> 16;
    x *= 0x7feb352dU;
    x ^= x >> 15;
    x *= 0x846ca68bU;
    x ^= x >> 16;
    return x;
}

std::uint32_t stream_seed(std::uint32_t seed, std::uint32_t iteration, std::uint32_t stream) {
    return mix32(mix32(mix32(seed) ^ iteration) ^ (0x9e3779b9U * (stream + 1U)));
}

} // namespace

std::uint32_t primal_seed(std::uint32_t seed, std::uint32_t iteration) {
    return stream_seed(seed, iteration, 0);
}

std::uint32_t adjoint_seed(std::uint32_t seed, std::uint32_t iteration) {
    return stream_seed(seed, iteration, 1);
}

CvMode cv_mode(const std::string& name) {
    if (name == "none") return CvMode::none;
    if (name == "pss") return CvMode::pss;
    if (name == "ps") return CvMode::ps;
    throw Error("unknown control variate '" + name + "' (none, pss, ps)");
}

const char* cv_mode_name(CvMode mode) {
    return mode == CvMode::none ? "none" : mode == CvMode::pss ? "pss" : "ps";
}

CvMode plan_cv(CvMode requested, const std::vector<const Parameter*>& changing, std::string* reason) {
    if (requested == CvMode::none) {
        *reason = "plain PRB, no control variate";
        return CvMode::none;
    }
    if (requested == CvMode::pss) {
        *reason = "CV-PSS as requested: two launches (theta_n, theta_{n-1}) with the same seed";
        return CvMode::pss;
    }
    // Parameters that move geometry would invalidate the shared path vertices (a shift mapping
    // would be needed, papers/000 Sec. 6); no kind does so far, so this never falls back today.
    for (const Parameter* p : changing)
        if (p->moves_geometry()) {
            *reason = "CV-PSS: " + p->name + " moves geometry, which two-state paths cannot share";
            return CvMode::pss;
        }
    std::string names;
    for (const Parameter* p : changing) names += (names.empty() ? "" : ", ") + p->name;
    *reason = "CV-PS: fused two-state kernel (the changing parameters, " + names + ", move no geometry)";
    return CvMode::ps;
}

GradientStep::GradientStep(Context& ctx, const KernelLibrary& lib, Renderer& renderer,
                           unsigned loss, const std::vector<float>& reference)
    : m_ctx(ctx), m_renderer(renderer), m_loss(loss), m_image_loss(ctx, lib) {
    const RenderScene& scene = renderer.scene();
    const std::size_t n = 3 * std::size_t(scene.camera.width) * scene.camera.height;
    if (loss != LOSS_MEAN && reference.size() != n)
        throw Error("the reference image has " + std::to_string(reference.size() / 3) +
                    " pixels, the scene renders " + std::to_string(n / 3));
    m_reference = Buffer<float>(ctx, "reference", reference.empty() ? std::vector<float>(1, 0.0f) : reference);
    m_image = Buffer<float>(ctx, "image", n);
    m_delta = Buffer<float>(ctx, "loss adjoint", n);
    m_grad = Buffer<float>(ctx, "gradient", renderer.parameters().size());
    renderer.prepare_backward(); // compile now, not inside the first (timed) iteration
}

void GradientStep::warm_up(const Buffer<float>& params) {
    m_renderer.render_image(params, 0xFFFFFFFFu, 1, m_image);
    if (m_cv == CvMode::ps) m_renderer.render_two_state(params, params, 0xFFFFFFFFu, 1, m_image, m_image_old);
    m_image_loss.evaluate(m_loss, m_image, m_reference, m_delta);
    Buffer<gpu::CvState> scratch(m_ctx, "scratch state",
                                 std::vector<gpu::CvState>(m_image.size(), gpu::cv_state_zero()));
    m_image_loss.evaluate_cv(m_loss, m_image, m_image, scratch, make_cv_config(0), m_reference, m_delta);
    m_renderer.backward(params, 0xFFFFFFFFu, 1, m_delta, m_grad);
    m_ctx.finish();
}

void GradientStep::enable_cv(CvMode mode) {
    m_cv = mode;
    if (mode == CvMode::none) return;
    m_image_old = Buffer<float>(m_ctx, "image (previous state)", m_image.size());
    m_cv_state = Buffer<gpu::CvState>(m_ctx, "control variate state",
                                      std::vector<gpu::CvState>(m_image.size(), gpu::cv_state_zero()));
}

float GradientStep::evaluate_cv(const Buffer<float>& params, const Buffer<float>& params_old,
                                unsigned iteration, std::uint32_t seed_primal, int spp,
                                std::uint32_t seed_adjoint, int spp_grad) {
    if (m_cv == CvMode::none) throw Error("evaluate_cv: the control variate is not enabled");
    if (m_cv == CvMode::ps) {
        m_guards = m_renderer.render_two_state(params, params_old, seed_primal, spp, m_image, m_image_old);
        m_times.primal = m_renderer.last_render_seconds();
    } else {
        m_guards = m_renderer.render_image(params, seed_primal, spp, m_image);
        m_times.primal = m_renderer.last_render_seconds();
        m_guards += m_renderer.render_image(params_old, seed_primal, spp, m_image_old);
        m_times.primal += m_renderer.last_render_seconds();
    }
    m_ctx.stage_times();
    const float loss = m_image_loss.evaluate_cv(m_loss, m_image, m_image_old, m_cv_state,
                                                make_cv_config(iteration), m_reference, m_delta);
    m_times.loss = stage_seconds(m_ctx.stage_times(), "loss");
    m_guards += m_renderer.backward(params, seed_adjoint, spp_grad, m_delta, m_grad);
    m_times.adjoint = m_renderer.last_backward_seconds();
    return loss;
}

float GradientStep::evaluate(const Buffer<float>& params, std::uint32_t seed_primal, int spp,
                             std::uint32_t seed_adjoint, int spp_grad) {
    m_guards = m_renderer.render_image(params, seed_primal, spp, m_image);
    m_times.primal = m_renderer.last_render_seconds();
    m_ctx.stage_times();
    const float loss = m_image_loss.evaluate(m_loss, m_image, m_reference, m_delta);
    m_times.loss = stage_seconds(m_ctx.stage_times(), "loss");
    m_guards += m_renderer.backward(params, seed_adjoint, spp_grad, m_delta, m_grad);
    m_times.adjoint = m_renderer.last_backward_seconds();
    return loss;
}

} // namespace tandem
