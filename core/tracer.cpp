// Host driver of kernels/trace.cl.
#include "core/tracer.h"

namespace tandem {

Tracer::Tracer(Context& ctx, const KernelLibrary& lib)
    : m_ctx(ctx), m_program(Program::build(ctx, lib, "trace.cl", "-cl-std=CL1.2")),
      m_closest(m_program, "trace_closest"), m_any(m_program, "trace_any") {}

void Tracer::closest(const DeviceBvh& bvh, const Buffer<gpu::Ray>& rays, Buffer<gpu::Hit>& hits) {
    const auto n = static_cast<unsigned>(rays.size());
    m_closest.launch(m_ctx, k_stage_closest, n, bvh.nodes, bvh.triangles, rays, hits, n);
}

void Tracer::any(const DeviceBvh& bvh, const Buffer<gpu::Ray>& rays, Buffer<unsigned>& occluded) {
    const auto n = static_cast<unsigned>(rays.size());
    m_any.launch(m_ctx, k_stage_any, n, bvh.nodes, bvh.triangles, rays, occluded, n);
}

} // namespace tandem
