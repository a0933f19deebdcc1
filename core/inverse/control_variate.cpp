// The recursive control variate.
#include "core/inverse/control_variate.h"

#include <cmath>

#include "runtime/error.h"

namespace tandem {

CvVariance cv_variance(const std::string& name) {
    if (name == "consistent") return CvVariance::consistent;
    if (name == "reference") return CvVariance::reference;
    throw Error("unknown cv_variance '" + name + "' (expected \"consistent\" or \"reference\")");
}

const char* cv_variance_name(CvVariance v) {
    return v == CvVariance::reference ? "reference" : "consistent";
}

gpu::CvConfig make_cv_config(unsigned iteration, CvVariance variance, unsigned warmup, float beta1,
                             float beta2) {
    gpu::CvConfig c{};
    const unsigned m = iteration > 0 ? iteration - 1 : 0;
    c.beta1 = beta1;
    c.beta2 = beta2;
    c.variance = static_cast<unsigned>(variance);
    c.corr1_after = static_cast<float>(1.0 - std::pow(double(beta1), double(m + 1)));
    c.corr2 = m == 0 ? 1.0f : static_cast<float>(1.0 - std::pow(double(beta2), double(m)));
    c.iteration = iteration;
    c.warmup = warmup;
    c.updates = m;
    return c;
}

ControlVariate::ControlVariate(ImageLoss& loss, std::size_t elements, const Settings& settings)
    : ControlVariate(&loss, false, elements, settings) {}

ControlVariate::ControlVariate(Context& ctx, const KernelLibrary& lib, std::size_t elements,
                               const Settings& settings)
    : ControlVariate(new ImageLoss(ctx, lib), true, elements, settings) {}

ControlVariate::ControlVariate(ImageLoss* loss, bool owned, std::size_t elements,
                               const Settings& settings)
    : m_own_loss(owned ? loss : nullptr), m_loss(*loss), m_elements(elements), m_settings(settings),
      m_own_stats(loss->context(), "control variate state",
                  std::vector<gpu::CvState>(elements, gpu::cv_state_zero())),
      m_stats(&m_own_stats), m_alpha(loss->context(), "control weights", elements),
      m_alpha_host(elements, 0.0f) {
    if (!(settings.beta1 > 0.0f && settings.beta1 < 1.0f) ||
        !(settings.beta2 > 0.0f && settings.beta2 < 1.0f))
        throw Error("beta1 and beta2 must be in (0, 1)");
}

ControlVariate::~ControlVariate() {
    try {
        m_loss.context().finish();
    } catch (...) {
    }
}

void ControlVariate::attach(ParamState& state, const std::string& name) {
    if (!state.has_buffer(name)) state.add_buffer(name, m_elements, gpu::cv_state_zero());
    m_stats = &state.buffer<gpu::CvState>(name);
    m_own_stats = Buffer<gpu::CvState>(); // the state's from now on: no second copy per view
}

gpu::CvConfig ControlVariate::config(unsigned iteration) const {
    return make_cv_config(iteration, m_settings.variance, m_settings.warmup, m_settings.beta1,
                          m_settings.beta2);
}

void ControlVariate::evaluate(unsigned iteration, unsigned kind, const Buffer<float>& f,
                              const Buffer<float>& h, const Buffer<float>& reference,
                              Buffer<float>& delta, const Buffer<float>* mask, bool add) {
    m_loss.evaluate_cv(kind, f, h, *m_stats, config(iteration), reference, delta, mask, add);
}

std::vector<float> ControlVariate::operator()(const float* f, const float* h) {
    Context& ctx = m_loss.context();
    if (m_f.size() != m_elements) {
        m_f = Buffer<float>(ctx, "F", m_elements);
        m_h = Buffer<float>(ctx, "H", m_elements);
        m_delta = Buffer<float>(ctx, "control variate delta", m_elements);
    }
    m_f.upload(f, m_elements);
    m_h.upload(h, m_elements);
    // The loss pass with LOSS_MEAN updates the statistics exactly as an optimization does; its
    // loss and delta are not needed, the estimate C_n is the state's.
    evaluate(m_iteration, LOSS_MEAN, m_f, m_h, m_f, m_delta);
    const std::vector<gpu::CvState> state = m_stats->download();
    std::vector<float> c(m_elements);
    for (std::size_t i = 0; i < m_elements; ++i)
        c[i] = state[i].estimate;
    ++m_iteration;
    return c;
}

void ControlVariate::reset() {
    m_stats->fill(gpu::cv_state_zero());
    m_iteration = 0;
}

void ControlVariate::enqueue_alpha_read() {
    m_loss.cv_alpha(*m_stats, m_alpha);
    m_alpha.enqueue_read(0, m_alpha.size(), m_alpha_host.data());
}

double ControlVariate::alpha_mean() const {
    double sum = 0.0;
    for (float a : m_alpha_host)
        sum += a;
    return sum / double(m_alpha_host.size());
}

std::vector<float> ControlVariate::alpha() {
    enqueue_alpha_read();
    m_loss.context().finish();
    return m_alpha_host;
}

std::vector<float> ControlVariate::variance(unsigned next) {
    const std::vector<gpu::CvState> cv = m_stats->download();
    std::vector<float> out(cv.size());
    const gpu::CvConfig c = config(next);
    for (std::size_t i = 0; i < cv.size(); ++i)
        out[i] = gpu::cv_estimate_variance(&cv[i], &c);
    return out;
}

} // namespace tandem
