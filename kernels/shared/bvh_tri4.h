// Leaves of four-triangle blocks (BvhTri4): one ray tests four triangles with float4 arithmetic,
// as Embree's single-ray kernels test its Triangle4 leaves. The operations of each lane are those
// of bvh_triangle_intersect_axis, in its order, so every triangle gives the same t, u and v bits
// as the one-record test, and the hit rules (closest, lowest primitive id among equal t) are the
// same: traversal over either leaf format reports the same hits.
#ifndef TANDEM_SHARED_BVH_TRI4_H
#define TANDEM_SHARED_BVH_TRI4_H

#include "shared/bvh_traverse.h"

TANDEM_NAMESPACE_BEGIN

/// Component k (0, 1, 2) of the lanes' points (x, y, z); k is a literal in the axis loops.
TANDEM_INLINE float4 bvh_tri4_component(float4 x, float4 y, float4 z, int k) {
    return k == 0 ? x : (k == 1 ? y : z);
}

/// Bit k of the result is set where lane k of the mask (a comparison's -1 or 0) is.
TANDEM_INLINE uint bvh_tri4_bits(int4 m) {
#if BVH_MOVEMASK
    return (uint)__builtin_ia32_movmskps(as_float4(m));
#else
    return ((uint)m.x & 1u) | ((uint)m.y & 2u) | ((uint)m.z & 4u) | ((uint)m.w & 8u);
#endif
}

/// Keeps triangle `prim`'s hit at t in *hit by bvh_leaf_closest_axis's rule (t within the
/// closest hit so far; nearer, or as near with a lower primitive id).
TANDEM_INLINE void bvh_tri4_keep(Hit* hit, float t, uint prim, float V, float W, float det) {
    if (!(t <= hit->t)) return;
    if (t < hit->t || (hit->prim != HIT_NONE && prim < hit->prim)) {
        const float inv_det = 1.0f / det;
        hit->t = t;
        hit->prim = prim;
        hit->u = V * inv_det;
        hit->v = W * inv_det;
    }
}

/// The four triangles of block b against a ray whose dominant axis is `kz` (r->kz). With a
/// closest-hit record `keep` (the closest-hit loops), the lanes hit with tmin <= t <= tmax
/// (closed, as the one-record test) are kept in it lane by lane (bvh_tri4_keep, lowest lane
/// first, so ties resolve as in the one-record loop), and the result is nonzero where any was.
/// With keep = 0 (a literal: the any-hit loops), bit k of the result is set where triangle k is
/// hit in [tmin, tmax). The plane distances are computed only when some lane passes the edge
/// tests.
///
/// One function without output parameters: PoCL gives each local whose address a helper takes
/// a per-work-item slot in memory (its work-item loops privatise every alloca that one mem2reg
/// before them leaves), so four float4 results passed out by pointer were stored and reloaded
/// at every leaf visit.
TANDEM_INLINE uint bvh_tri4_hits_axis(const RayPre* r, TANDEM_GLOBAL const BvhTri4* b, float tmax,
                                      int kz, Hit* keep) {
    const int kp = kz == 2 ? 0 : kz + 1, kq = kp == 2 ? 0 : kp + 1;
    const float4 zero = splat_float4(0.0f);
    // Step 1: vertices relative to the origin.
    const float4 ox = splat_float4(r->ox), oy = splat_float4(r->oy), oz = splat_float4(r->oz);
    const float4 ax = b->ax - ox, ay = b->ay - oy, az = b->az - oz;
    const float4 bx = b->bx - ox, by = b->by - oy, bz = b->bz - oz;
    const float4 cx = b->cx - ox, cy = b->cy - oy, cz = b->cz - oz;
    const float4 akz = bvh_tri4_component(ax, ay, az, kz);
    const float4 bkz = bvh_tri4_component(bx, by, bz, kz);
    const float4 ckz = bvh_tri4_component(cx, cy, cz, kz);
    // Step 2: shear.
    const float4 Ap = bvh_tri4_component(ax, ay, az, kp) - akz * r->shear_p;
    const float4 Aq = bvh_tri4_component(ax, ay, az, kq) - akz * r->shear_q;
    const float4 Bp = bvh_tri4_component(bx, by, bz, kp) - bkz * r->shear_p;
    const float4 Bq = bvh_tri4_component(bx, by, bz, kq) - bkz * r->shear_q;
    const float4 Cp = bvh_tri4_component(cx, cy, cz, kp) - ckz * r->shear_p;
    const float4 Cq = bvh_tri4_component(cx, cy, cz, kq) - ckz * r->shear_q;
    // Step 3: scaled barycentrics; a lane is inside where they do not differ in sign.
    const float4 u1 = Cp * Bq, u2 = Cq * Bp;
    const float4 v1 = Ap * Cq, v2 = Aq * Cp;
    const float4 w1 = Bp * Aq, w2 = Bq * Ap;
    const float4 U = r->swap ? u2 - u1 : u1 - u2;
    const float4 V = r->swap ? v2 - v1 : v1 - v2;
    const float4 W = r->swap ? w2 - w1 : w1 - w2;
    const int4 outside = (isless(U, zero) | isless(V, zero) | isless(W, zero)) &
                         (isless(zero, U) | isless(zero, V) | isless(zero, W));
    const float4 det = U + V + W;
    const int4 inside = ~outside & isnotequal(det, zero);
    if (bvh_tri4_bits(inside) == 0u) return 0u;
    // Step 4: t from the plane of each triangle (the blocks' normals, bvh_triangle_plane_normal).
    const float4 nx = b->nx, ny = b->ny, nz = b->nz;
    const float4 den = nx * r->dx + ny * r->dy + nz * r->dz;
    const float4 t = (ax * nx + ay * ny + az * nz) / den;
    const int4 hit = inside & isnotequal(den, zero) & islessequal(splat_float4(r->tmin), t) &
                     islessequal(t, splat_float4(tmax));
    if (!keep) return bvh_tri4_bits(hit & isless(t, splat_float4(tmax)));
    const uint lanes = bvh_tri4_bits(hit);
    if (lanes == 0u) return 0u;
    const uint4 prim = b->prim;
    if (lanes & 1u) bvh_tri4_keep(keep, t.x, prim.x, V.x, W.x, det.x);
    if (lanes & 2u) bvh_tri4_keep(keep, t.y, prim.y, V.y, W.y, det.y);
    if (lanes & 4u) bvh_tri4_keep(keep, t.z, prim.z, V.z, W.z, det.z);
    if (lanes & 8u) bvh_tri4_keep(keep, t.w, prim.w, V.w, W.w, det.w);
    return lanes;
}

/// bvh_tri4_leaf_closest for a ray whose dominant axis is the constant `kz`.
TANDEM_INLINE void bvh_tri4_leaf_closest_axis(const RayPre* r,
                                              TANDEM_GLOBAL const BvhTriangle* tris, uint first,
                                              uint count, Hit* hit, int kz) {
    TANDEM_GLOBAL const BvhTri4* b = (TANDEM_GLOBAL const BvhTri4*)(tris + first);
    for (uint k = 0; k < count; k += 4u, ++b)
        bvh_tri4_hits_axis(r, b, hit->t, kz, hit);
}

/// bvh_leaf_closest over the ceil(count / 4) blocks of a BvhTri4 leaf at record `first`.
TANDEM_INLINE void bvh_tri4_leaf_closest(const RayPre* r, TANDEM_GLOBAL const BvhTriangle* tris,
                                         uint first, uint count, Hit* hit) {
#if BVH_AXIS_LOOPS
    if (r->kz == 0)
        bvh_tri4_leaf_closest_axis(r, tris, first, count, hit, 0);
    else if (r->kz == 1)
        bvh_tri4_leaf_closest_axis(r, tris, first, count, hit, 1);
    else
        bvh_tri4_leaf_closest_axis(r, tris, first, count, hit, 2);
#else
    bvh_tri4_leaf_closest_axis(r, tris, first, count, hit, r->kz);
#endif
}

/// bvh_tri4_leaf_any for a ray whose dominant axis is the constant `kz`.
TANDEM_INLINE int bvh_tri4_leaf_any_axis(const RayPre* r, TANDEM_GLOBAL const BvhTriangle* tris,
                                         uint first, uint count, int kz) {
    TANDEM_GLOBAL const BvhTri4* b = (TANDEM_GLOBAL const BvhTri4*)(tris + first);
    for (uint k = 0; k < count; k += 4u, ++b)
        if (bvh_tri4_hits_axis(r, b, r->tmax, kz, 0) != 0u) return 1;
    return 0;
}

/// bvh_leaf_any over the blocks of a BvhTri4 leaf: 1 if any of its triangles is hit in
/// [tmin, tmax).
TANDEM_INLINE int bvh_tri4_leaf_any(const RayPre* r, TANDEM_GLOBAL const BvhTriangle* tris,
                                    uint first, uint count) {
#if BVH_AXIS_LOOPS
    if (r->kz == 0) return bvh_tri4_leaf_any_axis(r, tris, first, count, 0);
    if (r->kz == 1) return bvh_tri4_leaf_any_axis(r, tris, first, count, 1);
    return bvh_tri4_leaf_any_axis(r, tris, first, count, 2);
#else
    return bvh_tri4_leaf_any_axis(r, tris, first, count, r->kz);
#endif
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_BVH_TRI4_H
