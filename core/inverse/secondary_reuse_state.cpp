// The secondary term's reservoirs in the parameter state (core/inverse/secondary_reuse_state.h).
#include "core/inverse/secondary_reuse_state.h"

#include "core/inverse/param_state.h"
#include "core/render/boundary_reuse.h"

namespace tandem {

namespace {

// "boundary.header": whether the grid is fixed, its cell, the floor, whether there are previous
// reservoirs; the previous reservoirs and their edge table (one placeholder each where there are
// none), of whatever size the pass had.
constexpr const char* k_header = "boundary.header";
constexpr const char* k_reservoirs = "boundary.reservoirs";
constexpr const char* k_edges = "boundary.edges";

} // namespace

void attach_secondary_reuse(ParamState& state) {
    if (state.has_buffer(k_header)) return;
    state.add_buffer(k_header, 4, 0.0f);
    state.add_buffer(k_reservoirs, 1, gpu::BoundaryReservoir{}, true);
    state.add_buffer(k_edges, 1, gpu::SecondaryEdge{}, true);
}

void store_secondary_reuse(const SecondaryReservoirs& reservoirs, ParamState& state) {
    const SecondaryReservoirs::Saved s = reservoirs.saved();
    const bool previous = !s.previous.empty();
    state.buffer<float>(k_header).upload(
        {s.fixed ? 1.0f : 0.0f, s.cell, s.lum_floor, previous ? 1.0f : 0.0f});
    Buffer<gpu::BoundaryReservoir>& r = state.buffer<gpu::BoundaryReservoir>(k_reservoirs);
    Buffer<gpu::SecondaryEdge>& e = state.buffer<gpu::SecondaryEdge>(k_edges);
    // move-assigned: the state's references stay valid
    r = Buffer<gpu::BoundaryReservoir>(state.context(), k_reservoirs,
                                       previous ? s.previous
                                                : std::vector<gpu::BoundaryReservoir>(1));
    e = Buffer<gpu::SecondaryEdge>(state.context(), k_edges,
                                   previous ? s.edges : std::vector<gpu::SecondaryEdge>(1));
}

void load_secondary_reuse(ParamState& state, SecondaryReservoirs& reservoirs) {
    const std::vector<float> h = state.buffer<float>(k_header).download(); // 4, as attached
    SecondaryReservoirs::Saved s;
    s.fixed = h[0] != 0.0f;
    s.cell = h[1];
    s.lum_floor = h[2];
    if (h[3] != 0.0f) {
        s.previous = state.buffer<gpu::BoundaryReservoir>(k_reservoirs).download();
        s.edges = state.buffer<gpu::SecondaryEdge>(k_edges).download();
    }
    reservoirs.restore(s);
}

} // namespace tandem
