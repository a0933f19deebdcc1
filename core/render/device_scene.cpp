// Upload of a flattened scene and the binding of its kernel arguments.
#include "core/render/device_scene.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/bvh/bvh_build.h"
#include "core/bvh/bvh_refit.h"
#include "core/bvh/embree_device.h"
#include "core/bvh/device_bvh.h"
#include "core/scene/vertex_normals.h"
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
    m_mesh = scene.mesh;
    upload_geometry();
    const cl_mem_flags ro = CL_MEM_READ_ONLY;
    m_args.infos = Buffer<gpu::TriangleInfo>(ctx, "triangle infos", scene.infos, ro);
    m_args.uvs = Buffer<gpu::TriangleUV>(ctx, "triangle uvs", scene.uvs, ro);
    m_args.textures = Buffer<gpu::TextureInfo>(ctx, "textures", at_least_one(scene.textures), ro);
    m_args.texels = Buffer<gpu::float4>(ctx, "texels", at_least_one(scene.texels), ro);
    m_args.materials = Buffer<gpu::Material>(ctx, "materials", scene.materials, ro);
    m_emissive = scene.emissive;
    for (const gpu::EmissiveTriangle& e : m_emissive)
        m_emissive_density.push_back(e.p0.w > 0.0f ? e.p1.w / e.p0.w : 0.0f);
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
    m_args.prim_params = Buffer<gpu::uint4>(ctx, "primitive vertex parameters",
                                            std::vector<gpu::uint4>(1, gpu::uint4{}), ro);
    m_args.envmap = scene.envmap;
    m_cameras = scene.cameras;
    if (m_cameras.empty()) throw Error("a scene needs a sensor");
    m_args.cam = m_cameras.front();
    for (unsigned k = 0; k < sensors(); ++k) m_max_pixels = std::max(m_max_pixels, pixels(k));
    m_accum = Buffer<gpu::float4>(ctx, "accumulator", max_pixels());
    m_accum_old = Buffer<gpu::float4>(ctx, "accumulator (old state)", max_pixels());
    m_guards = Buffer<unsigned>(ctx, "guards", std::vector<unsigned>(max_pixels(), 0u));
}

FlatBvh DeviceScene::build_tree(const TriangleMesh& mesh) const {
    EmbreeDevice embree;
    const LeafFormat leaves = m_policy.tri4_leaves ? LeafFormat::tri4 : LeafFormat::records;
    return build_bvh(embree, mesh, m_policy.bvh_width, leaves, m_policy.repack);
}

void DeviceScene::upload_geometry() {
    // A refit (core/bvh/bvh_refit.h) costs a tenth of a build or less at every mesh size
    // (`tandem bench refit`, docs/performance.md) but keeps the topology the tree was built
    // with: rebuilt once its SAH cost has grown by k_refit_sah_growth over the last build's.
    constexpr double k_refit_sah_growth = 1.25;
    bool rebuild = m_bvh.node_count() == 0;
    if (!rebuild) {
        refit_bvh(m_bvh, m_mesh);
        rebuild = bvh_sah_cost(m_bvh) > k_refit_sah_growth * m_built_sah;
    }
    if (rebuild) {
        m_bvh = build_tree(m_mesh);
        m_built_sah = bvh_sah_cost(m_bvh);
        ++m_bvh_updates.builds;
    } else {
        ++m_bvh_updates.refits;
    }
    DeviceBvh bvh(*m_ctx, m_bvh);
    if (!m_track_geometry) m_bvh = FlatBvh(); // a scene that never moves keeps no host copy
    m_args.nodes = std::move(bvh.nodes);
    m_args.tris = std::move(bvh.triangles);
    m_args.prims = Buffer<gpu::ShadingPrimitive>(*m_ctx, "primitives", shading_primitives(m_mesh),
                                                 CL_MEM_READ_ONLY);
    upload_normals();
}

namespace {

/// Mesh shape s of `mesh` on its own: its positions, and its triangles' indices into them.
std::pair<std::vector<glm::vec3>, std::vector<glm::uvec3>> shape_part(const TriangleMesh& mesh,
                                                                      const MeshShape& s) {
    std::vector<glm::vec3> positions(mesh.positions.begin() + s.first_vertex,
                                     mesh.positions.begin() + s.first_vertex + s.vertex_count);
    std::vector<glm::uvec3> triangles(mesh.triangles.begin() + s.first_triangle,
                                      mesh.triangles.begin() + s.first_triangle + s.triangle_count);
    for (glm::uvec3& t : triangles) t -= glm::uvec3(s.first_vertex);
    return {std::move(positions), std::move(triangles)};
}

/// Sets the shading normals of the shapes of `scene` that derive theirs from their vertices to
/// those of mesh's positions.
void derive_normals(const RenderScene& scene, TriangleMesh& mesh) {
    for (const MeshShape& s : scene.mesh_shapes) {
        if (!s.normals_derived) continue;
        const auto [positions, triangles] = shape_part(mesh, s);
        const std::vector<glm::dvec3> normals = derived_normals(positions, triangles);
        for (unsigned k = 0; k < s.vertex_count; ++k)
            mesh.normals[s.first_vertex + k] = glm::vec3(normals[k]);
    }
}

} // namespace

std::vector<float> DeviceScene::vertex_coordinates(const Buffer<float>& params) const {
    std::vector<float> xyz(3 * m_mesh.positions.size());
    for (const MeshShape& s : m_scene->mesh_shapes)
        params.enqueue_read(s.param, 3 * std::size_t(s.vertex_count), &xyz[3 * s.first_vertex]);
    m_ctx->finish();
    return xyz;
}

std::vector<gpu::TriangleNormals>
DeviceScene::normal_records(const std::vector<glm::vec3>& normals) const {
    const bool smooth = m_features.get("HAS_SHADING_NORMALS") == 1;
    std::vector<gpu::TriangleNormals> records(smooth ? m_mesh.primitive_count() : 1);
    for (gpu::TriangleNormals& r : records) r.link = {0u, NO_PARAM, NO_PARAM, NO_PARAM};
    for (const MeshShape& s : smooth ? m_scene->mesh_shapes : std::vector<MeshShape>()) {
        if (!s.smooth) continue;
        for (unsigned i = 0; i < s.triangle_count; ++i) {
            const glm::uvec3& t = m_mesh.triangles[s.first_triangle + i];
            gpu::TriangleNormals& r = records[s.first_triangle + i];
            const glm::vec3 &n0 = normals[t.x], &n1 = normals[t.y], &n2 = normals[t.z];
            r.n0 = gpu::make_float4(n0.x, n0.y, n0.z, 0.0f);
            r.n1 = gpu::make_float4(n1.x, n1.y, n1.z, 0.0f);
            r.n2 = gpu::make_float4(n2.x, n2.y, n2.z, 0.0f);
            r.link = {1u, NO_PARAM, NO_PARAM, NO_PARAM};
        }
    }
    return records;
}

void DeviceScene::upload_normals() {
    std::vector<gpu::TriangleNormals> records = normal_records(m_mesh.normals);
    std::vector<gpu::NormalJacobian> blocks;
    const bool smooth = m_features.get("HAS_SHADING_NORMALS") == 1;
    for (const MeshShape& s : smooth ? m_scene->mesh_shapes : std::vector<MeshShape>()) {
        if (!s.smooth || !s.normals_derived || !shape_gradients()) continue;
        std::vector<unsigned> first_block(s.vertex_count, NO_PARAM);
        const auto [positions, triangles] = shape_part(m_mesh, s);
        const NormalJacobian jac = normal_jacobian(positions, triangles);
        for (unsigned k = 0; k < s.vertex_count; ++k) {
            const unsigned begin = jac.first[k], end = jac.first[k + 1];
            if (begin == end) continue;
            first_block[k] = static_cast<unsigned>(blocks.size());
            for (unsigned b = begin; b < end; ++b) {
                const glm::dmat3& m = jac.jacobian[b];
                const unsigned param = s.param + 3 * jac.vertex[b];
                blocks.push_back({gpu::make_float4(float(m[0].x), float(m[0].y), float(m[0].z),
                                                   gpu::as_float(param)),
                                  gpu::make_float4(float(m[1].x), float(m[1].y), float(m[1].z),
                                                   gpu::as_float(end - b)),
                                  gpu::make_float4(float(m[2].x), float(m[2].y), float(m[2].z),
                                                   0.0f)});
            }
        }
        for (unsigned i = 0; i < s.triangle_count; ++i) {
            const glm::uvec3& t = m_mesh.triangles[s.first_triangle + i];
            records[s.first_triangle + i].link = {1u, first_block[t.x - s.first_vertex],
                                                  first_block[t.y - s.first_vertex],
                                                  first_block[t.z - s.first_vertex]};
        }
    }
    const cl_mem_flags ro = CL_MEM_READ_ONLY;
    m_args.normals = Buffer<gpu::TriangleNormals>(*m_ctx, "shading normals", records, ro);
    m_args.normal_jac =
        Buffer<gpu::NormalJacobian>(*m_ctx, "vertex normal derivatives", at_least_one(blocks), ro);
}

DeviceScene::GeometryAt DeviceScene::geometry_at(const Buffer<float>& params) {
    const GeometryAt now{&m_args.nodes, &m_args.tris, &m_args.normals};
    if (!m_track_geometry || m_scene->mesh_shapes.empty()) return now;
    const std::vector<float> xyz = vertex_coordinates(params);
    std::vector<glm::vec3> positions(m_mesh.positions.size());
    for (std::size_t i = 0; i < positions.size(); ++i)
        positions[i] = glm::vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    if (positions == m_mesh.positions) return now;
    if (positions != m_at.positions) {
        TriangleMesh mesh = m_mesh;
        mesh.positions = std::move(positions);
        FlatBvh bvh = m_bvh;
        if (bvh.node_count() == 0) bvh = build_tree(mesh); // nothing moved since the load
        else refit_bvh(bvh, mesh);
        DeviceBvh device(*m_ctx, bvh);
        m_at.nodes = std::move(device.nodes);
        m_at.tris = std::move(device.triangles);
        derive_normals(*m_scene, mesh);
        m_at.normals = Buffer<gpu::TriangleNormals>(*m_ctx, "shading normals of another state",
                                                    normal_records(mesh.normals),
                                                    CL_MEM_READ_ONLY);
        m_at.positions = std::move(mesh.positions);
    }
    return {&m_at.nodes, &m_at.tris, &m_at.normals};
}

void DeviceScene::sync_geometry(const Buffer<float>& params) {
    const RenderScene& scene = *m_scene;
    if (!m_track_geometry || scene.mesh_shapes.empty()) return;
    const std::vector<float> xyz = vertex_coordinates(params);
    bool changed = false;
    for (const MeshShape& s : scene.mesh_shapes)
        for (unsigned i = 0; i < s.vertex_count; ++i) {
            const float* v = &xyz[3 * (s.first_vertex + i)];
            if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2]))
                throw Error(s.name + ".vertex_positions: vertex " + std::to_string(i) +
                            " is not finite");
            const glm::vec3 p(v[0], v[1], v[2]);
            changed |= p != m_mesh.positions[s.first_vertex + i];
        }
    if (!changed) return;
    for (std::size_t i = 0; i < m_mesh.positions.size(); ++i)
        m_mesh.positions[i] = glm::vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    // degenerate and folded triangles, counted against the file's orientation
    m_geometry_report.clear();
    for (const MeshShape& s : scene.mesh_shapes) {
        unsigned degenerate = 0, flipped = 0;
        for (unsigned i = 0; i < s.triangle_count; ++i) {
            const glm::uvec3& t = m_mesh.triangles[s.first_triangle + i];
            const glm::vec3 n = glm::cross(m_mesh.positions[t.y] - m_mesh.positions[t.x],
                                           m_mesh.positions[t.z] - m_mesh.positions[t.x]);
            const glm::vec3 n0 = glm::cross(scene.mesh.positions[t.y] - scene.mesh.positions[t.x],
                                            scene.mesh.positions[t.z] - scene.mesh.positions[t.x]);
            if (!(glm::dot(n, n) > 0.0f)) ++degenerate;
            else if (glm::dot(n, n0) < 0.0f) ++flipped;
        }
        if (s.triangle_count > 0 && degenerate == s.triangle_count) // nothing left to trace
            throw Error(s.name + ".vertex_positions: all " + std::to_string(degenerate) +
                        " triangles are degenerate (zero or non-finite area)");
        if (degenerate || flipped)
            m_geometry_report += (m_geometry_report.empty() ? "" : "; ") + s.name + ": " +
                                 std::to_string(degenerate) + " degenerate and " +
                                 std::to_string(flipped) + " folded triangles";
    }
    derive_normals(scene, m_mesh); // derived normals follow the vertices
    upload_geometry();
    if (m_emissive.empty()) return;
    // the emissive triangles where they are now; selection in proportion to power, each
    // triangle's power per unit area as at load
    std::vector<double> weights;
    bool moved = false;
    for (std::size_t prim = 0; prim < m_mesh.triangles.size(); ++prim) {
        const unsigned e = scene.infos[prim].emitter;
        if (e == NO_EMITTER) continue;
        const glm::uvec3& t = m_mesh.triangles[prim];
        const glm::vec3 p0 = m_mesh.positions[t.x], p1 = m_mesh.positions[t.y],
                        p2 = m_mesh.positions[t.z];
        gpu::EmissiveTriangle& et = m_emissive[e];
        const gpu::float4 q0{p0.x, p0.y, p0.z, 0.5f * glm::length(glm::cross(p1 - p0, p2 - p0))};
        moved |= std::memcmp(&q0, &et.p0, sizeof q0) != 0 || et.p1.x != p1.x ||
                 et.p1.y != p1.y || et.p1.z != p1.z || et.p2.x != p2.x || et.p2.y != p2.y ||
                 et.p2.z != p2.z;
        et.p0 = q0;
        et.p1 = gpu::make_float4(p1.x, p1.y, p1.z, et.p1.w);
        et.p2 = gpu::make_float4(p2.x, p2.y, p2.z, 0.0f);
        const gpu::float3 n = gpu::triangle_front_normal({p0.x, p0.y, p0.z}, {p1.x, p1.y, p1.z},
                                                         {p2.x, p2.y, p2.z});
        et.nx = n.x;
        et.ny = n.y;
        et.nz = n.z;
    }
    if (!moved) return;
    for (std::size_t e = 0; e < m_emissive.size(); ++e)
        weights.push_back(double(m_emissive_density[e]) * m_emissive[e].p0.w);
    for (const gpu::DeltaLight& d : scene.delta_lights) weights.push_back(d.position.w);
    double total = 0.0;
    for (double w : weights) total += w;
    if (!(total > 0.0)) throw Error("every emitter of the scene has lost its area");
    for (std::size_t e = 0; e < m_emissive.size(); ++e)
        m_emissive[e].p1.w = static_cast<float>(weights[e] / total);
    std::vector<gpu::DeltaLight> delta = scene.delta_lights;
    for (std::size_t i = 0; i < delta.size(); ++i)
        delta[i].position.w = static_cast<float>(weights[m_emissive.size() + i] / total);
    const cl_mem_flags ro = CL_MEM_READ_ONLY;
    m_args.emissive = Buffer<gpu::EmissiveTriangle>(*m_ctx, "emissive triangles", m_emissive, ro);
    m_args.delta_lights =
        Buffer<gpu::DeltaLight>(*m_ctx, "delta lights", at_least_one(delta), ro);
    m_args.alias =
        Buffer<gpu::AliasEntry>(*m_ctx, "light alias table", build_alias_table(weights), ro);
}

void DeviceScene::enable_shape_gradients() {
    if (shape_gradients()) return;
    const RenderScene& scene = *m_scene;
    std::vector<gpu::uint4> table(std::max<std::size_t>(1, m_mesh.primitive_count()),
                                  gpu::uint4{NO_PARAM, NO_PARAM, NO_PARAM, NO_PARAM});
    for (const MeshShape& s : scene.mesh_shapes)
        for (unsigned i = 0; i < s.triangle_count; ++i) {
            const glm::uvec3& t = m_mesh.triangles[s.first_triangle + i];
            table[s.first_triangle + i] = {s.param + 3 * (t.x - s.first_vertex),
                                           s.param + 3 * (t.y - s.first_vertex),
                                           s.param + 3 * (t.z - s.first_vertex), 0u};
        }
    m_args.prim_params =
        Buffer<gpu::uint4>(*m_ctx, "primitive vertex parameters", table, CL_MEM_READ_ONLY);
    m_features.set("SHAPE_GRAD", 1);
    upload_normals(); // with the derivatives of derived normals
    m_kernels.clear();
    m_programs.clear();
    m_wavefront.vectorised.clear();
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
