// The flattened BVH on the device: the one upload of a BVH, which the device scene binds (and the
// benchmarks' and tests' Tracer, bench/tracer.h, traverses).
#pragma once

#include "core/bvh/bvh_build.h"
#include "runtime/launch.h"

namespace tandem {

/// The BVH uploaded to device buffers "bvh nodes" and "bvh triangles": the one upload of a BVH,
/// for the trace kernels and the device scene (core/render/device_scene.h). The nodes are the
/// BvhNode, Bvh4Node or Bvh8Node records of the BVH's width, as float4 rows (the kernels' view of
/// them).
struct DeviceBvh {
    int width;
    bool analytic; ///< FlatBvh::analytic
    bool tri4;     ///< FlatBvh::tri4
    Buffer<gpu::float4> nodes;
    Buffer<gpu::BvhTriangle> triangles;

    DeviceBvh(Context& ctx, const FlatBvh& bvh);
};

} // namespace tandem
