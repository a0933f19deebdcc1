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

/// BVH_AXIS_LOOPS for `device` (kernels/shared/bvh_traverse.h): 1 on CPUs, where one copy of the
/// triangle test per dominant axis saves the per-triangle axis selects; 0 elsewhere: on a SIMT GPU
/// the copies would run one after another for the rays of a warp. (The rest of the device policy
/// is core/render/policy.h's.)
int bvh_axis_loops(const DeviceInfo& device);

/// The kernels of kernels/trace.cl, built once per context.
class Tracer {
public:
    /// `analytic`: build the traversal that also tests analytic spheres and disks (BVH_ANALYTIC),
    /// which a BVH of a mesh with them needs (closest and any throw Error for such a BVH
    /// otherwise); without, it is left out. `prefetch`: the eight-wide traversal's
    /// BVH_PREFETCH (core/render/policy.h: prefers_prefetch).
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
