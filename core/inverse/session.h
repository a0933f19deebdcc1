// A session: a loaded scene on a device, with its parameter state and its passes. It is what
// the CLI (render, grad, optimize), the Python module and the benchmarks build on: the scene is
// loaded, its device scene built (its BVH, its kernels) and its parameter state set up here, once,
// and every render or gradient taken through it is the same core's, bit for bit, whoever calls.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/inverse/control_variate.h"
#include "core/inverse/gradient_step.h"
#include "core/inverse/param_state.h"
#include "core/render/device_scene.h"
#include "core/render/passes.h"
#include "core/render/reservoirs.h"
#include "core/scene/render_scene.h"
#include "core/scene/scene.h"
#include "runtime/context.h"
#include "runtime/kernel_source.h"

namespace tandem {

/// -D style scene defines, in order.
using SceneDefines = std::vector<std::pair<std::string, std::string>>;

/// What a session's device scene is built for.
struct SessionOptions {
    /// gradient: render_features (gradients, two-state renders, and forward renders);
    /// forward: forward_render_features (`tandem render`: forward renders only).
    enum class Kernels { gradient, forward } kernels = Kernels::gradient;
    bool restir = false; ///< RESTIR=1 (restir_features): the passes can reuse light samples
    /// Flags set on top of those (a benchmark measuring a variant, e.g. DET_MATH=0).
    std::vector<std::pair<std::string, int>> flags;
};

/// A host array handed in by the caller: `count` floats at `data`, valid for the call.
struct FloatSpan {
    const float* data = nullptr;
    std::size_t count = 0;
};

class Session {
public:
    /// Loads `path` with `defines` onto a context of its own on `device` (an index or name
    /// substring; empty: $TANDEM_DEVICE, else the first GPU, else the first device), with the
    /// kernel library of the environment.
    Session(const std::string& path, const std::string& device, const SceneDefines& defines,
            const SessionOptions& options = {});
    /// Loads `path` onto `ctx` (which must outlive the session).
    Session(Context& ctx, const KernelLibrary& lib, const std::string& path,
            const SceneDefines& defines, const SessionOptions& options = {});
    /// A scene already built (a benchmark's resized one).
    Session(Context& ctx, const KernelLibrary& lib, RenderScene scene,
            const SessionOptions& options = {});
    Session(const Session&) = delete;
    Session& operator=(const Session&) = delete;

    const std::string& path() const { return m_path; }
    /// The scene's sensors (RenderScene::sensors), numbered in file order.
    unsigned sensors() const { return m_device->sensors(); }
    /// The index of the sensor `key` names (its index or its id: find_sensor).
    unsigned sensor(const std::string& key) const {
        return static_cast<unsigned>(find_sensor(m_scene.sensors, key));
    }
    unsigned width(unsigned sensor = 0) const { return m_device->width(sensor); }
    unsigned height(unsigned sensor = 0) const { return m_device->height(sensor); }
    /// Floats of an image of sensor `sensor`'s film.
    std::size_t image_size(unsigned sensor = 0) const { return 3 * m_device->pixels(sensor); }
    /// Sensor `sensor`'s sample count (its <sampler>).
    int default_spp(unsigned sensor = 0) const { return m_scene.sensors.at(sensor).spp; }
    const DeviceInfo& device_info() const { return m_ctx->device(); }
    const RenderScene& scene() const { return m_scene; }
    const std::vector<Parameter>& parameters() const { return m_scene.params.parameters(); }
    /// The parameter called `name`; throws Error naming the known ones otherwise.
    const Parameter& parameter(const std::string& name) const { return m_scene.params.find(name); }

    Context& context() { return *m_ctx; }
    const KernelLibrary& library() const { return m_lib; }
    DeviceScene& device_scene() { return *m_device; }
    ParamState& state() { return *m_state; }
    /// Serializes callers on several threads (the Python module holds it with the GIL released).
    std::mutex& mutex() { return m_mutex; }

    /// The current value of `p` (theta), downloaded.
    std::vector<float> value(const Parameter& p);
    /// Writes `values` (p.size elements, or 1 for every element, or 3 for every texel of an rgb
    /// texture) into theta, and into theta_prev: an assignment starts a new trajectory, it is
    /// not a step whose previous state the next two-state render should see. Throws Error naming
    /// the parameter for another count, a non-finite value or one outside the parameter's range;
    /// theta is unchanged then.
    void set_value(const Parameter& p, FloatSpan values);
    /// theta and theta_prev <- `values` (the whole layout).
    void set_values(const std::vector<float>& values);

    // Every render and gradient below is of one sensor, `sensor` (0: the first in the file).

    /// render_image() of theta (options.spp 0: the sensor's).
    RenderResult render_image(const RenderOptions& options, unsigned sensor = 0);
    /// render_image() of other parameter values of the same scene (a target's).
    RenderResult render_image(const std::vector<float>& values, const RenderOptions& options,
                              unsigned sensor = 0);
    /// spp (0: the sensor's) paths per pixel of theta with `seed`.
    std::vector<float> render(int spp, std::uint32_t seed, unsigned sensor = 0);
    /// The fused two-state render (CV-PS): <F(theta)> and <F(theta_prev)> along the same paths.
    /// theta_prev is the value before the last optimizer step (or the last assignment), with
    /// `previous` overriding the values of the parameters it names.
    std::pair<std::vector<float>, std::vector<float>>
    render_two_state(int spp, std::uint32_t seed,
                     const std::vector<std::pair<const Parameter*, FloatSpan>>& previous,
                     unsigned sensor = 0);
    /// The sample budgets of shape gradients' boundary terms for every gradient from now on
    /// (core/render/passes.h: BoundarySamples; -1, the default, takes the adjoint's spp).
    /// A null b.reuse keeps set_boundary_reuse's reservoirs.
    void set_boundary_samples(BoundarySamples b) {
        if (!b.reuse) b.reuse = m_boundary_reuse.get();
        m_boundary = b;
    }
    BoundarySamples boundary_samples() const { return m_boundary; }
    /// The secondary boundary term's reuse of light vertices from one gradient to the next
    /// (core/render/boundary_reuse.h), with reservoirs of the session's own that every grad()
    /// from now on reads and advances (as boundary_samples().reuse); nullopt: none, and the
    /// reservoirs are dropped. Throws Error unless the session was built with
    /// SessionOptions::restir.
    void set_boundary_reuse(const std::optional<SecondaryReuseConfig>& config);

    /// Path Replay Backpropagation for delta = dloss/dimage (image_size() floats): the gradient
    /// of every parameter element in the layout of the registry, those outside `params` zero.
    /// The gradient stays in the parameter state for an optimizer's step.
    std::vector<float> backward(FloatSpan delta, int spp, std::uint32_t seed,
                                const std::vector<const Parameter*>& params, unsigned sensor = 0);

    /// The gradient evaluation of this session's scene against `reference` (3 floats a pixel;
    /// empty for LOSS_MEAN) with the control variate `cv`, attached to the parameter state.
    std::unique_ptr<GradientStep> gradient_step(unsigned loss, const std::vector<float>& reference,
                                                CvMode cv = CvMode::none,
                                                CvVariance variance = CvVariance::consistent,
                                                unsigned sensor = 0);

    struct GradResult {
        float loss = 0.0f;
        std::vector<float> gradient; ///< as backward()
    };
    /// `tandem grad`: the primal render (Stream::primal of (seed, 0), spp; 0: the scene's), the
    /// loss `loss` against `reference` (empty for "mean") and its delta on the device, and the
    /// adjoint (Stream::adjoint, spp_grad; 0: spp). With `restir`, the adjoint reuses light
    /// samples after the burn-in (the session must be built with SessionOptions::restir).
    GradResult grad(unsigned loss, const std::vector<float>& reference,
                    const std::vector<const Parameter*>& params, int spp, int spp_grad,
                    std::uint32_t seed, const std::optional<RestirConfig>& restir = std::nullopt,
                    unsigned sensor = 0);
    /// The gradient of the sum of several views' losses, each against its target (one batch of
    /// GradientStep: one fixed-point accumulator), each view with its own streams (view_seed).
    GradResult grad(unsigned loss, std::vector<ViewTarget> targets,
                    const std::vector<const Parameter*>& params, int spp, int spp_grad,
                    std::uint32_t seed, const std::optional<RestirConfig>& restir = std::nullopt);
    /// As above with the loss by name and the reference from the caller (checked: size and
    /// finiteness).
    GradResult grad(const std::string& loss, FloatSpan reference,
                    const std::vector<const Parameter*>& params, int spp, int spp_grad,
                    std::uint32_t seed, unsigned sensor = 0);

private:
    Session(std::unique_ptr<Context> own, Context* ctx, const KernelLibrary& lib, std::string path,
            RenderScene scene, const SessionOptions& options);
    /// Uploads `data` into the scratch buffer `b` (image_size(sensor) floats), allocated on
    /// first use.
    Buffer<float>& upload_image(std::unique_ptr<Buffer<float>>& b, const char* name, FloatSpan data,
                                const char* what, unsigned sensor);
    /// `b`, allocated (again) for `floats` floats unless it holds that many.
    Buffer<float>& scratch(std::unique_ptr<Buffer<float>>& b, const char* name, std::size_t floats);

    std::unique_ptr<Context> m_own_ctx;
    Context* m_ctx;
    KernelLibrary m_lib;
    std::string m_path;
    RenderScene m_scene;
    std::unique_ptr<DeviceScene> m_device;
    std::unique_ptr<ParamState> m_state;
    std::unique_ptr<Buffer<float>> m_delta, m_image, m_image_old;
    std::mutex m_mutex;
    BoundarySamples m_boundary;
    std::unique_ptr<SecondaryReservoirs> m_boundary_reuse; ///< set_boundary_reuse's
};

} // namespace tandem
