// The JSON config of `tandem optimize`: what to optimize, against what, and how.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "core/render/boundary_reuse.h"
#include "core/render/passes.h"
#include "core/render/reservoirs.h"

namespace tandem {

/// One optimized parameter: its name (see `tandem params`), learning rate, and optionally a
/// starting value that replaces the scene's for every element (e.g. a flat grey texture).
struct OptimizedParam {
    std::string name;
    float lr = 0.01f;
    std::vector<float> init; ///< empty: the scene's value; 1 value: every element; 3: rgb per texel
    /// A grid's resolution schedule ("upsample": the iterations after which its resolution
    /// doubles, increasing; core/inverse/grid_schedule.h). Empty: optimized at full resolution.
    std::vector<int> upsample;
    /// Large Steps for a mesh's vertex positions or a bitmap texture ("large_steps": lambda > 0;
    /// 0: off): the optimizer steps u = (I + lambda L) x (core/inverse/large_step_params.h).
    double large_steps = 0.0;
};

/// The JSON config of `tandem optimize` (docs: README, "Command line": `tandem optimize`). Relative
/// paths are relative to the config file.
struct OptimizeConfig {
    std::string path; ///< the config file itself
    std::string scene;
    std::vector<std::pair<std::string, std::string>> defines;
    // target: images, one per sensor in order (photographs: EXR linear, PNG/JPEG sRGB), each with
    // an optional mask; or a reference scene whose sensors are rendered at target_spp
    std::vector<std::string> target_images, target_masks;
    std::string target_scene;
    std::vector<std::pair<std::string, std::string>> target_defines;
    int target_spp = 256;
    std::vector<OptimizedParam> params;
    std::string optimizer = "adam";
    float beta1 = 0.9f, beta2 = 0.999f, epsilon = 1e-8f;
    int iterations = 100, spp = 4, spp_grad = 4;
    /// shape gradients' boundary samples per pixel ("spp_primary", "spp_secondary"; default
    /// spp_grad) and the secondary term's guide ("secondary_guide": auto, on, off)
    BoundarySamples boundary;
    std::string loss = "l1";
    std::uint32_t seed = 0;
    int checkpoint_every = 10; ///< K: checkpoint, image and image_error every K iterations
    int image_error_spp = 64;  ///< spp of the re-render that image_error measures
    std::string cv =
        "ps"; ///< recursive control variate: "none", "pss" or "ps" (core/render/schedule.h)
    /// the control weight's variance estimate: "consistent" or "reference"
    /// (core/inverse/control_variate.h)
    std::string cv_variance = "consistent";
    /// Light-sample reuse in the adjoint and/or the primal (ReSTIR, core/inverse/restir.h): the
    /// "restir" object, absent (or "adjoint" and "primal" both false) for none.
    std::optional<RestirConfig> restir;
    /// The secondary boundary term's reuse of light vertices (restir.boundary: true or an object
    /// of its settings; core/render/boundary_reuse.h), absent for none.
    std::optional<SecondaryReuseConfig> boundary_reuse;
    /// The sensors optimized against ("views": indices or ids, in the config's order; empty:
    /// "all", every sensor in file order).
    std::vector<std::string> views;
    /// Views rendered per iteration ("batch"; 0: all of them): each iteration takes the next
    /// `batch` views of shuffled epochs (core/inverse/view_schedule.h).
    int batch = 0;
};

/// Reads and validates `path`. Throws Error "PATH: ..." on malformed JSON (with the position),
/// unknown keys, wrong types and out-of-range values.
OptimizeConfig load_optimize_config(const std::string& path);

/// The secondary boundary term's reuse as a config gives it (optimize's "restir": {"boundary":
/// ...}, the Python module's Scene.set_boundary_reuse): true (the defaults), false (none), or an
/// object of SecondaryReuseConfig's fields. Throws Error "WHERE: ..." naming a bad field.
std::optional<SecondaryReuseConfig> secondary_reuse_config(const std::string& where,
                                                           const nlohmann::json& value);

} // namespace tandem
