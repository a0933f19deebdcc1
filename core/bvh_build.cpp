// Embree rtcBuildBVH with our own node callbacks, then depth-first flattening.
#include "core/bvh_build.h"

#include <algorithm>
#include <cstring>
#include <functional>

#include "runtime/error.h"

namespace tandem {

namespace {

// ---- Temporary build tree, allocated by Embree's thread-local allocator (freed with the RTCBVH) --
struct BuildNode {
    bool is_leaf;
};
struct BuildInner : BuildNode {
    BuildNode* children[2];
    RTCBounds bounds[2];
    unsigned child_count;
};
struct BuildLeaf : BuildNode {
    unsigned count;
    unsigned prims[1]; // `count` entries, allocated past the struct
};

// Callbacks: each touches only the node it is handed or memory from its own thread's allocator,
// so they are safe under Embree's parallel build.
void* create_node(RTCThreadLocalAllocator alloc, unsigned child_count, void*) {
    if (child_count > 2) return nullptr; // cannot happen with maxBranchingFactor = 2
    void* mem = rtcThreadLocalAlloc(alloc, sizeof(BuildInner), 16);
    auto* node = new (mem) BuildInner;
    node->is_leaf = false;
    node->child_count = child_count;
    return node;
}

void set_children(void* node_ptr, void** children, unsigned count, void*) {
    auto* node = static_cast<BuildInner*>(node_ptr);
    for (unsigned i = 0; i < count; ++i) node->children[i] = static_cast<BuildNode*>(children[i]);
}

void set_bounds(void* node_ptr, const RTCBounds** bounds, unsigned count, void*) {
    auto* node = static_cast<BuildInner*>(node_ptr);
    for (unsigned i = 0; i < count; ++i) node->bounds[i] = *bounds[i];
}

void* create_leaf(RTCThreadLocalAllocator alloc, const RTCBuildPrimitive* prims, size_t count,
                  void*) {
    const std::size_t bytes = sizeof(BuildLeaf) + (count > 0 ? count - 1 : 0) * sizeof(unsigned);
    void* mem = rtcThreadLocalAlloc(alloc, bytes, 16);
    auto* leaf = static_cast<BuildLeaf*>(mem);
    leaf->is_leaf = true;
    leaf->count = static_cast<unsigned>(count);
    for (size_t i = 0; i < count; ++i) leaf->prims[i] = prims[i].primID;
    // Canonical order inside the leaf, so ties between equal-t triangles resolve the same way
    // whatever order the parallel partitioning left them in.
    std::sort(leaf->prims, leaf->prims + count);
    return leaf;
}

gpu::float4 pack(float x, float y, float z, unsigned bits) {
    return gpu::make_float4(x, y, z, gpu::as_float(bits));
}

// ---- Depth-first flattening ----
struct Flattener {
    const TriangleMesh& mesh;
    FlatBvh& out;

    /// Appends the leaf's triangles; returns (first triangle index, count).
    std::pair<unsigned, unsigned> emit_leaf(const BuildLeaf* leaf) {
        const auto first = static_cast<unsigned>(out.triangles.size());
        for (unsigned i = 0; i < leaf->count; ++i) {
            const unsigned prim = leaf->prims[i];
            const glm::uvec3& t = mesh.triangles[prim];
            const glm::vec3 &a = mesh.positions[t.x], &b = mesh.positions[t.y],
                            &c = mesh.positions[t.z];
            out.triangles.push_back(gpu::BvhTriangle{pack(a.x, a.y, a.z, prim),
                                                     gpu::make_float4(b.x, b.y, b.z, 0.0f),
                                                     gpu::make_float4(c.x, c.y, c.z, 0.0f)});
        }
        out.leaves += 1;
        return {first, leaf->count};
    }

    /// Writes the inner node and its subtree; returns its index.
    unsigned emit_inner(const BuildInner* node, int depth) {
        out.depth = std::max(out.depth, depth);
        const auto index = static_cast<unsigned>(out.nodes.size());
        out.nodes.emplace_back();
        unsigned link[2], count[2];
        for (unsigned i = 0; i < 2; ++i) {
            if (i >= node->child_count) { // a one-child node links its child twice
                link[i] = link[0];
                count[i] = count[0];
                continue;
            }
            const BuildNode* child = node->children[i];
            if (child->is_leaf) {
                std::tie(link[i], count[i]) = emit_leaf(static_cast<const BuildLeaf*>(child));
            } else {
                link[i] = emit_inner(static_cast<const BuildInner*>(child), depth + 1);
                count[i] = 0;
            }
        }
        const RTCBounds& l = node->bounds[0];
        const RTCBounds& r = node->bounds[std::min(1u, node->child_count - 1)];
        gpu::BvhNode& n = out.nodes[index];
        n.lmin = pack(l.lower_x, l.lower_y, l.lower_z, link[0]);
        n.lmax = pack(l.upper_x, l.upper_y, l.upper_z, count[0]);
        n.rmin = pack(r.lower_x, r.lower_y, r.lower_z, link[1]);
        n.rmax = pack(r.upper_x, r.upper_y, r.upper_z, count[1]);
        return index;
    }
};

} // namespace

FlatBvh build_bvh(const EmbreeDevice& device, const TriangleMesh& mesh) {
    validate_mesh(mesh);
    // Step 1: one build primitive (bounds + id) per triangle.
    std::vector<RTCBuildPrimitive> prims(mesh.triangles.size());
    for (std::size_t i = 0; i < prims.size(); ++i) {
        const glm::uvec3& t = mesh.triangles[i];
        const glm::vec3 &a = mesh.positions[t.x], &b = mesh.positions[t.y], &c = mesh.positions[t.z];
        const glm::vec3 lo = glm::min(a, glm::min(b, c)), hi = glm::max(a, glm::max(b, c));
        prims[i] = RTCBuildPrimitive{lo.x, lo.y, lo.z, 0, hi.x, hi.y, hi.z, static_cast<unsigned>(i)};
    }

    // Step 2: Embree's binned-SAH builder with two-wide nodes.
    RTCBVH rtc_bvh = rtcNewBVH(device.get());
    device.check("rtcNewBVH");
    RTCBuildArguments args = rtcDefaultBuildArguments();
    args.byteSize = sizeof(args);
    args.buildFlags = RTC_BUILD_FLAG_NONE;
    args.buildQuality = RTC_BUILD_QUALITY_MEDIUM; // binned SAH, no spatial splits
    args.maxBranchingFactor = 2;
    args.maxDepth = BVH_MAX_DEPTH;
    args.sahBlockSize = 1;
    args.minLeafSize = 1;
    args.maxLeafSize = BVH_MAX_LEAF_SIZE;
    args.traversalCost = 1.0f;
    args.intersectionCost = 1.0f;
    args.bvh = rtc_bvh;
    args.primitives = prims.data();
    args.primitiveCount = prims.size();
    args.primitiveArrayCapacity = prims.size();
    args.createNode = create_node;
    args.setNodeChildren = set_children;
    args.setNodeBounds = set_bounds;
    args.createLeaf = create_leaf;
    args.splitPrimitive = nullptr;
    args.buildProgress = nullptr;
    args.userPtr = nullptr;
    auto* root = static_cast<BuildNode*>(rtcBuildBVH(&args));
    if (!root) {
        rtcReleaseBVH(rtc_bvh);
        device.check(("rtcBuildBVH for " + mesh.source).c_str());
        throw Error(mesh.source + ": BVH build failed");
    }

    // Step 3: flatten depth-first. A leaf root becomes a node with that leaf as both children.
    FlatBvh out;
    out.nodes.reserve(prims.size());
    out.triangles.reserve(mesh.triangles.size());
    Flattener flat{mesh, out};
    if (root->is_leaf) {
        const Bounds b = mesh.bounds();
        BuildInner wrapper;
        wrapper.is_leaf = false;
        wrapper.child_count = 1;
        wrapper.children[0] = root;
        wrapper.bounds[0] = RTCBounds{b.lo.x, b.lo.y, b.lo.z, 0.0f, b.hi.x, b.hi.y, b.hi.z, 0.0f};
        flat.emit_inner(&wrapper, 1);
    } else {
        flat.emit_inner(static_cast<const BuildInner*>(root), 1);
    }
    rtcReleaseBVH(rtc_bvh);
    return out;
}

void check_bvh(const FlatBvh& bvh, std::size_t triangle_count) {
    if (bvh.nodes.empty()) throw Error("BVH has no nodes");
    if (bvh.depth > BVH_MAX_DEPTH)
        throw Error("BVH depth " + std::to_string(bvh.depth) + " exceeds BVH_MAX_DEPTH");
    std::vector<int> seen(triangle_count, 0);
    auto inside = [](const gpu::float4& lo, const gpu::float4& hi, const gpu::float4& p) {
        return p.x >= lo.x && p.y >= lo.y && p.z >= lo.z && p.x <= hi.x && p.y <= hi.y &&
               p.z <= hi.z;
    };
    std::vector<char> visited(bvh.nodes.size(), 0);
    std::function<void(unsigned, int)> visit = [&](unsigned index, int depth) {
        if (index >= bvh.nodes.size()) throw Error("BVH node link out of range");
        if (depth > BVH_MAX_DEPTH) throw Error("BVH deeper than BVH_MAX_DEPTH");
        if (visited[index]++) throw Error("BVH node " + std::to_string(index) + " has two parents");
        const gpu::BvhNode& n = bvh.nodes[index];
        const gpu::float4 mins[2] = {n.lmin, n.rmin}, maxs[2] = {n.lmax, n.rmax};
        for (int side = 0; side < 2; ++side) {
            const unsigned link = gpu::as_uint(mins[side].w), count = gpu::as_uint(maxs[side].w);
            if (count == 0) {
                visit(link, depth + 1);
                const gpu::BvhNode& c = bvh.nodes[link];
                if (!inside(mins[side], maxs[side], c.lmin) || !inside(mins[side], maxs[side], c.lmax) ||
                    !inside(mins[side], maxs[side], c.rmin) || !inside(mins[side], maxs[side], c.rmax))
                    throw Error("BVH child box of node " + std::to_string(index) + " does not contain its subtree");
                continue;
            }
            if (link + count > bvh.triangles.size()) throw Error("BVH leaf range out of bounds");
            for (unsigned i = link; i < link + count; ++i) {
                const gpu::BvhTriangle& t = bvh.triangles[i];
                const unsigned prim = gpu::as_uint(t.v0.w);
                if (prim >= triangle_count) throw Error("BVH leaf holds an unknown primitive id");
                if (!inside(mins[side], maxs[side], t.v0) || !inside(mins[side], maxs[side], t.v1) ||
                    !inside(mins[side], maxs[side], t.v2))
                    throw Error("BVH leaf box does not contain triangle " + std::to_string(prim));
                // a leaf repeated as both children of a one-child node counts once
                if (!(side == 1 && link == gpu::as_uint(n.lmin.w) && gpu::as_uint(n.lmax.w) == count))
                    seen[prim] += 1;
            }
        }
    };
    visit(0, 1);
    for (std::size_t i = 0; i < triangle_count; ++i)
        if (seen[i] != 1)
            throw Error("triangle " + std::to_string(i) + " appears in " + std::to_string(seen[i]) +
                        " leaves");
}

} // namespace tandem
