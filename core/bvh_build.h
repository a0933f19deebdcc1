// BVH construction with Embree's rtcBuildBVH (binned SAH) and depth-first flattening into the
// device layout of kernels/shared/bvh_layout.h.
#pragma once

#include <vector>

#include "core/embree_device.h"
#include "core/mesh.h"
#include "shared/bvh_layout.h"

namespace tandem {

/// The device-layout BVH: node 0 is the root; triangles are stored in leaf order.
struct FlatBvh {
    std::vector<gpu::BvhNode> nodes;
    std::vector<gpu::BvhTriangle> triangles;
    int depth = 0;          ///< levels of nodes on the longest root-to-leaf path
    std::size_t leaves = 0; ///< number of leaves
};

/// Builds the BVH of `mesh` (validated first). Embree's builder runs on its own worker threads;
/// the result does not depend on their timing (tests/core/test_bvh.cpp checks two builds match).
FlatBvh build_bvh(const EmbreeDevice& device, const TriangleMesh& mesh);

/// Checks the structural invariants of a flattened BVH: every triangle appears in exactly one
/// leaf, child boxes contain their triangles and subtrees, links are in range, depth is within
/// BVH_MAX_DEPTH. Throws Error describing the first violation.
void check_bvh(const FlatBvh& bvh, std::size_t triangle_count);

} // namespace tandem
