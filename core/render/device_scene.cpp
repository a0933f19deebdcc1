// Upload of a flattened scene and the binding of its kernel arguments.
#include "core/render/device_scene.h"

#include <algorithm>
#include <cstring>

#include "core/bvh/bvh_build.h"
#include "core/bvh/embree_device.h"
#include "core/bvh/device_bvh.h"
#include "runtime/error.h"
#include "shared/sampling.h"

namespace tandem {

std::vector<gpu::ShadingPrimitive> shading_primitives(const TriangleMesh& mesh) {
    std::vector<gpu::ShadingPrimitive> out(mesh.primitive_count());
    for (std::size_t i = 0; i < out.size(); ++i) {
        const gpu::BvhTriangle r = primitive_record(mesh, static_cast<unsigned>(i));
        out[i] = gpu::ShadingPrimitive{r.v0, r.v1, r.v2, gpu::float4{}};
        if (i < mesh.triangles.size()) {
            const gpu::float3 n =
                gpu::triangle_front_normal(gpu::xyz(r.v0), gpu::xyz(r.v1), gpu::xyz(r.v2));
            out[i].n_front = gpu::make_float4(n.x, n.y, n.z, 0.0f);
        }
    }
    return out;
}

DeviceScene::DeviceScene(Context& ctx, const KernelLibrary& lib, const RenderScene& scene)
    : DeviceScene(ctx, lib, scene, render_features(scene, ctx)) {}

DeviceScene::DeviceScene(Context& ctx, const KernelLibrary& lib, const RenderScene& scene,
                         const BuildFlags& features)
    : m_ctx(&ctx), m_lib(lib), m_scene(&scene), m_features(features),
      m_policy(policy_of(features, ctx.tuning())) {
    check_features(scene, features);
    m_wavefront.record_bounces = m_policy.wavefront_record_bounces;
    EmbreeDevice embree;
    const LeafFormat leaves = m_policy.tri4_leaves ? LeafFormat::tri4 : LeafFormat::records;
    DeviceBvh bvh(ctx,
                  build_bvh(embree, scene.mesh, m_policy.bvh_width, leaves, m_policy.repack));
    m_args.nodes = std::move(bvh.nodes);
    m_args.tris = std::move(bvh.triangles);
    const cl_mem_flags ro = CL_MEM_READ_ONLY;
    m_args.prims =
        Buffer<gpu::ShadingPrimitive>(ctx, "primitives", shading_primitives(scene.mesh), ro);
    m_args.infos = Buffer<gpu::TriangleInfo>(ctx, "triangle infos", scene.infos, ro);
    m_args.uvs = Buffer<gpu::TriangleUV>(ctx, "triangle uvs", scene.uvs, ro);
    m_args.textures = Buffer<gpu::TextureInfo>(ctx, "textures", at_least_one(scene.textures), ro);
    m_args.texels = Buffer<gpu::float4>(ctx, "texels", at_least_one(scene.texels), ro);
    m_args.materials = Buffer<gpu::Material>(ctx, "materials", scene.materials, ro);
    m_args.emissive =
        Buffer<gpu::EmissiveTriangle>(ctx, "emissive triangles", at_least_one(scene.emissive), ro);
    m_args.delta_lights =
        Buffer<gpu::DeltaLight>(ctx, "delta lights", at_least_one(scene.delta_lights), ro);
    m_args.alias = Buffer<gpu::AliasEntry>(ctx, "light alias table", at_least_one(scene.alias), ro);
    m_args.env_texels =
        Buffer<gpu::float4>(ctx, "envmap texels", at_least_one(scene.env_texels), ro);
    m_args.env_cdf = Buffer<float>(ctx, "envmap cdf", at_least_one(scene.env_cdf), ro);
    m_args.plastic_tables =
        Buffer<float>(ctx, "roughplastic tables", at_least_one(scene.plastic_tables), ro);
    m_args.media = Buffer<gpu::Medium>(ctx, "media", at_least_one(scene.media), ro);
    m_args.grids = Buffer<gpu::DeviceGrid>(ctx, "medium grids", at_least_one(scene.grids), ro);
    m_args.medium_data = // the majorant grids, refreshed by refresh_majorants
        Buffer<float>(ctx, "medium majorant grids", at_least_one(scene.medium_data));
    m_args.envmap = scene.envmap;
    m_cameras = scene.cameras;
    if (m_cameras.empty()) throw Error("a scene needs a sensor");
    m_args.cam = m_cameras.front();
    for (unsigned k = 0; k < sensors(); ++k) m_max_pixels = std::max(m_max_pixels, pixels(k));
    m_accum = Buffer<gpu::float4>(ctx, "accumulator", max_pixels());
    m_accum_old = Buffer<gpu::float4>(ctx, "accumulator (old state)", max_pixels());
    m_guards = Buffer<unsigned>(ctx, "guards", std::vector<unsigned>(max_pixels(), 0u));
}

const gpu::DeviceCamera& DeviceScene::camera(unsigned sensor) const {
    if (sensor >= m_cameras.size())
        throw Error("no sensor " + std::to_string(sensor) + ": the scene has " +
                    std::to_string(m_cameras.size()));
    return m_cameras[sensor];
}

gpu::RenderParams DeviceScene::launch_params(std::uint32_t seed) const {
    const RenderScene& s = *m_scene;
    gpu::RenderParams rp{};
    rp.env_param = s.env_param;
    rp.seed = seed;
    rp.max_depth = s.max_depth < 0 ? 0xFFFFFFFFu : static_cast<unsigned>(s.max_depth);
    rp.rr_depth = static_cast<unsigned>(std::max(0, s.rr_depth));
    rp.emissive_count = static_cast<unsigned>(s.emissive.size());
    rp.delta_count = static_cast<unsigned>(s.delta_lights.size());
    const bool other_lights = !s.emissive.empty() || !s.delta_lights.empty();
    rp.light_env_prob = !s.has_env ? 0.0f : (other_lights ? 0.5f : 1.0f);
    return rp;
}

Kernel& DeviceScene::kernel(const std::string& file, const std::string& name) {
    const std::string key = file + ":" + name;
    auto it = m_kernels.find(key);
    if (it != m_kernels.end()) return it->second;
    std::unique_ptr<Program>& program = m_programs[file];
    if (!program)
        program =
            std::make_unique<Program>(Program::build(*m_ctx, m_lib, file, m_features.options()));
    return m_kernels.emplace(key, Kernel(*program, name)).first->second;
}

void DeviceScene::refresh_majorants(const Buffer<float>& params, const Buffer<float>* params_old) {
    for (const gpu::Medium& m : m_scene->media) {
        if (m.kind != MEDIUM_GRID) continue;
        const gpu::DeviceGrid& g = m_scene->grids.at(m.majorant_grid);
        kernel("render.cl", "media_majorant")
            .launch(*m_ctx, "render", std::size_t(g.nx) * g.ny * g.nz, m_args.grids, params,
                    params_old ? *params_old : params, m_args.medium_data, m.sigma_t_grid, m.majorant_grid);
    }
}

std::vector<std::pair<std::string, std::string>> DeviceScene::argument_list() {
    std::vector<std::pair<std::string, std::string>> out;
#define TANDEM_LIST_BUFFER(T, name) out.emplace_back(#T "*", #name);
#define TANDEM_LIST_VALUE(T, name) out.emplace_back(#T, #name);
    TANDEM_SCENE_ARGS(TANDEM_LIST_BUFFER, TANDEM_LIST_VALUE)
#undef TANDEM_LIST_BUFFER
#undef TANDEM_LIST_VALUE
    return out;
}

std::uint64_t DeviceScene::read_guards() {
    const auto count = static_cast<unsigned>(max_pixels());
    const unsigned chunks = (count + k_guard_chunk - 1) / k_guard_chunk;
    if (m_guard_sums.size() != chunks)
        m_guard_sums = Buffer<std::uint64_t>(*m_ctx, "guard sums", chunks);
    kernel("render.cl", "sum_guards").launch(*m_ctx, "guards", chunks, m_guards, m_guard_sums, k_guard_chunk, count);
    std::uint64_t sum = 0;
    for (std::uint64_t s : m_guard_sums.download()) sum += s;
    return sum;
}

} // namespace tandem
