// BVH construction with Embree's rtcBuildBVH (binned SAH) and depth-first flattening into the
// device layout of kernels/shared/bvh_layout.h.
#pragma once

#include <utility>
#include <vector>

#include "core/bvh/embree_device.h"
#include "core/scene/mesh.h"
#include "shared/bvh_layout.h"

namespace tandem {

/// How the leaves of a BVH hold their primitives: a BvhTriangle record each, or (four- and
/// eight-wide BVHs of triangles only) BvhTri4 blocks of four triangles that one ray tests with
/// float4 arithmetic, in the space of four records each (kernels/shared/bvh_layout.h).
enum class LeafFormat { records, tri4 };

/// The device-layout BVH: node 0 is the root; triangles are stored in leaf order. Three layouts
/// share the triangles and the traversal interface: the 64-byte two-wide BvhNode (the portable
/// baseline), the 128-byte four-wide Bvh4Node (float4 box tests) and the 256-byte eight-wide
/// Bvh8Node (float8 box tests; the fastest on CPUs).
struct FlatBvh {
    int width = 2;                      ///< 2, 4 or 8
    std::vector<gpu::BvhNode> nodes;    ///< width 2
    std::vector<gpu::Bvh4Node> nodes4;  ///< width 4
    std::vector<gpu::Bvh8Node> nodes8;  ///< width 8
    std::vector<gpu::BvhTriangle> triangles; ///< primitive records (BvhTriangle), leaf order
    bool tri4 = false;     ///< the leaves are BvhTri4 blocks in `triangles` (LeafFormat::tri4)
    bool analytic = false; ///< some records are spheres or disks (traversal needs BVH_ANALYTIC)
    int depth = 0;          ///< levels of nodes on the longest root-to-leaf path
    std::size_t leaves = 0; ///< number of leaves

    std::size_t node_count() const {
        return width == 8 ? nodes8.size() : (width == 4 ? nodes4.size() : nodes.size());
    }
    std::size_t node_bytes() const {
        return width == 8   ? nodes8.size() * sizeof(gpu::Bvh8Node)
               : width == 4 ? nodes4.size() * sizeof(gpu::Bvh4Node)
                            : nodes.size() * sizeof(gpu::BvhNode);
    }
};

/// The device record of primitive `prim` of `mesh` (kernels/shared/bvh_layout.h: BvhTriangle):
/// a triangle's vertices, a sphere's centre, radius and orientation, or a disk's centre, axes and
/// orientation, with `prim` in v0.w.
gpu::BvhTriangle primitive_record(const TriangleMesh& mesh, unsigned prim);

/// The box of a primitive record (primitive_record): a triangle's vertices, or a sphere's or a
/// disk's box widened by a few ulps (the hit points the kernels compute may leave the exact
/// surface by that much).
std::pair<glm::vec3, glm::vec3> record_bounds(const gpu::BvhTriangle& r);

/// The BvhTri4 block of `mesh`'s triangles prims[0, n) (n <= 4): lanes past n have id HIT_NONE
/// and every vertex at the origin.
gpu::BvhTri4 tri4_block(const TriangleMesh& mesh, const unsigned* prims, unsigned n);

/// The deepest tree a BVH of `width` may have (Embree's maxDepth; traversal stacks are sized by
/// it).
int bvh_max_depth(int width);

/// Builds the `width`-wide (2, 4 or 8) BVH of `mesh`'s triangles, spheres and disks (validated
/// first), its leaves in the format `leaves`: LeafFormat::tri4 needs width 4 or 8 and a mesh of
/// triangles only (Error otherwise), and its SAH counts a leaf's cost by blocks of four.
/// Embree's builder runs on its own worker threads; the result does not depend on their timing
/// (tests/core/bvh/test_bvh.cpp).
FlatBvh build_bvh(const EmbreeDevice& device, const TriangleMesh& mesh, int width = 2,
                  LeafFormat leaves = LeafFormat::records, bool repack = true);

/// The record of primitive i (0 <= i < count) of the leaf at `first`, whatever its format: the
/// BvhTriangle the leaf holds, or the one a BvhTri4 lane stands for.
gpu::BvhTriangle leaf_record(const FlatBvh& bvh, unsigned first, unsigned i);

/// Checks the structural invariants of a flattened BVH: every primitive appears in exactly one
/// leaf, child boxes contain their primitives and subtrees, links are in range, depth is within
/// bvh_max_depth(width); BvhTri4 leaves start at whole blocks, hold their primitives in increasing
/// id, and pad their last block with zero-area lanes of id HIT_NONE. Throws Error describing the
/// first violation.
void check_bvh(const FlatBvh& bvh, std::size_t primitive_count);

} // namespace tandem
