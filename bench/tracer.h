// The closest-hit and any-hit trace kernels (bench/kernels/trace.cl) over a device BVH: the device
// traversal on its own, which `tandem bench trace` times and tests/kernels/test_trace.cpp checks
// against Embree (bench/embree_scene.h). Not part of the product: the render kernels traverse the
// BVH themselves.
#pragma once

#include "core/bvh/device_bvh.h"
#include "runtime/kernel_source.h"
#include "runtime/launch.h"

namespace tandem {

/// The kernels of bench/kernels/trace.cl, built once per context.
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
