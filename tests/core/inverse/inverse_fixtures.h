// Helpers of the gradient and control-variate tests: what one gradient evaluation needs.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/inverse/gradient_step.h"

namespace tandem::test {

/// Running mean and standard error of independent estimates.
struct Stat {
    double sum = 0, sum2 = 0;
    int n = 0;
    void add(double x) { sum += x, sum2 += x * x, ++n; }
    double mean() const { return sum / n; }
    double se() const { return std::sqrt(std::max(0.0, sum2 / n - mean() * mean()) / (n - 1)); }
};

/// A device scene, its parameter state (theta = the scene's values) and a gradient step.
struct Inverse {
    Inverse(Context& ctx, const RenderScene& scene, unsigned loss = LOSS_MEAN,
            const std::vector<float>& reference = {}, CvMode cv = CvMode::none)
        : device(ctx, KernelLibrary::from_environment(), scene), state(ctx, scene.params),
          step(device, KernelLibrary::from_environment(), loss, reference, cv) {
        step.attach(state);
    }
    /// The PRB gradient at theta of iteration 0 with these seeds; guards() counts what it dropped.
    std::vector<float> gradient(std::uint32_t seed_primal, int spp, std::uint32_t seed_adjoint,
                                int spp_grad) {
        device.reset_guards();
        step.evaluate(state, 0, seed_primal, spp, seed_adjoint, spp_grad);
        return state.gradient().value.download();
    }
    std::uint64_t guards() { return device.read_guards(); }

    DeviceScene device;
    ParamState state;
    GradientStep step;
};

} // namespace tandem::test
