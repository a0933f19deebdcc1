// Device layout of the flattened BVH, rays and hits, shared by host and device.
// The BVH is built by Embree on the host (core/bvh/bvh_build.cpp) and flattened depth-first into these.
#ifndef TANDEM_SHARED_BVH_LAYOUT_H
#define TANDEM_SHARED_BVH_LAYOUT_H

#include "shared/compat.h"

TANDEM_NAMESPACE_BEGIN

/// Maximum BVH depth; the build passes it to Embree as maxDepth and traversal sizes its stack by it.
#define BVH_MAX_DEPTH 64
/// Maximum number of triangles in one leaf (the build passes it to Embree as maxLeafSize).
#define BVH_MAX_LEAF_SIZE 8
/// Primitive id of a ray that hit nothing.
#define HIT_NONE 0xFFFFFFFFu

/// Two-wide BVH node, 64 bytes: both child boxes, child links in the .w lanes (tinybvh's layout).
///   lmin.xyz, lmax.xyz: left child bounds (world space); likewise rmin/rmax for the right child.
///   as_uint(lmin.w): left child link: a node index if as_uint(lmax.w) == 0, otherwise the index
///                    of the leaf's first triangle in the leaf-ordered triangle array.
///   as_uint(lmax.w): number of triangles in the left leaf; 0 means the left child is a node.
/// Node 0 is the root. Nodes are stored depth-first, so a node's left child interior node (if any)
/// immediately follows it.
typedef struct BvhNode {
    float4 lmin;
    float4 lmax;
    float4 rmin;
    float4 rmax;
} BvhNode;
TANDEM_STATIC_ASSERT_SIZE(BvhNode, 64);

/// Maximum depth of the four-wide BVH; its closest-hit stack holds 3 entries per level and one
/// more (193 in all; a smaller limit measured no faster on PoCL).
#define BVH4_MAX_DEPTH 64

/// Four-wide BVH node, 128 bytes, structure of arrays: lane k of each vector describes child k.
///   min_x .. max_z: child bounds (world space). An unused lane has min = +inf, max = -inf, which
///                   the ordered slab test never enters.
///   child[k]: a node index if count[k] == 0, else the index of the leaf's first triangle.
///   count[k]: number of triangles in leaf k; 0 means child k is a node (or an unused lane).
/// Node 0 is the root; nodes are stored depth-first.
typedef struct Bvh4Node {
    float4 min_x;
    float4 min_y;
    float4 min_z;
    float4 max_x;
    float4 max_y;
    float4 max_z;
    uint4 child;
    uint4 count;
} Bvh4Node;
TANDEM_STATIC_ASSERT_SIZE(Bvh4Node, 128);

/// Maximum depth of the eight-wide BVH; its closest-hit stack holds 7 entries per level and one
/// more.
#define BVH8_MAX_DEPTH 32

/// Eight-wide BVH node, 256 bytes (four cache lines), structure of arrays: entry k of each array
/// describes child k, as in Bvh4Node. One ray tests the eight boxes with float8 arithmetic
/// (vload8 of each array), which AVX CPUs run as one instruction per operation (Embree's
/// single-ray BVH8 on AVX). Unused lanes are empty boxes (min = +inf, max = -inf) with count 0.
typedef struct Bvh8Node {
    float min_x[8];
    float min_y[8];
    float min_z[8];
    float max_x[8];
    float max_y[8];
    float max_z[8];
    uint child[8];
    uint count[8];
} Bvh8Node;
TANDEM_STATIC_ASSERT_SIZE(Bvh8Node, 256);

/// as_uint(v1.w) of a primitive record: a triangle (0), an analytic sphere or an analytic disk
/// (single bits: the wavefront tells them apart by bit tests, wf_primitive_point).
#define BVH_PRIM_SPHERE 1u
#define BVH_PRIM_DISK 2u

/// One primitive, 64 bytes (one cache line), with its primitive id (its index in the scene's
/// primitive order) in as_uint(v0.w). A triangle: world-space vertices in v0, v1, v2; v1.w and
/// v2.w are zero; plane_n.xyz is bvh_triangle_plane_normal(v0, v1, v2), the normal of the plane
/// the triangle test takes the hit distance from, and plane_n.w is zero. The analytic shapes,
/// whose plane_n is zero (only traversal built with BVH_ANALYTIC tests them):
///   - a sphere (as_uint(v1.w) == BVH_PRIM_SPHERE): centre v0.xyz, radius v1.x, and in v1.y the
///     side its front faces, +1 outward or -1 inward (flip_normals); v1.z is zero, and v2 the
///     unit quaternion (x, y, z, w) that turns world directions into its own axes (its texture
///     coordinates'). Its hit reports in (u, v) the octahedral encoding of the direction from its
///     centre (bvh_oct_decode), not barycentrics;
///   - a disk (BVH_PRIM_DISK): centre v0.xyz, and v1.xyz, v2.xyz the world images of its local x
///     and y axes (orthogonal, as long as its radius); v2.w: +1 where its front faces
///     v1 x v2, -1 for the other side. Its hit reports in (u, v) the local (x, y) on the unit
///     disk.
typedef struct BvhTriangle {
    float4 v0;
    float4 v1;
    float4 v2;
    float4 plane_n;
} BvhTriangle;
TANDEM_STATIC_ASSERT_SIZE(BvhTriangle, 64);

/// A primitive as shading reads it (the scene's `prims`, in primitive order), 64 bytes: v0, v1, v2
/// as in BvhTriangle (a triangle's vertices and id, or a sphere's or a disk's record). For a
/// triangle, n_front.xyz is its unit front normal triangle_front_normal(v0, v1, v2) (shared/
/// sampling.h), computed by the host (a zero-area triangle, which is never hit, gets NaN); zero
/// for the analytic shapes, whose normal depends on the point. The normal sits at floats 12-14,
/// as in EmissiveTriangle, so either record is read the same way (path/interaction.h: triangle_point).
typedef struct ShadingPrimitive {
    float4 v0;
    float4 v1;
    float4 v2;
    float4 n_front;
} ShadingPrimitive;
TANDEM_STATIC_ASSERT_SIZE(ShadingPrimitive, 64);

/// Four triangles of a leaf, structure of arrays, 256 bytes (the space of four BvhTriangle
/// records): lane k of each vector is triangle k, so one ray tests all four with float4
/// arithmetic (Embree's Triangle4 leaves; kernels/shared/bvh_tri4.h, used by the path kernels
/// built with BVH_TRI4 and by trace.cl's *_tri4 kernels). ax .. az are the vertices v0 of the four,
/// bx .. bz v1 and cx .. cz v2, nx .. nz their plane normals (BvhTriangle.n); prim holds their
/// primitive ids. A leaf of `count` triangles from
/// record `first` (a multiple of 4) is ceil(count / 4) blocks, its triangles in increasing
/// primitive id; the unused lanes of its last block have prim HIT_NONE, all three vertices at
/// the origin (zero area: never hit) and a zero normal. Only triangles: scenes with analytic shapes
/// keep BvhTriangle leaves.
typedef struct BvhTri4 {
    float4 ax, ay, az;
    float4 bx, by, bz;
    float4 cx, cy, cz;
    float4 nx, ny, nz;
    uint4 prim;
    uint4 unused[3];
} BvhTri4;
TANDEM_STATIC_ASSERT_SIZE(BvhTri4, 256);

/// A ray, 32 bytes: world-space origin with tmin in .w, direction (any length) with tmax in .w.
/// t is measured in units of the direction's length, as in Embree.
typedef struct Ray {
    float4 org;
    float4 dir;
} Ray;
TANDEM_STATIC_ASSERT_SIZE(Ray, 32);

/// Closest-hit result, 16 bytes. prim is HIT_NONE on a miss, then t is the ray's tmax (or -inf for
/// an invalid ray: a non-finite origin or direction, or a NaN interval). Among hits at equal t the
/// lowest primitive id is reported, whatever the BVH layout.
/// On a triangle the hit point is (1 - u - v) * p0 + u * p1 + v * p2 of its input vertices; on a
/// sphere or a disk, (u, v) are as BvhTriangle says.
typedef struct Hit {
    float t;
    uint prim;
    float u;
    float v;
} Hit;
TANDEM_STATIC_ASSERT_SIZE(Hit, 16);

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_BVH_LAYOUT_H
