// Closest hits of up to eight rays traced together through the eight-wide BVH of four-triangle
// blocks: lane k of every float8 is ray k, so one AVX instruction does a step of the slab or the
// triangle test for eight rays, as Embree's packet kernels (rtcIntersect8) do. For rays that go
// the same way, such as the camera rays of one pixel's samples, the packet visits about the nodes
// and leaves each ray would, for an eighth of the work per ray.
//
// Each ray gets the hit the one-ray traversal (bvh8_intersect_closest_into) gives it, bit for
// bit: every ray/triangle pair is tested with bvh_triangle_intersect_axis's operations in its
// order (components chosen per lane by selects instead of per ray by the axis loops), and the hit
// kept does not depend on the order leaves are tested in (the closest t in [tmin, tmax), the
// lowest primitive id among equal t: bvh_tri4_keep), while the culling of boxes is the one-ray
// traversal's, per lane (bvh_cull_limit). Device code only (OpenCL C vector operators).
#ifndef TANDEM_SHARED_BVH8_PACKET_H
#define TANDEM_SHARED_BVH8_PACKET_H

#include "shared/bvh8_traverse.h"

/// Rays in a packet.
#define BVH8_PACKET 8

/// The per-ray constants of bvh_ray_prepare, lane k for ray k, and the lanes' closest hits so far.
typedef struct BvhPacket8 {
    float8 ox, oy, oz, dx, dy, dz, idx, idy, idz, shear_p, shear_q, tmin;
    int8 kz0, kz1, kz2;    ///< the dominant axis: -1 in the lanes where kz is 0, 1 or 2
    int8 swap;             ///< -1 where the ray's dominant component is negative (RayPre.swap)
    int8 negx, negy, negz; ///< -1 where the inverse direction is negative (far plane is the min)
    float8 t;              ///< the closest hit so far (tmax at first)
    uint8 prim;
    float8 u, v;
} BvhPacket8;

/// The lanes' component of (x, y, z) on the axis whose masks are k0 (axis 0) and k1 (axis 1), any
/// other lane taking z: bvh_component lane by lane.
TANDEM_INLINE float8 bvh8p_component(float8 x, float8 y, float8 z, int8 k0, int8 k1) {
    return select(select(z, y, k1), x, k0);
}

/// The smallest and the largest lane of v (selects only: PoCL calls fmin and fmax).
TANDEM_INLINE float bvh8p_hmin(float8 v) {
    const float4 a = select(v.lo, v.hi, isless(v.hi, v.lo));
    const float2 b = select(a.lo, a.hi, isless(a.hi, a.lo));
    return b.y < b.x ? b.y : b.x;
}
TANDEM_INLINE float bvh8p_hmax(float8 v) {
    const float4 a = select(v.lo, v.hi, isless(v.lo, v.hi));
    const float2 b = select(a.lo, a.hi, isless(a.lo, a.hi));
    return b.x < b.y ? b.y : b.x;
}

/// Entry distances of the lanes into child c of node n, INFINITY where a lane misses it before
/// its closest hit so far: bvh8_enter's operations for one box, lane by lane.
TANDEM_INLINE float8 bvh8p_enter(const BvhPacket8* p, TANDEM_GLOBAL const Bvh8Node* n, uint c) {
    const float8 lox = (splat_float8(n->min_x[c]) - p->ox) * p->idx;
    const float8 hix = (splat_float8(n->max_x[c]) - p->ox) * p->idx;
    const float8 loy = (splat_float8(n->min_y[c]) - p->oy) * p->idy;
    const float8 hiy = (splat_float8(n->max_y[c]) - p->oy) * p->idy;
    const float8 loz = (splat_float8(n->min_z[c]) - p->oz) * p->idz;
    const float8 hiz = (splat_float8(n->max_z[c]) - p->oz) * p->idz;
    const float8 tnx = select(lox, hix, p->negx), tfx = select(hix, lox, p->negx);
    const float8 tny = select(loy, hiy, p->negy), tfy = select(hiy, loy, p->negy);
    const float8 tnz = select(loz, hiz, p->negz), tfz = select(hiz, loz, p->negz);
    const float8 tnear = bvh8_max(bvh8_max(tnx, tny), bvh8_max(tnz, p->tmin));
    const float8 tfar = bvh8_min(bvh8_min(tfx, tfy), bvh8_min(tfz, p->t)) * BVH_TFAR_SCALE;
    return select(splat_float8(INFINITY), tnear, islessequal(tnear, tfar));
}

/// Triangle `prim` (vertices a, b, c, plane normal n) against the lanes: the watertight test of
/// bvh_triangle_intersect_axis lane by lane, and the hit kept by bvh_tri4_keep's rule.
TANDEM_INLINE void bvh8p_triangle(BvhPacket8* p, int8 lanes, float3 a, float3 b, float3 c, float3 n,
                                  uint prim) {
    const float8 zero = splat_float8(0.0f);
    // Step 1: vertices relative to the origins.
    const float8 ax = splat_float8(a.x) - p->ox, ay = splat_float8(a.y) - p->oy,
                 az = splat_float8(a.z) - p->oz;
    const float8 bx = splat_float8(b.x) - p->ox, by = splat_float8(b.y) - p->oy,
                 bz = splat_float8(b.z) - p->oz;
    const float8 cx = splat_float8(c.x) - p->ox, cy = splat_float8(c.y) - p->oy,
                 cz = splat_float8(c.z) - p->oz;
    // axis p is kz + 1 (0 where kz is 2), q is kz + 2 (mod 3)
    const float8 akz = bvh8p_component(ax, ay, az, p->kz0, p->kz1);
    const float8 bkz = bvh8p_component(bx, by, bz, p->kz0, p->kz1);
    const float8 ckz = bvh8p_component(cx, cy, cz, p->kz0, p->kz1);
    // Step 2: shear.
    const float8 Ap = bvh8p_component(ax, ay, az, p->kz2, p->kz0) - p->shear_p * akz;
    const float8 Aq = bvh8p_component(ax, ay, az, p->kz1, p->kz2) - p->shear_q * akz;
    const float8 Bp = bvh8p_component(bx, by, bz, p->kz2, p->kz0) - p->shear_p * bkz;
    const float8 Bq = bvh8p_component(bx, by, bz, p->kz1, p->kz2) - p->shear_q * bkz;
    const float8 Cp = bvh8p_component(cx, cy, cz, p->kz2, p->kz0) - p->shear_p * ckz;
    const float8 Cq = bvh8p_component(cx, cy, cz, p->kz1, p->kz2) - p->shear_q * ckz;
    // Step 3: scaled barycentrics.
    const float8 u1 = Cp * Bq, u2 = Cq * Bp;
    const float8 v1 = Ap * Cq, v2 = Aq * Cp;
    const float8 w1 = Bp * Aq, w2 = Bq * Ap;
    const float8 U = select(u1 - u2, u2 - u1, p->swap);
    const float8 V = select(v1 - v2, v2 - v1, p->swap);
    const float8 W = select(w1 - w2, w2 - w1, p->swap);
    const int8 outside = (isless(U, zero) | isless(V, zero) | isless(W, zero)) &
                         (isless(zero, U) | isless(zero, V) | isless(zero, W));
    const float8 det = U + V + W;
    const int8 inside = lanes & ~outside & isnotequal(det, zero);
    if (bvh8_bits(inside) == 0u) return;
    // Step 4: t from the plane.
    const float8 den = n.x * p->dx + n.y * p->dy + n.z * p->dz;
    const float8 t = (ax * n.x + ay * n.y + az * n.z) / den;
    const int8 hit =
        inside & isnotequal(den, zero) & islessequal(p->tmin, t) & islessequal(t, p->t);
    // kept: nearer, or as near with a lower primitive id than a hit already kept
    const int8 kept_before = p->prim != (uint8)(HIT_NONE);
    const int8 lower = p->prim > (uint8)(prim);
    const int8 keep = hit & (isless(t, p->t) | (kept_before & lower));
    if (bvh8_bits(keep) == 0u) return;
    const float8 inv_det = splat_float8(1.0f) / det;
    p->t = select(p->t, t, keep);
    p->prim = select(p->prim, (uint8)prim, keep);
    p->u = select(p->u, V * inv_det, keep);
    p->v = select(p->v, W * inv_det, keep);
}

/// The four triangles of block b against the lanes set in `lanes` (padded lanes never hit: their
/// vertices coincide).
TANDEM_INLINE void bvh8p_block(BvhPacket8* p, int8 lanes, TANDEM_GLOBAL const BvhTri4* b) {
    const float4 ax = b->ax, ay = b->ay, az = b->az, bx = b->bx, by = b->by, bz = b->bz;
    const float4 cx = b->cx, cy = b->cy, cz = b->cz, nx = b->nx, ny = b->ny, nz = b->nz;
    const uint4 prim = b->prim;
    bvh8p_triangle(p, lanes, make_float3(ax.x, ay.x, az.x), make_float3(bx.x, by.x, bz.x),
                   make_float3(cx.x, cy.x, cz.x), make_float3(nx.x, ny.x, nz.x), prim.x);
    bvh8p_triangle(p, lanes, make_float3(ax.y, ay.y, az.y), make_float3(bx.y, by.y, bz.y),
                   make_float3(cx.y, cy.y, cz.y), make_float3(nx.y, ny.y, nz.y), prim.y);
    bvh8p_triangle(p, lanes, make_float3(ax.z, ay.z, az.z), make_float3(bx.z, by.z, bz.z),
                   make_float3(cx.z, cy.z, cz.z), make_float3(nx.z, ny.z, nz.z), prim.z);
    bvh8p_triangle(p, lanes, make_float3(ax.w, ay.w, az.w), make_float3(bx.w, by.w, bz.w),
                   make_float3(cx.w, cy.w, cz.w), make_float3(nx.w, ny.w, nz.w), prim.w);
}

/// The lanes of bit mask `bits` (bit k: lane k) as a comparison result (-1 or 0 per lane).
TANDEM_INLINE int8 bvh8p_lanes(uint bits) {
    return ((int8)(1, 2, 4, 8, 16, 32, 64, 128) & (int8)((int)bits)) != (int8)0;
}

/// Lanes where x is finite (isfinite, without the call PoCL makes of it).
TANDEM_INLINE int8 bvh8p_finite(float8 x) {
    return (as_int8(x) & (int8)0x7fffffff) < (int8)0x7f800000;
}

/// The packet of rays[0 .. count) (count <= 8; the other lanes get an empty interval and miss
/// everything) and no hit yet (bvh_miss): bvh_ray_prepare lane by lane, the same operations on
/// eight rays at once.
TANDEM_INLINE BvhPacket8 bvh8p_prepare(const Ray* rays, uint count) {
    // the rays' eight floats (origin and tmin, direction and tmax) as eight rows of lanes
    float rows[8][BVH8_PACKET];
    for (uint k = 0; k < BVH8_PACKET; ++k) {
        const Ray r = rays[k < count ? k : 0u];
        rows[0][k] = r.org.x, rows[1][k] = r.org.y, rows[2][k] = r.org.z, rows[3][k] = r.org.w;
        rows[4][k] = r.dir.x, rows[5][k] = r.dir.y, rows[6][k] = r.dir.z, rows[7][k] = r.dir.w;
    }
    BvhPacket8 p;
    p.ox = vload8(0, rows[0]), p.oy = vload8(0, rows[1]), p.oz = vload8(0, rows[2]);
    p.dx = vload8(0, rows[4]), p.dy = vload8(0, rows[5]), p.dz = vload8(0, rows[6]);
    float8 tmin = vload8(0, rows[3]), tmax = vload8(0, rows[7]);
    // bvh_safe_rcp
    const float8 eps = splat_float8(1e-20f), zero = splat_float8(0.0f);
    const float8 ax = as_float8(as_int8(p.dx) & (int8)0x7fffffff);
    const float8 ay = as_float8(as_int8(p.dy) & (int8)0x7fffffff);
    const float8 az = as_float8(as_int8(p.dz) & (int8)0x7fffffff);
    p.idx =
        splat_float8(1.0f) / select(select(eps, -eps, isless(p.dx, zero)), p.dx, isless(eps, ax));
    p.idy =
        splat_float8(1.0f) / select(select(eps, -eps, isless(p.dy, zero)), p.dy, isless(eps, ay));
    p.idz =
        splat_float8(1.0f) / select(select(eps, -eps, isless(p.dz, zero)), p.dz, isless(eps, az));
    // the dominant axis: (ax > ay) ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2)
    const int8 xy = isless(ay, ax), xz = isless(az, ax), yz = isless(az, ay);
    p.kz0 = xy & xz;
    p.kz1 = ~xy & yz;
    p.kz2 = ~(p.kz0 | p.kz1);
    const float8 dkz = bvh8p_component(p.dx, p.dy, p.dz, p.kz0, p.kz1);
    p.swap = isless(dkz, zero);
    p.shear_p = bvh8p_component(p.dx, p.dy, p.dz, p.kz2, p.kz0) / dkz;
    p.shear_q = bvh8p_component(p.dx, p.dy, p.dz, p.kz1, p.kz2) / dkz;
    // an invalid ray (or an empty lane) gets an empty interval
    const int8 lane = (int8)(0, 1, 2, 3, 4, 5, 6, 7) < (int8)((int)count);
    const int8 valid = lane & bvh8p_finite(p.ox) & bvh8p_finite(p.oy) & bvh8p_finite(p.oz) &
                       bvh8p_finite(p.dx) & bvh8p_finite(p.dy) & bvh8p_finite(p.dz) &
                       ~isless(tmax, tmin) & isequal(tmin, tmin) & isequal(tmax, tmax);
    p.tmin = select(splat_float8(INFINITY), tmin, valid);
    p.t = select(splat_float8(-INFINITY), tmax, valid);
    p.negx = isless(p.idx, zero); // bvh8_near_offset's choice of the near plane (id is never NaN)
    p.negy = isless(p.idy, zero);
    p.negz = isless(p.idz, zero);
    p.prim = (uint8)(HIT_NONE);
    p.u = zero;
    p.v = zero;
    return p;
}

/// The closest hits of rays[0 .. count) (count <= 8) into hits[0 .. count): what
/// bvh8_intersect_closest_into(nodes, tris, rays[k], 1, ...) gives each, over the eight-wide tree
/// of BvhTri4 blocks. One stack for the packet, sorted by the nearest lane's entry distance as the
/// one-ray stack is by the ray's, each entry with the lanes that entered it before their closest
/// hit: a lane visits a child, and tests a leaf, only where it entered the box itself, and an
/// entry comes off untested when none of its lanes can still find a hit in it.
///
/// Where a ray meets a vertex at a grazing angle, the rounded t of a triangle there may lie
/// outside its box, and which of the nearly equal hits a ray keeps can then depend on the order of
/// the visits: the two-, four- and eight-wide trees disagree on a few such rays. Keeping each lane
/// to the boxes it entered itself, the packet gave every ray of the tests the one-ray traversal's
/// hit, such rays included (tests/kernels/test_trace.cpp).
TANDEM_INLINE void bvh8_packet_closest(TANDEM_GLOBAL const Bvh8Node* nodes,
                                       TANDEM_GLOBAL const BvhTriangle* tris, const Ray* rays,
                                       uint count, Hit* hits) {
    BvhPacket8 p = bvh8p_prepare(rays, count);
    uint stack_first[BVH8_STACK_SIZE];
    uint stack_count[BVH8_STACK_SIZE];
    float stack_dist[BVH8_STACK_SIZE];
    uint stack_lanes[BVH8_STACK_SIZE];
    int sp = 0;
    uint first = 0, leaf_count = 0; // the root
    uint lanes = (1u << count) - 1u;
    for (;;) {
        const int8 active = bvh8p_lanes(lanes);
        if (leaf_count == 0u) {
            TANDEM_GLOBAL const Bvh8Node* np = &nodes[first];
            const float8 limit = p.t * BVH_TFAR_SCALE; // bvh_cull_limit, lane by lane
            const int base = sp;
            for (uint c = 0; c < 8u; ++c) {
                const float8 d = bvh8p_enter(&p, np, c);
                const int8 in = active & isless(d, splat_float8(INFINITY)) & islessequal(d, limit);
                const uint entered = bvh8_bits(in);
                if (entered == 0u) continue;
                // bvh4_push_entry_sorted, with the lanes
                const float dist = bvh8p_hmin(select(splat_float8(INFINITY), d, in));
                int i = sp;
                while (i > base && stack_dist[i - 1] < dist) {
                    stack_first[i] = stack_first[i - 1];
                    stack_count[i] = stack_count[i - 1];
                    stack_dist[i] = stack_dist[i - 1];
                    stack_lanes[i] = stack_lanes[i - 1];
                    --i;
                }
                stack_first[i] = np->child[c];
                stack_count[i] = np->count[c];
                stack_dist[i] = dist;
                stack_lanes[i] = entered;
                ++sp;
            }
        } else {
            TANDEM_GLOBAL const BvhTri4* b = (TANDEM_GLOBAL const BvhTri4*)(tris + first);
            for (uint k = 0; k < leaf_count; k += 4u, ++b)
                bvh8p_block(&p, active, b);
        }
        // the nearest entry whose lanes may still find a hit in it
        for (;;) {
            if (sp == 0) {
                float t[BVH8_PACKET], u[BVH8_PACKET], v[BVH8_PACKET];
                uint prim[BVH8_PACKET];
                vstore8(p.t, 0, t);
                vstore8(p.u, 0, u);
                vstore8(p.v, 0, v);
                vstore8(p.prim, 0, prim);
                for (uint k = 0; k < count; ++k) {
                    hits[k].t = t[k];
                    hits[k].prim = prim[k];
                    hits[k].u = u[k];
                    hits[k].v = v[k];
                }
                return;
            }
            --sp;
            const float8 limit =
                select(splat_float8(-INFINITY), p.t * BVH_TFAR_SCALE, bvh8p_lanes(stack_lanes[sp]));
            if (stack_dist[sp] <= bvh8p_hmax(limit)) break;
        }
        first = stack_first[sp];
        leaf_count = stack_count[sp];
        lanes = stack_lanes[sp];
    }
}

#endif // TANDEM_SHARED_BVH8_PACKET_H
