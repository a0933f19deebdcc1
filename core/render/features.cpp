// Scene features to kernel build flags.
#include "core/render/features.h"

#include <algorithm>
#include <string>

#include "runtime/error.h"

namespace tandem {

namespace {

/// ceil(log2(n)) for n >= 1: the halvings that take [0, n) down to one index.
int ceil_log2(unsigned n) {
    int steps = 0;
    while ((1u << steps) < n)
        ++steps;
    return steps;
}

/// The steps of the envmap sampler's two CDF searches (kernels/shared/envmap.h: envmap_find):
/// its rows of cells (height - 1) and its columns (width).
int envmap_search_steps(const gpu::EnvMap& env) {
    return std::max(ceil_log2(env.height - 1u), ceil_log2(env.width));
}

/// Whether the scene has analytic spheres or disks (BVH_ANALYTIC).
bool has_analytic_shapes(const RenderScene& scene) {
    return !scene.mesh.spheres.empty() || !scene.mesh.disks.empty();
}

} // namespace

BuildFlags content_features(const RenderScene& scene) {
    BuildFlags f;
    f.set("HAS_AREA_LIGHTS", scene.emissive.empty() ? 0 : 1);
    f.set("HAS_ENV_LIGHT", scene.has_env ? 1 : 0);
    f.set("HAS_ENVMAP", scene.has_envmap ? 1 : 0);
    f.set("ENVMAP_SEARCH_STEPS", scene.has_envmap ? envmap_search_steps(scene.envmap) : 0);
    f.set("HAS_TEXTURES", scene.textures.empty() ? 0 : 1);
    f.set("HAS_BITMAPS", std::any_of(scene.textures.begin(), scene.textures.end(),
                                     [](const gpu::TextureInfo& t) { return t.kind == TEXTURE_BITMAP; }));
    f.set("HAS_DELTA_LIGHTS", scene.delta_lights.empty() ? 0 : 1);
    f.set("BVH_ANALYTIC", has_analytic_shapes(scene) ? 1 : 0);
    bool conductor = false, dielectric = false, plastic = false;
    for (const gpu::Material& m : scene.materials) {
        conductor |= m.type == MATERIAL_CONDUCTOR || m.type == MATERIAL_ROUGHCONDUCTOR;
        dielectric |= m.type == MATERIAL_DIELECTRIC;
        plastic |= m.type == MATERIAL_ROUGHPLASTIC;
    }
    f.set("BSDF_CONDUCTOR", conductor);
    f.set("BSDF_DIELECTRIC", dielectric);
    f.set("BSDF_PLASTIC", plastic);
    const bool null_bsdf = std::any_of(scene.materials.begin(), scene.materials.end(),
                                       [](const gpu::Material& m) { return m.type == MATERIAL_NULL; });
    f.set("HAS_MEDIA", !scene.media.empty() || null_bsdf);
    f.set("HAS_SHADING_NORMALS",
          std::any_of(scene.mesh_shapes.begin(), scene.mesh_shapes.end(),
                      [](const MeshShape& s) { return s.smooth; }));
    f.set("SHAPE_GRAD", 0); // DeviceScene::enable_shape_gradients turns it on
    return f;
}

BuildFlags render_features(const RenderScene& scene, const DeviceInfo& device,
                           const Tuning& tuning, LightStrategy strategy, int bvh_width,
                           Workload work) {
    BuildFlags f = content_features(scene);
    f.set("LIGHT_STRATEGY", static_cast<int>(strategy));
    f.set("RESTIR", 0);
    f.set("DET_MATH", 1);
    std::size_t pixels = 0; // the largest film's: the policy serves every sensor alike
    for (const gpu::DeviceCamera& c : scene.cameras)
        pixels = std::max(pixels, std::size_t(c.width) * c.height);
    set_policy_flags(decide_policy(f, scene.mesh.triangle_count(), pixels, device, tuning, work,
                                   bvh_width),
                     f);
    return f;
}

BuildFlags render_features(const RenderScene& scene, const Context& ctx, LightStrategy strategy,
                           int bvh_width) {
    return render_features(scene, ctx.device(), ctx.tuning(), strategy, bvh_width);
}

BuildFlags render_features(const RenderScene& scene, const DeviceInfo& device,
                           LightStrategy strategy, int bvh_width) {
    return render_features(scene, device, Tuning{}, strategy, bvh_width);
}

BuildFlags forward_render_features(const RenderScene& scene, const DeviceInfo& device,
                                   const Tuning& tuning) {
    return render_features(scene, device, tuning, LightStrategy::mis, 0, Workload::forward);
}

BuildFlags forward_render_features(const RenderScene& scene, const Context& ctx) {
    return forward_render_features(scene, ctx.device(), ctx.tuning());
}

void check_features(const RenderScene& scene, const BuildFlags& features) {
    const BuildFlags content = content_features(scene);
    for (const auto& [name, needed] : content.flags()) {
        const int given = features.get(name);
        const bool exact = name == "HAS_ENVMAP" || name == "ENVMAP_SEARCH_STEPS";
        if (exact ? given != needed : (needed && given != 1))
            throw Error("render features: the scene needs " + name + "=" + std::to_string(needed) +
                        " (given " + std::to_string(given) + ")");
    }
    for (const gpu::EmissiveTriangle& e : scene.emissive)
        if (e.radiance_param == NO_PARAM || e.radiance_param + 3 > scene.params.size())
            throw Error("render features: an emissive triangle has no radiance parameter");
}

} // namespace tandem
