// The resolution schedule of grid parameters: a job's `"upsample": [i_1, ..., i_k]` on a volume
// parameter optimizes it coarse to fine, its resolution doubling after each listed iteration, as
// the volume experiments of "Recursive Control Variates for Inverse Rendering" (§6) and Mitsuba's
// volume tutorials do (trilinear upsampling).
//
// The grid keeps its full resolution in the parameter buffer, so that the scene, its kernels and
// every buffer that mirrors the layout (gradients, moments, checkpoints) stay as they are. Level j
// < k is a coarse grid u_j of free values, ceil(N / 2^(k - j)) voxels per axis of the grid's N,
// and the rendered grid is its trilinear resampling theta = P u_j (kernels/shared/medium.h:
// grid_resample_at, voxel centres aligned, clamped at the faces as lookups are). Each iteration
// the coarse grid takes an optimizer step of its own with the gradient P^T (dL/dtheta), and theta
// becomes P u_j again. After iteration i_{j+1}, u_{j+1} = the resampling of u_j; after i_k the
// full grid itself. Each level starts its optimizer afresh (zero moments, bias corrections from
// its own first step), as Mitsuba's optimizers do for a parameter whose size changes: moments
// carried over from another level, or a step count that did not start with them, would make the
// first steps of Adam several times the learning rate. The schedule steps its grids at every
// level, the state's optimizer never does. What the levels change is the number of free values,
// the point of the schedule; the rendering cost is the full grid's throughout.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/inverse/optimize_config.h"
#include "core/inverse/optimizer.h"
#include "core/inverse/param_state.h"
#include "core/scene/params.h"

namespace tandem {

class GridSchedule {
public:
    /// The schedules of `config`'s parameters that have one ("upsample"), over `state` (which must
    /// outlive it): each grid's coarse values and moments become named buffers of the state
    /// ("upsample.NAME.u", ".m", ".v", sized for its finest coarse level), and so do the moments
    /// of its full level (".m_full", ".v_full", in the state's layout), so that checkpoints hold
    /// them at one size whatever the level. Throws Error naming the config for a schedule on a
    /// parameter that is not a grid.
    GridSchedule(ParamState& state, const KernelLibrary& lib, const OptimizeConfig& config,
                 const ParamRegistry& registry, const OptimizerConfig& optimizer);
    ~GridSchedule();
    GridSchedule(const GridSchedule&) = delete;
    GridSchedule& operator=(const GridSchedule&) = delete;

    bool empty() const { return m_grids.empty(); }

    /// A fresh run's start: each scheduled grid of `values` (the start values, in the layout of
    /// the registry) is sampled at its first level's voxel centres into its coarse values, and
    /// replaced by their resampling P u_0 (the state that renders first). Uploads u_0.
    void start(std::vector<float>& values);
    /// The learning rates of the state's own optimizer: `lr` with those of the scheduled grids set
    /// to 0 (the schedule steps them).
    std::vector<float> rates(std::vector<float> lr) const;
    /// After the state's optimizer stepped iteration `it` (0-based; the gradient is the state's):
    /// each grid takes its level's step (a coarse level's: on u, then theta = P u; the full
    /// level's: on theta), and after an iteration its schedule lists the next level begins.
    /// Enqueued.
    void step(int it);
    /// Messages for the log: the levels, and after step() the level changes it made.
    std::string plan() const;
    std::string changes(int it) const;

private:
    struct Grid;
    int level(const Grid& g, int done) const;
    void resample(const Buffer<float>& src, std::size_t src_offset, const int* src_dims,
                  Buffer<float>& dst, std::size_t dst_offset, const int* dst_dims, int channels);
    ParamState& m_state;
    Context& m_ctx;
    Program m_program;
    Kernel m_resample, m_adjoint;
    OptimizerUpdate m_update;
    std::vector<std::unique_ptr<Grid>> m_grids;
};

} // namespace tandem
