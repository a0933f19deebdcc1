// The Python module's C++ side (python/src/session.h).
#include "python/src/session.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/inverse/gradient_step.h"
#include "core/render/passes.h"
#include "runtime/error.h"

namespace tandem::python {

namespace {

/// The registry's values of every parameter element, for a state that starts at the scene.
std::vector<float> at_least_one_value(const ParamRegistry& params) {
    return at_least_one(params.values());
}

std::string number(float v) {
    std::ostringstream s;
    s << v;
    return s.str();
}

/// `values` expanded to p.size elements: p.size as given, 1 for every element, or 3 (one rgb)
/// for every texel of a texture. Checks finiteness and the range.
std::vector<float> expand_value(const Parameter& p, FloatSpan values) {
    std::vector<float> out(p.size);
    if (values.count == p.size) {
        std::copy(values.data, values.data + values.count, out.begin());
    } else if (values.count == 1) {
        std::fill(out.begin(), out.end(), values.data[0]);
    } else if (values.count == 3 && p.kind == Parameter::Kind::texture) {
        for (std::size_t i = 0; i < p.size; ++i)
            out[i] = values.data[i % 3];
    } else {
        throw Error(p.name + ": " + std::to_string(values.count) + " values for a parameter of " +
                    std::to_string(p.size) + " elements");
    }
    for (std::size_t i = 0; i < out.size(); ++i)
        if (!std::isfinite(out[i]) || out[i] < p.lower || out[i] > p.upper)
            throw Error(p.name + ": element " + std::to_string(i) + " is " + number(out[i]) +
                        ", outside the parameter's range [" + number(p.lower) + ", " +
                        number(p.upper) + "]");
    return out;
}

void check_spp(int spp, const char* what) {
    if (spp < 0 || spp > (1 << 20))
        throw Error(std::string(what) + " must be in [1, 1048576] (0: the scene's), not " +
                    std::to_string(spp));
}

} // namespace

Session::Session(const std::string& path, const std::string& device,
                 const std::vector<std::pair<std::string, std::string>>& defines)
    : m_path(path), m_ctx(Context::create(device)), m_lib(KernelLibrary::from_environment()),
      m_desc(load_scene(path, defines)), m_scene(build_render_scene(m_desc)) {
    m_device = std::make_unique<DeviceScene>(m_ctx, m_lib, m_scene);
    m_state = std::make_unique<ParamState>(m_ctx, m_scene.params);
    const std::vector<float> values = at_least_one_value(m_scene.params);
    m_state->theta().upload(values);
    m_state->theta_prev().upload(values);
}

std::vector<float> Session::value(const Parameter& p) {
    std::vector<float> out(p.size);
    m_state->theta().enqueue_read(p.offset, p.size, out.data());
    m_ctx.finish();
    return out;
}

void Session::set_value(const Parameter& p, FloatSpan values) {
    const std::vector<float> v = expand_value(p, values);
    for (Buffer<float>* b : {&m_state->theta(), &m_state->theta_prev()}) {
        std::vector<float> values = b->download();
        std::copy(v.begin(), v.end(), values.begin() + std::ptrdiff_t(p.offset));
        b->upload(values);
    }
}

std::vector<float> Session::render(int spp, std::uint32_t seed) {
    check_spp(spp, "spp");
    RenderOptions opt;
    opt.spp = spp;
    opt.seed = seed;
    return render_image(*m_device, m_state->theta(), opt).rgb;
}

std::pair<std::vector<float>, std::vector<float>>
Session::render_two_state(int spp, std::uint32_t seed,
                          const std::vector<std::pair<const Parameter*, FloatSpan>>& previous) {
    check_spp(spp, "spp");
    if (spp == 0) spp = m_scene.spp;
    const Buffer<float>* old = &m_state->theta_prev();
    Buffer<float> overridden;
    if (!previous.empty()) {
        std::vector<float> values = m_state->theta_prev().download();
        for (const auto& [p, span] : previous) {
            const std::vector<float> v = expand_value(*p, span);
            std::copy(v.begin(), v.end(), values.begin() + std::ptrdiff_t(p->offset));
        }
        overridden = Buffer<float>(m_ctx, "previous parameters", values);
        old = &overridden;
    }
    if (!m_image) m_image = std::make_unique<Buffer<float>>(m_ctx, "image", image_size());
    if (!m_image_old)
        m_image_old = std::make_unique<Buffer<float>>(m_ctx, "old image", image_size());
    tandem::render_two_state(*m_device, m_state->theta(), *old, seed, spp, *m_image, *m_image_old);
    std::pair<std::vector<float>, std::vector<float>> out{m_image->download(),
                                                          m_image_old->download()};
    return out;
}

Buffer<float>& Session::upload_image(std::unique_ptr<Buffer<float>>& b, const char* name,
                                     FloatSpan data, const char* what) {
    if (data.count != image_size())
        throw Error(std::string(what) + " has " + std::to_string(data.count) +
                    " elements; the film needs " + std::to_string(height()) + " x " +
                    std::to_string(width()) + " x 3 = " + std::to_string(image_size()));
    if (!b) b = std::make_unique<Buffer<float>>(m_ctx, name, image_size());
    b->upload(data.data, data.count);
    return *b;
}

std::vector<float> Session::backward(FloatSpan delta, int spp, std::uint32_t seed,
                                     const std::vector<const Parameter*>& params) {
    check_spp(spp, "spp");
    if (spp == 0) spp = m_scene.spp;
    for (std::size_t i = 0; i < delta.count; ++i)
        if (!std::isfinite(delta.data[i]))
            throw Error("delta: element " + std::to_string(i) + " is not finite");
    const Buffer<float>& d = upload_image(m_delta, "delta", delta, "delta");
    m_state->differentiate_only(params);
    tandem::backward(*m_device, m_state->theta(), seed, spp, d, m_state->gradient());
    return m_state->gradient().value.download();
}

Session::GradResult Session::grad(const std::string& loss, FloatSpan reference,
                                  const std::vector<const Parameter*>& params, int spp,
                                  int spp_grad, std::uint32_t seed) {
    check_spp(spp, "spp");
    check_spp(spp_grad, "spp_grad");
    const unsigned kind = loss_kind(loss);
    std::vector<float> ref;
    if (kind != LOSS_MEAN) {
        if (reference.data == nullptr) throw Error("loss '" + loss + "' needs a reference image");
        if (reference.count != image_size())
            throw Error("the reference has " + std::to_string(reference.count) +
                        " elements; the film needs " + std::to_string(height()) + " x " +
                        std::to_string(width()) + " x 3 = " + std::to_string(image_size()));
        ref.assign(reference.data, reference.data + reference.count);
        for (std::size_t i = 0; i < ref.size(); ++i)
            if (!std::isfinite(ref[i]))
                throw Error("reference: element " + std::to_string(i) + " is not finite");
    }
    if (spp == 0) spp = m_scene.spp;
    if (spp_grad == 0) spp_grad = spp;
    GradientStep step(*m_device, m_lib, kind, ref);
    step.attach(*m_state);
    m_state->differentiate_only(params);
    step.evaluate(*m_state, 0, primal_seed(seed, 0), spp, adjoint_seed(seed, 0), spp_grad);
    GradResult out;
    out.loss = step.loss();
    out.gradient = m_state->gradient().value.download();
    return out;
}

// ---- ControlVariate ----

ControlVariate::ControlVariate(Session& session, CvVariance variance, unsigned warmup, float beta1,
                               float beta2)
    : m_session(session), m_variance(variance), m_warmup(warmup), m_beta1(beta1), m_beta2(beta2),
      m_loss(session.context(), session.library()),
      m_state(session.context(), "control variate state",
              std::vector<gpu::CvState>(session.image_size(), gpu::cv_state_zero())),
      m_f(session.context(), "F", session.image_size()),
      m_h(session.context(), "H", session.image_size()),
      m_delta(session.context(), "control variate delta", session.image_size()),
      m_alpha(session.context(), "control weights", session.image_size()) {
    if (!(beta1 > 0.0f && beta1 < 1.0f) || !(beta2 > 0.0f && beta2 < 1.0f))
        throw Error("beta1 and beta2 must be in (0, 1)");
}

std::vector<float> ControlVariate::operator()(FloatSpan f, FloatSpan h) {
    const std::size_t n = m_session.image_size();
    if (f.count != n || h.count != n)
        throw Error("F and H must be images of the scene's film (" +
                    std::to_string(m_session.height()) + " x " + std::to_string(m_session.width()) +
                    " x 3)");
    m_f.upload(f.data, f.count);
    m_h.upload(h.data, h.count);
    // The loss pass with LOSS_MEAN updates the statistics exactly as an optimization does; its
    // loss and delta are not needed, the estimate C_n is the state's.
    m_loss.evaluate_cv(LOSS_MEAN, m_f, m_h, m_state,
                       make_cv_config(m_iteration, m_variance, m_warmup, m_beta1, m_beta2), m_f,
                       m_delta);
    const std::vector<gpu::CvState> state = m_state.download();
    std::vector<float> c(n);
    for (std::size_t i = 0; i < n; ++i)
        c[i] = state[i].estimate;
    ++m_iteration;
    return c;
}

std::vector<float> ControlVariate::alpha() {
    m_loss.cv_alpha(m_state, m_alpha);
    return m_alpha.download();
}

void ControlVariate::reset() {
    m_state.fill(gpu::cv_state_zero());
    m_iteration = 0;
}

// ---- SceneOptimizer ----

SceneOptimizer::SceneOptimizer(Session& session,
                               const std::vector<std::pair<const Parameter*, float>>& rates,
                               const OptimizerConfig& config)
    : m_session(session), m_optimizer(session.context(), session.library(), config) {
    const std::size_t n = session.state().size();
    std::vector<float> lr(n, 0.0f);
    for (const auto& [p, rate] : rates) {
        if (!std::isfinite(rate) || rate < 0.0f)
            throw Error(p->name + ": learning rate " + number(rate) + " must be finite and >= 0");
        std::fill(lr.begin() + std::ptrdiff_t(p->offset),
                  lr.begin() + std::ptrdiff_t(p->offset + p->size), rate);
    }
    Context& ctx = session.context();
    m_rates = Buffer<float>(ctx, "learning rates", lr);
    m_moment1 = Buffer<float>(ctx, "Adam first moment", std::vector<float>(n, 0.0f));
    m_moment2 = Buffer<float>(ctx, "Adam second moment", std::vector<float>(n, 0.0f));
}

void SceneOptimizer::step(const std::vector<std::pair<const Parameter*, FloatSpan>>* gradients) {
    ParamState& s = m_session.state();
    const Buffer<float>* grad = &s.gradient().value;
    if (gradients) {
        std::vector<float> g(s.size(), 0.0f);
        for (const auto& [p, span] : *gradients) {
            if (span.count != p->size)
                throw Error(p->name + ": a gradient of " + std::to_string(span.count) +
                            " elements for a parameter of " + std::to_string(p->size));
            for (std::size_t i = 0; i < span.count; ++i)
                if (!std::isfinite(span.data[i]))
                    throw Error(p->name + ": gradient element " + std::to_string(i) +
                                " is not finite");
            std::copy(span.data, span.data + span.count, g.begin() + std::ptrdiff_t(p->offset));
        }
        if (m_gradient.size() != g.size())
            m_gradient = Buffer<float>(m_session.context(), "gradient", g.size());
        m_gradient.upload(g);
        grad = &m_gradient;
    }
    s.remember_theta(); // the next two-state render's old state
    m_optimizer.update(s.theta(), *grad, m_moment1, m_moment2, m_rates, s.lower(), s.upper(),
                       ++m_steps);
    m_session.context().finish();
}

} // namespace tandem::python
