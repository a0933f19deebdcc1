// Helpers shared by the closed-form render tests (test_textures.cpp, test_lights.cpp).
#pragma once

#include <algorithm>
#include <cmath>

#include <glm/gtc/matrix_transform.hpp>

#include "core/render/features.h"
#include "core/render/passes.h"
#include "core/scene/scene.h"
#include "support.h"

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

/// render_flat in the megakernels and in the wavefront (WAVEFRONT 0 and 1, the rest of the
/// device's default features), checking that both give the same image bits; returns it.
inline RenderResult render_flat_both_forms(Context& ctx, const RenderScene& scene, int spp) {
    BuildFlags features = render_features(scene, ctx.device());
    RenderResult out[2];
    for (int wavefront : {0, 1}) {
        features.set("WAVEFRONT", wavefront);
        DeviceScene device(ctx, KernelLibrary::from_environment(), scene, features);
        RenderOptions opt;
        opt.spp = spp;
        out[wavefront] = render_image(device, parameter_buffer(ctx, scene.params), opt);
    }
    CHECK(same_bytes(out[0].rgb, out[1].rgb));
    return out[1];
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

/// The stress scene ("stress: extreme roughness, radiance and degenerate triangles", and the
/// gradient kernels' stress test) at res x res: GGX alpha and emitter radiance as given.
inline SceneDesc stress_scene(float alpha, float radiance, int res) {
    SceneDesc d;
    d.path = "stress";
    d.camera().to_world = look_at({0, 0.05f, 4}, {0, 0, 0}, {0, 1, 0}); // grazing floor
    d.camera().fov = 50.0f;
    d.camera().width = d.camera().height = res;
    Bsdf metal;
    metal.type = BsdfType::roughconductor;
    metal.alpha = alpha;
    metal.eta = glm::vec3(0.2f, 0.9f, 1.1f);
    metal.k = glm::vec3(3.9f, 2.4f, 2.2f);
    d.bsdfs.push_back(metal);
    Bsdf plastic;
    plastic.type = BsdfType::roughplastic;
    plastic.alpha = alpha;
    plastic.reflectance.value = glm::vec3(0.5f);
    plastic.int_ior = 1.49f;
    d.bsdfs.push_back(plastic);
    Bsdf glass;
    glass.type = BsdfType::dielectric;
    d.bsdfs.push_back(glass);
    Emitter e;
    e.type = EmitterType::area;
    e.radiance = glm::vec3(radiance);
    d.emitters.push_back(e);
    Emitter env;
    env.type = EmitterType::constant;
    env.radiance = glm::vec3(radiance);
    d.emitters.push_back(env);
    Shape mesh;
    mesh.type = ShapeType::obj;
    mesh.filename = test::mesh_path("degenerate.obj");
    mesh.bsdf = 0;
    d.shapes.push_back(mesh);
    Shape floor;
    floor.type = ShapeType::rectangle;
    floor.to_world = look_at({0, -0.3f, 0}, {0, 1, 0}, {0, 0, 1}) * glm::scale(glm::mat4(1.0f), glm::vec3(5.0f));
    floor.bsdf = 1;
    d.shapes.push_back(floor);
    Shape ball;
    ball.type = ShapeType::sphere;
    ball.center = glm::vec3(0.6f, 0.3f, 0.8f);
    ball.radius = 0.3f;
    ball.bsdf = 2;
    d.shapes.push_back(ball);
    Shape lamp;
    lamp.type = ShapeType::disk;
    lamp.to_world = look_at({0, 2, 1}, {0, 0, 0}, {0, 0, 1}) * glm::scale(glm::mat4(1.0f), glm::vec3(0.3f));
    lamp.emitter = 0;
    d.shapes.push_back(lamp);
    return d;
}

} // namespace tandem::test
