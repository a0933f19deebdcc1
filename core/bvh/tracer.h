// The flattened BVH on the device, and the closest-hit / any-hit trace kernels that run over it.
#pragma once

#include "core/bvh/bvh_build.h"
#include "runtime/kernel_source.h"
#include "runtime/launch.h"

namespace tandem {

/// The BVH uploaded to device buffers "bvh nodes" and "bvh triangles": the one upload of a BVH,
/// for the trace kernels and the device scene (core/render/device_scene.h). The nodes are the
/// BvhNode, Bvh4Node or Bvh8Node records of the BVH's width, as float4 rows (the kernels' view of
/// them).
struct DeviceBvh {
    int width;
    bool analytic; ///< FlatBvh::analytic
    bool tri4;     ///< FlatBvh::tri4
    Buffer<gpu::float4> nodes;
    Buffer<gpu::BvhTriangle> triangles;

    DeviceBvh(Context& ctx, const FlatBvh& bvh);
};

/// The BVH layout to trace with on `device`: 8 on CPUs whose native float vector holds 8 or more
/// (AVX, AVX2, AVX-512), where its float8 box tests are one instruction per operation
/// (bench/RESULTS.md, measured on AVX2: cbox 12-21 % less kernel time than with 4, indirect-room
/// and env-probe within noise); 4 on other CPUs (SSE, NEON), whose float4 tests were 1.4-1.8x
/// faster than BVH2 on PoCL; 2 elsewhere. For gradient work on an H200 (NVIDIA's OpenCL) the
/// measurements were mixed: with the eight-wide tree a gradient iteration of cbox took 11-18 % less
/// time, cbox-wall's 2-10 % less up to 512² and the same at 1024², but the fused two-state kernel
/// 6 % more (bench/RESULTS.md, "On an H200"). `tandem optimize` runs both on one tree, and no
/// whole optimization was timed there, so gradient work keeps 2; forward renders take
/// forward_bvh_width.
int preferred_bvh_width(const DeviceInfo& device);

/// The BVH layout of a forward render (`tandem render`, `tandem bench render`) of a scene with or
/// without analytic spheres and disks: preferred_bvh_width on CPUs; on GPUs 8 for scenes of
/// triangles only, whose renders took 7-28 % less kernel time than with 2 on an H200 (five
/// triangle scenes, a 131k-triangle knot among them), and 2 for scenes with analytic shapes,
/// which took 6-17 % more with 8. The same bits for every width.
int forward_bvh_width(const DeviceInfo& device, bool analytic);

/// BVH_AXIS_LOOPS for `device` (kernels/shared/bvh_traverse.h): 1 on CPUs, where one copy of the
/// triangle test per dominant axis saved 3 % of a render on PoCL (bench/RESULTS.md), 0 elsewhere:
/// on a SIMT GPU the copies would run one after another for the rays of a warp (not measured).
int bvh_axis_loops(const DeviceInfo& device);

/// Meshes of at least this many triangles get BvhTri4 leaves in four-wide BVHs on CPUs
/// (preferred_leaf_format).
constexpr std::size_t k_tri4_min_triangles = 1024;

/// The leaf format for a `width`-wide BVH of `triangles` triangles (of a mesh without analytic
/// shapes) on `device`. On CPUs, BvhTri4 blocks for every eight-wide tree, and for four-wide trees
/// of meshes of k_tri4_min_triangles or more: one float4 test of four triangles and an SAH that
/// counts blocks traced the knot's rays 1.10-1.24x faster. With four-wide trees, the bundled
/// scenes of a few dozen large triangles whose boxes overlap (cbox, indirect-room) rendered
/// 3-12 % slower with blocks; with eight-wide ones, 0-10 % faster (bench/RESULTS.md). A record
/// each elsewhere: two-wide trees, and GPUs, where a SIMT lane runs the four tests one after
/// another: blocks rendered 1.4-3.2x slower than records on an H200 (bench/RESULTS.md).
LeafFormat preferred_leaf_format(const DeviceInfo& device, std::size_t triangles, int width);

/// A setting switched by the environment variable `name` (the BVH's, and features.h's
/// SHADOW_RECORD): 1 or 0 as it says, -1 where it is unset. Throws Error, naming it, on any other
/// value.
int switch_from_environment(const char* name);

/// Whether builds repack their leaves (core/bvh/leaf_repack.h): $TANDEM_BVH_REPACK (0 or 1; 0
/// keeps Embree's tree as it built it, to compare) if set, else yes. Throws Error on another value.
bool bvh_repack_from_environment();

/// Meshes of at least this many triangles get BVH_PREFETCH on CPUs (bvh_prefetch).
constexpr std::size_t k_prefetch_min_triangles = 16384;

/// BVH_PREFETCH for a `width`-wide BVH of `triangles` triangles on `device`
/// (kernels/shared/bvh8_traverse.h: a node visit prefetches the children the ray enters), unless
/// $TANDEM_BVH_PREFETCH (0 or 1, to compare them) says otherwise. 1 on CPUs for eight-wide trees
/// of meshes of k_prefetch_min_triangles or more: on an AVX2 EPYC with PoCL, against Embree's
/// rate in the same rounds, incoherent rays traced 11-15 % faster and shadow rays 7-13 % through
/// knots of 65,536-524,288 triangles (trees of 5-42 MB), 5 % and 1 % through 16,384 (1.3 MB);
/// through 4,096 (a tree of 344 kB, which stays in the cache) shadow rays lost 2-3 %, and the
/// bundled scenes of a few dozen triangles executed 4 % more instructions for nothing
/// (bench/RESULTS.md, "Prefetching the children"). 0 elsewhere: four-wide trees (not measured)
/// and GPUs (not measured; thousands of rays in flight hide their latency). The same bits either
/// way.
int bvh_prefetch(const DeviceInfo& device, std::size_t triangles, int width);

/// CAMERA_PACKETS for the path kernels: 1 where the render pass traces the camera rays of a
/// pixel's samples as packets of eight (kernels/shared/bvh8_packet.h), which needs the eight-wide
/// tree of blocks: on CPUs, whose SIMD lanes then hold eight rays. 0 elsewhere (a GPU's lanes are
/// already its work items). $TANDEM_CAMERA_PACKETS=0|1 overrides the choice where the tree allows
/// it. The same bits either way.
int camera_packets(const DeviceInfo& device, int width, int tri4);

/// The kernels of kernels/trace.cl, built once per context.
class Tracer {
public:
    /// `analytic`: build the traversal that also tests analytic spheres and disks (BVH_ANALYTIC),
    /// which a BVH of a mesh with them needs (closest and any throw Error for such a BVH
    /// otherwise); without, it is left out. `prefetch`: the eight-wide traversal's
    /// BVH_PREFETCH (bvh_prefetch).
    Tracer(Context& ctx, const KernelLibrary& lib, bool analytic = false, bool prefetch = false);

    /// Enqueues closest-hit traversal of rays[0..n) into hits (stage "trace closest").
    void closest(const DeviceBvh& bvh, const Buffer<gpu::Ray>& rays, Buffer<gpu::Hit>& hits);
    /// Enqueues closest-hit traversal of rays[0..n) into hits in packets of eight consecutive rays
    /// (kernels/shared/bvh8_packet.h; stage "trace closest"): the hits closest() gives. Needs the
    /// eight-wide tree of blocks (Error otherwise).
    void closest_packets(const DeviceBvh& bvh, const Buffer<gpu::Ray>& rays,
                         Buffer<gpu::Hit>& hits);
    /// Enqueues any-hit traversal of rays[0..n) into occluded (stage "trace any").
    void any(const DeviceBvh& bvh, const Buffer<gpu::Ray>& rays, Buffer<unsigned>& occluded);

    static constexpr const char* k_stage_closest = "trace closest";
    static constexpr const char* k_stage_any = "trace any";

private:
    void check_analytic(const DeviceBvh& bvh) const;

    Context& m_ctx;
    bool m_analytic;
    Program m_program;
    Kernel m_closest2, m_any2, m_closest4, m_any4, m_closest4_tri4, m_any4_tri4;
    Kernel m_closest8, m_any8, m_closest8_tri4, m_any8_tri4, m_closest8_packets;
};

} // namespace tandem
