// Host driver of the path-tracing megakernel (kernels/render.cl).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/render_scene.h"
#include "runtime/kernel_source.h"
#include "runtime/launch.h"

namespace tandem {

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
    /// Uploads the scene and builds the kernel for it. bvh_width 0: the device's preferred.
    Renderer(Context& ctx, const KernelLibrary& lib, const RenderScene& scene, int bvh_width = 0);
    ~Renderer();

    RenderResult render(const RenderOptions& options);
    /// The kernel build options (feature flags) this scene compiled with.
    const std::string& build_options() const { return m_options; }

private:
    struct DeviceData;
    Context& m_ctx;
    const RenderScene& m_scene;
    std::string m_options;
    std::unique_ptr<DeviceData> m_data;
};

} // namespace tandem
