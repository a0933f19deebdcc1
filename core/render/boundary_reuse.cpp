// The secondary term's reservoirs across passes (core/render/boundary_reuse.h).
#include "core/render/boundary_reuse.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/scene/render_scene.h"
#include "runtime/error.h"

namespace tandem {

void validate_secondary_reuse(const SecondaryReuseConfig& c, const std::string& where) {
    auto fail = [&](const std::string& what) { throw Error(where + ": " + what); };
    if (c.candidates < 1 || c.candidates > 64) fail("candidates must be within 1..64");
    if (c.neighbours < 0 || c.neighbours > int(RESTIR_MAX_NEIGHBOURS))
        fail("neighbours must be within 0.." + std::to_string(RESTIR_MAX_NEIGHBOURS));
    if (!(c.m_cap >= 1.0f && std::isfinite(c.m_cap))) fail("m_cap must be at least 1");
    if (!(c.cell > 0.0f && c.cell <= 1.0f)) fail("cell must be within (0, 1]");
    if (!(c.floor >= 0.0f && c.floor <= 1.0f)) fail("floor must be within [0, 1]");
}

SecondaryReservoirs::SecondaryReservoirs(Context& ctx, const SecondaryReuseConfig& config)
    : m_ctx(ctx), m_config(config),
      m_prev(ctx, "secondary reservoirs (previous)", 1),
      m_current(ctx, "secondary reservoirs", 1),
      m_prev_edges(ctx, "secondary edges (previous)", 1), m_first(ctx, "secondary buckets", 1),
      m_slots(ctx, "secondary bucket slots", 1) {
    validate_secondary_reuse(config, "secondary reuse");
}

gpu::SecondaryReuse SecondaryReservoirs::begin(const RenderScene& scene,
                                               const std::vector<gpu::SecondaryEdge>& edges,
                                               std::size_t samples) {
    if (samples >= std::size_t(std::numeric_limits<unsigned>::max()))
        throw Error("secondary reuse: more than 2^32 samples per pass");
    if (m_cell == 0.0f) {
        // the grid: cells a fixed fraction of the edges' extent, for the whole run
        float lo[3], hi[3];
        std::fill_n(lo, 3, std::numeric_limits<float>::infinity());
        std::fill_n(hi, 3, -std::numeric_limits<float>::infinity());
        for (const gpu::SecondaryEdge& e : edges)
            for (const gpu::float4& p : {e.p0, e.p1}) {
                const float v[3] = {p.x, p.y, p.z};
                for (int k = 0; k < 3; ++k) {
                    lo[k] = std::min(lo[k], v[k]);
                    hi[k] = std::max(hi[k], v[k]);
                }
            }
        const float diagonal = std::hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
        m_cell = diagonal > 0.0f && std::isfinite(diagonal) ? m_config.cell * diagonal : 1.0f;
    }
    if (m_lum_floor < 0.0f) {
        // the floor: from the emitters' radiance where the run starts, for the whole run
        const std::vector<float> values = scene.params.values();
        float brightest = 0.0f;
        for (const gpu::EmissiveTriangle& t : scene.emissive) {
            if (t.radiance_param == NO_PARAM) continue;
            const float* c = &values.at(t.radiance_param);
            brightest = std::max(brightest, gpu::luminance(gpu::float3{c[0], c[1], c[2]}));
        }
        m_lum_floor = m_config.floor * brightest;
    }
    if (m_current.size() != samples)
        m_current = Buffer<gpu::BoundaryReservoir>(m_ctx, "secondary reservoirs", samples);
    gpu::SecondaryReuse r{};
    r.enabled = 1u;
    r.candidates = unsigned(m_config.candidates);
    r.neighbours = unsigned(m_config.neighbours);
    r.buckets = unsigned(m_buckets);
    r.cell = m_cell;
    r.m_cap = m_config.m_cap;
    r.lum_floor = m_lum_floor;
    r.flags = (m_config.visibility ? SECONDARY_REUSE_LIGHT_VISIBLE : 0u) |
              (m_config.receiver ? SECONDARY_REUSE_RECEIVER_SEEN : 0u);
    return r;
}

SecondaryReservoirs::Buckets
SecondaryReservoirs::bucket(const std::vector<gpu::BoundaryReservoir>& reservoirs) {
    std::size_t n = 1;
    while (n < 2 * reservoirs.size()) n *= 2;
    Buckets b;
    b.first.assign(n + 1, 0u);
    // every reservoir, empty ones too: which neighbours a point combines with may depend on their
    // points, never on their samples (kernels/path/boundary_reuse.h)
    for (const gpu::BoundaryReservoir& r : reservoirs) ++b.first[(r.cell & (n - 1)) + 1];
    for (std::size_t k = 0; k < n; ++k) b.first[k + 1] += b.first[k];
    b.slots.assign(b.first[n], 0u);
    std::vector<unsigned> next(b.first.begin(), b.first.end() - 1);
    for (std::size_t i = 0; i < reservoirs.size(); ++i)
        b.slots[next[reservoirs[i].cell & (n - 1)]++] = unsigned(i);
    return b;
}

void SecondaryReservoirs::commit(const std::vector<gpu::SecondaryEdge>& edges) {
    const std::vector<gpu::BoundaryReservoir> current = m_current.download();
    set_previous(current, edges);
    std::swap(m_prev, m_current);
}

void SecondaryReservoirs::set_previous(const std::vector<gpu::BoundaryReservoir>& reservoirs,
                                       const std::vector<gpu::SecondaryEdge>& edges) {
    const Buckets b = bucket(reservoirs);
    m_buckets = b.first.size() - 1;
    m_first = Buffer<unsigned>(m_ctx, "secondary buckets", b.first, CL_MEM_READ_ONLY);
    m_slots = Buffer<unsigned>(m_ctx, "secondary bucket slots", at_least_one(b.slots),
                               CL_MEM_READ_ONLY);
    m_prev_edges = Buffer<gpu::SecondaryEdge>(m_ctx, "secondary edges (previous)",
                                              at_least_one(edges), CL_MEM_READ_ONLY);
}

void SecondaryReservoirs::reset() { m_buckets = 0; }

SecondaryReservoirs::Saved SecondaryReservoirs::saved() const {
    Saved s;
    s.fixed = m_cell != 0.0f;
    s.cell = m_cell;
    s.lum_floor = m_lum_floor;
    if (m_buckets == 0) return s;
    s.previous = m_prev.download();
    s.edges = m_prev_edges.download();
    return s;
}

void SecondaryReservoirs::restore(const Saved& s) {
    m_cell = s.fixed ? s.cell : 0.0f;
    m_lum_floor = s.fixed ? s.lum_floor : -1.0f;
    m_buckets = 0;
    if (s.previous.empty()) return;
    if (s.edges.empty()) throw Error("secondary reuse: saved reservoirs without their edges");
    set_previous(s.previous, s.edges);
    m_prev = Buffer<gpu::BoundaryReservoir>(m_ctx, "secondary reservoirs (previous)", s.previous);
}

} // namespace tandem
