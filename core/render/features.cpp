// Scene features to kernel build flags.
#include "core/render/features.h"

#include <algorithm>
#include <cstdlib>
#include <string>

#include "core/bvh/tracer.h"
#include "core/render/wavefront.h"
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

/// The steps of the envmap sampler's two CDF searches (kernels/path/wavefront_lookup.h: wf_envmap_find):
/// its rows of cells (height - 1) and its columns (width).
int envmap_search_steps(const gpu::EnvMap& env) {
    return std::max(ceil_log2(env.height - 1u), ceil_log2(env.width));
}

/// The flags that only say what the scene contains (not how to render it).
/// Whether the scene has analytic spheres or disks (BVH_ANALYTIC).
bool has_analytic_shapes(const RenderScene& scene) {
    return !scene.mesh.spheres.empty() || !scene.mesh.disks.empty();
}

BuildFlags content_flags(const RenderScene& scene) {
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
    return f;
}

/// $TANDEM_BVH_WIDTH (2, 4 or 8: a BVH layout to force, for measurements and tests), or 0.
int bvh_width_from_environment() {
    const char* value = std::getenv("TANDEM_BVH_WIDTH");
    if (!value) return 0;
    const std::string text(value);
    if (text != "2" && text != "4" && text != "8")
        throw Error("TANDEM_BVH_WIDTH='" + text + "': expected the BVH width 2, 4 or 8");
    return std::stoi(text);
}

/// The leaf format of a four- or eight-wide tree: $TANDEM_BVH_LEAVES (records or tri4: a format
/// to force, for measurements) if set, else the device's preferred one.
LeafFormat leaf_format(const DeviceInfo& device, std::size_t triangles, int width) {
    const char* value = std::getenv("TANDEM_BVH_LEAVES");
    if (!value) return preferred_leaf_format(device, triangles, width);
    const std::string text(value);
    if (text == "records") return LeafFormat::records;
    if (text == "tri4") return LeafFormat::tri4;
    throw Error("TANDEM_BVH_LEAVES='" + text + "': expected the BVH leaf format records or tri4");
}

} // namespace

BuildFlags render_features(const RenderScene& scene, const DeviceInfo& device,
                           LightStrategy strategy, int bvh_width) {
    BuildFlags f = content_flags(scene);
    if (!bvh_width) bvh_width = bvh_width_from_environment();
    f.set("BVH_WIDTH", bvh_width ? bvh_width : preferred_bvh_width(device));
    f.set("BVH_AXIS_LOOPS", bvh_axis_loops(device));
    // the leaf format is read (and a bad $TANDEM_BVH_LEAVES reported) whatever the tree
    const LeafFormat leaves = leaf_format(device, scene.mesh.triangle_count(), f.get("BVH_WIDTH"));
    f.set("BVH_TRI4", f.get("BVH_WIDTH") != 2 && f.get("BVH_ANALYTIC") == 0 &&
                          leaves == LeafFormat::tri4);
    f.set("BVH_PREFETCH", bvh_prefetch(device, scene.mesh.triangle_count(), f.get("BVH_WIDTH")));
    f.set("CAMERA_PACKETS", camera_packets(device, f.get("BVH_WIDTH"), f.get("BVH_TRI4")));
    f.set("LIGHT_STRATEGY", static_cast<int>(strategy));
    f.set("RESTIR", 0);
    f.set("DET_MATH", 1);
    f.set("SHADOW_RECORD", switch_from_environment("TANDEM_SHADOW_RECORD") != 0);
    // the wavefront renderer where PoCL's vectoriser widens its shading (wavefront.h)
    const int force = switch_from_environment("TANDEM_WAVEFRONT");
    const bool want = force >= 0 ? force == 1 : wavefront_faster(f, device);
    f.set("WAVEFRONT", want && wavefront_supported(f));
    return f;
}

BuildFlags forward_render_features(const RenderScene& scene, const DeviceInfo& device) {
    const int width = bvh_width_from_environment();
    return render_features(scene, device, LightStrategy::mis,
                           width ? width : forward_bvh_width(device, has_analytic_shapes(scene)));
}

unsigned count_from_environment(const char* name, unsigned fallback, unsigned max,
                                const char* what) {
    const char* value = std::getenv(name);
    if (!value) return fallback;
    const std::string text(value);
    if (text.empty() || text.size() > 9 ||
        text.find_first_not_of("0123456789") != std::string::npos || std::stoul(text) > max)
        throw Error(std::string(name) + "='" + text + "': expected " + what + " (0 to " +
                    std::to_string(max) + ")");
    return static_cast<unsigned>(std::stoul(text));
}

void check_features(const RenderScene& scene, const BuildFlags& features) {
    const BuildFlags content = content_flags(scene);
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
