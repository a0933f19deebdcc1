// The list of shared structs and fields whose size and offsets the layout test compares between the
// host compiler and the device compiler (tests/kernels/test_layout.cpp, kernels/layout.cl).
#ifndef TANDEM_SHARED_LAYOUT_PROBE_H
#define TANDEM_SHARED_LAYOUT_PROBE_H

#include "shared/bvh_layout.h"

// X-macro lists: STRUCT(T) for each shared struct, FIELD(T, f) for each of its fields, in order.
// Add a struct here when you add it to kernels/shared.
#define TANDEM_SHARED_LAYOUT(STRUCT, FIELD)                                                        \
    STRUCT(BvhNode)                                                                                \
    FIELD(BvhNode, lmin) FIELD(BvhNode, lmax) FIELD(BvhNode, rmin) FIELD(BvhNode, rmax)            \
    STRUCT(Bvh4Node)                                                                               \
    FIELD(Bvh4Node, min_x) FIELD(Bvh4Node, min_y) FIELD(Bvh4Node, min_z) FIELD(Bvh4Node, max_x)    \
    FIELD(Bvh4Node, max_y) FIELD(Bvh4Node, max_z) FIELD(Bvh4Node, child) FIELD(Bvh4Node, count)    \
    STRUCT(BvhTriangle)                                                                            \
    FIELD(BvhTriangle, v0) FIELD(BvhTriangle, v1) FIELD(BvhTriangle, v2)                           \
    STRUCT(Ray)                                                                                    \
    FIELD(Ray, org) FIELD(Ray, dir)                                                                \
    STRUCT(Hit)                                                                                    \
    FIELD(Hit, t) FIELD(Hit, prim) FIELD(Hit, u) FIELD(Hit, v)

#endif // TANDEM_SHARED_LAYOUT_PROBE_H
