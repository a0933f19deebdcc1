// Large Steps in `tandem optimize`: a job's `"large_steps": lambda` on a mesh's vertex positions
// optimizes its differential coordinates u = (I + lambda L) x (core/inverse/large_steps.h) with an
// optimizer of its own, and the rendered positions are x = (I + lambda L)^-1 u after each step, as
// Mitsuba's largesteps module and "Large Steps in Inverse Rendering of Geometry" (Nicolet et al.
// 2021, Sec. 5) do. The positions stay in the parameter buffer, so the scene, its gradients and
// checkpoints see the mesh as always; u and its moments are named buffers of the state
// ("large_steps.NAME.u", ".m", ".v"), so that a resume continues bit for bit.
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

class ShapeSteps {
public:
    /// The Large Steps of `config`'s parameters that ask for them, over `state` (which must
    /// outlive it). Throws Error naming the config for one on a parameter that is not a mesh's
    /// vertex positions.
    ShapeSteps(ParamState& state, const KernelLibrary& lib, const OptimizeConfig& config,
               const RenderScene& scene, const OptimizerConfig& optimizer);
    ~ShapeSteps();
    ShapeSteps(const ShapeSteps&) = delete;
    ShapeSteps& operator=(const ShapeSteps&) = delete;

    bool empty() const { return m_shapes.empty(); }
    /// A fresh run's start: u = (I + lambda L) x of each mesh's start positions in `values`,
    /// which become (I + lambda L)^-1 u (its copies of a point agree). Uploads u.
    void start(std::vector<float>& values);
    /// The learning rates of the state's own optimizer: `lr` with those of these meshes set to 0.
    std::vector<float> rates(std::vector<float> lr) const;
    /// After iteration `it` (0-based; the gradient is the state's): each mesh's u takes step
    /// it + 1 of its optimizer with (I + lambda L)^-1 of the positions' gradient, and theta's
    /// positions become (I + lambda L)^-1 u. Blocks (the solves run on the host).
    void step(int it);
    /// A line for the log naming the meshes and their lambda, or "".
    std::string plan() const;

private:
    struct Shape;
    ParamState& m_state;
    OptimizerUpdate m_update;
    std::vector<std::unique_ptr<Shape>> m_shapes;
};

} // namespace tandem
