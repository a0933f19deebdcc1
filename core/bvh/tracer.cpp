// Host driver of kernels/trace.cl.
#include "core/bvh/tracer.h"

namespace tandem {

DeviceBvh::DeviceBvh(Context& ctx, const FlatBvh& bvh)
    : width(bvh.width),
      nodes(ctx, "bvh nodes", bvh.width == 2 ? bvh.nodes : std::vector<gpu::BvhNode>(1),
            CL_MEM_READ_ONLY),
      nodes4(ctx, "bvh nodes", bvh.width == 4 ? bvh.nodes4 : std::vector<gpu::Bvh4Node>(1),
             CL_MEM_READ_ONLY),
      triangles(ctx, "bvh triangles", bvh.triangles, CL_MEM_READ_ONLY) {}

int preferred_bvh_width(const DeviceInfo& device) { return device.type == "CPU" ? 4 : 2; }

Tracer::Tracer(Context& ctx, const KernelLibrary& lib)
    : m_ctx(ctx), m_program(Program::build(ctx, lib, "trace.cl", "")),
      m_closest2(m_program, "trace_closest_bvh2"), m_any2(m_program, "trace_any_bvh2"),
      m_closest4(m_program, "trace_closest_bvh4"), m_any4(m_program, "trace_any_bvh4") {}

namespace {

void check_output_size(const char* what, std::size_t have, std::size_t rays) {
    if (have < rays)
        throw Error(std::string("trace: '") + what + "' holds " + std::to_string(have) +
                    " results for " + std::to_string(rays) + " rays");
}

} // namespace

void Tracer::closest(const DeviceBvh& bvh, const Buffer<gpu::Ray>& rays, Buffer<gpu::Hit>& hits) {
    check_output_size(hits.name().c_str(), hits.size(), rays.size());
    const auto n = static_cast<unsigned>(rays.size());
    if (bvh.width == 4)
        m_closest4.launch(m_ctx, k_stage_closest, n, bvh.nodes4, bvh.triangles, rays, hits, n);
    else
        m_closest2.launch(m_ctx, k_stage_closest, n, bvh.nodes, bvh.triangles, rays, hits, n);
}

void Tracer::any(const DeviceBvh& bvh, const Buffer<gpu::Ray>& rays, Buffer<unsigned>& occluded) {
    check_output_size(occluded.name().c_str(), occluded.size(), rays.size());
    const auto n = static_cast<unsigned>(rays.size());
    if (bvh.width == 4)
        m_any4.launch(m_ctx, k_stage_any, n, bvh.nodes4, bvh.triangles, rays, occluded, n);
    else
        m_any2.launch(m_ctx, k_stage_any, n, bvh.nodes, bvh.triangles, rays, occluded, n);
}

} // namespace tandem
