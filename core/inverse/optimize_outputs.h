// The files of `tandem optimize` besides its metrics and checkpoints (core/inverse/optimize.h):
// the start values a config sets, the target image, and the final parameters.
#pragma once

#include <string>
#include <vector>

#include "core/inverse/gradient_step.h"
#include "core/inverse/optimize_config.h"
#include "core/inverse/session.h"

namespace tandem {

/// The start values and learning rates of `config` over the registry's layout (at least one
/// element each), and the optimized parameters. Throws Error naming the config for an unknown
/// parameter or a start value outside its range.
struct StartValues {
    std::vector<float> values, lr;
    std::vector<const Parameter*> optimized;
};
StartValues start_values(const OptimizeConfig& config, const ParamRegistry& registry);

/// The sensors `config` optimizes against ("views"), as indices into the session's sensors, in
/// the config's order. Throws Error naming the config for an unknown or repeated sensor.
std::vector<unsigned> view_sensors(const Session& session, const OptimizeConfig& config);

/// The targets of `sensors` (view_sensors) in `config`: each sensor's image, read (with its mask)
/// from target.images, or rendered from the target scene's sensor of the same index (at
/// target.spp, with the Stream::target seed of that sensor: view_seed); and into
/// `reference_values` the target's values of the optimized parameters when it is rendered from
/// a scene (nothing otherwise). A target scene that is the session's own (the same file and
/// defines) is rendered on the session's device scene with the scene's own parameter values: no
/// second BVH, no second compilation. Throws Error, one line naming the file, for images that
/// are not one per sensor, and for a target scene whose sensors' films differ from the scene's.
std::vector<ViewTarget> load_targets(Session& session, const OptimizeConfig& config,
                                     const std::vector<unsigned>& sensors,
                                     const std::vector<const Parameter*>& optimized,
                                     std::vector<float>* reference_values);

/// `prefix` and the iteration in four digits, ".exr".
std::string iteration_name(const char* prefix, int iteration);

/// Final parameters into `out`: values in params.json, textures as images.
void write_parameters(const std::string& out, const std::vector<const Parameter*>& optimized,
                      const std::vector<float>& values);

/// The meshes whose vertex positions are optimized, as `theta` holds them at iteration
/// `iteration` (1-based), into `out`/meshes/NAME_iter_NNNN.ply (binary PLY); nothing where no
/// vertex positions are optimized.
void write_meshes(const std::string& out, int iteration, const std::vector<const Parameter*>& optimized,
                  const RenderScene& scene, ParamState& theta);

/// What the run will do with ReSTIR, for the log (a line of `tandem optimize`'s notes).
std::string restir_note(const RestirConfig& r);
/// The lines of restir_note where the config has "restir", and of the boundary term's reuse
/// where it has restir.boundary.
std::string reuse_notes(const OptimizeConfig& c);

/// The log's line for what the moving meshes of `scene` became at iteration `it` (0-based;
/// DeviceScene::take_geometry_report): "" where there is nothing to report.
std::string geometry_note(DeviceScene& scene, int it);

/// "" where every value of `optimized` (concatenated in `values`, in their order) is finite, else
/// which is not: the parameter and its element, or for vertex positions its vertex.
std::string non_finite_note(const std::vector<const Parameter*>& optimized,
                            const std::vector<float>& values);

} // namespace tandem
