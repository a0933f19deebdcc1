// Helpers shared by the closed-form render tests (test_textures.cpp, test_lights.cpp).
#pragma once

#include <algorithm>
#include <cmath>

#include "core/render/passes.h"
#include "core/scene/scene.h"

namespace tandem::test {

/// A camera 3 above the plane z = 0 looking down, framing [-1,1]^2 exactly: film position
/// (fx, fy) sees the world point (-1 + 2 fx, 1 - 2 fy, 0).
inline Camera top_down_camera(int res) {
    Camera c;
    c.to_world = look_at({0, 0, 3}, {0, 0, 0}, {0, 1, 0});
    c.fov = 2.0f * std::atan(1.0f / 3.0f) * 180.0f / 3.14159265f;
    c.width = c.height = res;
    return c;
}

/// Renders an already flattened scene with the device's default features, at `spp`, seed 0.
inline RenderResult render_flat(Context& ctx, const RenderScene& scene, int spp) {
    DeviceScene device(ctx, KernelLibrary::from_environment(), scene);
    RenderOptions opt;
    opt.spp = spp;
    return render_image(device, parameter_buffer(ctx, scene.params), opt);
}

/// Flattens and renders `desc` (see render_flat).
inline RenderResult render_desc(Context& ctx, const SceneDesc& desc, int spp) {
    return render_flat(ctx, build_render_scene(desc), spp);
}

/// Mean, standard error and RMS of rendered-minus-expected differences over pixels.
struct DiffStats {
    double sum = 0, sum2 = 0;
    std::size_t n = 0;
    void add(double diff) {
        sum += diff;
        sum2 += diff * diff;
        ++n;
    }
    double mean() const { return sum / double(n); }
    double std_error() const {
        return std::sqrt(std::max(0.0, sum2 / double(n) - mean() * mean()) / double(n));
    }
    double rms() const { return std::sqrt(sum2 / double(n)); }
};

} // namespace tandem::test
