// Packet traversal of the four-wide BVH for coherent rays: one work item traces PACKET_SIZE (16)
// rays together, as Embree's packet kernels do (rtcIntersect16; Wald, Slusallek, Benthin and
// Wagner, "Interactive Rendering with Coherent Ray Tracing", 2001). Each child box and each leaf
// triangle is tested against every ray of the packet at once in float16 arithmetic, which CPU
// OpenCL compilers map to SIMD (one AVX-512 instruction, or two AVX2 ones); a node is visited
// when any ray of the packet enters it.
//
// Per ray, the arithmetic is the single-ray code's (shared/bvh_traverse.h) lane by lane: the same
// IEEE operations in the same order, selects where the single-ray code branches on a per-ray
// value. The closest hit does not depend on which extra nodes and triangles a ray visits (the
// lowest-id tie rule, and culling that is only ever conservative), so the hits are the single-ray
// kernels' bit for bit (tests/kernels/test_trace.cpp). Device only: float16 has no host twin.
#ifndef TANDEM_KERNELS_PATH_PACKET_TRAVERSE_H
#define TANDEM_KERNELS_PATH_PACKET_TRAVERSE_H

#include "shared/bvh4_traverse.h"

#define PACKET_SIZE 16
typedef float16 pfloat;
typedef int16 pint; // lane masks: -1 true, 0 false, as vector comparisons give them
typedef uint16 puint;

/// The per-ray constants of RayPre, one lane per ray. A lane without a ray (past the end of the
/// ray array) holds an invalid ray, whose empty interval enters no box.
typedef struct PacketRays {
    pfloat ox, oy, oz;
    pfloat dx, dy, dz;
    pfloat idx, idy, idz;
    pfloat sp, sq;
    pint kz, kp, kq, swap;
    pfloat tmin, tmax;
    int axis; ///< the dominant axis of every ray of the packet, or -1 when they differ
} PacketRays;

/// Closest hits so far, one lane per ray (Hit's fields).
typedef struct PacketHits {
    pfloat t, u, v;
    puint prim;
} PacketHits;

/// Loads rays [first, first + PACKET_SIZE) of rays[0..count) and prepares each with the
/// single-ray code (bvh_ray_prepare), so every per-ray constant has its bits.
TANDEM_INLINE void packet_prepare(__global const Ray* rays, uint first, uint count,
                                  PacketRays* out) {
    float ox[PACKET_SIZE], oy[PACKET_SIZE], oz[PACKET_SIZE];
    float dx[PACKET_SIZE], dy[PACKET_SIZE], dz[PACKET_SIZE];
    float idx[PACKET_SIZE], idy[PACKET_SIZE], idz[PACKET_SIZE];
    float sp[PACKET_SIZE], sq[PACKET_SIZE], tmin[PACKET_SIZE], tmax[PACKET_SIZE];
    int kz[PACKET_SIZE], kp[PACKET_SIZE], kq[PACKET_SIZE], swap[PACKET_SIZE];
    for (uint l = 0; l < PACKET_SIZE; ++l) {
        Ray ray;
        if (first + l < count) {
            ray = rays[first + l];
        } else { // no ray: an empty interval, which bvh_ray_prepare marks invalid
            ray.org = make_float4(0.0f, 0.0f, 0.0f, INFINITY);
            ray.dir = make_float4(0.0f, 0.0f, 1.0f, -INFINITY);
        }
        const RayPre r = bvh_ray_prepare(ray);
        ox[l] = r.ox, oy[l] = r.oy, oz[l] = r.oz;
        dx[l] = r.dx, dy[l] = r.dy, dz[l] = r.dz;
        idx[l] = r.idx, idy[l] = r.idy, idz[l] = r.idz;
        sp[l] = r.sp, sq[l] = r.sq, tmin[l] = r.tmin, tmax[l] = r.tmax;
        kz[l] = r.kz;
        kp[l] = r.kz == 2 ? 0 : r.kz + 1;
        kq[l] = kp[l] == 2 ? 0 : kp[l] + 1;
        swap[l] = r.swap ? -1 : 0;
    }
    out->ox = vload16(0, ox), out->oy = vload16(0, oy), out->oz = vload16(0, oz);
    out->dx = vload16(0, dx), out->dy = vload16(0, dy), out->dz = vload16(0, dz);
    out->idx = vload16(0, idx), out->idy = vload16(0, idy), out->idz = vload16(0, idz);
    out->sp = vload16(0, sp), out->sq = vload16(0, sq);
    out->tmin = vload16(0, tmin), out->tmax = vload16(0, tmax);
    out->kz = vload16(0, kz), out->kp = vload16(0, kp), out->kq = vload16(0, kq);
    out->swap = vload16(0, swap);
    out->axis = kz[0];
    for (uint l = 1; l < PACKET_SIZE; ++l)
        if (kz[l] != kz[0]) out->axis = -1;
}

/// Writes the packet's hits to hits[first..min(first + PACKET_SIZE, count)).
TANDEM_INLINE void packet_store(const PacketHits* h, uint first, uint count, __global Hit* hits) {
    float t[PACKET_SIZE], u[PACKET_SIZE], v[PACKET_SIZE];
    uint prim[PACKET_SIZE];
    vstore16(h->t, 0, t), vstore16(h->u, 0, u), vstore16(h->v, 0, v);
    vstore16(h->prim, 0, prim);
    for (uint l = 0; l < PACKET_SIZE && first + l < count; ++l) {
        Hit hit;
        hit.t = t[l];
        hit.prim = prim[l];
        hit.u = u[l];
        hit.v = v[l];
        hits[first + l] = hit;
    }
}

/// bvh_component, lane by lane: axis k of each lane, or the constant `axis` of every lane when
/// it is not -1 (the selects fold away in the copies of the leaf loop that pass a constant).
TANDEM_INLINE pfloat packet_component(pfloat x, pfloat y, pfloat z, pint k, int axis) {
    if (axis == 0) return x;
    if (axis == 1) return y;
    if (axis == 2) return z;
    return select(select(z, y, k == 1), x, k == 0);
}

/// The smallest lane.
TANDEM_INLINE float packet_hmin(pfloat a) {
    const float8 b = select(a.hi, a.lo, isless(a.lo, a.hi));
    const float4 c = select(b.hi, b.lo, isless(b.lo, b.hi));
    const float2 d = select(c.hi, c.lo, isless(c.lo, c.hi));
    return d.x < d.y ? d.x : d.y;
}

/// The largest lane.
TANDEM_INLINE float packet_hmax(pfloat a) {
    const float8 b = select(a.lo, a.hi, isless(a.lo, a.hi));
    const float4 c = select(b.lo, b.hi, isless(b.lo, b.hi));
    const float2 d = select(c.lo, c.hi, isless(c.lo, c.hi));
    return d.x < d.y ? d.y : d.x;
}

/// bvh4_min and bvh4_max, lane by lane (NaN-free operands, as there).
TANDEM_INLINE pfloat packet_min(pfloat a, pfloat b) { return select(b, a, isless(a, b)); }
TANDEM_INLINE pfloat packet_max(pfloat a, pfloat b) { return select(a, b, isless(a, b)); }

/// bvh_cull_limit, lane by lane.
TANDEM_INLINE pfloat packet_cull_limit(pfloat t) { return t * BVH_TFAR_SCALE; }

/// Entry distance of each ray into one box (bvh4_enter's arithmetic for one lane of the node),
/// INFINITY where the ray misses it before tmax.
TANDEM_INLINE pfloat packet_enter(const PacketRays* r, float min_x, float min_y, float min_z,
                                  float max_x, float max_y, float max_z, pfloat tmax) {
    const pint px = r->idx >= 0.0f, py = r->idy >= 0.0f, pz = r->idz >= 0.0f;
    const pfloat lo_x = (pfloat)(min_x), hi_x = (pfloat)(max_x);
    const pfloat lo_y = (pfloat)(min_y), hi_y = (pfloat)(max_y);
    const pfloat lo_z = (pfloat)(min_z), hi_z = (pfloat)(max_z);
    const pfloat tnx = (select(hi_x, lo_x, px) - r->ox) * r->idx;
    const pfloat tfx = (select(lo_x, hi_x, px) - r->ox) * r->idx;
    const pfloat tny = (select(hi_y, lo_y, py) - r->oy) * r->idy;
    const pfloat tfy = (select(lo_y, hi_y, py) - r->oy) * r->idy;
    const pfloat tnz = (select(hi_z, lo_z, pz) - r->oz) * r->idz;
    const pfloat tfz = (select(lo_z, hi_z, pz) - r->oz) * r->idz;
    const pfloat tnear = packet_max(packet_max(tnx, tny), packet_max(tnz, r->tmin));
    const pfloat tfar = packet_min(packet_min(tfx, tfy), packet_min(tfz, tmax)) * BVH_TFAR_SCALE;
    return select((pfloat)(INFINITY), tnear, islessequal(tnear, tfar));
}

/// bvh_triangle_intersect_axis for every lane in `mask`, with each lane's own axes: the lanes
/// where the triangle is hit in [tmin, tmax], with t and the barycentrics in *t_out, *u_out,
/// *v_out (unspecified elsewhere).
TANDEM_INLINE pint packet_triangle(const PacketRays* r, BvhTriangle tri, pfloat tmax, pint mask,
                                   int axis, pfloat* t_out, pfloat* u_out, pfloat* v_out) {
    const int ap = axis < 0 ? -1 : (axis == 2 ? 0 : axis + 1), aq = ap < 0 ? -1 : (ap == 2 ? 0 : ap + 1);
    // Steps 1-3 of the single-ray test, lane by lane.
    const pfloat ax = tri.v0.x - r->ox, ay = tri.v0.y - r->oy, az = tri.v0.z - r->oz;
    const pfloat bx = tri.v1.x - r->ox, by = tri.v1.y - r->oy, bz = tri.v1.z - r->oz;
    const pfloat cx = tri.v2.x - r->ox, cy = tri.v2.y - r->oy, cz = tri.v2.z - r->oz;
    const pfloat akz = packet_component(ax, ay, az, r->kz, axis);
    const pfloat bkz = packet_component(bx, by, bz, r->kz, axis);
    const pfloat ckz = packet_component(cx, cy, cz, r->kz, axis);
    const pfloat Ap = packet_component(ax, ay, az, r->kp, ap) - r->sp * akz;
    const pfloat Aq = packet_component(ax, ay, az, r->kq, aq) - r->sq * akz;
    const pfloat Bp = packet_component(bx, by, bz, r->kp, ap) - r->sp * bkz;
    const pfloat Bq = packet_component(bx, by, bz, r->kq, aq) - r->sq * bkz;
    const pfloat Cp = packet_component(cx, cy, cz, r->kp, ap) - r->sp * ckz;
    const pfloat Cq = packet_component(cx, cy, cz, r->kq, aq) - r->sq * ckz;
    const pfloat u1 = Cp * Bq, u2 = Cq * Bp;
    const pfloat v1 = Ap * Cq, v2 = Aq * Cp;
    const pfloat w1 = Bp * Aq, w2 = Bq * Ap;
    const pfloat U = select(u1 - u2, u2 - u1, r->swap);
    const pfloat V = select(v1 - v2, v2 - v1, r->swap);
    const pfloat W = select(w1 - w2, w2 - w1, r->swap);
    const pint neg = U < 0.0f | V < 0.0f | W < 0.0f;
    const pint pos = U > 0.0f | V > 0.0f | W > 0.0f;
    const pfloat det = U + V + W;
    pint ok = mask & ~(neg & pos) & (det != 0.0f);
    if (!any(ok)) return ok;
    // Step 4: the plane's normal is the triangle's alone (the single-ray code's choice of edges).
    const float fx = tri.v2.x - tri.v1.x, fy = tri.v2.y - tri.v1.y, fz = tri.v2.z - tri.v1.z;
    const float gx = tri.v0.x - tri.v2.x, gy = tri.v0.y - tri.v2.y, gz = tri.v0.z - tri.v2.z;
    const float hx = tri.v1.x - tri.v0.x, hy = tri.v1.y - tri.v0.y, hz = tri.v1.z - tri.v0.z;
    const float lf = fx * fx + fy * fy + fz * fz;
    const float lg = gx * gx + gy * gy + gz * gz;
    const float lh = hx * hx + hy * hy + hz * hz;
    float px, py, pz, qx, qy, qz;
    if (lf >= lg && lf >= lh) {
        px = hx, py = hy, pz = hz, qx = -gx, qy = -gy, qz = -gz;
    } else if (lg >= lh) {
        px = fx, py = fy, pz = fz, qx = -hx, qy = -hy, qz = -hz;
    } else {
        px = gx, py = gy, pz = gz, qx = -fx, qy = -fy, qz = -fz;
    }
    const float nx = py * qz - pz * qy, ny = pz * qx - px * qz, nz = px * qy - py * qx;
    const pfloat den = nx * r->dx + ny * r->dy + nz * r->dz;
    const pfloat t = (ax * nx + ay * ny + az * nz) / den;
    ok &= (den != 0.0f) & (t >= r->tmin) & (t <= tmax);
    const pfloat inv_det = 1.0f / det;
    *t_out = t;
    *u_out = V * inv_det;
    *v_out = W * inv_det;
    return ok;
}

/// packet_leaf_closest with the packet's dominant axis `axis` (a constant, or -1: per lane).
TANDEM_INLINE void packet_leaf_closest_axis(const PacketRays* r, __global const BvhTriangle* tris,
                                            uint first, uint count, pint mask, PacketHits* hit,
                                            int axis) {
    for (uint i = first; i < first + count; ++i) {
        const BvhTriangle tri = tris[i];
        pfloat t, u, v;
        const pint ok = packet_triangle(r, tri, hit->t, mask, axis, &t, &u, &v);
        if (!any(ok)) continue;
        const puint prim = (puint)(as_uint(tri.v0.w));
        const pint better = ok & (t < hit->t | (hit->prim != HIT_NONE & prim < hit->prim));
        hit->t = select(hit->t, t, better);
        hit->u = select(hit->u, u, better);
        hit->v = select(hit->v, v, better);
        hit->prim = select(hit->prim, prim, better);
    }
}

/// bvh_leaf_closest for the lanes in `mask`: keeps each lane's closest hit, lowest id on ties.
/// Camera rays mostly share their dominant axis; one copy of the loop per shared axis.
TANDEM_INLINE void packet_leaf_closest(const PacketRays* r, __global const BvhTriangle* tris,
                                       uint first, uint count, pint mask, PacketHits* hit) {
    if (r->axis == 0) packet_leaf_closest_axis(r, tris, first, count, mask, hit, 0);
    else if (r->axis == 1) packet_leaf_closest_axis(r, tris, first, count, mask, hit, 1);
    else if (r->axis == 2) packet_leaf_closest_axis(r, tris, first, count, mask, hit, 2);
    else packet_leaf_closest_axis(r, tris, first, count, mask, hit, -1);
}

/// One child lane of a node: entry distances, the lanes that enter it before their closest hit,
/// and its leaf triangles tested right away (step 1 of bvh4_intersect_closest_into).
#define PACKET_CHILD(lane)                                                                          \
    const pfloat d_##lane = packet_enter(r, np->min_x.lane, np->min_y.lane, np->min_z.lane,         \
                                         np->max_x.lane, np->max_y.lane, np->max_z.lane, hit->t);   \
    pint m_##lane = d_##lane < INFINITY & d_##lane <= packet_cull_limit(hit->t);                    \
    if (np->count.lane != 0 && any(m_##lane))                                                       \
        packet_leaf_closest(r, tris, np->child.lane, np->count.lane, m_##lane, hit);

/// Pushes an interior child that some lane still enters before its closest hit (step 2), with
/// the nearest entry over those lanes.
#define PACKET_PUSH(lane)                                                                           \
    m_##lane &= d_##lane <= packet_cull_limit(hit->t);                                              \
    if (np->count.lane == 0 && any(m_##lane))                                                       \
        bvh4_push_sorted(stack_node, stack_dist, base, &sp, np->child.lane,                         \
                         packet_hmin(select((pfloat)(INFINITY), d_##lane, m_##lane)));

/// The closest hit of every ray of the packet (bvh4_intersect_closest_into's result, lane by
/// lane). Children are visited nearest first by their nearest entry over the packet; an entry
/// is popped while any lane may still hit something in it.
TANDEM_INLINE void packet_intersect_closest(__global const Bvh4Node* nodes,
                                            __global const BvhTriangle* tris, const PacketRays* r,
                                            PacketHits* hit) {
    hit->t = r->tmax;
    hit->u = (pfloat)(0.0f);
    hit->v = (pfloat)(0.0f);
    hit->prim = (puint)(HIT_NONE);
    uint stack_node[BVH4_STACK_SIZE];
    float stack_dist[BVH4_STACK_SIZE];
    int sp = 0;
    uint node = 0;
    for (;;) {
        __global const Bvh4Node* np = &nodes[node];
        PACKET_CHILD(x)
        PACKET_CHILD(y)
        PACKET_CHILD(z)
        PACKET_CHILD(w)
        const int base = sp;
        PACKET_PUSH(x)
        PACKET_PUSH(y)
        PACKET_PUSH(z)
        PACKET_PUSH(w)
        // The farthest any lane may still hit, for the entries left on the stack.
        const float limit = packet_hmax(packet_cull_limit(hit->t));
        for (;;) {
            if (sp == 0) return;
            --sp;
            if (stack_dist[sp] <= limit) break;
        }
        node = stack_node[sp];
    }
}

#undef PACKET_CHILD
#undef PACKET_PUSH

#endif // TANDEM_KERNELS_PATH_PACKET_TRAVERSE_H
