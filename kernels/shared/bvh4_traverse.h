// Closest-hit and any-hit traversal of the four-wide BVH (Bvh4Node): one ray tests its four child
// boxes with float4 arithmetic, which CPU OpenCL compilers map to SIMD (Embree's single-ray BVH4
// approach). Triangles and the per-ray setup are shared with the two-wide traversal. Leaves hold
// BvhTriangle records or, where `tri4` is set, BvhTri4 blocks of four triangles (the kernels pass
// a literal, so the other test folds away).
#ifndef TANDEM_SHARED_BVH4_TRAVERSE_H
#define TANDEM_SHARED_BVH4_TRAVERSE_H

#include "shared/bvh_tri4.h"

TANDEM_NAMESPACE_BEGIN

#define BVH4_STACK_SIZE (3 * BVH4_MAX_DEPTH + 1)

TANDEM_INLINE float4 bvh4_min(float4 a, float4 b) { return select(b, a, isless(a, b)); }
TANDEM_INLINE float4 bvh4_max(float4 a, float4 b) { return select(a, b, isless(a, b)); }

/// Entry distances of the ray into the four child boxes, INFINITY in lanes it misses. The slab
/// planes are ordered by the direction's sign, so an unused lane (min > max) is never entered.
/// The exit distance is scaled by BVH_TFAR_SCALE so the test is conservative.
TANDEM_INLINE float4 bvh4_enter(const RayPre* r, TANDEM_GLOBAL const Bvh4Node* n, float tmax) {
    const float4 ox = splat_float4(r->ox), oy = splat_float4(r->oy), oz = splat_float4(r->oz);
    const float4 tnx = ((r->idx >= 0.0f ? n->min_x : n->max_x) - ox) * r->idx;
    const float4 tfx = ((r->idx >= 0.0f ? n->max_x : n->min_x) - ox) * r->idx;
    const float4 tny = ((r->idy >= 0.0f ? n->min_y : n->max_y) - oy) * r->idy;
    const float4 tfy = ((r->idy >= 0.0f ? n->max_y : n->min_y) - oy) * r->idy;
    const float4 tnz = ((r->idz >= 0.0f ? n->min_z : n->max_z) - oz) * r->idz;
    const float4 tfz = ((r->idz >= 0.0f ? n->max_z : n->min_z) - oz) * r->idz;
    const float4 tnear = bvh4_max(bvh4_max(tnx, tny), bvh4_max(tnz, splat_float4(r->tmin)));
    const float4 tfar =
        bvh4_min(bvh4_min(tfx, tfy), bvh4_min(tfz, splat_float4(tmax))) * BVH_TFAR_SCALE;
    return select(splat_float4(INFINITY), tnear, islessequal(tnear, tfar));
}

/// Pushes an entry onto the stack, keeping the entries above `base` sorted so the nearest is on
/// top. The entry is a leaf of `count` triangles from `first`, or the interior node `first` when
/// count is 0; `dist` is where the ray enters its box.
TANDEM_INLINE void bvh4_push_entry_sorted(uint* stack_first, uint* stack_count, float* stack_dist,
                                          int base, int* sp, uint first, uint count, float dist) {
    int i = *sp;
    while (i > base && stack_dist[i - 1] < dist) {
        stack_first[i] = stack_first[i - 1];
        stack_count[i] = stack_count[i - 1];
        stack_dist[i] = stack_dist[i - 1];
        --i;
    }
    stack_first[i] = first;
    stack_count[i] = count;
    stack_dist[i] = dist;
    *sp += 1;
}

/// Step 2 of the closest-hit traversals over the sorted stack (four- and eight-wide): pops the
/// nearest entries that still start before the closest hit, testing leaves into *hit (BvhTri4
/// blocks with `tri4`), until an interior node comes up. Returns 1 with that node in *node, or 0
/// when the stack is empty.
TANDEM_INLINE int bvh_pop_to_node(const RayPre* r, TANDEM_GLOBAL const BvhTriangle* tris, int tri4,
                                  const uint* stack_first, const uint* stack_count,
                                  const float* stack_dist, int* sp, Hit* hit, uint* node) {
    for (;;) {
        if (*sp == 0) return 0;
        const int top = --*sp;
        if (stack_dist[top] > bvh_cull_limit(hit->t)) continue;
        if (stack_count[top] == 0) {
            *node = stack_first[top];
            return 1;
        }
        if (tri4)
            bvh_tri4_leaf_closest(r, tris, stack_first[top], stack_count[top], hit);
        else
            bvh_leaf_closest(r, tris, stack_first[top], stack_count[top], hit);
    }
}

/// The closest hit along the ray in [tmin, tmax), or prim == HIT_NONE, written to *out (through a
/// pointer for Oclgrind: see TANDEM_INLINE in compat.h). Leaves and interior children share one
/// stack sorted by entry distance, so a leaf is tested only when nothing nearer is left and its
/// box still starts before the closest hit found so far. `tri4`: the leaves are BvhTri4 blocks.
TANDEM_INLINE void bvh4_intersect_closest_into(TANDEM_GLOBAL const Bvh4Node* nodes,
                                               TANDEM_GLOBAL const BvhTriangle* tris, Ray ray,
                                               int tri4, Hit* out) {
    const RayPre r = bvh_ray_prepare(ray);
    Hit hit = bvh_miss(r.tmax);
    uint stack_first[BVH4_STACK_SIZE];
    uint stack_count[BVH4_STACK_SIZE];
    float stack_dist[BVH4_STACK_SIZE];
    int sp = 0;
    uint node = 0;
    for (;;) {
        TANDEM_GLOBAL const Bvh4Node* np = &nodes[node];
        const uint4 child = np->child, count = np->count;
        // Missed lanes are INFINITY, which the cull test alone would accept while hit.t is still
        // an infinite tmax; hence both tests below.
        const float4 d = bvh4_enter(&r, np, hit.t);
        const float limit = bvh_cull_limit(hit.t);
        // Step 1: the children the ray enters before the closest hit go on the stack, nearest on
        // top.
        const int base = sp;
        if (d.x < INFINITY && d.x <= limit)
            bvh4_push_entry_sorted(stack_first, stack_count, stack_dist, base, &sp, child.x,
                                   count.x, d.x);
        if (d.y < INFINITY && d.y <= limit)
            bvh4_push_entry_sorted(stack_first, stack_count, stack_dist, base, &sp, child.y,
                                   count.y, d.y);
        if (d.z < INFINITY && d.z <= limit)
            bvh4_push_entry_sorted(stack_first, stack_count, stack_dist, base, &sp, child.z,
                                   count.z, d.z);
        if (d.w < INFINITY && d.w <= limit)
            bvh4_push_entry_sorted(stack_first, stack_count, stack_dist, base, &sp, child.w,
                                   count.w, d.w);
        // Step 2: the nearest interior node still ahead, its leaves tested on the way.
        if (!bvh_pop_to_node(&r, tris, tri4, stack_first, stack_count, stack_dist, &sp, &hit,
                             &node)) {
            *out = hit;
            return;
        }
    }
}

/// bvh4_intersect_closest_into, returned.
TANDEM_INLINE Hit bvh4_intersect_closest(TANDEM_GLOBAL const Bvh4Node* nodes,
                                         TANDEM_GLOBAL const BvhTriangle* tris, Ray ray, int tri4) {
    Hit hit;
    bvh4_intersect_closest_into(nodes, tris, ray, tri4, &hit);
    return hit;
}

/// bvh_leaf_any or, with `tri4`, bvh_tri4_leaf_any.
TANDEM_INLINE int bvh4_leaf_any(const RayPre* r, TANDEM_GLOBAL const BvhTriangle* tris, uint first,
                                uint count, int tri4) {
    return tri4 ? bvh_tri4_leaf_any(r, tris, first, count) : bvh_leaf_any(r, tris, first, count);
}

/// 1 if anything is hit along the ray in [tmin, tmax), else 0. Stops at the first hit found.
/// `tri4`: the leaves are BvhTri4 blocks.
TANDEM_INLINE int bvh4_intersect_any(TANDEM_GLOBAL const Bvh4Node* nodes,
                                     TANDEM_GLOBAL const BvhTriangle* tris, Ray ray, int tri4) {
    const RayPre r = bvh_ray_prepare(ray);
    uint stack_node[BVH4_STACK_SIZE];
    int sp = 0;
    uint node = 0;
    for (;;) {
        TANDEM_GLOBAL const Bvh4Node* np = &nodes[node];
        const uint4 child = np->child, count = np->count;
        const float4 d = bvh4_enter(&r, np, r.tmax);
        if (d.x != INFINITY) {
            if (count.x == 0) stack_node[sp++] = child.x;
            else if (bvh4_leaf_any(&r, tris, child.x, count.x, tri4))
                return 1;
        }
        if (d.y != INFINITY) {
            if (count.y == 0) stack_node[sp++] = child.y;
            else if (bvh4_leaf_any(&r, tris, child.y, count.y, tri4))
                return 1;
        }
        if (d.z != INFINITY) {
            if (count.z == 0) stack_node[sp++] = child.z;
            else if (bvh4_leaf_any(&r, tris, child.z, count.z, tri4))
                return 1;
        }
        if (d.w != INFINITY) {
            if (count.w == 0) stack_node[sp++] = child.w;
            else if (bvh4_leaf_any(&r, tris, child.w, count.w, tri4))
                return 1;
        }
        if (sp == 0) return 0;
        node = stack_node[--sp];
    }
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_BVH4_TRAVERSE_H
