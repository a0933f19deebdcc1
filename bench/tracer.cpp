// Host driver of bench/kernels/trace.cl.
#include "bench/tracer.h"
#include "core/render/policy.h"

#include <string>

namespace tandem {

/// The files of bench/kernels, each named k_bench_kernels + its name (generated at build time:
/// bench/CMakeLists.txt).
const EmbeddedFile* bench_kernel_files(std::size_t* count);

namespace {
constexpr const char* k_bench_kernels = "bench/";
} // namespace

namespace {

/// `lib` with bench/kernels in front: trace.cl includes the product's shared headers.
KernelLibrary bench_kernels(const KernelLibrary& lib) {
    std::size_t count = 0;
    const EmbeddedFile* files = bench_kernel_files(&count);
    return lib.with_files(files, count);
}

} // namespace

Tracer::Tracer(Context& ctx, const KernelLibrary& lib, bool analytic, bool prefetch)
    : m_ctx(ctx), m_analytic(analytic),
      m_program(Program::build(ctx, bench_kernels(lib), std::string(k_bench_kernels) + "trace.cl",
                               "-D BVH_AXIS_LOOPS=" + std::to_string(bvh_axis_loops(ctx.device())) +
                                   " -D BVH_ANALYTIC=" + (analytic ? "1" : "0") +
                                   " -D BVH_PREFETCH=" + (prefetch ? "1" : "0"))),
      m_closest2(m_program, "trace_closest_bvh2"), m_any2(m_program, "trace_any_bvh2"),
      m_closest4(m_program, "trace_closest_bvh4"), m_any4(m_program, "trace_any_bvh4"),
      m_closest4_tri4(m_program, "trace_closest_bvh4_tri4"),
      m_any4_tri4(m_program, "trace_any_bvh4_tri4"), m_closest8(m_program, "trace_closest_bvh8"),
      m_any8(m_program, "trace_any_bvh8"), m_closest8_tri4(m_program, "trace_closest_bvh8_tri4"),
      m_any8_tri4(m_program, "trace_any_bvh8_tri4"),
      m_closest8_packets(m_program, "trace_closest_packets_bvh8_tri4") {}

namespace {

void check_output_size(const char* what, std::size_t have, std::size_t rays) {
    if (have < rays)
        throw Error(std::string("trace: '") + what + "' holds " + std::to_string(have) +
                    " results for " + std::to_string(rays) + " rays");
}

} // namespace

void Tracer::check_analytic(const DeviceBvh& bvh) const {
    if (bvh.analytic && !m_analytic)
        throw Error("trace: the BVH holds analytic spheres or disks; build the Tracer with analytic = true");
}

void Tracer::closest(const DeviceBvh& bvh, const Buffer<gpu::Ray>& rays, Buffer<gpu::Hit>& hits) {
    check_analytic(bvh);
    check_output_size(hits.name().c_str(), hits.size(), rays.size());
    const auto n = static_cast<unsigned>(rays.size());
    (bvh.width == 8   ? (bvh.tri4 ? m_closest8_tri4 : m_closest8)
     : bvh.width == 4 ? (bvh.tri4 ? m_closest4_tri4 : m_closest4)
                      : m_closest2)
        .launch(m_ctx, k_stage_closest, n, bvh.nodes, bvh.triangles, rays, hits, n);
}

void Tracer::closest_packets(const DeviceBvh& bvh, const Buffer<gpu::Ray>& rays,
                             Buffer<gpu::Hit>& hits) {
    check_analytic(bvh);
    if (bvh.width != 8 || !bvh.tri4 || bvh.analytic)
        throw Error("closest_packets: packets of rays need the eight-wide tree of blocks");
    check_output_size(hits.name().c_str(), hits.size(), rays.size());
    const auto n = static_cast<unsigned>(rays.size());
    m_closest8_packets.launch(m_ctx, k_stage_closest, (n + 7) / 8, bvh.nodes, bvh.triangles, rays,
                              hits, n);
}

void Tracer::any(const DeviceBvh& bvh, const Buffer<gpu::Ray>& rays, Buffer<unsigned>& occluded) {
    check_analytic(bvh);
    check_output_size(occluded.name().c_str(), occluded.size(), rays.size());
    const auto n = static_cast<unsigned>(rays.size());
    (bvh.width == 8   ? (bvh.tri4 ? m_any8_tri4 : m_any8)
     : bvh.width == 4 ? (bvh.tri4 ? m_any4_tri4 : m_any4)
                      : m_any2)
        .launch(m_ctx, k_stage_any, n, bvh.nodes, bvh.triangles, rays, occluded, n);
}

} // namespace tandem
