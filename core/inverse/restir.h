// ReSTIR across gradient iterations ("Amortizing Samples in Physics-Based Inverse Rendering using
// ReSTIR", Wang, Wyman, Wu, Zhao, SIGGRAPH Asia 2023, Sec. 4; docs/restir.md): the reservoirs of
// the adjoint's sample slots, kept in the parameter state from one iteration to the next, and the
// resampling pass (kernels/path/resample.h) that refreshes them before each adjoint reads them.
//
// Per iteration n, with theta_n = state.theta() and theta_{n-1} = state.theta_prev():
//   backward(..., a_n, resampled_by_paths(r_n))   prev (iteration n-1) -> current, fused into
//                                                 the adjoint's first kernel, which reads current
//   commit(): prev <- current
// or, the same bits with the pass on its own: resample(a_n, r_n), then backward(..., a_n,
// reservoirs()).
// prev lives in the parameter state under k_reservoirs, so checkpoints carry it and a resumed run
// continues bit for bit; current is scratch.
//
// A second, independent chain can serve the primal image as well (RestirChain::primal, with
// "cv": "none" only: docs/restir.md, "Reuse in the primal"): the same pass on the primal's
// camera paths and its own streams, its reservoirs under k_primal_reservoirs, read by render().
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/inverse/param_state.h"
#include "core/inverse/streams.h"
#include "core/render/device_scene.h"
#include "core/render/passes.h"
#include "core/render/reservoirs.h"
#include "shared/reservoir.h"

namespace tandem {

/// Which paths a chain of reservoirs serves: the adjoint's (PRB's primary vertices) or the primal
/// image's. The two never share reservoirs (docs/restir.md).
enum class RestirChain { adjoint, primal };

class Restir {
public:
    /// The named buffers of the parameter state that hold the previous iteration's reservoirs of
    /// the adjoint's chain and of the primal's.
    static constexpr const char* k_reservoirs = "restir.reservoirs";
    static constexpr const char* k_primal_reservoirs = "restir.primal.reservoirs";

    /// Reservoirs for `spp` samples per pixel of the film of `view` (the adjoint's spp_grad, or
    /// the primal's spp for the primal chain), whose scene must be built with RESTIR=1
    /// (restir_features). Each view of a scene with several sensors has a chain of its own, kept
    /// under its own name (view_buffer). Throws Error for a config out of range or a scene it
    /// cannot serve (restir_unsupported).
    Restir(const View& view, const RestirConfig& config, int spp,
           RestirChain chain = RestirChain::adjoint);

    const RestirConfig& config() const { return m_passes.config(); }
    int spp() const { return m_passes.spp(); }
    std::size_t slots() const { return m_passes.slots(); } ///< reservoirs of a chain
    RestirChain chain() const { return m_chain; }
    const View& view() const { return m_view; }
    /// The parameter state's buffer of this chain's previous reservoirs (view_buffer of
    /// k_reservoirs or k_primal_reservoirs).
    const std::string& state_buffer() const { return m_state_buffer; }

    /// Registers the reservoirs (all empty) in `state`: call once, before restoring a checkpoint
    /// into it.
    void attach(ParamState& state) const;

    /// The reservoirs for backward() (or render(), for the primal chain) to resample themselves
    /// before their paths read them, fused into their first kernel (PathReservoirs::resample;
    /// docs/restir.md, "One pass fewer"): the same bits as resample() with those paths' seed,
    /// then reservoirs(). `seed` is the pass's own stream (restir_seed), as resample()'s.
    PathReservoirs resampled_by_paths(ParamState& state, std::uint32_t seed);
    /// As above with the previous reservoirs' domain `theta_prev` (a view's, revisited after other
    /// views' steps: the parameters it was last rendered with) instead of state.theta_prev().
    PathReservoirs resampled_by_paths(ParamState& state, std::uint32_t seed,
                                      const Buffer<float>& theta_prev);
    /// Enqueues one resampling pass on its own for the paths of seed `seed_paths` (the
    /// adjoint's, or the primal's for the primal chain): reads the previous
    /// reservoirs of `state`, writes current() for state.theta(); `seed` is the pass's own
    /// stream (restir_seed). The previous reservoirs were drawn under state.theta_prev(), which
    /// the caller keeps at theta_{n-1} (ParamState::remember_theta before each step): their
    /// targets are evaluated under it, and another theta biases the combine where a support
    /// changes. Only the slots that need a reservoir are served, as state.gradient() says which
    /// elements are differentiated (kernels/path/resample.h: restir_serves), by either chain: the
    /// adjoint should use the same gradient buffers.
    void resample(ParamState& state, std::uint32_t seed_paths, std::uint32_t seed);
    /// The previous reservoirs become the current ones (enqueued): call after the pass that read
    /// them (the adjoint, or the primal render).
    void commit(ParamState& state);
    /// config().burn_in resampling-only passes at state.theta() (theta_prev taken equal to it),
    /// pass b with the streams Stream::restir_burn_in_paths and restir_burn_in of (seed, b)
    /// (restir_primal_burn_in_* for the primal chain); each is committed.
    void burn_in(ParamState& state, std::uint32_t seed);

    /// What backward() (or render(), for the primal chain) reads: the current reservoirs and how.
    PathReservoirs reservoirs() const;
    Buffer<gpu::Reservoir>& current() { return m_current; }

private:
    /// reservoirs() to be resampled from `prev` (their domain theta_prev) with the pass's seed
    /// `seed`, for the elements `grad` differentiates.
    PathReservoirs pending(const Buffer<float>& theta_prev, const Buffer<gpu::Reservoir>& prev,
                           const GradientBuffers& grad, std::uint32_t seed) const;

    View m_view;
    ReservoirPasses m_passes; ///< what the passes read, filled by the render layer
    RestirChain m_chain;
    std::string m_state_buffer;
    Buffer<gpu::Reservoir> m_current;
};

} // namespace tandem
