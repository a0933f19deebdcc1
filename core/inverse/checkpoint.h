// Checkpoints of `tandem optimize`: everything needed to resume bit-identically. The parameter
// state saves itself generically (core/inverse/param_state.h); this adds the run's progress
// and metrics, under a fingerprint of the setup, written atomically.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/inverse/metrics.h"
#include "core/inverse/optimize_config.h"
#include "core/inverse/param_state.h"
#include "core/scene/render_scene.h"

namespace tandem {

/// FNV-1a over what a checkpoint must agree on to be resumed: the scene file and its defines, the
/// target, the scene's parameter layout, the film, and the settings that shape the trajectory.
std::uint64_t run_fingerprint(const RenderScene& scene, const OptimizeConfig& config);

struct CheckpointProgress {
    int iterations_done = 0;
    double seconds = 0.0; ///< optimization seconds so far
    std::vector<MetricsRow> rows;
    std::uint64_t guards = 0; ///< samples, gradient contributions and sums dropped so far (guards)
};

/// Writes `state` and `progress` to `path` (through a temporary and a rename). Blocks for the
/// downloads.
void save_checkpoint(const std::string& path, std::uint64_t fingerprint, const ParamState& state,
                     const CheckpointProgress& progress);

/// Restores `state` (with the same named buffers registered) from `path` and returns the
/// progress. Throws Error naming the file when it is missing, not a checkpoint, from another
/// setup (fingerprint) or truncated.
CheckpointProgress load_checkpoint(const std::string& path, std::uint64_t fingerprint,
                                   ParamState& state);

} // namespace tandem
