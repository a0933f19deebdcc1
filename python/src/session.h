// What the Python module binds, in plain C++: a loaded scene on a device with its parameter
// state, the recursive control variate as an object that keeps its per-pixel statistics, and the
// device optimizer over a scene's parameters. Nothing here knows about Python (python/src/
// module.cpp converts arrays and errors); everything is the same core the CLI runs, so a render
// or a gradient taken here is the CLI's bit for bit.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "core/inverse/control_variate.h"
#include "core/inverse/loss.h"
#include "core/inverse/optimizer.h"
#include "core/inverse/param_state.h"
#include "core/render/device_scene.h"
#include "core/scene/render_scene.h"
#include "core/scene/scene.h"
#include "runtime/context.h"
#include "runtime/kernel_source.h"

namespace tandem::python {

/// A host array handed in by the caller: `count` floats at `data`, valid for the call.
struct FloatSpan {
    const float* data = nullptr;
    std::size_t count = 0;
};

/// A scene loaded onto a device: the description, its flattened form, the device buffers and
/// kernels, and one parameter state whose theta every pass reads. Calls are serialized by
/// mutex(): the module holds it while the GIL is released.
class Session {
public:
    /// Loads `path` with -D style `defines` onto `device` (an index or name substring; empty:
    /// $TANDEM_DEVICE, else the first GPU, else the first device).
    Session(const std::string& path, const std::string& device,
            const std::vector<std::pair<std::string, std::string>>& defines);
    Session(const Session&) = delete;
    Session& operator=(const Session&) = delete;

    const std::string& path() const { return m_path; }
    unsigned width() const { return m_device->width(); }
    unsigned height() const { return m_device->height(); }
    std::size_t image_size() const { return 3 * m_device->pixels(); } ///< floats of an image
    int default_spp() const { return m_scene.spp; }
    const DeviceInfo& device_info() const { return m_ctx.device(); }
    const std::vector<Parameter>& parameters() const { return m_scene.params.parameters(); }
    /// The parameter called `name`; throws Error naming the known ones otherwise.
    const Parameter& parameter(const std::string& name) const { return m_scene.params.find(name); }

    /// The current value of `p` (theta), downloaded.
    std::vector<float> value(const Parameter& p);
    /// Writes `values` (p.size elements, or 1 for every element, or 3 for every texel of an rgb
    /// texture) into theta, and into theta_prev: an assignment starts a new trajectory, it is
    /// not a step whose previous state the next two-state render should see. Throws Error naming
    /// the parameter for another count, a non-finite value or one outside the parameter's range;
    /// theta is unchanged then.
    void set_value(const Parameter& p, FloatSpan values);

    /// render_image(): spp (0: the scene's) paths per pixel of theta with `seed`.
    std::vector<float> render(int spp, std::uint32_t seed);
    /// The fused two-state render (CV-PS): <F(theta)> and <F(theta_prev)> along the same paths.
    /// theta_prev is the value before the last Optimizer step (or the last assignment), with
    /// `previous` overriding the values of the parameters it names.
    std::pair<std::vector<float>, std::vector<float>>
    render_two_state(int spp, std::uint32_t seed,
                     const std::vector<std::pair<const Parameter*, FloatSpan>>& previous);
    /// Path Replay Backpropagation for delta = dloss/dimage (image_size() floats): the gradient
    /// of every parameter element in the layout of the registry, those outside `params` zero.
    /// The gradient stays in the parameter state for Optimizer::step.
    std::vector<float> backward(FloatSpan delta, int spp, std::uint32_t seed,
                                const std::vector<const Parameter*>& params);

    struct GradResult {
        float loss = 0.0f;
        std::vector<float> gradient; ///< as backward()
    };
    /// `tandem grad`: the primal render (primal_seed(seed, 0), spp), the built-in loss `loss`
    /// against `reference` (empty for "mean") and its delta on the device, and the adjoint
    /// (adjoint_seed(seed, 0), spp_grad).
    GradResult grad(const std::string& loss, FloatSpan reference,
                    const std::vector<const Parameter*>& params, int spp, int spp_grad,
                    std::uint32_t seed);

    Context& context() { return m_ctx; }
    const KernelLibrary& library() const { return m_lib; }
    DeviceScene& device_scene() { return *m_device; }
    ParamState& state() { return *m_state; }
    std::mutex& mutex() { return m_mutex; }

private:
    /// Uploads `data` into the scratch buffer `b` (image_size() floats), allocated on first use.
    Buffer<float>& upload_image(std::unique_ptr<Buffer<float>>& b, const char* name, FloatSpan data,
                                const char* what);

    std::string m_path;
    Context m_ctx;
    KernelLibrary m_lib;
    SceneDesc m_desc;
    RenderScene m_scene;
    std::unique_ptr<DeviceScene> m_device;
    std::unique_ptr<ParamState> m_state;
    std::unique_ptr<Buffer<float>> m_delta, m_reference, m_image, m_image_old;
    std::mutex m_mutex;
};

/// The recursive control variate of one scene's images, keeping its per-element statistics
/// across calls: call it once per iteration with F = <F_n>_n and H = <F_{n-1}>_n.
class ControlVariate {
public:
    ControlVariate(Session& session, CvVariance variance, unsigned warmup, float beta1,
                   float beta2);
    /// C_n for this iteration (then the iteration count advances).
    std::vector<float> operator()(FloatSpan f, FloatSpan h);
    /// The control weight of every element after the last call.
    std::vector<float> alpha();
    unsigned iteration() const { return m_iteration; }
    void reset(); ///< back to iteration 0
    Session& session() { return m_session; }

private:
    Session& m_session;
    CvVariance m_variance;
    unsigned m_warmup;
    float m_beta1, m_beta2;
    unsigned m_iteration = 0;
    ImageLoss m_loss;
    Buffer<gpu::CvState> m_state;
    Buffer<float> m_f, m_h, m_delta, m_alpha;
};

/// Adam or SGD on the device over a scene's parameters, with per-parameter learning rates (the
/// others are left as they are). Each optimizer owns its moments and step count, so two of them
/// over disjoint parameters of one scene do not disturb each other.
class SceneOptimizer {
public:
    SceneOptimizer(Session& session, const std::vector<std::pair<const Parameter*, float>>& rates,
                   const OptimizerConfig& config);
    /// One step with the gradient the last backward() or grad() left on the device, or with
    /// `gradients` (each p.size floats) for the parameters they name and zero for the rest.
    /// theta_prev becomes theta first (the next two-state render's old state).
    void step(const std::vector<std::pair<const Parameter*, FloatSpan>>* gradients);
    unsigned steps() const { return m_steps; }
    Session& session() { return m_session; }

private:
    Session& m_session;
    Optimizer m_optimizer;
    Buffer<float> m_rates, m_moment1, m_moment2; ///< per element of the parameter layout
    Buffer<float> m_gradient;                    ///< the `gradients` of step(), uploaded
    unsigned m_steps = 0;
};

} // namespace tandem::python
