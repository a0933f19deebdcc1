// The device policy: how a scene is traced and rendered on one device at its film size (the
// BVH's layout and leaves, prefetching, camera packets, the wavefront or the megakernels, what the
// adjoint records). Decided here, once per scene, device and film size, from the device's
// properties and the switches of a Tuning; a DeviceScene keeps the decision and the passes read
// it. The kernels see it as build flags (features.h). Every choice gives the same bits.
#pragma once

#include <cstddef>

#include "core/bvh/bvh_build.h"
#include "runtime/build_flags.h"
#include "runtime/device.h"
#include "runtime/tuning.h"

namespace tandem {

/// What the policy decided for one scene.
struct DevicePolicy {
    /// BVH_WIDTH: the BVH layout, 2, 4 or 8 children per node.
    int bvh_width = 2;
    /// BVH_TRI4: leaves of BvhTri4 blocks, four triangles per float4 test (four- and eight-wide
    /// trees of scenes without analytic shapes), rather than a record per triangle.
    bool tri4_leaves = false;
    /// BVH_AXIS_LOOPS: the triangle test's leaf loops copied per dominant axis.
    bool axis_loops = false;
    /// BVH_PREFETCH: a node visit of the eight-wide traversal prefetches the children the ray
    /// enters.
    bool prefetch = false;
    /// CAMERA_PACKETS: the render pass traces the camera rays of up to eight samples of a pixel
    /// as one packet.
    bool camera_packets = false;
    /// Whether the BVH build repacks Embree's leaves (core/bvh/leaf_repack.h).
    bool repack = true;
    /// WAVEFRONT, where the wavefront covers the scene (wavefront_supported): the passes run
    /// stage by stage over all paths (core/render/wavefront.h); otherwise as megakernels.
    bool wavefront = false;
    /// SHADOW_RECORD: the adjoint's replay reads its primal's record of the NEE shadow rays.
    bool shadow_record = true;
    /// The most bounces whose hits the megakernel adjoint records for its replay
    /// (passes.h: adjoint_launches).
    unsigned hit_record_bounces = k_max_hit_record_bounces;
    /// The most bounces the wavefront adjoint records for its replay (deeper ones are traced
    /// again).
    unsigned wavefront_record_bounces = 16;
};

/// What the scene's BVH and render are for: gradient work (the PRB adjoint and the two-state
/// render, which share one tree with the primal), or a forward render alone (`tandem render`,
/// `tandem bench render`), which may take another layout.
enum class Workload { gradient, forward };

// ---- The device's own rules (what the policy decides where the Tuning forces nothing) ----

/// BVH_AXIS_LOOPS for `device` (kernels/shared/bvh_traverse.h): 1 on CPUs, where one copy of the
/// triangle test per dominant axis saves the per-triangle axis selects; 0 elsewhere: on a SIMT GPU
/// the copies would run one after another for the rays of a warp.
int bvh_axis_loops(const DeviceInfo& device);

/// The BVH layout of gradient work on `device`: 8 on CPUs whose native float vector holds 8 or
/// more (AVX, AVX2, AVX-512), where its float8 box tests are one instruction per operation; 4 on
/// other CPUs (SSE, NEON), whose float4 tests beat BVH2; 2 elsewhere. On GPUs, the eight-wide
/// tree helped some gradient kernels and slowed the fused two-state kernel, and `tandem optimize`
/// runs both on one tree: gradient work keeps 2 there.
int preferred_bvh_width(const DeviceInfo& device);

/// The BVH layout of a forward render on `device` of a scene with or without analytic spheres and
/// disks: preferred_bvh_width on CPUs; on GPUs 8 for scenes of triangles only, and 2 for scenes
/// with analytic shapes, which the eight-wide tree slowed down.
int forward_bvh_width(const DeviceInfo& device, bool analytic);

/// Meshes of at least this many triangles get BvhTri4 leaves in four-wide BVHs on CPUs
/// (preferred_leaf_format).
constexpr std::size_t k_tri4_min_triangles = 1024;

/// The leaf format for a `width`-wide BVH of `triangles` triangles (of a mesh without analytic
/// shapes) on `device`. On CPUs, BvhTri4 blocks for every eight-wide tree, and for four-wide trees
/// of meshes of k_tri4_min_triangles or more, whose rays one float4 test of four triangles and an
/// SAH that counts blocks trace faster; four-wide trees of a few dozen large triangles whose boxes
/// overlap (the bundled rooms) render faster with records. A record each elsewhere: two-wide
/// trees, and GPUs, where a SIMT lane would run the four tests one after another.
LeafFormat preferred_leaf_format(const DeviceInfo& device, std::size_t triangles, int width);

/// Meshes of at least this many triangles get BVH_PREFETCH on CPUs (prefers_prefetch).
constexpr std::size_t k_prefetch_min_triangles = 16384;

/// BVH_PREFETCH for a `width`-wide BVH of `triangles` triangles on `device`
/// (kernels/shared/bvh8_traverse.h): on CPUs for eight-wide trees of meshes of
/// k_prefetch_min_triangles or more, whose trees outgrow the caches; smaller trees stay in the
/// cache, where the prefetches are instructions for nothing. Not elsewhere: four-wide trees, and
/// GPUs, where thousands of rays in flight hide the latency.
bool prefers_prefetch(const DeviceInfo& device, std::size_t triangles, int width);

/// CAMERA_PACKETS: on CPUs, whose SIMD lanes then hold eight rays, where the tree allows it (the
/// eight-wide tree of blocks); not on GPUs, whose lanes are already its work items.
bool prefers_camera_packets(const DeviceInfo& device, int width, bool tri4);

/// Films of at least this many pixels render with the wavefront where wavefront_faster says it is
/// the faster form: a wave is one sample of every pixel, and each bounce of a wave costs launches
/// and a read of the live count whatever the number of paths, which smaller films do not repay.
constexpr std::size_t k_wavefront_min_pixels = 256 * 256;

/// Whether the wavefront is the faster form on `device` for a scene it supports, of a film of
/// `pixels` pixels: where PoCL vectorises its shading stages (runtime/pocl_llvm.h:
/// pocl_widens_gathers, a CPU with AVX-512), every material is diffuse (other materials' stage
/// is one path per work item, slower than the megakernels), and the film has at least
/// k_wavefront_min_pixels. On an AVX2 CPU its shading stays scalar and computes both sides of
/// every select: the megakernels are faster there.
bool wavefront_faster(const BuildFlags& features, const DeviceInfo& device, std::size_t pixels);

// ---- The decision ----

/// The policy for a scene whose content flags (and LIGHT_STRATEGY) are `content`, of `triangles`
/// triangles and a film of `pixels` pixels, on `device`, for `work`: the device's rules above,
/// except where `tuning` forces a choice, and a BVH width of `bvh_width` where it is not 0 (a
/// caller's own, before the tuning's).
DevicePolicy decide_policy(const BuildFlags& content, std::size_t triangles, std::size_t pixels,
                           const DeviceInfo& device, const Tuning& tuning,
                           Workload work = Workload::gradient, int bvh_width = 0);

/// Sets the kernels' view of `policy`: BVH_WIDTH, BVH_TRI4, BVH_AXIS_LOOPS, BVH_PREFETCH,
/// CAMERA_PACKETS, WAVEFRONT and SHADOW_RECORD.
void set_policy_flags(const DevicePolicy& policy, BuildFlags& flags);

/// The policy of a device scene built with `features` (which its caller may have changed after
/// render_features chose them): the choices the flags say, the wavefront only where it covers
/// the flags (wavefront_supported: a flag set on top, such as a BSDF or RESTIR's light strategy,
/// may rule it out), and the host's own choices from `tuning` (repacking, what the adjoints
/// record).
DevicePolicy policy_of(const BuildFlags& features, const Tuning& tuning);

} // namespace tandem
