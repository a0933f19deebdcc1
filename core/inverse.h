// One step of inverse rendering: primal render -> image loss and its adjoint -> PRB gradient, all
// on the device (papers/000 eq. 12-13: the primal image that feeds the loss and the adjoint pass
// use independent seeds, so the product of their estimates is unbiased).
#pragma once

#include <cstdint>
#include <vector>

#include "core/optimize_kernels.h"
#include "core/renderer.h"

namespace tandem {

/// The seeds of iteration `iteration` of a run seeded with `seed`: distinct, decorrelated
/// streams for the primal render and the adjoint pass (a hash of (seed, iteration, stream)).
std::uint32_t primal_seed(std::uint32_t seed, std::uint32_t iteration);
std::uint32_t adjoint_seed(std::uint32_t seed, std::uint32_t iteration);

struct StepTimes {
    double primal = 0.0, loss = 0.0, adjoint = 0.0; ///< device seconds
};

class GradientStep {
public:
    /// `reference`: the target image (rgb, the scene's film size); empty for LOSS_MEAN. Throws
    /// Error when its size does not match the film.
    GradientStep(Context& ctx, const KernelLibrary& lib, Renderer& renderer, unsigned loss,
                 const std::vector<float>& reference);

    /// Renders `params` at (seed_primal, spp), evaluates the loss, and writes the PRB gradient
    /// (seed_adjoint, spp_grad) to gradient(). Returns the loss. Counts dropped samples and
    /// saturated gradient contributions in guards().
    float evaluate(const Buffer<float>& params, std::uint32_t seed_primal, int spp,
                   std::uint32_t seed_adjoint, int spp_grad);

    Buffer<float>& gradient() { return m_grad; }
    Buffer<float>& image() { return m_image; }
    Buffer<float>& delta() { return m_delta; }
    std::uint64_t guards() const { return m_guards; }
    const StepTimes& times() const { return m_times; }

private:
    Context& m_ctx;
    Renderer& m_renderer;
    unsigned m_loss;
    ImageLoss m_image_loss;
    Buffer<float> m_reference, m_image, m_delta, m_grad;
    std::uint64_t m_guards = 0;
    StepTimes m_times;
};

} // namespace tandem
