// Leaf repacking after Embree's build (core/bvh/bvh_build.cpp, step 3).
//
// Embree's builder fills each node to maxBranchingFactor children by splitting its child of
// largest area, whatever the SAH says of that split (only minLeafSize stops it), and it decides
// leaves with a node traversal cost that a free lane of the parent does not have. In scenes of
// large quads both show: the two triangles of a rectangle land in two leaves with the same box,
// so every ray that meets the rectangle tests both, while a wall and the small light beside it
// share one leaf whose box every shadow ray toward the light enters. (minLeafSize 2 keeps the
// pairs together, but also forces unrelated pairs, such as a sphere and the ground disk under
// it, into one large box.) So each inner node's leaf children are repacked afterwards by the SAH
// of their intersection tests alone, cost(leaf) = area(box) * tests(count), with tests(n) = n
// records or ceil(n / 4) blocks: first two leaves merge while area(A u B) * tests(nA + nB) <=
// area(A) * tests(nA) + area(B) * tests(nB) (best gain first); then, while the node has a free
// lane, the leaf whose best two-way split (primitives sorted by centroid on one axis) lowers
// its cost most is split. Lanes of one node are tested together, so a merge or a split changes
// no node visit. Hits do not depend on the tree (closest, then lowest id), so images keep their
// bits. docs/bvh.md says what it changes.
#pragma once

#include <memory>
#include <vector>

#include "core/bvh/build_tree.h"

namespace tandem {

class LeafRepacker {
public:
    /// `width`: children per node (2, 4 or 8); `block`: primitives per intersection test (4 for
    /// BvhTri4 leaves, else 1); `bounds`: each primitive's box, by id.
    LeafRepacker(unsigned width, unsigned block, const std::vector<RTCBounds>& bounds)
        : m_width(width), m_block(block), m_bounds(bounds) {}

    /// Repacks `node`'s subtrees, then its own leaf children. Returns what replaces `node` in its
    /// parent: `node` itself, or its only child when one remains. The leaves it makes live as
    /// long as the repacker.
    BuildNode* run(BuildInner* node);

private:
    struct Split;

    float tests(unsigned count) const {
        return static_cast<float>((count + m_block - 1) / m_block);
    }
    BuildLeaf* make_leaf(const unsigned* prims, unsigned count);
    bool merge_best(BuildInner* node);
    Split best_split(const BuildLeaf* leaf, const RTCBounds& box) const;
    bool split_best(BuildInner* node);

    unsigned m_width;
    unsigned m_block;
    const std::vector<RTCBounds>& m_bounds;
    std::vector<std::unique_ptr<unsigned char[]>> m_storage; ///< the leaves made here
};

} // namespace tandem
