// Host driver of the path-tracing megakernel (kernels/render.cl).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/render_scene.h"
#include "runtime/build_flags.h"
#include "runtime/kernel_source.h"
#include "runtime/launch.h"

namespace tandem {

/// How next-event estimation and BSDF sampling combine. Tests compare the three; renders use MIS.
/// bsdf_only cannot see point and spot lights (no direction reaches them), so the comparison
/// holds for scenes without them.
enum class LightStrategy { mis = 0, bsdf_only = 1, nee_only = 2 };

/// The scheduler's first job: the kernel features a scene needs. Every flag is always set:
///   BVH_WIDTH       2 or 4: the BVH layout (preferred_bvh_width of the device)
///   HAS_AREA_LIGHTS 1 if any shape emits: emission lookups and triangle light sampling
///   HAS_ENV_LIGHT   1 if there is an environment (constant or envmap)
///   HAS_ENVMAP      1 if the environment is an importance-sampled envmap
///   HAS_TEXTURES    1 if any texture exists: uv interpolation and texture lookups
///   HAS_DELTA_LIGHTS 1 if there are point or spot lights
///   BSDF_CONDUCTOR  1 if a conductor or roughconductor is used; likewise BSDF_DIELECTRIC
///                   (dielectric) and BSDF_PLASTIC (roughplastic). Diffuse is always compiled.
///   LIGHT_STRATEGY  0 MIS, 1 BSDF sampling only, 2 next-event estimation only
/// Programs are cached per flag set (the options are part of the binary cache key).
BuildFlags render_features(const RenderScene& scene, const DeviceInfo& device,
                           LightStrategy strategy = LightStrategy::mis, int bvh_width = 0);

struct RenderOptions {
    int spp = 0;             ///< samples per pixel; 0: the scene's sample_count
    std::uint32_t seed = 0;  ///< RNG seed; the same seed gives the same image bit for bit
    /// Called after each pass with (samples done, samples total), e.g. for a progress bar.
    std::function<void(int, int)> progress;
};

struct RenderResult {
    int width = 0, height = 0, spp = 0;
    std::vector<float> rgb;      ///< linear RGB, row-major from the top-left pixel
    double seconds = 0.0;        ///< wall time of the render passes
    double kernel_seconds = 0.0; ///< device time of the render passes
    std::uint64_t nan_guards = 0; ///< samples dropped because they were not finite
};

class Renderer {
public:
    /// Uploads the scene and builds the kernel with `features` (see render_features()).
    Renderer(Context& ctx, const KernelLibrary& lib, const RenderScene& scene,
             const BuildFlags& features);
    /// As above with render_features(scene, device).
    Renderer(Context& ctx, const KernelLibrary& lib, const RenderScene& scene);
    ~Renderer();

    RenderResult render(const RenderOptions& options);
    /// The feature flags this scene compiled with.
    const BuildFlags& features() const { return m_features; }

private:
    struct DeviceData;
    Context& m_ctx;
    const RenderScene& m_scene;
    BuildFlags m_features;
    std::unique_ptr<DeviceData> m_data;
};

} // namespace tandem
