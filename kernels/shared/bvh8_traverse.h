// Closest-hit and any-hit traversal of the eight-wide BVH (Bvh8Node): one ray tests its eight
// child boxes with float8 arithmetic, one AVX instruction per operation on CPUs (Embree's
// single-ray BVH8). The children the ray enters are taken from a bit mask, lowest lane first;
// leaves and the per-ray setup are shared with the narrower layouts. The host runs the same code
// over compat.h's float8 (tests/core/bvh).
#ifndef TANDEM_SHARED_BVH8_TRAVERSE_H
#define TANDEM_SHARED_BVH8_TRAVERSE_H

#include "shared/bvh4_traverse.h"

TANDEM_NAMESPACE_BEGIN

#define BVH8_STACK_SIZE (7 * BVH8_MAX_DEPTH + 1)

/// No child held back (bvh8_intersect_any): node indices are below it.
#define BVH8_NONE 0xffffffffu

/// 1: the closest-hit loop takes its nearest child next without a push and a pop (and tests it
/// where it is a leaf), and the any-hit loop holds its last interior child back the same way.
/// That saves stack traffic where PoCL keeps the stack in memory (Clang for x86); on a GPU the
/// extra leaf test and branches made forward renders slower, so GPUs push
/// every child and pop the nearest. The same
/// visits in the same order either way, so the same hits.
#define BVH8_HOLD_NEAREST TANDEM_X86_CLANG

TANDEM_INLINE float8 bvh8_min(float8 a, float8 b) {
    return select(b, a, isless(a, b));
}
TANDEM_INLINE float8 bvh8_max(float8 a, float8 b) {
    return select(a, b, isless(a, b));
}

/// The float offset, within a Bvh8Node, of the bound array that holds the near slab plane of
/// `axis` (0, 1, 2) for inverse direction component `id`: min_* for id >= 0, max_* (24 floats
/// further) otherwise. The far plane is at 2 * 8 * axis + 24 - this. Computed once per ray, so
/// a node visit finds its six arrays by address arithmetic instead of six selects.
TANDEM_INLINE int bvh8_near_offset(float id, int axis) {
    return 8 * axis + (id >= 0.0f ? 0 : 24);
}

/// bvh8_near_offset of the ray's three axes in x, y, z (w unused), returned by value (no address
/// taken: PoCL would keep such a local in memory; bvh_tri4.h).
TANDEM_INLINE int4 bvh8_near_offsets(const RayPre* r) {
    int4 n;
    n.x = bvh8_near_offset(r->idx, 0);
    n.y = bvh8_near_offset(r->idy, 1);
    n.z = bvh8_near_offset(r->idz, 2);
    n.w = 0;
    return n;
}

/// Entry distances of the ray into the eight child boxes, INFINITY in lanes it misses: bvh4_enter
/// lane for lane (the same operations in the same order). planes: bvh8_near_offsets.
TANDEM_INLINE float8 bvh8_enter(const RayPre* r, TANDEM_GLOBAL const Bvh8Node* n, float tmax,
                                int4 planes) {
    TANDEM_GLOBAL const float* b = n->min_x; // the six bound arrays, one after another
    const int nx = planes.x, ny = planes.y, nz = planes.z;
    const float8 ox = splat_float8(r->ox), oy = splat_float8(r->oy), oz = splat_float8(r->oz);
    const float8 tnx = (vload8(0, b + nx) - ox) * r->idx;
    const float8 tfx = (vload8(0, b + (24 - nx)) - ox) * r->idx;
    const float8 tny = (vload8(0, b + ny) - oy) * r->idy;
    const float8 tfy = (vload8(0, b + (40 - ny)) - oy) * r->idy;
    const float8 tnz = (vload8(0, b + nz) - oz) * r->idz;
    const float8 tfz = (vload8(0, b + (56 - nz)) - oz) * r->idz;
    const float8 tnear = bvh8_max(bvh8_max(tnx, tny), bvh8_max(tnz, splat_float8(r->tmin)));
    const float8 tfar =
        bvh8_min(bvh8_min(tfx, tfy), bvh8_min(tfz, splat_float8(tmax))) * BVH_TFAR_SCALE;
    return select(splat_float8(INFINITY), tnear, islessequal(tnear, tfar));
}

/// Bit k set where lane k of the comparison result `m` (-1 or 0) is true.
TANDEM_INLINE uint bvh8_bits(int8 m) {
#if BVH_MOVEMASK
    return (uint)__builtin_ia32_movmskps256(as_float8(m));
#else
    return (uint)((m.s0 & 1) | (m.s1 & 2) | (m.s2 & 4) | (m.s3 & 8) | (m.s4 & 16) | (m.s5 & 32) |
                  (m.s6 & 64) | (m.s7 & 128));
#endif
}

/// The index of the lowest set bit of a nonzero `bits`.
TANDEM_INLINE uint bvh8_lowest(uint bits) {
    return 31u - clz(bits & (0u - bits));
}

/// BVH_PREFETCH 1 (the FeatureSet's choice on CPUs for trees too large to stay in cache:
/// prefers_prefetch in core/render/policy.h): a node visit asks the cache for every child the ray enters
/// before it tests or pushes any of them, so that the loads of the children it visits later
/// overlap the work on the nearest. PoCL runs one work item's traversal to its end before the
/// next, so nothing else hides a miss. The request is Clang's __builtin_prefetch (one x86
/// prefetcht0 per line) where the compiler is Clang for x86 with AVX (TANDEM_X86_CLANG,
/// compat.h); elsewhere it compiles to nothing (Oclgrind, for one, cannot run LLVM's prefetch
/// intrinsic). 0: nothing is asked (small trees, where it only costs instructions; GPUs; the host
/// build). Prefetches change no result.
#ifndef BVH_PREFETCH
#define BVH_PREFETCH 0
#endif
#define BVH8_PREFETCHES (BVH_PREFETCH && TANDEM_X86_CLANG)

/// Asks for the 256 bytes at p (a Bvh8Node, a leaf's first BvhTri4 block, or its first four
/// triangle records) to be brought into the cache: four lines of 64 bytes.
TANDEM_INLINE void bvh8_prefetch(TANDEM_GLOBAL const void* p) {
#if BVH8_PREFETCHES
    TANDEM_GLOBAL const char* c = (TANDEM_GLOBAL const char*)p;
    __builtin_prefetch(c);
    __builtin_prefetch(c + 64);
    __builtin_prefetch(c + 128);
    __builtin_prefetch(c + 192);
#else
    (void)p;
#endif
}

/// bvh8_prefetch of each child of node n that `bits` selects: an interior node or a leaf's data.
TANDEM_INLINE void bvh8_prefetch_children(TANDEM_GLOBAL const Bvh8Node* nodes,
                                          TANDEM_GLOBAL const BvhTriangle* tris,
                                          TANDEM_GLOBAL const Bvh8Node* n, uint bits) {
#if BVH8_PREFETCHES
    for (; bits != 0u; bits &= bits - 1u) {
        const uint k = bvh8_lowest(bits);
        bvh8_prefetch(n->count[k] == 0u ? (TANDEM_GLOBAL const void*)&nodes[n->child[k]]
                                        : (TANDEM_GLOBAL const void*)(tris + n->child[k]));
    }
#else
    (void)nodes;
    (void)tris;
    (void)n;
    (void)bits;
#endif
}

/// As bvh4_intersect_closest_into, over the eight-wide layout.
TANDEM_INLINE void bvh8_intersect_closest_into(TANDEM_GLOBAL const Bvh8Node* nodes,
                                               TANDEM_GLOBAL const BvhTriangle* tris, Ray ray,
                                               int tri4, Hit* out) {
    const RayPre r = bvh_ray_prepare(ray);
    const int4 planes = bvh8_near_offsets(&r);
    Hit hit = bvh_miss(r.tmax);
    uint stack_first[BVH8_STACK_SIZE];
    uint stack_count[BVH8_STACK_SIZE];
    float stack_dist[BVH8_STACK_SIZE];
    int sp = 0;
    uint node = 0;
    for (;;) {
        TANDEM_GLOBAL const Bvh8Node* np = &nodes[node];
        const float8 d = bvh8_enter(&r, np, hit.t, planes);
        const float limit = bvh_cull_limit(hit.t);
        // Step 1: the children the ray enters before the closest hit. Missed lanes are INFINITY,
        // which the cull test alone would accept while hit.t is still an infinite tmax; hence
        // both tests.
        uint bits =
            bvh8_bits(isless(d, splat_float8(INFINITY)) & islessequal(d, splat_float8(limit)));
#if BVH8_HOLD_NEAREST
        if (bits != 0u) {
            bvh8_prefetch_children(nodes, tris, np, bits);
            float dist[8];
            vstore8(d, 0, dist);
            // Step 2: all but the nearest go on the stack, nearest on top, and the nearest is
            // taken next without a push and a pop: an interior node is visited, a leaf tested.
            // Of equal entry distances the highest lane counts as nearest, as the sorted push
            // orders ties (the later push on top), so the stack and the order of visits are
            // those of pushing every child and popping the top: a child is held back only until
            // a later lane at most as far displaces it.
            const int base = sp;
            uint near = bvh8_lowest(bits);
            bits &= bits - 1u;
            while (bits != 0u) {
                const uint k = bvh8_lowest(bits);
                bits &= bits - 1u;
                const int displaces = dist[k] <= dist[near];
                const uint pushed = displaces ? near : k;
                near = displaces ? k : near;
                bvh4_push_entry_sorted(stack_first, stack_count, stack_dist, base, &sp,
                                       np->child[pushed], np->count[pushed], dist[pushed]);
            }
            const uint count = np->count[near];
            if (count == 0u) {
                node = np->child[near];
                continue;
            }
            if (tri4)
                bvh_tri4_leaf_closest(&r, tris, np->child[near], count, &hit);
            else
                bvh_leaf_closest(&r, tris, np->child[near], count, &hit);
        }
#else
        float dist[8];
        vstore8(d, 0, dist);
        // Step 2: every child on the stack, nearest on top (ties: the later lane on top).
        const int base = sp;
        while (bits != 0u) {
            const uint k = bvh8_lowest(bits);
            bits &= bits - 1u;
            bvh4_push_entry_sorted(stack_first, stack_count, stack_dist, base, &sp, np->child[k],
                                   np->count[k], dist[k]);
        }
#endif
        // Step 3: the nearest interior node still ahead, its leaves tested on the way.
        if (!bvh_pop_to_node(&r, tris, tri4, stack_first, stack_count, stack_dist, &sp, &hit,
                             &node)) {
            *out = hit;
            return;
        }
    }
}

/// bvh8_intersect_closest_into, returned.
TANDEM_INLINE Hit bvh8_intersect_closest(TANDEM_GLOBAL const Bvh8Node* nodes,
                                         TANDEM_GLOBAL const BvhTriangle* tris, Ray ray, int tri4) {
    Hit hit;
    bvh8_intersect_closest_into(nodes, tris, ray, tri4, &hit);
    return hit;
}

/// As bvh4_intersect_any, over the eight-wide layout.
TANDEM_INLINE int bvh8_intersect_any(TANDEM_GLOBAL const Bvh8Node* nodes,
                                     TANDEM_GLOBAL const BvhTriangle* tris, Ray ray, int tri4) {
    const RayPre r = bvh_ray_prepare(ray);
    const int4 planes = bvh8_near_offsets(&r);
    uint stack_node[BVH8_STACK_SIZE];
    int sp = 0;
    uint node = 0;
    for (;;) {
        TANDEM_GLOBAL const Bvh8Node* np = &nodes[node];
        const float8 d = bvh8_enter(&r, np, r.tmax, planes);
        uint bits = bvh8_bits(isnotequal(d, splat_float8(INFINITY)));
#if BVH8_HOLD_NEAREST
        // Leaves are tested as they come, interior children go on the stack in lane order; the
        // last of them is held back and visited next, as a push and a pop would.
        bvh8_prefetch_children(nodes, tris, np, bits);
        uint next = BVH8_NONE;
        while (bits != 0u) {
            const uint k = bvh8_lowest(bits);
            bits &= bits - 1u;
            const uint count = np->count[k];
            if (count == 0u) {
                if (next != BVH8_NONE) stack_node[sp++] = next;
                next = np->child[k];
            } else if (bvh4_leaf_any(&r, tris, np->child[k], count, tri4)) {
                return 1;
            }
        }
        if (next != BVH8_NONE) {
            node = next;
            continue;
        }
#else
        // Leaves are tested as they come, interior children go on the stack in lane order.
        while (bits != 0u) {
            const uint k = bvh8_lowest(bits);
            bits &= bits - 1u;
            const uint count = np->count[k];
            if (count == 0u)
                stack_node[sp++] = np->child[k];
            else if (bvh4_leaf_any(&r, tris, np->child[k], count, tri4))
                return 1;
        }
#endif
        if (sp == 0) return 0;
        node = stack_node[--sp];
    }
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_BVH8_TRAVERSE_H
