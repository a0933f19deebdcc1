// ReSTIR across gradient iterations: the reservoirs and the resampling pass.
#include "core/inverse/restir.h"

#include "runtime/error.h"

namespace tandem {

Restir::Restir(const View& view, const RestirConfig& config, int spp, RestirChain chain)
    : m_view(view), m_passes(view, config, spp), m_chain(chain),
      m_state_buffer(view_buffer(chain == RestirChain::primal ? k_primal_reservoirs : k_reservoirs,
                                 view.sensor, view.scene->sensors())),
      m_current(view.scene->context(), "reservoirs (current)", m_passes.slots()) {
    DeviceScene& scene = *view.scene;
    scene.kernel("restir.cl", "restir_resample"); // compile now, not inside a timed iteration
    if (chain == RestirChain::primal)
        scene.kernel("render.cl", "render_pass_resample");
    else
        scene.kernel("adjoint.cl", "adjoint_primal_resample");
}

void Restir::attach(ParamState& state) const {
    if (!state.has_buffer(state_buffer()))
        state.add_buffer(state_buffer(), m_current.size(), gpu::reservoir_empty());
}

PathReservoirs Restir::pending(const Buffer<float>& theta_prev, const Buffer<gpu::Reservoir>& prev,
                               const GradientBuffers& grad, std::uint32_t seed) const {
    return m_passes.resampled(m_current, theta_prev, prev, grad, seed);
}

PathReservoirs Restir::resampled_by_paths(ParamState& state, std::uint32_t seed) {
    return resampled_by_paths(state, seed, state.theta_prev());
}

PathReservoirs Restir::resampled_by_paths(ParamState& state, std::uint32_t seed,
                                          const Buffer<float>& theta_prev) {
    return pending(theta_prev, state.buffer<gpu::Reservoir>(state_buffer()), state.gradient(),
                   seed);
}

void Restir::resample(ParamState& state, std::uint32_t seed_paths, std::uint32_t seed) {
    resample_reservoirs(m_view, state.theta(), seed_paths, resampled_by_paths(state, seed));
}

void Restir::commit(ParamState& state) {
    state.buffer<gpu::Reservoir>(state_buffer()).copy_from(m_current);
}

void Restir::burn_in(ParamState& state, std::uint32_t seed) {
    const bool primal = m_chain == RestirChain::primal;
    const Stream paths =
        primal ? Stream::restir_primal_burn_in_paths : Stream::restir_burn_in_paths;
    const Stream resample = primal ? Stream::restir_primal_burn_in : Stream::restir_burn_in;
    for (int b = 0; b < config().burn_in; ++b) {
        const std::uint32_t iteration = static_cast<std::uint32_t>(b);
        resample_reservoirs(m_view, state.theta(), stream_seed(seed, iteration, paths),
                            pending(state.theta(), state.buffer<gpu::Reservoir>(state_buffer()),
                                    state.gradient(), stream_seed(seed, iteration, resample)));
        commit(state);
    }
}

PathReservoirs Restir::reservoirs() const {
    return m_passes.read(m_current);
}

} // namespace tandem
