// A loaded scene on a device with its parameter state and passes.
#include "core/inverse/session.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/inverse/restir.h"
#include "core/render/features.h"
#include "runtime/error.h"

namespace tandem {

namespace {

std::string number(float v) {
    std::ostringstream s;
    s << v;
    return s.str();
}

/// `values` expanded to p.size elements: p.size as given, 1 for every element, or 3 (one rgb)
/// for every texel of a texture or voxel of an rgb grid. Checks finiteness and the range.
std::vector<float> expand_value(const Parameter& p, FloatSpan values) {
    std::vector<float> out(p.size);
    if (values.count == p.size) {
        std::copy(values.data, values.data + values.count, out.begin());
    } else if (values.count == 1) {
        std::fill(out.begin(), out.end(), values.data[0]);
    } else if (values.count == 3 && (p.kind == Parameter::Kind::texture ||
                                      (p.kind == Parameter::Kind::volume && p.channels == 3))) {
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

RenderScene load(const std::string& path, const SceneDefines& defines) {
    const SceneDesc desc = load_scene(path, defines);
    return build_render_scene(desc);
}

} // namespace

Session::Session(const std::string& path, const std::string& device, const SceneDefines& defines,
                 const SessionOptions& options)
    : Session(std::make_unique<Context>(Context::create(device)), nullptr,
              KernelLibrary::from_environment(), path, load(path, defines), options) {}

Session::Session(Context& ctx, const KernelLibrary& lib, const std::string& path,
                 const SceneDefines& defines, const SessionOptions& options)
    : Session(nullptr, &ctx, lib, path, load(path, defines), options) {}

Session::Session(Context& ctx, const KernelLibrary& lib, RenderScene scene,
                 const SessionOptions& options)
    : Session(nullptr, &ctx, lib, std::string(), std::move(scene), options) {}

Session::Session(std::unique_ptr<Context> own, Context* ctx, const KernelLibrary& lib,
                 std::string path, RenderScene scene, const SessionOptions& options)
    : m_own_ctx(std::move(own)), m_ctx(ctx ? ctx : m_own_ctx.get()), m_lib(lib),
      m_path(std::move(path)), m_scene(std::move(scene)) {
    // The one place a device scene is built: its BVH and its kernels.
    BuildFlags features = options.kernels == SessionOptions::Kernels::forward
                              ? forward_render_features(m_scene, m_ctx->device())
                              : render_features(m_scene, m_ctx->device());
    if (options.restir) features = restir_features(features);
    for (const auto& [name, value] : options.flags)
        features.set(name, value);
    m_device = std::make_unique<DeviceScene>(*m_ctx, m_lib, m_scene, features);
    m_state = std::make_unique<ParamState>(*m_ctx, m_scene.params);
}

std::vector<float> Session::value(const Parameter& p) {
    std::vector<float> out(p.size);
    m_state->theta().enqueue_read(p.offset, p.size, out.data());
    m_ctx->finish();
    return out;
}

void Session::set_value(const Parameter& p, FloatSpan values) {
    const std::vector<float> v = expand_value(p, values);
    for (Buffer<float>* b : {&m_state->theta(), &m_state->theta_prev()}) {
        std::vector<float> values = b->download();
        std::copy(v.begin(), v.end(), values.begin() + std::ptrdiff_t(p.offset));
        b->upload(values);
    }
    if (p.moves_geometry()) m_device->track_geometry(); // the passes trace the new positions
}

void Session::set_values(const std::vector<float>& values) {
    if (!m_scene.mesh_shapes.empty()) m_device->track_geometry();
    m_state->theta().upload(values);
    m_state->theta_prev().upload(values);
}

RenderResult Session::render_image(const RenderOptions& options, unsigned sensor) {
    return tandem::render_image(View(*m_device, sensor), m_state->theta(), options);
}

RenderResult Session::render_image(const std::vector<float>& values, const RenderOptions& options,
                                   unsigned sensor) {
    const Buffer<float> params(*m_ctx, "parameters", at_least_one(values));
    if (!m_scene.mesh_shapes.empty()) m_device->track_geometry(); // its shapes where they say
    return tandem::render_image(View(*m_device, sensor), params, options);
}

std::vector<float> Session::render(int spp, std::uint32_t seed, unsigned sensor) {
    check_spp(spp, "spp");
    RenderOptions opt;
    opt.spp = spp;
    opt.seed = seed;
    return render_image(opt, sensor).rgb;
}

Buffer<float>& Session::scratch(std::unique_ptr<Buffer<float>>& b, const char* name,
                                std::size_t floats) {
    if (!b || b->size() != floats) b = std::make_unique<Buffer<float>>(*m_ctx, name, floats);
    return *b;
}

std::pair<std::vector<float>, std::vector<float>>
Session::render_two_state(int spp, std::uint32_t seed,
                          const std::vector<std::pair<const Parameter*, FloatSpan>>& previous,
                          unsigned sensor) {
    const View view(*m_device, sensor);
    check_spp(spp, "spp");
    if (spp == 0) spp = default_spp(sensor);
    const Buffer<float>* old = &m_state->theta_prev();
    Buffer<float> overridden;
    if (!previous.empty()) {
        std::vector<float> values = m_state->theta_prev().download();
        for (const auto& [p, span] : previous) {
            const std::vector<float> v = expand_value(*p, span);
            std::copy(v.begin(), v.end(), values.begin() + std::ptrdiff_t(p->offset));
        }
        overridden = Buffer<float>(*m_ctx, "previous parameters", values);
        old = &overridden;
    }
    Buffer<float>& image = scratch(m_image, "image", image_size(sensor));
    Buffer<float>& image_old = scratch(m_image_old, "old image", image_size(sensor));
    tandem::render_two_state(view, m_state->theta(), *old, seed, spp, image, image_old);
    std::pair<std::vector<float>, std::vector<float>> out{image.download(), image_old.download()};
    return out;
}

Buffer<float>& Session::upload_image(std::unique_ptr<Buffer<float>>& b, const char* name,
                                     FloatSpan data, const char* what, unsigned sensor) {
    if (data.count != image_size(sensor))
        throw Error(std::string(what) + " has " + std::to_string(data.count) +
                    " elements; the film" + (sensors() > 1 ? " of sensor " + std::to_string(sensor) : "") +
                    " needs " + std::to_string(height(sensor)) + " x " +
                    std::to_string(width(sensor)) + " x 3 = " + std::to_string(image_size(sensor)));
    Buffer<float>& out = scratch(b, name, image_size(sensor));
    out.upload(data.data, data.count);
    return out;
}

std::vector<float> Session::backward(FloatSpan delta, int spp, std::uint32_t seed,
                                     const std::vector<const Parameter*>& params,
                                     unsigned sensor) {
    const View view(*m_device, sensor);
    check_spp(spp, "spp");
    if (spp == 0) spp = default_spp(sensor);
    for (std::size_t i = 0; i < delta.count; ++i)
        if (!std::isfinite(delta.data[i]))
            throw Error("delta: element " + std::to_string(i) + " is not finite");
    const Buffer<float>& d = upload_image(m_delta, "delta", delta, "delta", sensor);
    m_state->differentiate_only(params);
    tandem::backward(view, m_state->theta(), seed, spp, d, m_state->gradient());
    return m_state->gradient().value.download();
}

void Session::set_boundary_reuse(const std::optional<SecondaryReuseConfig>& config) {
    if (config && m_device->features().get("RESTIR") != 1)
        throw Error("boundary reuse: the scene's kernels were not built for ReSTIR (Python: "
                    "tandem.load(..., restir=True))");
    if (config) validate_secondary_reuse(*config, "boundary reuse");
    m_boundary_reuse = config ? std::make_unique<SecondaryReservoirs>(*m_ctx, *config) : nullptr;
    m_boundary.reuse = m_boundary_reuse.get();
}

std::unique_ptr<GradientStep> Session::gradient_step(unsigned loss,
                                                     const std::vector<float>& reference, CvMode cv,
                                                     CvVariance variance, unsigned sensor) {
    auto step = std::make_unique<GradientStep>(
        *m_device, m_lib, loss, std::vector<ViewTarget>{ViewTarget{sensor, reference, {}}}, cv,
        variance);
    step->set_boundary_samples(m_boundary);
    return step;
}

Session::GradResult Session::grad(unsigned loss, const std::vector<float>& reference,
                                  const std::vector<const Parameter*>& params, int spp,
                                  int spp_grad, std::uint32_t seed,
                                  const std::optional<RestirConfig>& restir, unsigned sensor) {
    return grad(loss, std::vector<ViewTarget>{ViewTarget{sensor, reference, {}}}, params, spp,
                spp_grad, seed, restir);
}

Session::GradResult Session::grad(unsigned loss, std::vector<ViewTarget> targets,
                                  const std::vector<const Parameter*>& params, int spp,
                                  int spp_grad, std::uint32_t seed,
                                  const std::optional<RestirConfig>& restir) {
    if (targets.empty()) throw Error("grad: no view");
    if (spp == 0) spp = default_spp(targets.front().sensor);
    if (spp_grad == 0) spp_grad = spp;
    std::vector<ViewPass> batch;
    for (unsigned v = 0; v < targets.size(); ++v)
        batch.push_back(ViewPass::of(v, 0, targets[v].sensor, seed, 0));
    const auto step = std::make_unique<GradientStep>(*m_device, m_lib, loss, std::move(targets),
                                                     CvMode::none, CvVariance::consistent);
    if (restir) step->enable_restir(*restir, spp_grad);
    step->set_boundary_samples(m_boundary);
    step->attach(*m_state);
    m_state->differentiate_only(params); // only the requested gradients are computed
    if (restir)
        for (unsigned v = 0; v < step->views(); ++v)
            step->restir(v)->burn_in(*m_state, view_seed(seed, step->sensor(v)));
    step->evaluate(*m_state, batch, spp, spp_grad);
    GradResult out;
    out.loss = step->loss();
    out.gradient = m_state->gradient().value.download();
    return out;
}

Session::GradResult Session::grad(const std::string& loss, FloatSpan reference,
                                  const std::vector<const Parameter*>& params, int spp,
                                  int spp_grad, std::uint32_t seed, unsigned sensor) {
    check_spp(spp, "spp");
    check_spp(spp_grad, "spp_grad");
    const unsigned kind = loss_kind(loss);
    std::vector<float> ref;
    if (kind != LOSS_MEAN) {
        if (reference.data == nullptr) throw Error("loss '" + loss + "' needs a reference image");
        if (reference.count != image_size(sensor))
            throw Error("the reference has " + std::to_string(reference.count) +
                        " elements; the film needs " + std::to_string(height(sensor)) + " x " +
                        std::to_string(width(sensor)) + " x 3 = " +
                        std::to_string(image_size(sensor)));
        ref.assign(reference.data, reference.data + reference.count);
        for (std::size_t i = 0; i < ref.size(); ++i)
            if (!std::isfinite(ref[i]))
                throw Error("reference: element " + std::to_string(i) + " is not finite");
    }
    return grad(kind, ref, params, spp, spp_grad, seed, std::nullopt, sensor);
}

} // namespace tandem
