// The Python module's objects over the core: a Scene is a core Session (core/inverse/session.h);
// ControlVariate and Optimizer are the core's ControlVariate and Optimizer over a scene's film
// and parameter state, with the scene whose lock the module takes around every call. Nothing
// here knows about Python (python/src/convert.h converts arrays and errors).
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "core/inverse/control_variate.h"
#include "core/inverse/optimizer.h"
#include "core/inverse/session.h"

namespace tandem::python {

using tandem::FloatSpan;
using tandem::Session;

/// The recursive control variate of one scene's images, keeping its per-element statistics
/// across calls: call it once per iteration with F = <F_n>_n and H = <F_{n-1}>_n.
class ControlVariate {
public:
    /// Over images of sensor `sensor`'s film.
    ControlVariate(Session& session, const CvSettings& settings, unsigned sensor = 0);
    /// C_n for this iteration (then the iteration count advances).
    std::vector<float> operator()(FloatSpan f, FloatSpan h);
    /// The control weight of every element after the last call.
    std::vector<float> alpha() { return m_cv.alpha(); }
    unsigned iteration() const { return m_cv.iteration(); }
    void reset() { m_cv.reset(); } ///< back to iteration 0
    Session& session() { return m_session; }
    unsigned sensor() const { return m_sensor; }

private:
    Session& m_session;
    unsigned m_sensor;
    tandem::ControlVariate m_cv;
};

/// Adam or SGD on the device over a scene's parameters, with per-parameter learning rates (the
/// others are left as they are). Each optimizer has its own moments (in the scene's parameter
/// state) and step count, so two of them over disjoint parameters of one scene do not disturb
/// each other.
class SceneOptimizer {
public:
    SceneOptimizer(Session& session, const std::vector<std::pair<const Parameter*, float>>& rates,
                   const OptimizerConfig& config);
    /// One step with the gradient the last backward() or grad() left on the device, or with
    /// `gradients` (each p.size floats) for the parameters they name and zero for the rest.
    /// theta_prev becomes theta first (the next two-state render's old state).
    void step(const std::vector<std::pair<const Parameter*, FloatSpan>>* gradients);
    unsigned steps() const { return m_optimizer.steps(); }
    Session& session() { return m_session; }
    unsigned sensor() const { return m_sensor; }

private:
    Session& m_session;
    unsigned m_sensor;
    Optimizer m_optimizer;
    Buffer<float> m_gradient; ///< the `gradients` of step(), uploaded
};

} // namespace tandem::python
