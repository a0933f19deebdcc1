// Refitting a built BVH to moved vertices (core/bvh/bvh_refit.h).
#include "core/bvh/bvh_refit.h"

#include <algorithm>
#include <cstring>
#include <limits>

#include "runtime/error.h"

namespace tandem {

namespace {

struct Box {
    glm::vec3 lo{std::numeric_limits<float>::infinity()};
    glm::vec3 hi{-std::numeric_limits<float>::infinity()};
    void extend(const Box& b) {
        lo = glm::min(lo, b.lo);
        hi = glm::max(hi, b.hi);
    }
    double area() const {
        const glm::dvec3 d = glm::max(glm::dvec3(hi) - glm::dvec3(lo), glm::dvec3(0.0));
        return 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
    }
};

/// One child slot of a node of any width: its box and links, read and written in place.
struct Slot {
    float *lo[3], *hi[3];
    unsigned link, count;
    Box box() const { return {{*lo[0], *lo[1], *lo[2]}, {*hi[0], *hi[1], *hi[2]}}; }
    void set(const Box& b) const {
        for (int a = 0; a < 3; ++a) *lo[a] = b.lo[a], *hi[a] = b.hi[a];
    }
};

/// The used slots of node `index` (an unused lane of a four- or eight-wide node links nothing:
/// child and count 0, node 0 being the root; a two-wide node with one child links it twice, both
/// slots kept).
std::vector<Slot> slots(FlatBvh& bvh, unsigned index) {
    std::vector<Slot> out;
    if (bvh.width == 2) {
        gpu::BvhNode& n = bvh.nodes[index];
        out.push_back({{&n.lmin.x, &n.lmin.y, &n.lmin.z}, {&n.lmax.x, &n.lmax.y, &n.lmax.z},
                       gpu::as_uint(n.lmin.w), gpu::as_uint(n.lmax.w)});
        out.push_back({{&n.rmin.x, &n.rmin.y, &n.rmin.z}, {&n.rmax.x, &n.rmax.y, &n.rmax.z},
                       gpu::as_uint(n.rmin.w), gpu::as_uint(n.rmax.w)});
        return out;
    }
    if (bvh.width == 4) {
        gpu::Bvh4Node& n = bvh.nodes4[index];
        for (int k = 0; k < 4; ++k)
            if ((&n.child.x)[k] != 0u || (&n.count.x)[k] != 0u)
                out.push_back({{&n.min_x.x + k, &n.min_y.x + k, &n.min_z.x + k},
                               {&n.max_x.x + k, &n.max_y.x + k, &n.max_z.x + k},
                               (&n.child.x)[k], (&n.count.x)[k]});
        return out;
    }
    gpu::Bvh8Node& n = bvh.nodes8[index];
    for (int k = 0; k < 8; ++k)
        if (n.child[k] != 0u || n.count[k] != 0u)
            out.push_back({{n.min_x + k, n.min_y + k, n.min_z + k},
                           {n.max_x + k, n.max_y + k, n.max_z + k}, n.child[k], n.count[k]});
    return out;
}

/// Rewrites the records of the leaf at `first` (`count` primitives) and returns their box.
Box refit_leaf(FlatBvh& bvh, const TriangleMesh& mesh, unsigned first, unsigned count) {
    if (bvh.tri4) {
        for (unsigned i = 0; i < count; i += 4) {
            unsigned ids[4];
            gpu::BvhTri4 b;
            std::memcpy(&b, &bvh.triangles[first + i], sizeof b);
            std::memcpy(ids, &b.prim.x, sizeof ids);
            b = tri4_block(mesh, ids, std::min(4u, count - i));
            std::memcpy(&bvh.triangles[first + i], &b, sizeof b);
        }
    } else {
        for (unsigned i = 0; i < count; ++i)
            bvh.triangles[first + i] =
                primitive_record(mesh, gpu::as_uint(bvh.triangles[first + i].v0.w));
    }
    Box box;
    for (unsigned i = 0; i < count; ++i) {
        const auto [lo, hi] = record_bounds(leaf_record(bvh, first, i));
        box.extend({lo, hi});
    }
    return box;
}

/// Refits node `index` and its subtree; returns the union of its children's boxes.
Box refit_node(FlatBvh& bvh, const TriangleMesh& mesh, unsigned index) {
    Box all;
    for (const Slot& s : slots(bvh, index)) {
        const Box b = s.count ? refit_leaf(bvh, mesh, s.link, s.count)
                              : refit_node(bvh, mesh, s.link);
        s.set(b);
        all.extend(b);
    }
    return all;
}

} // namespace

void refit_bvh(FlatBvh& bvh, const TriangleMesh& mesh) {
    if (bvh.node_count() == 0) throw Error(mesh.source + ": refit of an empty BVH");
    refit_node(bvh, mesh, 0);
}

double bvh_sah_cost(const FlatBvh& bvh) {
    FlatBvh& b = const_cast<FlatBvh&>(bvh); // slots() reads through the same view as refit
    Box root;
    for (const Slot& s : slots(b, 0)) root.extend(s.box());
    const double root_area = root.area();
    if (!(root_area > 0.0)) return 0.0;
    double cost = 0.0;
    for (unsigned i = 0; i < bvh.node_count(); ++i)
        for (const Slot& s : slots(b, i))
            cost += s.box().area() / root_area * (s.count ? 1.0 + s.count : 1.0);
    return cost;
}

} // namespace tandem
