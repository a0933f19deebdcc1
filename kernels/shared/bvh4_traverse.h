// Closest-hit and any-hit traversal of the four-wide BVH (Bvh4Node): one ray tests its four child
// boxes, and then the four triangles of a leaf group (BvhTri4), with float4 arithmetic, which CPU
// OpenCL compilers map to SIMD (Embree's single-ray BVH4 approach). The per-ray setup is shared
// with the two-wide traversal, and the triangle test is bvh_triangle_intersect's, lane by lane:
// the same operations in the same order, so the hits are the same bits.
#ifndef TANDEM_SHARED_BVH4_TRAVERSE_H
#define TANDEM_SHARED_BVH4_TRAVERSE_H

#include "shared/bvh_traverse.h"

TANDEM_NAMESPACE_BEGIN

#define BVH4_STACK_SIZE (3 * BVH4_MAX_DEPTH)

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

/// One of three float4 by the ray's axis index k (0, 1, 2): the shear's permutation.
TANDEM_INLINE float4 bvh4_axis(float4 x, float4 y, float4 z, int k) {
    return k == 0 ? x : (k == 1 ? y : z);
}

/// bvh_triangle_intersect for the four triangles of a group at once. Lanes where the ray hits with
/// tmin <= t <= tmax are -1 in the result; *t, *V and *det hold every lane's distance and scaled
/// barycentrics (u = V / det, v = W / det: *W likewise). Lanes past a leaf's end are the caller's
/// to ignore.
TANDEM_INLINE int4 bvh4_triangles_intersect(const RayPre* r, TANDEM_GLOBAL const BvhTri4* g,
                                            float tmax, float4* t_out, float4* V_out,
                                            float4* W_out, float4* det_out) {
    const float4 zero = splat_float4(0.0f);
    // Step 1: vertices relative to the origin, permuted so the ray runs along +z.
    const float4 ox = splat_float4(r->ox), oy = splat_float4(r->oy), oz = splat_float4(r->oz);
    const float4 ax = g->v0x - ox, ay = g->v0y - oy, az = g->v0z - oz;
    const float4 bx = g->v1x - ox, by = g->v1y - oy, bz = g->v1z - oz;
    const float4 cx = g->v2x - ox, cy = g->v2y - oy, cz = g->v2z - oz;
    const float4 akz = bvh4_axis(ax, ay, az, r->kz), bkz = bvh4_axis(bx, by, bz, r->kz),
                 ckz = bvh4_axis(cx, cy, cz, r->kz);
    // Step 2: shear.
    const float4 sx = splat_float4(r->sx), sy = splat_float4(r->sy);
    const float4 Ax = bvh4_axis(ax, ay, az, r->kx) - sx * akz;
    const float4 Ay = bvh4_axis(ax, ay, az, r->ky) - sy * akz;
    const float4 Bx = bvh4_axis(bx, by, bz, r->kx) - sx * bkz;
    const float4 By = bvh4_axis(bx, by, bz, r->ky) - sy * bkz;
    const float4 Cx = bvh4_axis(cx, cy, cz, r->kx) - sx * ckz;
    const float4 Cy = bvh4_axis(cx, cy, cz, r->ky) - sy * ckz;
    // Step 3: scaled barycentrics; mixed signs mean outside, a zero sum degenerate.
    const float4 U = Cx * By - Cy * Bx;
    const float4 V = Ax * Cy - Ay * Cx;
    const float4 W = Bx * Ay - By * Ax;
    const int4 negative = isless(U, zero) | isless(V, zero) | isless(W, zero);
    const int4 positive = isgreater(U, zero) | isgreater(V, zero) | isgreater(W, zero);
    const float4 det = U + V + W;
    int4 hit = ~(negative & positive) & isnotequal(det, zero);
    // Step 4: distance from the plane equation, the normal taken at the vertex opposite the
    // longest edge (see bvh_triangle_intersect), chosen lane by lane.
    const float4 fx = g->v2x - g->v1x, fy = g->v2y - g->v1y, fz = g->v2z - g->v1z;
    const float4 gx = g->v0x - g->v2x, gy = g->v0y - g->v2y, gz = g->v0z - g->v2z;
    const float4 hx = g->v1x - g->v0x, hy = g->v1y - g->v0y, hz = g->v1z - g->v0z;
    const float4 lf = fx * fx + fy * fy + fz * fz;
    const float4 lg = gx * gx + gy * gy + gz * gz;
    const float4 lh = hx * hx + hy * hy + hz * hz;
    const int4 at_v0 = isgreaterequal(lf, lg) & isgreaterequal(lf, lh);
    const int4 at_v1 = isgreaterequal(lg, lh); // where not at_v0
    const float4 px = select(select(gx, fx, at_v1), hx, at_v0);
    const float4 py = select(select(gy, fy, at_v1), hy, at_v0);
    const float4 pz = select(select(gz, fz, at_v1), hz, at_v0);
    const float4 qx = select(select(-fx, -hx, at_v1), -gx, at_v0);
    const float4 qy = select(select(-fy, -hy, at_v1), -gy, at_v0);
    const float4 qz = select(select(-fz, -hz, at_v1), -gz, at_v0);
    const float4 nx = py * qz - pz * qy, ny = pz * qx - px * qz, nz = px * qy - py * qx;
    const float4 den = nx * splat_float4(r->dx) + ny * splat_float4(r->dy) + nz * splat_float4(r->dz);
    const float4 t = (ax * nx + ay * ny + az * nz) / den;
    hit = hit & isnotequal(den, zero) & isgreaterequal(t, splat_float4(r->tmin)) &
          islessequal(t, splat_float4(tmax));
    *t_out = t;
    *V_out = V;
    *W_out = W;
    *det_out = det;
    return hit;
}

/// Lane L of a group's test, in leaf order, under bvh_leaf_closest's rule: the closer hit, or at
/// equal t the lower primitive id.
#define BVH4_TAKE_LANE(L)                                                                          \
    if (hit4.L && t.L <= hit->t &&                                                                 \
        (t.L < hit->t || (hit->prim != HIT_NONE && g->prim.L < hit->prim))) {                      \
        const float inv_det = 1.0f / det.L;                                                        \
        hit->t = t.L;                                                                              \
        hit->prim = g->prim.L;                                                                     \
        hit->u = V.L * inv_det;                                                                    \
        hit->v = W.L * inv_det;                                                                    \
    }

/// bvh_leaf_closest over the leaf of `count` triangles starting at triangle slot `first` (a
/// multiple of 4): the same hit, the same bits.
TANDEM_INLINE void bvh4_leaf_closest(const RayPre* r, TANDEM_GLOBAL const BvhTriangle* tris,
                                     uint first, uint count, Hit* hit) {
    TANDEM_GLOBAL const BvhTri4* g = (TANDEM_GLOBAL const BvhTri4*)tris + (first >> 2);
    for (uint left = count;; ++g, left -= 4) {
        float4 t, V, W, det;
        const int4 hit4 = bvh4_triangles_intersect(r, g, hit->t, &t, &V, &W, &det);
        BVH4_TAKE_LANE(x)
        if (left > 1) BVH4_TAKE_LANE(y)
        if (left > 2) BVH4_TAKE_LANE(z)
        if (left > 3) BVH4_TAKE_LANE(w)
        if (left <= 4) return;
    }
}
#undef BVH4_TAKE_LANE

/// 1 if any of the leaf's triangles is hit in [tmin, tmax).
TANDEM_INLINE int bvh4_leaf_any(const RayPre* r, TANDEM_GLOBAL const BvhTriangle* tris, uint first,
                                uint count) {
    TANDEM_GLOBAL const BvhTri4* g = (TANDEM_GLOBAL const BvhTri4*)tris + (first >> 2);
    for (uint left = count;; ++g, left -= 4) {
        float4 t, V, W, det;
        int4 hit4 = bvh4_triangles_intersect(r, g, r->tmax, &t, &V, &W, &det);
        hit4 = hit4 & isless(t, splat_float4(r->tmax)); // after the call has written t
        if (hit4.x || (left > 1 && hit4.y) || (left > 2 && hit4.z) || (left > 3 && hit4.w))
            return 1;
        if (left <= 4) return 0;
    }
}

/// Pushes (node, dist) onto the stack, keeping the entries above `base` sorted so the nearest is
/// on top.
TANDEM_INLINE void bvh4_push_sorted(uint* stack_node, float* stack_dist, int base, int* sp,
                                    uint node, float dist) {
    int i = *sp;
    while (i > base && stack_dist[i - 1] < dist) {
        stack_node[i] = stack_node[i - 1];
        stack_dist[i] = stack_dist[i - 1];
        --i;
    }
    stack_node[i] = node;
    stack_dist[i] = dist;
    *sp += 1;
}

/// The closest hit along the ray in [tmin, tmax), or prim == HIT_NONE, written to *out (through a
/// pointer for Oclgrind: see TANDEM_INLINE in compat.h).
TANDEM_INLINE void bvh4_intersect_closest_into(TANDEM_GLOBAL const Bvh4Node* nodes,
                                               TANDEM_GLOBAL const BvhTriangle* tris, Ray ray,
                                               Hit* out) {
    const RayPre r = bvh_ray_prepare(ray);
    Hit hit = bvh_miss(r.tmax);
    uint stack_node[BVH4_STACK_SIZE];
    float stack_dist[BVH4_STACK_SIZE];
    int sp = 0;
    uint node = 0;
    for (;;) {
        TANDEM_GLOBAL const Bvh4Node* np = &nodes[node];
        const uint4 child = np->child, count = np->count;
        // Missed lanes are INFINITY, which the cull test alone would accept while hit.t is still
        // an infinite tmax; hence both tests below.
        const float4 d = bvh4_enter(&r, np, hit.t);
        // Step 1: leaves are intersected right away.
        if (count.x != 0 && d.x < INFINITY && d.x <= bvh_cull_limit(hit.t))
            bvh4_leaf_closest(&r, tris, child.x, count.x, &hit);
        if (count.y != 0 && d.y < INFINITY && d.y <= bvh_cull_limit(hit.t))
            bvh4_leaf_closest(&r, tris, child.y, count.y, &hit);
        if (count.z != 0 && d.z < INFINITY && d.z <= bvh_cull_limit(hit.t))
            bvh4_leaf_closest(&r, tris, child.z, count.z, &hit);
        if (count.w != 0 && d.w < INFINITY && d.w <= bvh_cull_limit(hit.t))
            bvh4_leaf_closest(&r, tris, child.w, count.w, &hit);
        // Step 2: interior children in front of the closest hit go on the stack, nearest on top.
        const int base = sp;
        if (count.x == 0 && d.x < INFINITY && d.x <= bvh_cull_limit(hit.t))
            bvh4_push_sorted(stack_node, stack_dist, base, &sp, child.x, d.x);
        if (count.y == 0 && d.y < INFINITY && d.y <= bvh_cull_limit(hit.t))
            bvh4_push_sorted(stack_node, stack_dist, base, &sp, child.y, d.y);
        if (count.z == 0 && d.z < INFINITY && d.z <= bvh_cull_limit(hit.t))
            bvh4_push_sorted(stack_node, stack_dist, base, &sp, child.z, d.z);
        if (count.w == 0 && d.w < INFINITY && d.w <= bvh_cull_limit(hit.t))
            bvh4_push_sorted(stack_node, stack_dist, base, &sp, child.w, d.w);
        // Step 3: pop the nearest entry that still starts before the closest hit.
        for (;;) {
            if (sp == 0) {
                *out = hit;
                return;
            }
            --sp;
            if (stack_dist[sp] <= bvh_cull_limit(hit.t)) break;
        }
        node = stack_node[sp];
    }
}

/// bvh4_intersect_closest_into, returned.
TANDEM_INLINE Hit bvh4_intersect_closest(TANDEM_GLOBAL const Bvh4Node* nodes,
                                         TANDEM_GLOBAL const BvhTriangle* tris, Ray ray) {
    Hit hit;
    bvh4_intersect_closest_into(nodes, tris, ray, &hit);
    return hit;
}

/// 1 if anything is hit along the ray in [tmin, tmax), else 0. Stops at the first hit found.
TANDEM_INLINE int bvh4_intersect_any(TANDEM_GLOBAL const Bvh4Node* nodes,
                                     TANDEM_GLOBAL const BvhTriangle* tris, Ray ray) {
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
            else if (bvh4_leaf_any(&r, tris, child.x, count.x)) return 1;
        }
        if (d.y != INFINITY) {
            if (count.y == 0) stack_node[sp++] = child.y;
            else if (bvh4_leaf_any(&r, tris, child.y, count.y)) return 1;
        }
        if (d.z != INFINITY) {
            if (count.z == 0) stack_node[sp++] = child.z;
            else if (bvh4_leaf_any(&r, tris, child.z, count.z)) return 1;
        }
        if (d.w != INFINITY) {
            if (count.w == 0) stack_node[sp++] = child.w;
            else if (bvh4_leaf_any(&r, tris, child.w, count.w)) return 1;
        }
        if (sp == 0) return 0;
        node = stack_node[--sp];
    }
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_BVH4_TRAVERSE_H
