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

    /// Renders with the parameter buffer parameters() and downloads the image.
    RenderResult render(const RenderOptions& options);

    /// The flat parameter buffer the kernels read (core/params.h), initialised from the scene.
    /// Optimizers update it in place.
    Buffer<float>& parameters() { return m_params; }

    /// Renders spp samples per pixel with `seed` into `rgb` (3 floats per pixel, the mean of the
    /// samples) on the device, reading `params` (the layout of parameters()). Returns the samples
    /// dropped as non-finite. Blocks until done.
    std::uint64_t render_image(const Buffer<float>& params, std::uint32_t seed, int spp,
                               Buffer<float>& rgb);

    /// The fused two-state render (CV-PS, kernels/render.cl: render_two_state): spp paths per pixel
    /// sampled from `params` (theta_n) with `seed`, each also estimating `params_old`
    /// (theta_{n-1}); writes <F_n>_n to rgb and <F_{n-1}>_n to rgb_old. Returns the dropped
    /// samples. Blocks until done.
    std::uint64_t render_two_state(const Buffer<float>& params, const Buffer<float>& params_old,
                                   std::uint32_t seed, int spp, Buffer<float>& rgb,
                                   Buffer<float>& rgb_old);

    /// Path Replay Backpropagation: given delta = dloss/d(image) (3 floats per pixel) for an image
    /// of spp samples per pixel rendered with `seed`, writes dloss/d(params) to `grad` (the layout
    /// of parameters()). Use a seed independent of the image's that fed the loss (papers/000, eq.
    /// 13). Deterministic bit for bit. Returns the non-finite samples skipped plus the gradient
    /// contributions that saturated the fixed-point range (shared/fixed_point.h); 0 normally.
    std::uint64_t backward(const Buffer<float>& params, std::uint32_t seed, int spp,
                           const Buffer<float>& delta, Buffer<float>& grad);

    /// Builds the adjoint program now (else the first backward() does), e.g. before timing.
    void prepare_backward();

    /// Device seconds of the last render_image and backward calls.
    double last_render_seconds() const { return m_last_render_seconds; }
    double last_backward_seconds() const { return m_last_backward_seconds; }
    const RenderScene& scene() const { return m_scene; }
    /// The feature flags this scene compiled with.
    const BuildFlags& features() const { return m_features; }

private:
    struct DeviceData;
    Context& m_ctx;
    const KernelLibrary* m_lib = nullptr;
    const RenderScene& m_scene;
    BuildFlags m_features;
    std::unique_ptr<DeviceData> m_data;
    Buffer<float> m_params;
    double m_last_render_seconds = 0.0, m_last_backward_seconds = 0.0;

    gpu::RenderParams launch_params(std::uint32_t seed) const;
    /// Accumulates samples [begin, begin + count) into the scratch accumulator and guards.
    void render_samples(const Buffer<float>& params, gpu::RenderParams rp, int begin, int count);
};

} // namespace tandem
