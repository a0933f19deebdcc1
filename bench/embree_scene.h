// Embree's own BVH and intersectors over a mesh: the reference that the device traversal is tested
// and benchmarked against.
#pragma once

#include <vector>

#include "core/bvh/embree_device.h"
#include "core/scene/mesh.h"
#include "shared/bvh_layout.h"

namespace tandem {

/// How Embree traces a batch: one ray at a time (rtcIntersect1/rtcOccluded1), or 8- or 16-wide
/// packets (rtcIntersect8/16), each from a pool of host threads.
enum class EmbreeMode { single, packet8, packet16 };
/// The Embree entry point of `mode`: rtcIntersect1/8/16, or rtcOccluded1/8/16 when !closest.
const char* embree_mode_name(EmbreeMode mode, bool closest = true);

class EmbreeScene {
public:
    /// Builds Embree's scene over `mesh`. `robust` sets RTC_SCENE_FLAG_ROBUST: conservative box
    /// tests, needed for a trustworthy reference far from the origin; without it Embree runs its
    /// default, fastest mode (what the benchmark compares against).
    EmbreeScene(const EmbreeDevice& device, const TriangleMesh& mesh, bool robust);
    ~EmbreeScene();
    EmbreeScene(const EmbreeScene&) = delete;
    EmbreeScene& operator=(const EmbreeScene&) = delete;

    gpu::Hit intersect(const gpu::Ray& ray) const;
    bool occluded(const gpu::Ray& ray) const;

    /// Closest hits of all rays, split into contiguous chunks over `threads` host threads.
    void intersect(const std::vector<gpu::Ray>& rays, std::vector<gpu::Hit>& hits, int threads,
                   EmbreeMode mode) const;
    /// Occlusion (1 or 0) of all rays, same threading.
    void occluded(const std::vector<gpu::Ray>& rays, std::vector<unsigned>& occluded, int threads,
                  EmbreeMode mode) const;

private:
    template <int N> void intersect_packets(const gpu::Ray* rays, gpu::Hit* hits, std::size_t n) const;
    template <int N> void occluded_packets(const gpu::Ray* rays, unsigned* occ, std::size_t n) const;

    RTCScene m_scene = nullptr;
};

} // namespace tandem
