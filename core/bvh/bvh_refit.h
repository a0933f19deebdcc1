// Refitting a built BVH to moved vertices: the tree kept, its records and boxes recomputed.
// Shape optimization moves every vertex a little each iteration; a refit costs a pass over the
// nodes where a build sorts the primitives, and leaves the traversal's results as they were
// (the closest hit does not depend on the tree: kernels/shared/bvh_layout.h, Hit), only its
// speed, which the SAH cost below tracks.
#pragma once

#include "core/bvh/bvh_build.h"

namespace tandem {

/// Rewrites every primitive record of `bvh` from `mesh` (the mesh it was built from, its vertices
/// moved: the same primitives) and every child box as the union of what the child holds, bottom
/// up, in place. The boxes are those a build computes for the same leaves (record_bounds, then
/// minima and maxima), so check_bvh holds after it.
void refit_bvh(FlatBvh& bvh, const TriangleMesh& mesh);

/// The tree's SAH cost relative to its root box: the sum over the child boxes of every node of
/// their surface areas over the root's (each the probability that a random ray through the root
/// crosses that box), plus, for the leaves, the same ratio times their primitive count (triangle
/// by triangle, in either leaf format). A measure of drift, compared between trees of one
/// layout: a refit tree's cost grows as the vertices move away from where it was built.
double bvh_sah_cost(const FlatBvh& bvh);

} // namespace tandem
