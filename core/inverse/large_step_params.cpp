// Large Steps of optimized meshes and textures: each step's solves on the host, the optimizer's
// update on the device (the state's kernels).
#include "core/inverse/large_step_params.h"

#include <algorithm>
#include <limits>
#include <sstream>

#include "runtime/error.h"

namespace tandem {

struct LargeStepParams::Entry {
    const Parameter* param = nullptr;
    float rate = 0.0f;
    LargeSteps steps;
    Buffer<float>* u = nullptr;
    Buffer<float>* m = nullptr;
    Buffer<float>* v = nullptr;
    Buffer<float> grad, lr, lower, upper;
    Entry(const Parameter* p, float rate, LargeSteps ls) : param(p), rate(rate), steps(std::move(ls)) {}
};

LargeStepParams::~LargeStepParams() = default;

namespace {

/// The parametrization of `q`: its mesh's Laplacian for vertex positions, its texel grid's for a
/// bitmap texture.
LargeSteps laplacian_of(const Parameter& q, const RenderScene& scene, double lambda,
                        const OptimizeConfig& config) {
    if (q.kind == Parameter::Kind::texture)
        return LargeSteps::image(unsigned(q.width), unsigned(q.height), 3, lambda);
    if (q.kind != Parameter::Kind::vertices)
        throw Error(config.path + ": params." + q.name + ": 'large_steps' is for a mesh's vertex "
                    "positions or a bitmap texture, and this is a " + parameter_kind_name(q.kind) +
                    " parameter");
    const MeshShape& shape = scene.mesh_shape(q);
    const std::vector<float>& values = scene.params.values();
    const std::vector<float> xyz(values.begin() + std::ptrdiff_t(q.offset),
                                 values.begin() + std::ptrdiff_t(q.offset + q.size));
    return LargeSteps(xyz, scene.shape_triangles(shape), lambda);
}

/// x clamped to the range of `q` (a texture's; vertex positions have none).
std::vector<float> clamped(std::vector<float> x, const Parameter& q) {
    for (float& v : x) v = std::min(std::max(v, q.lower), q.upper);
    return x;
}

/// A projected gradient for a texture's range: no pull outward where a texel is held at a bound
/// already (else u would drift on past it, and the solve spread that drift to its neighbours).
void hold_at_bounds(std::vector<float>& g, const Buffer<float>& theta, Context& ctx,
                    const Parameter& q) {
    std::vector<float> x(q.size);
    theta.enqueue_read(q.offset, q.size, x.data());
    ctx.finish();
    for (std::size_t i = 0; i < g.size(); ++i)
        if ((x[i] <= q.lower && g[i] > 0.0f) || (x[i] >= q.upper && g[i] < 0.0f)) g[i] = 0.0f;
}

} // namespace

LargeStepParams::LargeStepParams(ParamState& state, const KernelLibrary& lib,
                                 const OptimizeConfig& config, const RenderScene& scene,
                                 const OptimizerConfig& optimizer)
    : m_state(state), m_update(state.context(), lib, optimizer) {
    for (const OptimizedParam& p : config.params) {
        if (!(p.large_steps > 0.0)) continue;
        const Parameter& q = scene.params.find(p.name);
        auto s = std::make_unique<Entry>(&q, p.lr, laplacian_of(q, scene, p.large_steps, config));
        const std::size_t n = std::size_t(s->steps.channels()) * s->steps.points();
        const std::string name = "large_steps." + q.name;
        Context& ctx = state.context();
        s->u = &state.add_buffer(name + ".u", n, 0.0f);
        s->m = &state.add_buffer(name + ".m", n, 0.0f);
        s->v = &state.add_buffer(name + ".v", n, 0.0f);
        const float inf = std::numeric_limits<float>::infinity();
        s->grad = Buffer<float>(ctx, name + " gradient", std::vector<float>(n, 0.0f));
        s->lr = Buffer<float>(ctx, name + " rates", std::vector<float>(n, p.lr));
        s->lower = Buffer<float>(ctx, name + " lower", std::vector<float>(n, -inf));
        s->upper = Buffer<float>(ctx, name + " upper", std::vector<float>(n, inf));
        m_entries.push_back(std::move(s));
    }
}

void LargeStepParams::start(std::vector<float>& values) {
    for (const auto& s : m_entries) {
        const Parameter& q = *s->param;
        const std::vector<float> x(values.begin() + std::ptrdiff_t(q.offset),
                                   values.begin() + std::ptrdiff_t(q.offset + q.size));
        const std::vector<float> u = s->steps.to_differential(x);
        s->u->upload(u);
        const std::vector<float> back = clamped(s->steps.from_differential(u), q);
        std::copy(back.begin(), back.end(), values.begin() + std::ptrdiff_t(q.offset));
    }
}

std::vector<float> LargeStepParams::rates(std::vector<float> lr) const {
    for (const auto& s : m_entries)
        std::fill_n(lr.begin() + std::ptrdiff_t(s->param->offset), s->param->size, 0.0f);
    return lr;
}

void LargeStepParams::step(int it) {
    for (const auto& s : m_entries) {
        const Parameter& q = *s->param;
        std::vector<float> g(q.size);
        m_state.gradient().value.enqueue_read(q.offset, q.size, g.data());
        m_state.context().finish();
        if (q.kind == Parameter::Kind::texture)
            hold_at_bounds(g, m_state.theta(), m_state.context(), q);
        s->grad.upload(s->steps.gradient(g));
        m_update.update(*s->u, s->grad, *s->m, *s->v, s->lr, s->lower, s->upper,
                        static_cast<unsigned>(it + 1));
        const std::vector<float> x = clamped(s->steps.from_differential(s->u->download()), q);
        m_state.theta().write(q.offset, x.data(), x.size());
    }
}

std::string LargeStepParams::plan() const {
    std::ostringstream out;
    for (const auto& s : m_entries)
        out << "tandem optimize: " << s->param->name << " by Large Steps (lambda "
            << s->steps.lambda() << ", " << s->steps.points()
            << (s->param->kind == Parameter::Kind::texture ? " texels)\n" : " points)\n");
    return out.str();
}

} // namespace tandem
