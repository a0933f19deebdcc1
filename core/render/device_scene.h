// The device scene: what was uploaded for one flattened scene (BVH, geometry, materials, lights,
// the sensors' cameras), the kernels built for its features, and the one binding of the scene's
// kernel arguments (kernels/shared/scene_args.h). Passes (core/render/passes.h) are functions of
// it and of the sensor they render.
#pragma once

#include <algorithm>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/bvh/bvh_build.h"
#include "core/render/features.h"
#include "core/scene/render_scene.h"
#include "runtime/kernel_source.h"
#include "runtime/launch.h"
#include "shared/bvh_layout.h"
#include "shared/reservoir.h"
#include "shared/scene_args.h"

namespace tandem {

namespace gpu {
/// The scene's kernel arguments on the host, declared from TANDEM_SCENE_ARGS (in this namespace,
/// so the shared type names resolve): a Buffer per device array, a copy per by-value record.
struct SceneArgs {
#define TANDEM_SCENE_ARGS_BUFFER(T, name) Buffer<T> name;
#define TANDEM_SCENE_ARGS_VALUE(T, name) T name{};
    TANDEM_SCENE_ARGS(TANDEM_SCENE_ARGS_BUFFER, TANDEM_SCENE_ARGS_VALUE)
#undef TANDEM_SCENE_ARGS_BUFFER
#undef TANDEM_SCENE_ARGS_VALUE
};
} // namespace gpu

/// The mesh's triangles, spheres and disks in primitive order as shading reads them (the scene's
/// `prims`): each primitive's record (primitive_record), and each triangle's unit front normal.
std::vector<gpu::ShadingPrimitive> shading_primitives(const TriangleMesh& mesh);

class DeviceScene {
public:
    /// Validates `features` against the scene (check_features), builds the BVH with Embree
    /// (width BVH_WIDTH) and uploads everything. Its policy is the one the features say, with
    /// the host's own choices from ctx.tuning() (core/render/policy.h: policy_of). `scene` must
    /// outlive this object.
    DeviceScene(Context& ctx, const KernelLibrary& lib, const RenderScene& scene,
                const BuildFlags& features);
    /// As above with render_features(scene, ctx): the policy of the context's device and Tuning
    /// for the scene's film.
    DeviceScene(Context& ctx, const KernelLibrary& lib, const RenderScene& scene);
    /// The scene is kept by reference: a temporary cannot be one.
    DeviceScene(Context&, const KernelLibrary&, RenderScene&&, const BuildFlags&) = delete;
    DeviceScene(Context&, const KernelLibrary&, RenderScene&&) = delete;
    DeviceScene(const DeviceScene&) = delete;
    DeviceScene& operator=(const DeviceScene&) = delete;

    Context& context() { return *m_ctx; }
    const RenderScene& scene() const { return *m_scene; }
    const BuildFlags& features() const { return m_features; } ///< the flags it was built with
    /// How it is traced and rendered, decided once (the passes read it: the wavefront or the
    /// megakernels, what the adjoints record).
    const DevicePolicy& policy() const { return m_policy; }
    /// The scene's sensors (RenderScene::sensors), numbered in file order.
    unsigned sensors() const { return static_cast<unsigned>(m_cameras.size()); }
    /// Sensor `sensor`'s device camera; throws Error naming the count for a sensor out of range.
    const gpu::DeviceCamera& camera(unsigned sensor) const;
    unsigned width(unsigned sensor = 0) const { return camera(sensor).width; }
    unsigned height(unsigned sensor = 0) const { return camera(sensor).height; }
    std::size_t pixels(unsigned sensor = 0) const {
        return std::size_t(width(sensor)) * height(sensor);
    }
    /// The most pixels of any sensor's film: what the per-pixel scratch below holds.
    std::size_t max_pixels() const { return m_max_pixels; }
    /// Elements of the flat parameter buffer the kernels read (ParamRegistry::size()).
    std::size_t param_count() const { return m_scene->params.size(); }

    /// The per-launch record (seed, depths, light counts); passes set the sample range.
    gpu::RenderParams launch_params(std::uint32_t seed) const;

    /// Recomputes the majorant grids of the scene's grid media from the grids' voxels in `params`
    /// (kernels/render.cl: media_majorant), so that they bound the state a pass renders: the
    /// passes call it before they trace (a homogeneous medium's majorant is derived in the
    /// kernels). A two-state pass passes the old state too: the majorants then bound both.
    /// Nothing for a scene without grid media.
    void refresh_majorants(const Buffer<float>& params, const Buffer<float>* params_old = nullptr);

    /// The mesh the device traces now: the scene's, with the vertex positions of its mesh shapes
    /// as the last sync_geometry() found them in the parameters.
    const TriangleMesh& mesh() const { return m_mesh; }
    /// From now on, sync_geometry() reads the vertex positions from the parameters (a session
    /// calls it when they are optimized or assigned). Off at first: a scene whose shapes never
    /// move reads nothing back.
    void track_geometry() { m_track_geometry = true; }
    /// Where track_geometry() is on and the mesh shapes' vertex positions in `params`
    /// (NAME.vertex_positions) differ from mesh(): takes them, refits the BVH kept from the last
    /// change (or rebuilds it, with Embree as at construction, the first time and once a refit
    /// tree's SAH cost has grown a quarter over its build's), and uploads the primitives and, where emitters moved, the emissive triangles
    /// with their selection table (each triangle's probability follows its area). The passes
    /// call it before they trace. Throws Error naming the shape and vertex for a non-finite
    /// position, before anything changes, and naming the shape where every one of its triangles
    /// has collapsed to zero area (the device then keeps the last geometry it had).
    void sync_geometry(const Buffer<float>& params);
    /// What the kernels trace and shade in another state's geometry: its tree (nodes, tris) and
    /// its primitives' shading normals.
    struct GeometryAt {
        const Buffer<gpu::float4>* nodes;
        const Buffer<gpu::BvhTriangle>* tris;
        const Buffer<gpu::TriangleNormals>* normals;
    };
    /// The geometry with the vertex positions of `params` in place of those sync_geometry() last
    /// found: another state's, such as the one where reused light samples find their points again
    /// (kernels/path/resample.h: restir_resample_at, under theta_{n-1}). The tree is the device's
    /// refit to those positions (a fresh build where the device keeps none yet); normals derived
    /// from the vertices follow them, a file's stay. The synced buffers themselves where nothing
    /// moved; kept for the next call with the same positions, valid until one with others.
    GeometryAt geometry_at(const Buffer<float>& params);
    /// What the last change of sync_geometry() found in the moving meshes: triangles of zero
    /// area, and triangles whose normal turned against its direction in the scene file (the
    /// mesh folded over). Traced as they are; the gradients skip what a zero area leaves
    /// undefined. One line for the log, naming the shapes, or "" where there are none; each
    /// report is returned once.
    std::string take_geometry_report() { return std::exchange(m_geometry_report, std::string()); }
    /// How often the BVH was built (construction included) and refit: sync_geometry()'s choices.
    struct BvhUpdates {
        unsigned builds = 0, refits = 0;
    };
    BvhUpdates bvh_updates() const { return m_bvh_updates; }

    /// Builds the kernels with SHAPE_GRAD from now on (the interior term of shape gradients in
    /// the replay: kernels/path/shape_adjoint.h), with each triangle's vertex parameters uploaded
    /// (`prim_params`); programs built before are dropped, so call it before taking kernels.
    /// Nothing the second time.
    void enable_shape_gradients();
    bool shape_gradients() const { return m_features.get("SHAPE_GRAD") == 1; }

    /// Kernel `name` of kernels/`file`, built with the scene's features on first use and kept.
    Kernel& kernel(const std::string& file, const std::string& name);

    /// Launches `kernel` over `n` work items with the scene's arguments (TANDEM_SCENE_ARGS; their
    /// camera `cam` is sensor `sensor`'s), then `rp`, then the pass's own arguments `extra`.
    /// Enqueued, not waited for. The cameras live here, one record per sensor, and each launch
    /// passes its sensor's by value (80 bytes of the argument block, constant on a GPU): the
    /// kernels read no array to find it, and a scene with one sensor launches what it did
    /// before sensors were several.
    template <class... Extra>
    void launch(unsigned sensor, Kernel& kernel, const char* stage, std::size_t n,
                const gpu::RenderParams& rp, const Extra&... extra) {
        m_args.cam = camera(sensor);
#define TANDEM_HOST_SCENE_ARG(T, name) , m_args.name
        kernel.launch(*m_ctx, stage,
                      n TANDEM_SCENE_ARGS(TANDEM_HOST_SCENE_ARG, TANDEM_HOST_SCENE_ARG), rp,
                      extra...);
#undef TANDEM_HOST_SCENE_ARG
    }

    /// The scene's kernel arguments as (OpenCL C type, name), in binding order: what launch()
    /// binds, for the test that compares it with the compiled kernels' signatures.
    static std::vector<std::pair<std::string, std::string>> argument_list();

    /// Per-pixel scratch the passes share, for the largest film (max_pixels()): sample sums (rgb, w = count) of the new and the old
    /// state, and the running count of dropped samples, saturated gradient contributions and
    /// wrapped gradient sums (read with read_guards()).
    Buffer<gpu::float4>& accum() {
        return m_accum;
    }
    Buffer<gpu::float4>& accum_old() {
        return m_accum_old;
    }
    Buffer<unsigned>& guards() {
        return m_guards;
    }
    /// Scratch for the adjoint: 16 bytes for each of `count` samples (a launch's samples of every
    /// pixel of the view), the primal radiance (rgb) and, from the megakernel (kernels/adjoint.cl,
    /// adjoint_primal), the bits of its shadow record in the fourth word. Allocated on first use
    /// and grown, never shrunk: views of several film sizes share it without reallocating, and
    /// since each view's launches stay within the adjoint's cap (adjoint_launches), so does the
    /// largest.
    Buffer<gpu::float4>& sample_radiance(std::size_t count) {
        if (m_sample_radiance.size() < count)
            m_sample_radiance = Buffer<gpu::float4>(*m_ctx, "adjoint sample radiance", count);
        return m_sample_radiance;
    }
    /// Scratch for the adjoint: the hits of `count` samples' recorded bounces (kernels/adjoint.cl,
    /// adjoint_primal; at least one, so that there is a buffer to pass); grown as
    /// sample_radiance() is.
    Buffer<gpu::Hit>& sample_hits(std::size_t count) {
        count = std::max<std::size_t>(count, 1);
        if (m_sample_hits.size() < count)
            m_sample_hits = Buffer<gpu::Hit>(*m_ctx, "adjoint recorded hits", count);
        return m_sample_hits;
    }
    /// Scratch of the wavefront renderer (core/render/wavefront.cpp), kept across passes.
    struct Wavefront {
        Buffer<float> state;         ///< the float fields of every path (kernels/path/wavefront.h)
        Buffer<unsigned> flags;      ///< the uint fields
        Buffer<unsigned> live;       ///< the paths alive at the start of a bounce, in order
        Buffer<unsigned> live_counts, live_offsets, live_total; ///< the list's prefix sums
        Buffer<unsigned> hits, seen; ///< what the adjoint records of a path for its replay
        /// the most bounces the adjoint records (deeper ones are traced again): the policy's
        /// wavefront_record_bounces (tests may lower it)
        unsigned record_bounces = 16;
        /// the vectorised stages launched (so compiled) so far (core/render/wavefront.cpp)
        std::vector<const Kernel*> vectorised;
    };
    Wavefront& wavefront() { return m_wavefront; }
    /// A placeholder for the reservoir argument of the adjoint kernels when there are none.
    const Buffer<gpu::Reservoir>& no_reservoirs() {
        if (m_no_reservoirs.size() == 0)
            m_no_reservoirs = Buffer<gpu::Reservoir>(*m_ctx, "no reservoirs",
                                                     std::vector<gpu::Reservoir>(1, gpu::reservoir_empty()));
        return m_no_reservoirs;
    }
    /// The guard counters since the last reset_guards(), summed on the device (blocks for the
    /// few partial sums: call when reporting, not inside an iteration).
    std::uint64_t read_guards();
    /// Zeroes the guard counters (enqueued).
    void reset_guards() {
        m_guards.fill(0u);
    }

    /// The emissive triangles as the device has them (their selection pmf in p1.w).
    const std::vector<gpu::EmissiveTriangle>& emissive_triangles() const { return m_emissive; }

private:
    Context* m_ctx;
    KernelLibrary m_lib; ///< a copy: callers often pass a temporary
    const RenderScene* m_scene;
    BuildFlags m_features;
    DevicePolicy m_policy;
    gpu::SceneArgs m_args;                   ///< cam: the last launch's sensor's
    std::vector<gpu::DeviceCamera> m_cameras; ///< one per sensor
    TriangleMesh m_mesh;                       ///< what is traced (mesh())
    std::vector<gpu::EmissiveTriangle> m_emissive; ///< what is uploaded (sync_geometry)
    std::vector<float> m_emissive_density;     ///< each emissive triangle's pmf per unit area
    bool m_track_geometry = false;
    std::string m_geometry_report;
    FlatBvh m_bvh;           ///< the host's copy of the device's tree, kept once geometry is tracked
    double m_built_sah = 0;  ///< its SAH cost when last built (bvh_sah_cost)
    BvhUpdates m_bvh_updates;
    /// Builds or refits the BVH of m_mesh and uploads it with the primitives.
    void upload_geometry();
    /// Uploads each primitive's shading normals (m_args.normals) from mesh(), and with shape
    /// gradients the derivatives of the derived ones (m_args.normal_jac).
    void upload_normals();
    /// The TriangleNormals records of the mesh with per-vertex shading normals `normals` (those of
    /// m_mesh, or another state's): smooth primitives flagged, no derivative blocks linked.
    std::vector<gpu::TriangleNormals> normal_records(const std::vector<glm::vec3>& normals) const;
    /// The coordinates of every vertex of the mesh (3 floats each) in `params`, where each mesh
    /// shape keeps its vertex positions (every vertex belongs to one).
    std::vector<float> vertex_coordinates(const Buffer<float>& params) const;
    /// A tree of the device's layout over `mesh`, built anew (Embree).
    FlatBvh build_tree(const TriangleMesh& mesh) const;
    /// geometry_at()'s: the positions it was made for, and its buffers
    struct {
        std::vector<glm::vec3> positions;
        Buffer<gpu::float4> nodes;
        Buffer<gpu::BvhTriangle> tris;
        Buffer<gpu::TriangleNormals> normals;
    } m_at;
    std::size_t m_max_pixels = 0;
    std::map<std::string, std::unique_ptr<Program>> m_programs; ///< by file
    std::map<std::string, Kernel> m_kernels;                    ///< by "file:name"
    Buffer<gpu::float4> m_accum, m_accum_old;
    Buffer<gpu::float4> m_sample_radiance;
    Buffer<gpu::Hit> m_sample_hits;
    Wavefront m_wavefront;
    Buffer<gpu::Reservoir> m_no_reservoirs;
    Buffer<unsigned> m_guards;
    Buffer<std::uint64_t> m_guard_sums; ///< one per chunk of k_guard_chunk pixels
    static constexpr unsigned k_guard_chunk = 4096;
};

/// What a pass renders: one sensor of a device scene. A device scene converts to its sensor 0, so
/// that a caller with one sensor passes the scene itself.
struct View {
    /// Throws Error naming the count when the scene has no sensor `sensor`.
    View(DeviceScene& scene, unsigned sensor = 0) : scene(&scene), sensor(sensor) {
        scene.camera(sensor);
    }
    DeviceScene* scene;
    unsigned sensor;
    unsigned width() const { return scene->width(sensor); }
    unsigned height() const { return scene->height(sensor); }
    std::size_t pixels() const { return scene->pixels(sensor); }
};

} // namespace tandem
