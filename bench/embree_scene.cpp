// Embree reference scene: rtcIntersect1 / rtcOccluded1 and packet variants over a thread pool.
#include "bench/embree_scene.h"

#include <algorithm>
#include <atomic>
#include <memory>
#include <cstring>
#include <limits>
#include <thread>

#include "runtime/error.h"

namespace tandem {

const char* embree_mode_name(EmbreeMode mode, bool closest) {
    switch (mode) {
    case EmbreeMode::single: return closest ? "rtcIntersect1" : "rtcOccluded1";
    case EmbreeMode::packet8: return closest ? "rtcIntersect8" : "rtcOccluded8";
    case EmbreeMode::packet16: return closest ? "rtcIntersect16" : "rtcOccluded16";
    }
    return "?";
}

EmbreeScene::EmbreeScene(const EmbreeDevice& device, const TriangleMesh& mesh, bool robust) {
    validate_mesh(mesh);
    // Owned locally until the end, so an error on the way releases both.
    std::unique_ptr<RTCSceneTy, void (*)(RTCScene)> scene(rtcNewScene(device.get()), rtcReleaseScene);
    std::unique_ptr<RTCGeometryTy, void (*)(RTCGeometry)> geom(
        rtcNewGeometry(device.get(), RTC_GEOMETRY_TYPE_TRIANGLE), rtcReleaseGeometry);
    device.check("rtcNewScene");
    if (robust) rtcSetSceneFlags(scene.get(), RTC_SCENE_FLAG_ROBUST);
    auto* verts = static_cast<float*>(rtcSetNewGeometryBuffer(geom.get(), RTC_BUFFER_TYPE_VERTEX, 0,
                                                              RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                                              mesh.positions.size()));
    auto* tris = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom.get(), RTC_BUFFER_TYPE_INDEX, 0,
                                                                RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                                                mesh.triangles.size()));
    device.check("rtcSetNewGeometryBuffer");
    std::memcpy(verts, mesh.positions.data(), mesh.positions.size() * 3 * sizeof(float));
    std::memcpy(tris, mesh.triangles.data(), mesh.triangles.size() * 3 * sizeof(unsigned));
    rtcCommitGeometry(geom.get());
    rtcAttachGeometry(scene.get(), geom.get());
    rtcCommitScene(scene.get());
    device.check(("Embree scene build for " + mesh.source).c_str());
    m_scene = scene.release();
}

EmbreeScene::~EmbreeScene() { rtcReleaseScene(m_scene); }

namespace {

void to_rtc(const gpu::Ray& r, RTCRay& out) {
    out.org_x = r.org.x;
    out.org_y = r.org.y;
    out.org_z = r.org.z;
    out.tnear = r.org.w;
    out.dir_x = r.dir.x;
    out.dir_y = r.dir.y;
    out.dir_z = r.dir.z;
    out.tfar = r.dir.w;
    out.time = 0.0f;
    out.mask = 0xFFFFFFFFu;
    out.id = 0;
    out.flags = 0;
}

/// Runs body(begin, end) over [0, n) on `threads` host threads that take chunks of 4096 items
/// from a shared counter (dynamic scheduling, so no thread idles while another has work left).
/// Threads are started per batch; that costs tens of microseconds against batches of
/// milliseconds.
template <class F> void parallel_chunks(std::size_t n, int threads, F&& body) {
    constexpr std::size_t chunk = 4096;
    std::atomic<std::size_t> next{0};
    auto worker = [&] {
        for (std::size_t begin; (begin = next.fetch_add(chunk)) < n;)
            body(begin, std::min(n, begin + chunk));
    };
    std::vector<std::thread> pool;
    for (int t = 1; t < std::max(1, threads); ++t) pool.emplace_back(worker);
    worker();
    for (std::thread& th : pool) th.join();
}

// Packet types and entry points by width.
template <int N> struct Packet;
template <> struct Packet<8> {
    using RayHit = RTCRayHit8;
    using RayN = RTCRay8;
    static void intersect(const int* valid, RTCScene s, RTCIntersectContext* c, RayHit* rh) {
        rtcIntersect8(valid, s, c, rh);
    }
    static void occluded(const int* valid, RTCScene s, RTCIntersectContext* c, RayN* r) {
        rtcOccluded8(valid, s, c, r);
    }
};
template <> struct Packet<16> {
    using RayHit = RTCRayHit16;
    using RayN = RTCRay16;
    static void intersect(const int* valid, RTCScene s, RTCIntersectContext* c, RayHit* rh) {
        rtcIntersect16(valid, s, c, rh);
    }
    static void occluded(const int* valid, RTCScene s, RTCIntersectContext* c, RayN* r) {
        rtcOccluded16(valid, s, c, r);
    }
};

template <class R> void fill_packet(R& p, int k, const gpu::Ray& r) {
    p.org_x[k] = r.org.x;
    p.org_y[k] = r.org.y;
    p.org_z[k] = r.org.z;
    p.tnear[k] = r.org.w;
    p.dir_x[k] = r.dir.x;
    p.dir_y[k] = r.dir.y;
    p.dir_z[k] = r.dir.z;
    p.tfar[k] = r.dir.w;
    p.time[k] = 0.0f;
    p.mask[k] = 0xFFFFFFFFu;
    p.id[k] = 0;
    p.flags[k] = 0;
}

} // namespace

gpu::Hit EmbreeScene::intersect(const gpu::Ray& ray) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh;
    to_rtc(ray, rh.ray);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(m_scene, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return gpu::Hit{ray.dir.w, HIT_NONE, 0.0f, 0.0f};
    return gpu::Hit{rh.ray.tfar, rh.hit.primID, rh.hit.u, rh.hit.v};
}

bool EmbreeScene::occluded(const gpu::Ray& ray) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRay r;
    to_rtc(ray, r);
    rtcOccluded1(m_scene, &ctx, &r);
    return r.tfar < 0.0f; // Embree sets tfar to -inf on occlusion
}

template <int N>
void EmbreeScene::intersect_packets(const gpu::Ray* rays, gpu::Hit* hits, std::size_t n) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    alignas(64) typename Packet<N>::RayHit rh;
    alignas(64) int valid[N];
    for (std::size_t base = 0; base < n; base += N) {
        const int m = static_cast<int>(std::min<std::size_t>(N, n - base));
        for (int k = 0; k < N; ++k) {
            valid[k] = k < m ? -1 : 0;
            fill_packet(rh.ray, k, rays[base + std::min(k, m - 1)]);
            rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
        }
        Packet<N>::intersect(valid, m_scene, &ctx, &rh);
        for (int k = 0; k < m; ++k)
            hits[base + k] = rh.hit.geomID[k] == RTC_INVALID_GEOMETRY_ID
                                 ? gpu::Hit{rays[base + k].dir.w, HIT_NONE, 0.0f, 0.0f}
                                 : gpu::Hit{rh.ray.tfar[k], rh.hit.primID[k], rh.hit.u[k], rh.hit.v[k]};
    }
}

template <int N>
void EmbreeScene::occluded_packets(const gpu::Ray* rays, unsigned* occ, std::size_t n) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    alignas(64) typename Packet<N>::RayN r;
    alignas(64) int valid[N];
    for (std::size_t base = 0; base < n; base += N) {
        const int m = static_cast<int>(std::min<std::size_t>(N, n - base));
        for (int k = 0; k < N; ++k) {
            valid[k] = k < m ? -1 : 0;
            fill_packet(r, k, rays[base + std::min(k, m - 1)]);
        }
        Packet<N>::occluded(valid, m_scene, &ctx, &r);
        for (int k = 0; k < m; ++k) occ[base + k] = r.tfar[k] < 0.0f ? 1u : 0u;
    }
}

void EmbreeScene::intersect(const std::vector<gpu::Ray>& rays, std::vector<gpu::Hit>& hits,
                            int threads, EmbreeMode mode) const {
    hits.resize(rays.size());
    parallel_chunks(rays.size(), threads, [&](std::size_t b, std::size_t e) {
        switch (mode) {
        case EmbreeMode::single:
            for (std::size_t i = b; i < e; ++i) hits[i] = intersect(rays[i]);
            break;
        case EmbreeMode::packet8: intersect_packets<8>(&rays[b], &hits[b], e - b); break;
        case EmbreeMode::packet16: intersect_packets<16>(&rays[b], &hits[b], e - b); break;
        }
    });
}

void EmbreeScene::occluded(const std::vector<gpu::Ray>& rays, std::vector<unsigned>& occ,
                           int threads, EmbreeMode mode) const {
    occ.resize(rays.size());
    parallel_chunks(rays.size(), threads, [&](std::size_t b, std::size_t e) {
        switch (mode) {
        case EmbreeMode::single:
            for (std::size_t i = b; i < e; ++i) occ[i] = occluded(rays[i]) ? 1u : 0u;
            break;
        case EmbreeMode::packet8: occluded_packets<8>(&rays[b], &occ[b], e - b); break;
        case EmbreeMode::packet16: occluded_packets<16>(&rays[b], &occ[b], e - b); break;
        }
    });
}

} // namespace tandem
