// Ray-tracing kernels over the flattened BVH: closest hit and any hit (shadow rays).
// One work item per ray; barrier-free; launched with a fixed local size (runtime/launch.h).
#pragma OPENCL FP_CONTRACT OFF

#include "shared/bvh_traverse.h"

/// Reads rays[0..count), the BVH nodes and leaf-ordered triangles; writes hits[0..count).
__kernel void trace_closest(__global const BvhNode* nodes, __global const BvhTriangle* tris,
                            __global const Ray* rays, __global Hit* hits, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    hits[i] = bvh_intersect_closest(nodes, tris, rays[i]);
}

/// Reads rays[0..count), the BVH nodes and triangles; writes occluded[i] = 1 if anything lies
/// along ray i in [tmin, tmax), else 0.
__kernel void trace_any(__global const BvhNode* nodes, __global const BvhTriangle* tris,
                        __global const Ray* rays, __global uint* occluded, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    occluded[i] = (uint)bvh_intersect_any(nodes, tris, rays[i]);
}
