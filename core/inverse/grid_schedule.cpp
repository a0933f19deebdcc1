// The resolution schedule of grid parameters (grid_schedule.h says what it does).
#include "core/inverse/grid_schedule.h"

#include <array>
#include <sstream>

#include "runtime/error.h"
#include "shared/medium.h"

namespace tandem {

namespace {

using Dims = std::array<int, 3>;

std::size_t voxels(const Dims& d) { return std::size_t(d[0]) * d[1] * d[2]; }

std::string dims_text(const Dims& d) {
    return std::to_string(d[0]) + "x" + std::to_string(d[1]) + "x" + std::to_string(d[2]);
}

/// `src` (dims s) resampled to dims d, on the host: what the kernel grid_resample computes.
std::vector<float> resample_host(const float* src, const Dims& s, const Dims& d, int channels) {
    std::vector<float> out(voxels(d) * channels);
    const auto c = unsigned(channels);
    std::size_t e = 0;
    for (unsigned z = 0; z < unsigned(d[2]); ++z)
        for (unsigned y = 0; y < unsigned(d[1]); ++y)
            for (unsigned x = 0; x < unsigned(d[0]); ++x)
                for (unsigned k = 0; k < c; ++k)
                    out[e++] = gpu::grid_resample_at(src, s[0], s[1], s[2], c, x, y, z, d[0],
                                                     d[1], d[2], k);
    return out;
}

} // namespace

struct GridSchedule::Grid {
    const Parameter* param = nullptr;
    std::vector<int> upsample; ///< the iterations after which the next level begins
    std::vector<Dims> dims;    ///< per level 0..k; level k is the grid's own
    int channels = 1;
    float rate = 0.0f;
    std::string name; ///< of its buffers in the state: "upsample.NAME"
    Buffer<float>*u = nullptr, *m = nullptr, *v = nullptr; ///< the coarse levels'
    Buffer<float> grad, lr, lower, upper, scratch;
    Buffer<float>*m_full = nullptr, *v_full = nullptr; ///< the full level's, in the state's layout
    Buffer<float> lr_full; ///< the rate on the grid's elements, 0 elsewhere
    int rates_level = -1;  ///< the coarse level whose rates `lr` holds
    int levels() const { return int(upsample.size()); } ///< k: the coarse levels
    std::size_t count(int level) const { return voxels(dims[level]) * std::size_t(channels); }
    /// The first iteration (0-based) of `level`.
    int first(int level) const { return level == 0 ? 0 : upsample[level - 1]; }
};

GridSchedule::GridSchedule(ParamState& state, const KernelLibrary& lib,
                           const OptimizeConfig& config, const ParamRegistry& registry,
                           const OptimizerConfig& optimizer)
    : m_state(state), m_ctx(state.context()),
      m_program(Program::build(state.context(), lib, "optim.cl", "")),
      m_resample(m_program, "grid_resample"), m_adjoint(m_program, "grid_resample_adjoint"),
      m_update(state.context(), lib, optimizer) {
    for (const OptimizedParam& p : config.params) {
        if (p.upsample.empty()) continue;
        const Parameter& q = registry.find(p.name);
        if (q.kind != Parameter::Kind::volume)
            throw Error(config.path + ": params." + p.name + ": 'upsample' is a grid's schedule, "
                        "and this is a " + parameter_kind_name(q.kind) + " parameter");
        auto g = std::make_unique<Grid>();
        g->param = &q;
        g->upsample = p.upsample;
        g->channels = q.channels;
        g->rate = p.lr;
        g->name = "upsample." + q.name;
        const int k = g->levels();
        for (int j = 0; j <= k; ++j) {
            Dims d{q.width, q.height, q.depth};
            for (int& n : d) n = std::max(1, (n + (1 << (k - j)) - 1) >> (k - j));
            g->dims.push_back(d);
        }
        const std::size_t n = g->count(k - 1); // the finest coarse level
        g->u = &state.add_buffer(g->name + ".u", n, 0.0f);
        g->m = &state.add_buffer(g->name + ".m", n, 0.0f);
        g->v = &state.add_buffer(g->name + ".v", n, 0.0f);
        g->grad = Buffer<float>(m_ctx, g->name + " gradient", std::vector<float>(n, 0.0f));
        g->lr = Buffer<float>(m_ctx, g->name + " rates", std::vector<float>(n, 0.0f));
        g->lower = Buffer<float>(m_ctx, g->name + " lower", std::vector<float>(n, q.lower));
        g->upper = Buffer<float>(m_ctx, g->name + " upper", std::vector<float>(n, q.upper));
        g->scratch = Buffer<float>(m_ctx, g->name + " scratch", std::vector<float>(n, 0.0f));
        g->m_full = &state.add_buffer(g->name + ".m_full", state.size(), 0.0f);
        g->v_full = &state.add_buffer(g->name + ".v_full", state.size(), 0.0f);
        std::vector<float> rates(state.size(), 0.0f);
        std::fill_n(rates.begin() + std::ptrdiff_t(q.offset), q.size, p.lr);
        g->lr_full = Buffer<float>(m_ctx, g->name + " rates (full)", rates);
        m_grids.push_back(std::move(g));
    }
}

GridSchedule::~GridSchedule() {
    for (const auto& g : m_grids)
        for (const char* b : {".u", ".m", ".v", ".m_full", ".v_full"})
            m_state.remove_buffer(g->name + b);
}

int GridSchedule::level(const Grid& g, int done) const {
    int j = 0;
    while (j < g.levels() && g.upsample[j] <= done) ++j;
    return j;
}

void GridSchedule::start(std::vector<float>& values) {
    for (const auto& g : m_grids) {
        const Parameter& p = *g->param;
        const Dims full = g->dims.back();
        std::vector<float> u = resample_host(values.data() + p.offset, full, g->dims[0], g->channels);
        const std::vector<float> theta = resample_host(u.data(), g->dims[0], full, g->channels);
        std::copy(theta.begin(), theta.end(), values.begin() + std::ptrdiff_t(p.offset));
        u.resize(g->u->size(), 0.0f);
        g->u->upload(u);
    }
}

std::vector<float> GridSchedule::rates(std::vector<float> lr) const {
    for (const auto& g : m_grids)
        std::fill_n(lr.begin() + std::ptrdiff_t(g->param->offset), g->param->size, 0.0f);
    return lr;
}

void GridSchedule::resample(const Buffer<float>& src, std::size_t src_offset, const int* s,
                            Buffer<float>& dst, std::size_t dst_offset, const int* d,
                            int channels) {
    const std::size_t n = std::size_t(d[0]) * d[1] * d[2] * channels;
    m_resample.launch(m_ctx, "optimizer", n, src, unsigned(src_offset), unsigned(s[0]),
                      unsigned(s[1]), unsigned(s[2]), dst, unsigned(dst_offset), unsigned(d[0]),
                      unsigned(d[1]), unsigned(d[2]), unsigned(channels));
}

void GridSchedule::step(int it) {
    for (const auto& g : m_grids) {
        const int j = level(*g, it);
        const auto t = unsigned(it + 1 - g->first(j)); // the level's own steps, from 1
        if (j == g->levels()) {
            m_update.update(m_state.theta(), m_state.gradient().value, *g->m_full, *g->v_full,
                            g->lr_full, m_state.lower(), m_state.upper(), t);
            continue;
        }
        const Parameter& p = *g->param;
        const Dims& d = g->dims[j];
        const Dims& full = g->dims.back();
        // P^T of theta's gradient into the coarse grid's, a step on it, and theta = P u again
        m_adjoint.launch(m_ctx, "optimizer", g->count(j), m_state.gradient().value,
                         unsigned(p.offset), unsigned(full[0]), unsigned(full[1]),
                         unsigned(full[2]), g->grad, 0u, unsigned(d[0]), unsigned(d[1]),
                         unsigned(d[2]), unsigned(g->channels));
        if (g->rates_level != j) { // the level's rates: its voxels' (a resume starts anywhere)
            std::vector<float> rates(g->lr.size(), 0.0f);
            std::fill_n(rates.begin(), g->count(j), g->rate);
            g->lr.upload(rates);
            g->rates_level = j;
        }
        m_update.update(*g->u, g->grad, *g->m, *g->v, g->lr, g->lower, g->upper, t);
        resample(*g->u, 0, d.data(), m_state.theta(), p.offset, full.data(), g->channels);
        // after the level's last step: the next coarse level starts from u's resampling (the
        // full level from theta = P u, as it is)
        if (it + 1 != g->upsample[j] || j + 1 == g->levels()) continue;
        resample(*g->u, 0, d.data(), g->scratch, 0, g->dims[j + 1].data(), g->channels);
        g->u->copy_from(g->scratch);
        g->m->fill(0.0f);
        g->v->fill(0.0f);
    }
}

std::string GridSchedule::plan() const {
    std::ostringstream out;
    for (const auto& g : m_grids) {
        out << "tandem optimize: " << g->param->name << ": resolution schedule "
            << dims_text(g->dims[0]);
        for (int j = 1; j <= g->levels(); ++j)
            out << " -> " << dims_text(g->dims[j]) << " after iteration " << g->upsample[j - 1];
        out << " (trilinear; coarse levels are resampled to the full grid)\n";
    }
    return out.str();
}

std::string GridSchedule::changes(int it) const {
    std::string out;
    for (const auto& g : m_grids)
        for (int j = 0; j < g->levels(); ++j)
            if (g->upsample[j] == it + 1)
                out += "tandem optimize: iteration " + std::to_string(it + 1) + ": " +
                       g->param->name + " now " + dims_text(g->dims[j + 1]) + "\n";
    return out;
}

} // namespace tandem
