// Large Steps in `tandem optimize`: a job's `"large_steps": lambda` on a mesh's vertex positions
// optimizes its differential coordinates u = (I + lambda L) x (core/inverse/large_steps.h) with an
// optimizer of its own, and the rendered positions are x = (I + lambda L)^-1 u after each step, as
// Mitsuba's largesteps module and "Large Steps in Inverse Rendering of Geometry" (Nicolet et al.
// 2021, Sec. 5) do. On a bitmap texture, L is the texel grid's Laplacian and x is clamped to the
// parameter's range after the solve (the range bounds x, not u), as for the texture experiments of
// "Recursive Control Variates for Inverse Rendering" (Nicolet et al. 2023, Sec. 6). The values stay
// in the parameter buffer, so the scene, its gradients and checkpoints see them as always; u and
// its moments are named buffers of the state ("large_steps.NAME.u", ".m", ".v"), so that a resume
// continues bit for bit.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/inverse/large_steps.h"
#include "core/inverse/optimize_config.h"
#include "core/inverse/optimizer.h"
#include "core/inverse/param_state.h"
#include "core/scene/render_scene.h"

namespace tandem {

class LargeStepParams {
public:
    /// The Large Steps of `config`'s parameters that ask for them, over `state` (which must
    /// outlive it). Throws Error naming the config for one on a parameter that is neither a
    /// mesh's vertex positions nor a bitmap texture.
    LargeStepParams(ParamState& state, const KernelLibrary& lib, const OptimizeConfig& config,
                    const RenderScene& scene, const OptimizerConfig& optimizer);
    ~LargeStepParams();
    LargeStepParams(const LargeStepParams&) = delete;
    LargeStepParams& operator=(const LargeStepParams&) = delete;

    bool empty() const { return m_entries.empty(); }
    /// A fresh run's start: u = (I + lambda L) x of each parameter's start values in `values`,
    /// which become (I + lambda L)^-1 u (a mesh's copies of a point agree). Uploads u.
    void start(std::vector<float>& values);
    /// The learning rates of the state's own optimizer: `lr` with those of these parameters set
    /// to 0.
    std::vector<float> rates(std::vector<float> lr) const;
    /// After iteration `it` (0-based; the gradient is the state's): each parameter's u takes step
    /// it + 1 of its optimizer with (I + lambda L)^-1 of its gradient, and theta's values become
    /// (I + lambda L)^-1 u, clamped to the parameter's range; a texel held at a bound takes no
    /// gradient pulling it further out (a projected gradient). Blocks (the solves run on the host).
    void step(int it);
    /// A line for the log per parameter, naming it and its lambda, or "".
    std::string plan() const;

private:
    struct Entry;
    ParamState& m_state;
    OptimizerUpdate m_update;
    std::vector<std::unique_ptr<Entry>> m_entries;
};

} // namespace tandem
