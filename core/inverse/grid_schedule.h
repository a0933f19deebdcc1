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
// becomes P u_j again. After iteration i_{j+1}, u_{j+1} = the resampling of u_j, with fresh moments;
// after i_k the state's own optimizer steps the full grid (its moments, which saw the full grid's
// gradients all along, carry over). What the levels change is the number of free values, the
// point of the schedule; the rendering cost is the full grid's throughout.
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
    /// ("upsample.NAME.u", ".m", ".v"), sized for its finest coarse level, so that checkpoints
    /// hold them at one size whatever the level. Throws Error naming the config for a schedule on
    /// a parameter that is not a grid.
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
    /// The learning rates of the state's own optimizer with `done` iterations done: `lr` with
    /// those of grids still at a coarse level set to 0 (their coarse optimizer steps them).
    /// Sets the coarse optimizers' own rates for that point too.
    std::vector<float> rates(std::vector<float> lr, int done);
    /// After the state's optimizer stepped iteration `it` (0-based; the gradient is the state's):
    /// each grid at a coarse level steps its coarse values and writes P u into theta; after an
    /// iteration its schedule lists, the next level begins. Enqueued. Returns whether a grid has
    /// just reached its full resolution (the state's learning rates then change: rates()).
    bool step(int it);
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
