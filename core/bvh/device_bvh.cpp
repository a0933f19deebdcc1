// The BVH's upload.
#include "core/bvh/device_bvh.h"

#include <algorithm>
#include <cstring>
#include <string>

namespace tandem {

namespace {

/// Node records as float4 rows (either layout is a whole number of rows); at least one row, as
/// OpenCL buffers cannot be empty.
template <class Node> std::vector<gpu::float4> as_rows(const std::vector<Node>& nodes) {
    static_assert(sizeof(Node) % sizeof(gpu::float4) == 0, "a node is a whole number of float4");
    std::vector<gpu::float4> rows(
        std::max<std::size_t>(1, nodes.size() * (sizeof(Node) / sizeof(gpu::float4))));
    if (!nodes.empty()) std::memcpy(rows.data(), nodes.data(), nodes.size() * sizeof(Node));
    return rows;
}

} // namespace

DeviceBvh::DeviceBvh(Context& ctx, const FlatBvh& bvh)
    : width(bvh.width), analytic(bvh.analytic), tri4(bvh.tri4),
      nodes(ctx, "bvh nodes",
            bvh.width == 8 ? as_rows(bvh.nodes8)
                           : (bvh.width == 4 ? as_rows(bvh.nodes4) : as_rows(bvh.nodes)),
            CL_MEM_READ_ONLY),
      triangles(ctx, "bvh triangles", bvh.triangles, CL_MEM_READ_ONLY) {}


} // namespace tandem
