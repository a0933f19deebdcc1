// The Python module's objects over the core (python/src/session.h).
#include "python/src/session.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "runtime/error.h"

namespace tandem::python {

ControlVariate::ControlVariate(Session& session, const CvSettings& settings, unsigned sensor)
    : m_session(session), m_sensor(sensor),
      m_cv(session.context(), session.library(), session.image_size(sensor), settings) {}

std::vector<float> ControlVariate::operator()(FloatSpan f, FloatSpan h) {
    const std::size_t n = m_session.image_size(m_sensor);
    if (f.count != n || h.count != n)
        throw Error("F and H must be images of the sensor's film (" +
                    std::to_string(m_session.height(m_sensor)) + " x " +
                    std::to_string(m_session.width(m_sensor)) + " x 3)");
    return m_cv(f.data, h.data);
}

SceneOptimizer::SceneOptimizer(Session& session,
                               const std::vector<std::pair<const Parameter*, float>>& rates,
                               const OptimizerConfig& config)
    : m_session(session), m_optimizer(session.state(), session.library(), config, "") {
    m_optimizer.set_rates(rates);
}

void SceneOptimizer::step(const std::vector<std::pair<const Parameter*, FloatSpan>>* gradients) {
    ParamState& s = m_session.state();
    const Buffer<float>* grad = nullptr; // the state's
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
    m_optimizer.step(grad);
    m_session.context().finish();
}

} // namespace tandem::python
