// Large Steps of optimized meshes: each step's solves on the host, the optimizer's update on the
// device (the state's kernels).
#include "core/inverse/shape_steps.h"

#include <limits>
#include <sstream>

#include "runtime/error.h"

namespace tandem {

struct ShapeSteps::Shape {
    const Parameter* param = nullptr;
    float rate = 0.0f;
    LargeSteps steps;
    Buffer<float>* u = nullptr;
    Buffer<float>* m = nullptr;
    Buffer<float>* v = nullptr;
    Buffer<float> grad, lr, lower, upper;
    Shape(const Parameter* p, float rate, LargeSteps ls) : param(p), rate(rate), steps(std::move(ls)) {}
};

ShapeSteps::~ShapeSteps() = default;

ShapeSteps::ShapeSteps(ParamState& state, const KernelLibrary& lib, const OptimizeConfig& config,
                       const RenderScene& scene, const OptimizerConfig& optimizer)
    : m_state(state), m_update(state.context(), lib, optimizer) {
    for (const OptimizedParam& p : config.params) {
        if (!(p.large_steps > 0.0)) continue;
        const Parameter& q = scene.params.find(p.name);
        if (q.kind != Parameter::Kind::vertices)
            throw Error(config.path + ": params." + p.name + ": 'large_steps' is for a mesh's "
                        "vertex positions, and this is a " + parameter_kind_name(q.kind) +
                        " parameter");
        const MeshShape& shape = scene.mesh_shape(q);
        const std::vector<float>& values = scene.params.values();
        const std::vector<float> xyz(values.begin() + std::ptrdiff_t(q.offset),
                                     values.begin() + std::ptrdiff_t(q.offset + q.size));
        std::vector<unsigned> tris;
        for (unsigned t = 0; t < shape.triangle_count; ++t)
            for (int c = 0; c < 3; ++c)
                tris.push_back(scene.mesh.triangles[shape.first_triangle + t][c] - shape.first_vertex);
        auto s = std::make_unique<Shape>(&q, p.lr, LargeSteps(xyz, tris, p.large_steps));
        const std::size_t n = 3 * s->steps.points();
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
        m_shapes.push_back(std::move(s));
    }
}

void ShapeSteps::start(std::vector<float>& values) {
    for (const auto& s : m_shapes) {
        const Parameter& q = *s->param;
        const std::vector<float> x(values.begin() + std::ptrdiff_t(q.offset),
                                   values.begin() + std::ptrdiff_t(q.offset + q.size));
        const std::vector<float> u = s->steps.to_differential(x);
        s->u->upload(u);
        const std::vector<float> back = s->steps.from_differential(u);
        std::copy(back.begin(), back.end(), values.begin() + std::ptrdiff_t(q.offset));
    }
}

std::vector<float> ShapeSteps::rates(std::vector<float> lr) const {
    for (const auto& s : m_shapes)
        std::fill_n(lr.begin() + std::ptrdiff_t(s->param->offset), s->param->size, 0.0f);
    return lr;
}

void ShapeSteps::step(int it) {
    for (const auto& s : m_shapes) {
        const Parameter& q = *s->param;
        std::vector<float> g(q.size);
        m_state.gradient().value.enqueue_read(q.offset, q.size, g.data());
        m_state.context().finish();
        s->grad.upload(s->steps.gradient(g));
        m_update.update(*s->u, s->grad, *s->m, *s->v, s->lr, s->lower, s->upper,
                        static_cast<unsigned>(it + 1));
        const std::vector<float> x = s->steps.from_differential(s->u->download());
        m_state.theta().write(q.offset, x.data(), x.size());
    }
}

std::string ShapeSteps::plan() const {
    std::ostringstream out;
    for (const auto& s : m_shapes)
        out << "tandem optimize: " << s->param->name << " by Large Steps (lambda "
            << s->steps.lambda() << ", " << s->steps.points() << " points)\n";
    return out.str();
}

} // namespace tandem
