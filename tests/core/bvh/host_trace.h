// The host's traversal of a flattened BVH of any width and leaf format: the kernels' shared code
// (kernels/shared/bvh8_traverse.h), for the BVH tests.
#pragma once

#include "core/bvh/bvh_build.h"
#include "shared/bvh8_traverse.h"

namespace tandem::test {

/// The host's closest hit over a BVH of any width and leaf format (the kernels' shared code).
inline gpu::Hit host_closest(const FlatBvh& bvh, const gpu::Ray& ray) {
    if (bvh.width == 8)
        return gpu::bvh8_intersect_closest(bvh.nodes8.data(), bvh.triangles.data(), ray, bvh.tri4);
    if (bvh.width == 4)
        return gpu::bvh4_intersect_closest(bvh.nodes4.data(), bvh.triangles.data(), ray, bvh.tri4);
    return gpu::bvh_intersect_closest(bvh.nodes.data(), bvh.triangles.data(), ray);
}

/// The host's any-hit query over a BVH of any width and leaf format.
inline int host_any(const FlatBvh& bvh, const gpu::Ray& ray) {
    if (bvh.width == 8)
        return gpu::bvh8_intersect_any(bvh.nodes8.data(), bvh.triangles.data(), ray, bvh.tri4);
    if (bvh.width == 4)
        return gpu::bvh4_intersect_any(bvh.nodes4.data(), bvh.triangles.data(), ray, bvh.tri4);
    return gpu::bvh_intersect_any(bvh.nodes.data(), bvh.triangles.data(), ray);
}

} // namespace tandem::test
