// Path tracer host driver: uploads the flattened scene and launches render passes.
#include "core/renderer.h"

#include <algorithm>
#include <chrono>

#include "core/embree_device.h"
#include "core/tracer.h"
#include "runtime/error.h"
#include "shared/scene_args.h"

namespace tandem {

struct Renderer::DeviceData {
    int width;
    Buffer<gpu::BvhNode> nodes2;
    Buffer<gpu::Bvh4Node> nodes4;
    Buffer<gpu::BvhTriangle> tris, prims;
    Buffer<gpu::TriangleInfo> infos;
    Buffer<gpu::TriangleUV> uvs;
    Buffer<gpu::TextureInfo> textures;
    Buffer<gpu::float4> texels;
    Buffer<gpu::Material> materials;
    Buffer<gpu::EmissiveTriangle> emissive;
    Buffer<gpu::DeltaLight> delta_lights;
    Buffer<gpu::float4> env_texels;
    Buffer<float> env_cdf;
    Buffer<gpu::AliasEntry> alias;
    Program program;
    Kernel render, render_two_state, resolve;
    // The adjoint program is built on first use, so plain renders do not compile it.
    std::unique_ptr<Program> adjoint_program;
    Kernel adjoint, decode;
    Buffer<unsigned> fixed_grad; ///< 2 words per parameter element (shared/fixed_point.h), kept zero
    // Per-pixel scratch, reused by every render and adjoint call (zero-filled on the device).
    Buffer<gpu::float4> accum, accum_old;
    Buffer<unsigned> guards;

    DeviceData(Context& ctx, const KernelLibrary& lib, const RenderScene& scene, const FlatBvh& bvh,
               const std::string& options);

    /// Launches `kernel` over n work items with the scene arguments, bound by name in the order of
    /// kernels/shared/scene_args.h (SCENE_ARGS), then the launch's RenderParams rp, then `extra`.
    template <class... Extra>
    void launch(Kernel& kernel, Context& ctx, const char* stage, std::size_t n,
                const RenderScene& scene, const gpu::RenderParams& rp, const Extra&... extra) {
        const cl::Buffer& nodes = width == 4 ? nodes4.cl() : nodes2.cl();
        const gpu::EnvMap& envmap = scene.envmap;
        const gpu::DeviceCamera& cam = scene.camera;
#define TANDEM_BIND_SCENE_ARG(T, name) name,
        kernel.launch(ctx, stage, n,
                      TANDEM_SCENE_ARGS(TANDEM_BIND_SCENE_ARG, TANDEM_BIND_SCENE_ARG) rp, extra...);
#undef TANDEM_BIND_SCENE_ARG
    }
    /// Zeroes the accumulators and guards for a new image.
    void clear() {
        accum.fill(gpu::float4{});
        accum_old.fill(gpu::float4{});
        guards.fill(0u);
    }
};

namespace {

template <class T> std::vector<T> at_least_one(std::vector<T> v) {
    if (v.empty()) v.resize(1); // OpenCL buffers cannot be empty; the kernel never reads it
    return v;
}

std::vector<gpu::BvhTriangle> primitive_order(const TriangleMesh& mesh) {
    std::vector<gpu::BvhTriangle> out(mesh.triangles.size());
    for (std::size_t i = 0; i < out.size(); ++i) {
        const glm::uvec3 t = mesh.triangles[i];
        const glm::vec3 &a = mesh.positions[t.x], &b = mesh.positions[t.y], &c = mesh.positions[t.z];
        out[i] = {gpu::make_float4(a.x, a.y, a.z, gpu::as_float(static_cast<unsigned>(i))),
                  gpu::make_float4(b.x, b.y, b.z, 0.0f), gpu::make_float4(c.x, c.y, c.z, 0.0f)};
    }
    return out;
}

} // namespace

Renderer::DeviceData::DeviceData(Context& ctx, const KernelLibrary& lib, const RenderScene& scene,
                                 const FlatBvh& bvh, const std::string& options)
    : width(bvh.width),
      nodes2(ctx, "bvh nodes", at_least_one(bvh.nodes), CL_MEM_READ_ONLY),
      nodes4(ctx, "bvh nodes", at_least_one(bvh.nodes4), CL_MEM_READ_ONLY),
      tris(ctx, "bvh triangles", bvh.triangles, CL_MEM_READ_ONLY),
      prims(ctx, "primitives", primitive_order(scene.mesh), CL_MEM_READ_ONLY),
      infos(ctx, "triangle infos", scene.infos, CL_MEM_READ_ONLY),
      uvs(ctx, "triangle uvs", scene.uvs, CL_MEM_READ_ONLY),
      textures(ctx, "textures", at_least_one(scene.textures), CL_MEM_READ_ONLY),
      texels(ctx, "texels", at_least_one(scene.texels), CL_MEM_READ_ONLY),
      materials(ctx, "materials", scene.materials, CL_MEM_READ_ONLY),
      emissive(ctx, "emissive triangles", at_least_one(scene.emissive), CL_MEM_READ_ONLY),
      delta_lights(ctx, "delta lights", at_least_one(scene.delta_lights), CL_MEM_READ_ONLY),
      env_texels(ctx, "envmap texels", at_least_one(scene.env_texels), CL_MEM_READ_ONLY),
      env_cdf(ctx, "envmap cdf", at_least_one(scene.env_cdf), CL_MEM_READ_ONLY),
      alias(ctx, "light alias table", at_least_one(scene.alias), CL_MEM_READ_ONLY),
      program(Program::build(ctx, lib, "render.cl", options)), render(program, "render_pass"),
      render_two_state(program, "render_two_state"), resolve(program, "resolve_image"),
      accum(ctx, "accumulator", std::size_t(scene.camera.width) * scene.camera.height),
      accum_old(ctx, "accumulator (old state)", std::size_t(scene.camera.width) * scene.camera.height),
      guards(ctx, "nan guards", std::size_t(scene.camera.width) * scene.camera.height) {}

BuildFlags render_features(const RenderScene& scene, const DeviceInfo& device,
                           LightStrategy strategy, int bvh_width) {
    BuildFlags f;
    f.set("BVH_WIDTH", bvh_width ? bvh_width : preferred_bvh_width(device));
    f.set("HAS_AREA_LIGHTS", scene.emissive.empty() ? 0 : 1);
    f.set("HAS_ENV_LIGHT", scene.has_env ? 1 : 0);
    f.set("HAS_ENVMAP", scene.has_envmap ? 1 : 0);
    f.set("HAS_TEXTURES", scene.textures.empty() ? 0 : 1);
    f.set("HAS_DELTA_LIGHTS", scene.delta_lights.empty() ? 0 : 1);
    bool conductor = false, dielectric = false, plastic = false;
    for (const gpu::Material& m : scene.materials) {
        conductor |= m.type == MATERIAL_CONDUCTOR || m.type == MATERIAL_ROUGHCONDUCTOR;
        dielectric |= m.type == MATERIAL_DIELECTRIC;
        plastic |= m.type == MATERIAL_ROUGHPLASTIC;
    }
    f.set("BSDF_CONDUCTOR", conductor);
    f.set("BSDF_DIELECTRIC", dielectric);
    f.set("BSDF_PLASTIC", plastic);
    f.set("LIGHT_STRATEGY", static_cast<int>(strategy));
    return f;
}

Renderer::Renderer(Context& ctx, const KernelLibrary& lib, const RenderScene& scene)
    : Renderer(ctx, lib, scene, render_features(scene, ctx.device())) {}

Renderer::Renderer(Context& ctx, const KernelLibrary& lib, const RenderScene& scene,
                   const BuildFlags& features)
    : m_ctx(ctx), m_scene(scene), m_features(features) {
    if (scene.has_envmap != (features.get("HAS_ENVMAP") == 1))
        throw Error("render features: HAS_ENVMAP must match whether the scene has an envmap");
    if (scene.has_env && !features.get("HAS_ENV_LIGHT"))
        throw Error("render features: the scene has an environment light but HAS_ENV_LIGHT=0");
    if (!scene.emissive.empty() && !features.get("HAS_AREA_LIGHTS"))
        throw Error("render features: the scene has area lights but HAS_AREA_LIGHTS=0");
    if (!scene.delta_lights.empty() && !features.get("HAS_DELTA_LIGHTS"))
        throw Error("render features: the scene has point or spot lights but HAS_DELTA_LIGHTS=0");
    for (const gpu::Material& m : scene.materials) {
        const char* flag = m.type == MATERIAL_CONDUCTOR || m.type == MATERIAL_ROUGHCONDUCTOR
                               ? "BSDF_CONDUCTOR"
                               : m.type == MATERIAL_DIELECTRIC ? "BSDF_DIELECTRIC"
                               : m.type == MATERIAL_ROUGHPLASTIC ? "BSDF_PLASTIC" : nullptr;
        if (flag && features.get(flag) != 1)
            throw Error(std::string("render features: the scene needs ") + flag + "=1");
    }
    if (!scene.textures.empty() && !features.get("HAS_TEXTURES"))
        throw Error("render features: the scene has textures but HAS_TEXTURES=0");
    for (const gpu::EmissiveTriangle& e : scene.emissive)
        if (e.radiance_param == NO_PARAM || e.radiance_param + 3 > scene.params.size())
            throw Error("renderer: an emissive triangle has no radiance parameter");
    EmbreeDevice embree;
    const FlatBvh bvh = build_bvh(embree, scene.mesh, features.get("BVH_WIDTH"));
    m_data = std::make_unique<DeviceData>(ctx, lib, scene, bvh, features.options());
    m_lib = &lib;
    m_params = Buffer<float>(ctx, "parameters", at_least_one(scene.params.values()));
}

Renderer::~Renderer() = default;

gpu::RenderParams Renderer::launch_params(std::uint32_t seed) const {
    gpu::RenderParams rp{};
    rp.env_param = m_scene.env_param;
    rp.seed = seed;
    rp.max_depth = m_scene.max_depth < 0 ? 0xFFFFFFFFu : static_cast<unsigned>(m_scene.max_depth);
    rp.rr_depth = static_cast<unsigned>(std::max(0, m_scene.rr_depth));
    rp.emissive_count = static_cast<unsigned>(m_scene.emissive.size());
    rp.delta_count = static_cast<unsigned>(m_scene.delta_lights.size());
    const bool other_lights = !m_scene.emissive.empty() || !m_scene.delta_lights.empty();
    rp.light_env_prob = !m_scene.has_env ? 0.0f : (other_lights ? 0.5f : 1.0f);
    return rp;
}

void Renderer::render_samples(const Buffer<float>& params, gpu::RenderParams rp, int begin,
                              int count) {
    DeviceData& d = *m_data;
    rp.sample_begin = static_cast<unsigned>(begin);
    rp.sample_count = static_cast<unsigned>(count);
    d.launch(d.render, m_ctx, "render", d.accum.size(), m_scene, rp, params, d.accum, d.guards);
}

namespace {

std::uint64_t sum_of(const std::vector<unsigned>& v) {
    std::uint64_t s = 0;
    for (unsigned x : v) s += x;
    return s;
}

} // namespace

RenderResult Renderer::render(const RenderOptions& opt) {
    const gpu::DeviceCamera& cam = m_scene.camera;
    const std::size_t pixels = std::size_t(cam.width) * cam.height;
    const int spp = opt.spp > 0 ? opt.spp : m_scene.spp;
    RenderResult out;
    out.width = static_cast<int>(cam.width);
    out.height = static_cast<int>(cam.height);
    out.spp = spp;

    DeviceData& d = *m_data;
    d.clear();
    const gpu::RenderParams rp = launch_params(opt.seed);

    // Passes of a few samples keep each launch short (progress, and no driver watchdog on GPUs).
    // Every pixel adds its samples in sample order whatever the split, so the image is the same.
    const int per_pass = std::max(1, std::min(spp, 4));
    const auto t0 = std::chrono::steady_clock::now();
    m_ctx.stage_times();
    for (int begin = 0; begin < spp; begin += per_pass) {
        const int count = std::min(per_pass, spp - begin);
        render_samples(m_params, rp, begin, count);
        if (opt.progress) {
            m_ctx.finish();
            opt.progress(begin + count, spp);
        }
    }
    const std::vector<gpu::float4> sums = d.accum.download();
    out.nan_guards = sum_of(d.guards.download());
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    out.kernel_seconds = stage_seconds(m_ctx.stage_times(), "render");

    out.rgb.resize(pixels * 3);
    for (std::size_t i = 0; i < pixels; ++i) {
        const float inv = sums[i].w > 0.0f ? 1.0f / sums[i].w : 0.0f;
        out.rgb[3 * i + 0] = sums[i].x * inv;
        out.rgb[3 * i + 1] = sums[i].y * inv;
        out.rgb[3 * i + 2] = sums[i].z * inv;
    }
    return out;
}

std::uint64_t Renderer::render_image(const Buffer<float>& params, std::uint32_t seed, int spp,
                                     Buffer<float>& rgb) {
    const std::size_t pixels = std::size_t(m_scene.camera.width) * m_scene.camera.height;
    if (rgb.size() != 3 * pixels) throw Error("render_image: the image buffer has the wrong size");
    if (params.size() != m_params.size())
        throw Error("render_image: the parameter buffer does not match the scene's layout");
    DeviceData& d = *m_data;
    m_ctx.stage_times();
    d.clear();
    render_samples(params, launch_params(seed), 0, std::max(1, spp));
    d.resolve.launch(m_ctx, "resolve", pixels, d.accum, rgb, static_cast<unsigned>(pixels));
    const std::uint64_t dropped = sum_of(d.guards.download());
    m_last_render_seconds = stage_seconds(m_ctx.stage_times(), "render");
    return dropped;
}

std::uint64_t Renderer::render_two_state(const Buffer<float>& params, const Buffer<float>& params_old,
                                         std::uint32_t seed, int spp, Buffer<float>& rgb,
                                         Buffer<float>& rgb_old) {
    DeviceData& d = *m_data;
    const std::size_t pixels = std::size_t(m_scene.camera.width) * m_scene.camera.height;
    if (rgb.size() != 3 * pixels || rgb_old.size() != 3 * pixels)
        throw Error("render_two_state: an image buffer has the wrong size");
    if (params.size() != m_params.size() || params_old.size() != m_params.size())
        throw Error("render_two_state: a parameter buffer does not match the scene's layout");
    gpu::RenderParams rp = launch_params(seed);
    rp.sample_begin = 0;
    rp.sample_count = static_cast<unsigned>(std::max(1, spp));
    m_ctx.stage_times();
    d.clear();
    d.launch(d.render_two_state, m_ctx, "render", pixels, m_scene, rp, params, params_old, d.accum,
             d.accum_old, d.guards);
    d.resolve.launch(m_ctx, "resolve", pixels, d.accum, rgb, static_cast<unsigned>(pixels));
    d.resolve.launch(m_ctx, "resolve", pixels, d.accum_old, rgb_old, static_cast<unsigned>(pixels));
    const std::uint64_t dropped = sum_of(d.guards.download());
    m_last_render_seconds = stage_seconds(m_ctx.stage_times(), "render");
    return dropped;
}

void Renderer::prepare_backward() {
    DeviceData& d = *m_data;
    if (d.adjoint_program) return;
    d.adjoint_program = std::make_unique<Program>(
        Program::build(m_ctx, *m_lib, "adjoint.cl", m_features.options()));
    d.adjoint = Kernel(*d.adjoint_program, "adjoint_pass");
    d.decode = Kernel(*d.adjoint_program, "decode_gradients");
    d.fixed_grad = Buffer<unsigned>(m_ctx, "fixed-point gradients",
                                    std::vector<unsigned>(2 * m_params.size(), 0u));
}

std::uint64_t Renderer::backward(const Buffer<float>& params, std::uint32_t seed, int spp,
                                 const Buffer<float>& delta, Buffer<float>& grad) {
    DeviceData& d = *m_data;
    const std::size_t pixels = std::size_t(m_scene.camera.width) * m_scene.camera.height;
    if (delta.size() != 3 * pixels) throw Error("backward: the adjoint image has the wrong size");
    if (params.size() != m_params.size() || grad.size() != m_params.size())
        throw Error("backward: the parameter or gradient buffer does not match the scene's layout");
    prepare_backward();
    gpu::RenderParams rp = launch_params(seed);
    const int total = std::max(1, spp);
    const float inv_spp = 1.0f / static_cast<float>(total);
    m_ctx.stage_times();
    d.guards.fill(0u);
    // Passes of a few samples, as render(): the fixed-point sums do not depend on the split.
    for (int begin = 0; begin < total; begin += 4) {
        rp.sample_begin = static_cast<unsigned>(begin);
        rp.sample_count = static_cast<unsigned>(std::min(4, total - begin));
        d.launch(d.adjoint, m_ctx, "adjoint", pixels, m_scene, rp, params, delta, inv_spp,
                 d.fixed_grad, d.guards);
    }
    d.decode.launch(m_ctx, "decode gradients", grad.size(), d.fixed_grad, grad,
                    static_cast<unsigned>(grad.size()));
    const std::uint64_t caught = sum_of(d.guards.download());
    m_last_backward_seconds = stage_seconds(m_ctx.stage_times(), "adjoint");
    return caught;
}

} // namespace tandem
