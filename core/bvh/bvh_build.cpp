// Embree rtcBuildBVH with our own node callbacks, then depth-first flattening.
#include "core/bvh/bvh_build.h"

#include "core/bvh/build_tree.h"
#include "core/bvh/leaf_repack.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>

#include "runtime/error.h"
#include "shared/bvh_traverse.h"

namespace tandem {

namespace {

// Callbacks: each touches only the node it is handed or memory from its own thread's allocator,
// so they are safe under Embree's parallel build.
void* create_node(RTCThreadLocalAllocator alloc, unsigned child_count, void*) {
    if (child_count > 8) return nullptr; // cannot happen with maxBranchingFactor <= 8
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

/// A triangle's record: its vertices and the plane normal its intersection test reads
/// (bvh_triangle_plane_normal).
gpu::BvhTriangle triangle_record(gpu::float4 v0, gpu::float4 v1, gpu::float4 v2) {
    return gpu::BvhTriangle{v0, v1, v2, gpu::bvh_triangle_plane_normal(v0, v1, v2)};
}

// ---- Depth-first flattening ----
struct Flattener {
    const TriangleMesh& mesh;
    FlatBvh& out;

    /// Appends the leaf's primitives (records, or blocks of four); returns (first record, count).
    std::pair<unsigned, unsigned> emit_leaf(const BuildLeaf* leaf) {
        const auto first = static_cast<unsigned>(out.triangles.size());
        if (out.tri4) {
            for (unsigned i = 0; i < leaf->count; i += 4)
                emit_block(leaf->prims + i, std::min(4u, leaf->count - i));
        } else {
            for (unsigned i = 0; i < leaf->count; ++i)
                out.triangles.push_back(primitive_record(mesh, leaf->prims[i]));
        }
        out.leaves += 1;
        return {first, leaf->count};
    }

    /// Appends tri4_block(mesh, prims, n), in the space of four records.
    void emit_block(const unsigned* prims, unsigned n) {
        const gpu::BvhTri4 b = tri4_block(mesh, prims, n);
        static_assert(sizeof(gpu::BvhTri4) == 4 * sizeof(gpu::BvhTriangle),
                      "a block is four records");
        const std::size_t at = out.triangles.size();
        out.triangles.resize(at + 4);
        std::memcpy(&out.triangles[at], &b, sizeof b);
    }

    /// Links of one child: (node index, 0) for an inner node, (first triangle, count) for a leaf.
    std::pair<unsigned, unsigned> emit_child(const BuildNode* child, int depth) {
        if (child->is_leaf) return emit_leaf(static_cast<const BuildLeaf*>(child));
        return {emit_inner(static_cast<const BuildInner*>(child), depth + 1), 0u};
    }

    /// Writes the inner node and its subtree depth-first; returns its index.
    unsigned emit_inner(const BuildInner* node, int depth) {
        out.depth = std::max(out.depth, depth);
        if (out.width == 8) return emit_inner8(node, depth);
        return out.width == 4 ? emit_inner4(node, depth) : emit_inner2(node, depth);
    }

    unsigned emit_inner2(const BuildInner* node, int depth) {
        const auto index = static_cast<unsigned>(out.nodes.size());
        out.nodes.emplace_back();
        unsigned link[2] = {0, 0}, count[2] = {0, 0};
        for (unsigned i = 0; i < 2; ++i) {
            if (i >= node->child_count) { // a one-child node links its child twice
                link[i] = link[0];
                count[i] = count[0];
                continue;
            }
            std::tie(link[i], count[i]) = emit_child(node->children[i], depth);
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

    unsigned emit_inner4(const BuildInner* node, int depth) {
        const auto index = static_cast<unsigned>(out.nodes4.size());
        out.nodes4.emplace_back();
        float lo[3][4], hi[3][4];
        unsigned link[4] = {0, 0, 0, 0}, count[4] = {0, 0, 0, 0};
        for (unsigned i = 0; i < 4; ++i) {
            if (i >= node->child_count) { // unused lane: an empty (inverted) box
                for (int a = 0; a < 3; ++a) {
                    lo[a][i] = std::numeric_limits<float>::infinity();
                    hi[a][i] = -std::numeric_limits<float>::infinity();
                }
                continue;
            }
            std::tie(link[i], count[i]) = emit_child(node->children[i], depth);
            const RTCBounds& b = node->bounds[i];
            lo[0][i] = b.lower_x, lo[1][i] = b.lower_y, lo[2][i] = b.lower_z;
            hi[0][i] = b.upper_x, hi[1][i] = b.upper_y, hi[2][i] = b.upper_z;
        }
        auto vec = [](const float* v) { return gpu::make_float4(v[0], v[1], v[2], v[3]); };
        gpu::Bvh4Node& n = out.nodes4[index];
        n.min_x = vec(lo[0]), n.min_y = vec(lo[1]), n.min_z = vec(lo[2]);
        n.max_x = vec(hi[0]), n.max_y = vec(hi[1]), n.max_z = vec(hi[2]);
        n.child = gpu::uint4{link[0], link[1], link[2], link[3]};
        n.count = gpu::uint4{count[0], count[1], count[2], count[3]};
        return index;
    }

    unsigned emit_inner8(const BuildInner* node, int depth) {
        const auto index = static_cast<unsigned>(out.nodes8.size());
        out.nodes8.emplace_back();
        gpu::Bvh8Node n{};
        for (unsigned i = 0; i < 8; ++i) {
            if (i >= node->child_count) { // unused lane: an empty (inverted) box
                n.min_x[i] = n.min_y[i] = n.min_z[i] = std::numeric_limits<float>::infinity();
                n.max_x[i] = n.max_y[i] = n.max_z[i] = -std::numeric_limits<float>::infinity();
                continue;
            }
            std::tie(n.child[i], n.count[i]) = emit_child(node->children[i], depth);
            const RTCBounds& b = node->bounds[i];
            n.min_x[i] = b.lower_x, n.min_y[i] = b.lower_y, n.min_z[i] = b.lower_z;
            n.max_x[i] = b.upper_x, n.max_y[i] = b.upper_y, n.max_z[i] = b.upper_z;
        }
        out.nodes8[index] = n;
        return index;
    }
};

/// centre -+ half, widened by 2^-20 of `half` and computed in double, then rounded outward to
/// float: a box that holds the hit points the kernels compute, which rounding may move off the
/// exact surface by a few ulps of the centre or of the size.
std::pair<glm::vec3, glm::vec3> padded_box(const glm::vec3& centre, const glm::vec3& half) {
    glm::vec3 lo, hi;
    for (int k = 0; k < 3; ++k) {
        const double h = double(half[k]) * (1.0 + 1.0 / 1048576.0);
        lo[k] = std::nextafter(static_cast<float>(double(centre[k]) - h), -INFINITY);
        hi[k] = std::nextafter(static_cast<float>(double(centre[k]) + h), INFINITY);
    }
    return {lo, hi};
}

} // namespace

std::pair<glm::vec3, glm::vec3> record_bounds(const gpu::BvhTriangle& r) {
    const glm::vec3 a(r.v0.x, r.v0.y, r.v0.z);
    if (gpu::as_uint(r.v1.w) == BVH_PRIM_SPHERE) return padded_box(a, glm::vec3(r.v1.x));
    const glm::vec3 b(r.v1.x, r.v1.y, r.v1.z), c(r.v2.x, r.v2.y, r.v2.z);
    if (gpu::as_uint(r.v1.w) == BVH_PRIM_DISK) return padded_box(a, disk_half_extent(Disk{a, b, c, 1.0f}));
    return {glm::min(a, glm::min(b, c)), glm::max(a, glm::max(b, c))};
}

gpu::BvhTri4 tri4_block(const TriangleMesh& mesh, const unsigned* prims, unsigned n) {
    gpu::BvhTri4 b{};
    float* lanes[12] = {&b.ax.x, &b.ay.x, &b.az.x, &b.bx.x, &b.by.x, &b.bz.x,
                        &b.cx.x, &b.cy.x, &b.cz.x, &b.nx.x, &b.ny.x, &b.nz.x};
    unsigned* ids = &b.prim.x;
    for (unsigned k = 0; k < 4; ++k) {
        ids[k] = HIT_NONE;
        if (k >= n) continue;
        const gpu::BvhTriangle r = primitive_record(mesh, prims[k]);
        const gpu::float4 v[4] = {r.v0, r.v1, r.v2, r.plane_n};
        for (int j = 0; j < 4; ++j) {
            lanes[3 * j][k] = v[j].x;
            lanes[3 * j + 1][k] = v[j].y;
            lanes[3 * j + 2][k] = v[j].z;
        }
        ids[k] = prims[k];
    }
    return b;
}

gpu::BvhTriangle primitive_record(const TriangleMesh& mesh, unsigned prim) {
    const std::size_t first_disk = mesh.triangles.size() + mesh.spheres.size();
    if (prim >= first_disk) {
        const Disk& d = mesh.disks.at(prim - first_disk);
        return gpu::BvhTriangle{pack(d.center.x, d.center.y, d.center.z, prim),
                                pack(d.x_axis.x, d.x_axis.y, d.x_axis.z, BVH_PRIM_DISK),
                                gpu::make_float4(d.y_axis.x, d.y_axis.y, d.y_axis.z, d.orientation),
                                gpu::float4{}};
    }
    if (prim >= mesh.triangles.size()) {
        const Sphere& s = mesh.spheres.at(prim - mesh.triangles.size());
        return gpu::BvhTriangle{
            pack(s.center.x, s.center.y, s.center.z, prim),
            pack(s.radius, s.orientation, 0.0f, BVH_PRIM_SPHERE),
            gpu::make_float4(s.to_local.x, s.to_local.y, s.to_local.z, s.to_local.w),
            gpu::float4{}};
    }
    const glm::uvec3& t = mesh.triangles[prim];
    const glm::vec3 &a = mesh.positions[t.x], &b = mesh.positions[t.y], &c = mesh.positions[t.z];
    return triangle_record(pack(a.x, a.y, a.z, prim), gpu::make_float4(b.x, b.y, b.z, 0.0f),
                           gpu::make_float4(c.x, c.y, c.z, 0.0f));
}

int bvh_max_depth(int width) {
    return width == 8 ? BVH8_MAX_DEPTH : (width == 4 ? BVH4_MAX_DEPTH : BVH_MAX_DEPTH);
}

FlatBvh build_bvh(const EmbreeDevice& device, const TriangleMesh& mesh, int width,
                  LeafFormat leaves, bool repack) {
    const bool tri4 = leaves == LeafFormat::tri4;
    if (tri4 && (width == 2 || mesh.primitive_count() != mesh.triangle_count()))
        throw Error(
            mesh.source +
            ": leaves of four-triangle blocks need a four- or eight-wide BVH of triangles only");
    if (width != 2 && width != 4 && width != 8)
        throw Error("BVH width must be 2, 4 or 8, not " + std::to_string(width));
    validate_mesh(mesh);
    // Step 1: one build primitive (bounds + id) per triangle, sphere and disk.
    std::vector<RTCBuildPrimitive> prims(mesh.primitive_count());
    std::vector<RTCBounds> prim_bounds(prims.size()); // by id: the builder reorders `prims`
    for (std::size_t i = 0; i < prims.size(); ++i) {
        const auto [lo, hi] = record_bounds(primitive_record(mesh, static_cast<unsigned>(i)));
        prims[i] = RTCBuildPrimitive{lo.x, lo.y, lo.z, 0, hi.x, hi.y, hi.z, static_cast<unsigned>(i)};
        prim_bounds[i] = RTCBounds{lo.x, lo.y, lo.z, 0.0f, hi.x, hi.y, hi.z, 0.0f};
    }

    // Step 2: Embree's binned-SAH builder. The build tree lives in the RTCBVH's allocator until
    // the flattening below has copied it.
    const std::unique_ptr<RTCBVHTy, void (*)(RTCBVH)> owner(rtcNewBVH(device.get()), rtcReleaseBVH);
    RTCBVH rtc_bvh = owner.get();
    device.check("rtcNewBVH");
    RTCBuildArguments args = rtcDefaultBuildArguments();
    args.byteSize = sizeof(args);
    args.buildFlags = RTC_BUILD_FLAG_NONE;
    args.buildQuality = RTC_BUILD_QUALITY_MEDIUM; // binned SAH, no spatial splits
    args.maxBranchingFactor = static_cast<unsigned>(width);
    args.maxDepth = bvh_max_depth(width);
    // With blocks of four, the SAH counts a leaf's cost in whole blocks (Embree does the same for
    // its Triangle4 leaves): a partly filled block costs a whole test, so the build fills them.
    args.sahBlockSize = tri4 ? 4 : 1;
    args.minLeafSize = 1;
    args.maxLeafSize = BVH_MAX_LEAF_SIZE;
    // SAH costs: a node visit against one triangle test, equal (Embree's default). A cheaper
    // triangle (fewer, larger leaves) helps large meshes of small triangles but slows the bundled
    // scenes, whose large triangles overlap many boxes. The hits do not depend on the BVH.
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
        device.check(("rtcBuildBVH for " + mesh.source).c_str());
        throw Error(mesh.source + ": BVH build failed");
    }

    // Step 3: repack each node's leaves by the SAH of their tests (core/bvh/leaf_repack.h).
    LeafRepacker repacker(static_cast<unsigned>(width), tri4 ? 4u : 1u, prim_bounds);
    if (repack && !root->is_leaf) root = repacker.run(static_cast<BuildInner*>(root));

    // Step 4: flatten depth-first. A leaf root becomes a node with that leaf as both children.
    FlatBvh out;
    out.width = width;
    out.tri4 = tri4;
    out.analytic = mesh.primitive_count() != mesh.triangle_count();
    out.nodes.reserve(width == 2 ? prims.size() : 0);
    out.nodes4.reserve(width == 4 ? prims.size() / 2 : 0);
    out.nodes8.reserve(width == 8 ? prims.size() / 4 : 0);
    out.triangles.reserve(mesh.primitive_count());
    Flattener flat{mesh, out};
    if (root->is_leaf) {
        Bounds b;
        for (const RTCBuildPrimitive& p : prims) {
            b.extend({p.lower_x, p.lower_y, p.lower_z});
            b.extend({p.upper_x, p.upper_y, p.upper_z});
        }
        BuildInner wrapper;
        wrapper.is_leaf = false;
        wrapper.child_count = 1;
        wrapper.children[0] = root;
        wrapper.bounds[0] = RTCBounds{b.lo.x, b.lo.y, b.lo.z, 0.0f, b.hi.x, b.hi.y, b.hi.z, 0.0f};
        flat.emit_inner(&wrapper, 1);
    } else {
        flat.emit_inner(static_cast<const BuildInner*>(root), 1);
    }
    // Traversal stacks are sized by the maximum depth (BVH_MAX_DEPTH - 1 pushes for two-wide,
    // 3 per level for four-wide, 7 for eight-wide); Embree honours maxDepth, and this guard keeps
    // it that way.
    if (out.depth > static_cast<int>(args.maxDepth))
        throw Error(mesh.source + ": BVH depth " + std::to_string(out.depth) + " exceeds " +
                    std::to_string(args.maxDepth));
    return out;
}

namespace {

/// One child slot of a node of either width, for check_bvh.
struct ChildRef {
    glm::vec3 lo, hi;
    unsigned link, count;
};

std::vector<ChildRef> children_of(const FlatBvh& bvh, unsigned index) {
    std::vector<ChildRef> out;
    if (bvh.width == 2) {
        const gpu::BvhNode& n = bvh.nodes[index];
        out.push_back({{n.lmin.x, n.lmin.y, n.lmin.z}, {n.lmax.x, n.lmax.y, n.lmax.z},
                       gpu::as_uint(n.lmin.w), gpu::as_uint(n.lmax.w)});
        const ChildRef right{{n.rmin.x, n.rmin.y, n.rmin.z}, {n.rmax.x, n.rmax.y, n.rmax.z},
                             gpu::as_uint(n.rmin.w), gpu::as_uint(n.rmax.w)};
        // a one-child node links its leaf twice; count it once
        if (!(right.count != 0 && right.link == out[0].link && right.count == out[0].count))
            out.push_back(right);
        return out;
    }
    if (bvh.width == 8) {
        const gpu::Bvh8Node& n = bvh.nodes8[index];
        for (int k = 0; k < 8; ++k) {
            if (n.min_x[k] > n.max_x[k]) { // unused lane
                if (n.count[k] != 0)
                    throw Error("BVH8 node " + std::to_string(index) +
                                " has a leaf in an unused lane");
                continue;
            }
            out.push_back({{n.min_x[k], n.min_y[k], n.min_z[k]},
                           {n.max_x[k], n.max_y[k], n.max_z[k]},
                           n.child[k],
                           n.count[k]});
        }
        return out;
    }
    const gpu::Bvh4Node& n = bvh.nodes4[index];
    const float* mnx = &n.min_x.x; const float* mny = &n.min_y.x; const float* mnz = &n.min_z.x;
    const float* mxx = &n.max_x.x; const float* mxy = &n.max_y.x; const float* mxz = &n.max_z.x;
    const unsigned* child = &n.child.x; const unsigned* count = &n.count.x;
    for (int k = 0; k < 4; ++k) {
        if (mnx[k] > mxx[k]) { // unused lane
            if (count[k] != 0) throw Error("BVH4 node " + std::to_string(index) + " has a leaf in an unused lane");
            continue;
        }
        out.push_back({{mnx[k], mny[k], mnz[k]}, {mxx[k], mxy[k], mxz[k]}, child[k], count[k]});
    }
    return out;
}

bool inside(const ChildRef& box, float x, float y, float z) {
    return x >= box.lo.x && y >= box.lo.y && z >= box.lo.z && x <= box.hi.x && y <= box.hi.y &&
           z <= box.hi.z;
}

/// The BvhTri4 block at record `slot` (a multiple of 4).
gpu::BvhTri4 block_at(const FlatBvh& bvh, unsigned slot) {
    gpu::BvhTri4 b;
    std::memcpy(&b, &bvh.triangles.at(slot + 3) - 3, sizeof b);
    return b;
}

/// The format of a BvhTri4 leaf: whole blocks, increasing ids, padding lanes of zero area.
void check_tri4_leaf(const FlatBvh& bvh, unsigned first, unsigned count) {
    if (first % 4 != 0)
        throw Error("BVH tri4 leaf at record " + std::to_string(first) + " is not a whole block");
    const gpu::BvhTri4 last = block_at(bvh, first + (count - 1) / 4 * 4);
    const float* lanes[12] = {&last.ax.x, &last.ay.x, &last.az.x, &last.bx.x,
                              &last.by.x, &last.bz.x, &last.cx.x, &last.cy.x,
                              &last.cz.x, &last.nx.x, &last.ny.x, &last.nz.x};
    for (unsigned k = (count - 1) % 4 + 1; k < 4; ++k) {
        if ((&last.prim.x)[k] != HIT_NONE)
            throw Error("BVH tri4 leaf pads a lane with a primitive id");
        for (const float* lane : lanes)
            if (lane[k] != 0.0f)
                throw Error("BVH tri4 leaf pads a lane with a nonzero vertex or normal");
    }
    for (unsigned i = 1; i < count; ++i)
        if (gpu::as_uint(leaf_record(bvh, first, i - 1).v0.w) >=
            gpu::as_uint(leaf_record(bvh, first, i).v0.w))
            throw Error("BVH tri4 leaf at record " + std::to_string(first) +
                        " is not in increasing primitive id");
}

} // namespace

gpu::BvhTriangle leaf_record(const FlatBvh& bvh, unsigned first, unsigned i) {
    if (!bvh.tri4) return bvh.triangles.at(std::size_t(first) + i);
    const gpu::BvhTri4 b = block_at(bvh, first + i / 4 * 4);
    const unsigned k = i % 4;
    auto lane = [k](const gpu::float4& v) { return (&v.x)[k]; };
    return gpu::BvhTriangle{pack(lane(b.ax), lane(b.ay), lane(b.az), (&b.prim.x)[k]),
                            gpu::make_float4(lane(b.bx), lane(b.by), lane(b.bz), 0.0f),
                            gpu::make_float4(lane(b.cx), lane(b.cy), lane(b.cz), 0.0f),
                            gpu::make_float4(lane(b.nx), lane(b.ny), lane(b.nz), 0.0f)};
}

void check_bvh(const FlatBvh& bvh, std::size_t primitive_count) {
    const std::size_t nodes = bvh.node_count();
    const int max_depth = bvh_max_depth(bvh.width);
    if (nodes == 0) throw Error("BVH has no nodes");
    if (bvh.depth > max_depth)
        throw Error("BVH depth " + std::to_string(bvh.depth) + " exceeds its maximum");
    std::vector<int> seen(primitive_count, 0);
    std::vector<char> visited(nodes, 0);
    std::function<void(unsigned, int)> visit = [&](unsigned index, int depth) {
        if (index >= nodes) throw Error("BVH node link out of range");
        if (depth > max_depth) throw Error("BVH deeper than its maximum depth");
        if (visited[index]++) throw Error("BVH node " + std::to_string(index) + " has two parents");
        for (const ChildRef& c : children_of(bvh, index)) {
            if (c.count == 0) {
                visit(c.link, depth + 1);
                for (const ChildRef& g : children_of(bvh, c.link))
                    if (!inside(c, g.lo.x, g.lo.y, g.lo.z) || !inside(c, g.hi.x, g.hi.y, g.hi.z))
                        throw Error("BVH child box of node " + std::to_string(index) +
                                    " does not contain its subtree");
                continue;
            }
            if (c.count > BVH_MAX_LEAF_SIZE) throw Error("BVH leaf larger than BVH_MAX_LEAF_SIZE");
            const unsigned slots = bvh.tri4 ? (c.count + 3) / 4 * 4 : c.count;
            if (std::size_t(c.link) + slots > bvh.triangles.size())
                throw Error("BVH leaf range out of bounds");
            if (bvh.tri4) check_tri4_leaf(bvh, c.link, c.count);
            for (unsigned i = 0; i < c.count; ++i) {
                const gpu::BvhTriangle t = leaf_record(bvh, c.link, i);
                const unsigned prim = gpu::as_uint(t.v0.w);
                if (prim >= primitive_count) throw Error("BVH leaf holds an unknown primitive id");
                // a triangle's record holds the plane normal its test reads, an analytic one zero
                const gpu::float4 n = gpu::as_uint(t.v1.w) == 0u
                                          ? gpu::bvh_triangle_plane_normal(t.v0, t.v1, t.v2)
                                          : gpu::float4{};
                if (std::memcmp(&n, &t.plane_n, sizeof n) != 0)
                    throw Error("BVH record of primitive " + std::to_string(prim) +
                                " has a stale plane normal");
                const auto [lo, hi] = record_bounds(t);
                if (!inside(c, lo.x, lo.y, lo.z) || !inside(c, hi.x, hi.y, hi.z))
                    throw Error("BVH leaf box does not contain primitive " + std::to_string(prim));
                seen[prim] += 1;
            }
        }
    };
    visit(0, 1);
    for (std::size_t i = 0; i < primitive_count; ++i)
        if (seen[i] != 1)
            throw Error("primitive " + std::to_string(i) + " appears in " + std::to_string(seen[i]) +
                        " leaves");
}

} // namespace tandem
