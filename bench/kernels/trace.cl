// Ray-tracing kernels over the flattened BVH: closest hit and any hit (shadow rays), for the
// two-wide (BvhNode), four-wide (Bvh4Node) and eight-wide (Bvh8Node) layouts, the wider two with
// either leaf format, and packets of eight rays over the eight-wide tree of blocks. One work item
// per ray (per packet for those); barrier-free;
// launched with a fixed local size (runtime/launch.h).
#pragma OPENCL FP_CONTRACT OFF

#include "shared/bvh8_packet.h"

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
    hits[i] = bvh4_intersect_closest(nodes, tris, rays[i], 0);
}

/// As trace_any_bvh2, over the four-wide layout.
__kernel void trace_any_bvh4(__global const Bvh4Node* nodes, __global const BvhTriangle* tris,
                             __global const Ray* rays, __global uint* occluded, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    occluded[i] = (uint)bvh4_intersect_any(nodes, tris, rays[i], 0);
}

/// As trace_closest_bvh4, over leaves of BvhTri4 blocks.
__kernel void trace_closest_bvh4_tri4(__global const Bvh4Node* nodes,
                                      __global const BvhTriangle* tris, __global const Ray* rays,
                                      __global Hit* hits, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    hits[i] = bvh4_intersect_closest(nodes, tris, rays[i], 1);
}

/// As trace_any_bvh4, over leaves of BvhTri4 blocks.
__kernel void trace_any_bvh4_tri4(__global const Bvh4Node* nodes, __global const BvhTriangle* tris,
                                  __global const Ray* rays, __global uint* occluded, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    occluded[i] = (uint)bvh4_intersect_any(nodes, tris, rays[i], 1);
}

/// As trace_closest_bvh4, over the eight-wide layout.
__kernel void trace_closest_bvh8(__global const Bvh8Node* nodes,
                                 __global const BvhTriangle* tris, __global const Ray* rays,
                                 __global Hit* hits, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    hits[i] = bvh8_intersect_closest(nodes, tris, rays[i], 0);
}

/// As trace_any_bvh4, over the eight-wide layout.
__kernel void trace_any_bvh8(__global const Bvh8Node* nodes, __global const BvhTriangle* tris,
                             __global const Ray* rays, __global uint* occluded, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    occluded[i] = (uint)bvh8_intersect_any(nodes, tris, rays[i], 0);
}

/// As trace_closest_bvh4_tri4, over the eight-wide layout.
__kernel void trace_closest_bvh8_tri4(__global const Bvh8Node* nodes,
                                      __global const BvhTriangle* tris, __global const Ray* rays,
                                      __global Hit* hits, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    hits[i] = bvh8_intersect_closest(nodes, tris, rays[i], 1);
}

/// As trace_any_bvh4_tri4, over the eight-wide layout.
__kernel void trace_any_bvh8_tri4(__global const Bvh8Node* nodes, __global const BvhTriangle* tris,
                                  __global const Ray* rays, __global uint* occluded, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    occluded[i] = (uint)bvh8_intersect_any(nodes, tris, rays[i], 1);
}

/// Closest hits of rays[0..count) in packets of eight over the eight-wide tree of blocks: work
/// item i traces rays [8 i, 8 i + 8) together (kernels/shared/bvh8_packet.h), each ray getting
/// trace_closest_bvh8_tri4's hit.
__kernel void trace_closest_packets_bvh8_tri4(__global const Bvh8Node* nodes,
                                              __global const BvhTriangle* tris,
                                              __global const Ray* rays, __global Hit* hits,
                                              uint count) {
    const uint first = get_global_id(0) * BVH8_PACKET;
    if (first >= count) return;
    const uint n = min(count - first, (uint)BVH8_PACKET);
    Ray packet[BVH8_PACKET];
    Hit found[BVH8_PACKET];
    for (uint k = 0; k < n; ++k) packet[k] = rays[first + k];
    bvh8_packet_closest(nodes, tris, packet, n, found);
    for (uint k = 0; k < n; ++k) hits[first + k] = found[k];
}
