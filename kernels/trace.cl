// Ray-tracing kernels over the flattened BVH: closest hit and any hit (shadow rays), for the
// two-wide (BvhNode) and four-wide (Bvh4Node) layouts, one work item per ray; and closest hit in
// packets of 16 coherent rays per work item over the four-wide layout. Barrier-free; launched
// with a fixed local size (runtime/launch.h).
#pragma OPENCL FP_CONTRACT OFF

#include "path/packet_traverse.h"

/// Reads rays[0..count), the BVH nodes and leaf-ordered triangles; writes hits[0..count).
__kernel void trace_closest_bvh2(__global const BvhNode* nodes, __global const BvhTriangle* tris,
                                 __global const Ray* rays, __global Hit* hits, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    hits[i] = bvh_intersect_closest(nodes, tris, rays[i]);
}

/// Reads rays[0..count), the BVH nodes and triangles; writes occluded[i] = 1 if anything lies
/// along ray i in [tmin, tmax), else 0.
__kernel void trace_any_bvh2(__global const BvhNode* nodes, __global const BvhTriangle* tris,
                             __global const Ray* rays, __global uint* occluded, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    occluded[i] = (uint)bvh_intersect_any(nodes, tris, rays[i]);
}

/// As trace_closest_bvh2, over the four-wide layout.
__kernel void trace_closest_bvh4(__global const Bvh4Node* nodes, __global const BvhTriangle* tris,
                                 __global const Ray* rays, __global Hit* hits, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    hits[i] = bvh4_intersect_closest(nodes, tris, rays[i]);
}

/// As trace_any_bvh2, over the four-wide layout.
__kernel void trace_any_bvh4(__global const Bvh4Node* nodes, __global const BvhTriangle* tris,
                             __global const Ray* rays, __global uint* occluded, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    occluded[i] = (uint)bvh4_intersect_any(nodes, tris, rays[i]);
}

/// As trace_closest_bvh4, PACKET_SIZE rays per work item (path/packet_traverse.h): work item i
/// traces rays [i PACKET_SIZE, (i + 1) PACKET_SIZE), for coherent rays such as a camera's.
__kernel void trace_closest_bvh4_packet(__global const Bvh4Node* nodes,
                                        __global const BvhTriangle* tris, __global const Ray* rays,
                                        __global Hit* hits, uint count) {
    const uint first = get_global_id(0) * PACKET_SIZE;
    if (first >= count) return;
    PacketRays r;
    packet_prepare(rays, first, count, &r);
    PacketHits hit;
    packet_intersect_closest(nodes, tris, &r, &hit);
    packet_store(&hit, first, count, hits);
}
