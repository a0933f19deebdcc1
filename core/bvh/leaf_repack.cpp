// Leaf repacking after Embree's build: see leaf_repack.h.
#include "core/bvh/leaf_repack.h"

#include <algorithm>
#include <limits>
#include <new>

#include "shared/bvh_layout.h"

namespace tandem {

namespace {

float half_area(const RTCBounds& b) {
    const float dx = b.upper_x - b.lower_x, dy = b.upper_y - b.lower_y, dz = b.upper_z - b.lower_z;
    return dx * dy + dy * dz + dz * dx;
}

RTCBounds merged_bounds(const RTCBounds& a, const RTCBounds& b) {
    return RTCBounds{std::min(a.lower_x, b.lower_x), std::min(a.lower_y, b.lower_y),
                     std::min(a.lower_z, b.lower_z), 0.0f,
                     std::max(a.upper_x, b.upper_x), std::max(a.upper_y, b.upper_y),
                     std::max(a.upper_z, b.upper_z), 0.0f};
}

RTCBounds empty_bounds() {
    constexpr float inf = std::numeric_limits<float>::infinity();
    return RTCBounds{inf, inf, inf, 0.0f, -inf, -inf, -inf, 0.0f};
}

const BuildLeaf* leaf_at(const BuildInner* node, unsigned i) {
    return node->children[i]->is_leaf ? static_cast<const BuildLeaf*>(node->children[i]) : nullptr;
}

} // namespace

struct LeafRepacker::Split {
    float gain = 0.0f;
    std::vector<unsigned> order; ///< the leaf's primitives, sorted on the split axis
    unsigned left = 0;           ///< primitives in the first part
    RTCBounds lb{}, rb{};
};

BuildLeaf* LeafRepacker::make_leaf(const unsigned* prims, unsigned count) {
    m_storage.emplace_back(new unsigned char[sizeof(BuildLeaf) + (count - 1) * sizeof(unsigned)]);
    auto* leaf = new (m_storage.back().get()) BuildLeaf;
    leaf->is_leaf = true;
    leaf->count = count;
    std::copy(prims, prims + count, leaf->prims);
    std::sort(leaf->prims, leaf->prims + count); // canonical order, as create_leaf
    return leaf;
}

/// Merges the pair of leaf children with the largest gain >= 0; false when there is none.
bool LeafRepacker::merge_best(BuildInner* node) {
    bool found = false;
    float best_gain = 0.0f;
    unsigned bi = 0, bj = 0;
    for (unsigned i = 0; i < node->child_count; ++i) {
        const BuildLeaf* a = leaf_at(node, i);
        for (unsigned j = i + 1; a && j < node->child_count; ++j) {
            const BuildLeaf* b = leaf_at(node, j);
            if (!b || a->count + b->count > BVH_MAX_LEAF_SIZE) continue;
            const float apart = half_area(node->bounds[i]) * tests(a->count) +
                                half_area(node->bounds[j]) * tests(b->count);
            const float together = half_area(merged_bounds(node->bounds[i], node->bounds[j])) *
                                   tests(a->count + b->count);
            const float gain = apart - together;
            if (gain >= 0.0f && (!found || gain > best_gain))
                found = true, best_gain = gain, bi = i, bj = j;
        }
    }
    if (!found) return false;
    const BuildLeaf* a = leaf_at(node, bi);
    const BuildLeaf* b = leaf_at(node, bj);
    std::vector<unsigned> prims(a->prims, a->prims + a->count);
    prims.insert(prims.end(), b->prims, b->prims + b->count);
    node->children[bi] = make_leaf(prims.data(), static_cast<unsigned>(prims.size()));
    node->bounds[bi] = merged_bounds(node->bounds[bi], node->bounds[bj]);
    for (unsigned k = bj; k + 1 < node->child_count; ++k) {
        node->children[k] = node->children[k + 1];
        node->bounds[k] = node->bounds[k + 1];
    }
    node->child_count -= 1;
    return true;
}

/// The best split of `leaf` (box `box`) into two parts, by centroid order on one axis.
LeafRepacker::Split LeafRepacker::best_split(const BuildLeaf* leaf, const RTCBounds& box) const {
    Split best;
    const unsigned n = leaf->count;
    std::vector<unsigned> order(leaf->prims, leaf->prims + n);
    std::vector<RTCBounds> suffix(n + 1);
    for (int axis = 0; axis < 3; ++axis) {
        auto centre = [&](unsigned p) {
            const RTCBounds& b = m_bounds[p];
            const float lo[3] = {b.lower_x, b.lower_y, b.lower_z};
            const float hi[3] = {b.upper_x, b.upper_y, b.upper_z};
            return lo[axis] + hi[axis];
        };
        // ties by id: the order, and so the tree, does not depend on the sort's internals
        std::sort(order.begin(), order.end(), [&](unsigned x, unsigned y) {
            const float cx = centre(x), cy = centre(y);
            return cx < cy || (cx == cy && x < y);
        });
        suffix[n] = empty_bounds();
        for (unsigned k = n; k-- > 0;)
            suffix[k] = merged_bounds(suffix[k + 1], m_bounds[order[k]]);
        RTCBounds prefix = empty_bounds();
        for (unsigned k = 1; k < n; ++k) {
            prefix = merged_bounds(prefix, m_bounds[order[k - 1]]);
            const float gain = half_area(box) * tests(n) -
                               (half_area(prefix) * tests(k) + half_area(suffix[k]) * tests(n - k));
            if (gain > best.gain) best = Split{gain, order, k, prefix, suffix[k]};
        }
    }
    return best;
}

/// Splits the leaf child whose best split gains most (> 0) into a free lane; false when the
/// node is full or no split gains.
bool LeafRepacker::split_best(BuildInner* node) {
    if (node->child_count >= m_width) return false;
    Split best;
    unsigned at = 0;
    for (unsigned i = 0; i < node->child_count; ++i) {
        const BuildLeaf* leaf = leaf_at(node, i);
        if (!leaf || leaf->count < 2) continue;
        Split s = best_split(leaf, node->bounds[i]);
        if (s.gain > best.gain) best = std::move(s), at = i;
    }
    if (best.gain <= 0.0f) return false;
    const unsigned n = static_cast<unsigned>(best.order.size());
    node->children[at] = make_leaf(best.order.data(), best.left);
    node->bounds[at] = best.lb;
    node->children[node->child_count] = make_leaf(best.order.data() + best.left, n - best.left);
    node->bounds[node->child_count] = best.rb;
    node->child_count += 1;
    return true;
}

/// Repacks `node`'s subtrees, then its own leaf children. Returns what replaces `node` in its
/// parent: `node` itself, or its only child when one remains.
BuildNode* LeafRepacker::run(BuildInner* node) {
    for (unsigned i = 0; i < node->child_count; ++i)
        if (!node->children[i]->is_leaf)
            node->children[i] = run(static_cast<BuildInner*>(node->children[i]));
    while (merge_best(node)) {
    }
    while (split_best(node)) {
    }
    return node->child_count == 1 ? node->children[0] : node;
}

} // namespace tandem
