// Closest-hit and any-hit traversal of the flattened two-wide BVH, with the watertight ray/triangle
// test of Woop, Benthin and Wald, "Watertight Ray/Triangle Intersection", JCGT 2(1), 2013; the hit
// distance comes from the plane equation instead (see bvh_triangle_intersect_axis).
// Shared: the render kernels, bench/kernels/trace.cl and the host reference (tests) run this code.
#ifndef TANDEM_SHARED_BVH_TRAVERSE_H
#define TANDEM_SHARED_BVH_TRAVERSE_H

#include "shared/bvh_layout.h"

TANDEM_NAMESPACE_BEGIN

/// BVH_AXIS_LOOPS 1 (the default, and the FeatureSet's choice on CPUs): one copy of each leaf loop
/// per dominant axis, so that the triangle test's component choices are constants (selecting them
/// per ray cost PoCL a large share of the render kernel). 0 (the FeatureSet's choice elsewhere): one loop that selects the
/// components per ray, without branches, for SIMT devices, where the rays of one warp that differ
/// in their axis would run the copies one after another. Both give the same bits.
#ifndef BVH_AXIS_LOOPS
#define BVH_AXIS_LOOPS 1
#endif

/// BVH_ANALYTIC 1: leaves may hold analytic spheres and disks (BVH_PRIM_SPHERE and BVH_PRIM_DISK
/// records), which the leaf loops test as such. 0 (the FeatureSet's choice for scenes without
/// them): triangles only, and the loops carry no test of the record's kind. Kernels are always
/// given it; the host build (the tests' reference) has the tests, whose branches leave
/// triangles' hits unchanged.
#ifndef BVH_ANALYTIC
#ifdef __OPENCL_C_VERSION__
#define BVH_ANALYTIC 0
#else
#define BVH_ANALYTIC 1
#endif
#endif

/// BVH_MOVEMASK 1 (where TANDEM_X86_CLANG, compat.h): a comparison's lanes become a bit mask by one
/// movmskps, which OpenCL C lacks; the portable and-or reduction (elsewhere) takes eight
/// instructions per node and leaf block. Same bits.
#ifndef BVH_MOVEMASK
#define BVH_MOVEMASK TANDEM_X86_CLANG
#endif

/// Per-ray constants: origin, conservative inverse direction for the slab test, and the shear of
/// the watertight triangle test. kz is the dominant axis; the test works in the axes p = kz + 1 and
/// q = kz + 2 (mod 3), sheared by shear_p = d_p / d_kz and shear_q = d_q / d_kz. `swap` (d_kz < 0)
/// exchanges the roles of p and q as the paper's x and y, which keeps the winding.
typedef struct RayPre {
    float ox, oy, oz;
    float dx, dy, dz;
    float idx, idy, idz;
    float shear_p, shear_q;
    int kz, swap;
    float tmin, tmax;
} RayPre;

TANDEM_INLINE float bvh_component(float x, float y, float z, int k) {
    return k == 0 ? x : (k == 1 ? y : z);
}

/// 1 / d with zero and tiny components replaced by +-1e-20, so the slab test never forms 0 * inf.
TANDEM_INLINE float bvh_safe_rcp(float d) {
    const float eps = 1e-20f;
    return 1.0f / (fabs(d) > eps ? d : (d < 0.0f ? -eps : eps));
}

/// Scale of the exit distance that makes the slab test conservative, 1 + 10 * 2^-24: each distance
/// is within 3 * 2^-24 with a correctly rounded reciprocal (pbrt's 1 + 2 gamma_3, Ize 2013). With
/// the 2.5-ulp division OpenCL allows (a device `tandem devices` calls not reproducible), 7 * 2^-24
/// each, and 14 would be needed: there a box the ray grazes at an edge may be missed.
#define BVH_TFAR_SCALE 1.0000006f

/// The farthest box entry distance that may still hold a hit at t (for t >= 0): entry distances
/// are rounded like exits, so boxes are culled against t scaled like an exit. Without the
/// scale, a box whose rounded entry lands just past t would hide an equal-t triangle and break
/// the lowest-id tie rule.
TANDEM_INLINE float bvh_cull_limit(float t) { return t * BVH_TFAR_SCALE; }

/// Per-ray setup. A ray with a non-finite origin or direction component, or a NaN interval, is
/// invalid: its interval is emptied, so it misses everything (as a ray that escapes).
TANDEM_INLINE RayPre bvh_ray_prepare(Ray ray) {
    RayPre r;
    const float dx = ray.dir.x, dy = ray.dir.y, dz = ray.dir.z;
    r.ox = ray.org.x;
    r.oy = ray.org.y;
    r.oz = ray.org.z;
    r.dx = dx;
    r.dy = dy;
    r.dz = dz;
    r.idx = bvh_safe_rcp(dx);
    r.idy = bvh_safe_rcp(dy);
    r.idz = bvh_safe_rcp(dz);
    const float ax = fabs(dx), ay = fabs(dy), az = fabs(dz);
    r.kz = (ax > ay) ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2);
    const int kp = r.kz == 2 ? 0 : r.kz + 1, kq = kp == 2 ? 0 : kp + 1;
    const float dkz = bvh_component(dx, dy, dz, r.kz);
    r.swap = dkz < 0.0f; // to preserve the winding direction of triangles
    r.shear_p = bvh_component(dx, dy, dz, kp) / dkz;
    r.shear_q = bvh_component(dx, dy, dz, kq) / dkz;
    r.tmin = ray.org.w;
    r.tmax = ray.dir.w;
    const int valid = isfinite(ray.org.x) && isfinite(ray.org.y) && isfinite(ray.org.z) &&
                      isfinite(dx) && isfinite(dy) && isfinite(dz) && !(r.tmin > r.tmax) &&
                      r.tmin == r.tmin && r.tmax == r.tmax;
    if (!valid) {
        r.tmin = INFINITY;
        r.tmax = -INFINITY;
    }
    return r;
}

/// min/max without IEEE NaN handling: compiles to a single minps/maxps on x86 (fmin/fmax do not).
/// In the slab test operands are NaN-free for valid rays (finite origin, finite nonzero inverse
/// direction from bvh_safe_rcp, finite boxes); invalid rays have an empty interval and miss.
TANDEM_INLINE float bvh_min(float a, float b) { return a < b ? a : b; }
TANDEM_INLINE float bvh_max(float a, float b) { return a > b ? a : b; }

/// Entry distance of the ray into the box, or INFINITY when it misses [tmin, tmax].
/// The exit distance is scaled by BVH_TFAR_SCALE so the test is conservative.
TANDEM_INLINE float bvh_box_enter(const RayPre* r, float4 bmin, float4 bmax, float tmax) {
    const float tx0 = (bmin.x - r->ox) * r->idx, tx1 = (bmax.x - r->ox) * r->idx;
    const float ty0 = (bmin.y - r->oy) * r->idy, ty1 = (bmax.y - r->oy) * r->idy;
    const float tz0 = (bmin.z - r->oz) * r->idz, tz1 = (bmax.z - r->oz) * r->idz;
    const float tnear = bvh_max(bvh_max(bvh_min(tx0, tx1), bvh_min(ty0, ty1)),
                                bvh_max(bvh_min(tz0, tz1), r->tmin));
    const float tfar = bvh_min(bvh_min(bvh_max(tx0, tx1), bvh_max(ty0, ty1)),
                               bvh_min(bvh_max(tz0, tz1), tmax)) *
                       BVH_TFAR_SCALE;
    return tnear <= tfar ? tnear : INFINITY;
}

/// The normal of the plane that the triangle test takes the hit distance from:
/// t = dot(v0 - o, n) / dot(d, n). The paper interpolates the vertex depths with U, V, W instead,
/// which loses up to 1e-3 relative on long thin slivers (tests/kernels/test_trace.cpp). The normal
/// is the cross product of the two edges at the vertex opposite the longest edge: for a sliver,
/// the long edges are nearly parallel and their cross product would cancel to a few digits. It
/// depends on the vertices alone: the host stores it in each leaf record (BvhTriangle.plane_n,
/// BvhTri4.nx .. nz) and bvh_triangle_intersect_axis reads it from there. Only products and
/// differences, so it has the same bits wherever it is computed. w is zero.
TANDEM_INLINE float4 bvh_triangle_plane_normal(float4 v0, float4 v1, float4 v2) {
    const float fx = v2.x - v1.x, fy = v2.y - v1.y, fz = v2.z - v1.z;
    const float gx = v0.x - v2.x, gy = v0.y - v2.y, gz = v0.z - v2.z;
    const float hx = v1.x - v0.x, hy = v1.y - v0.y, hz = v1.z - v0.z;
    const float lf = fx * fx + fy * fy + fz * fz; // opposite v0
    const float lg = gx * gx + gy * gy + gz * gz; // opposite v1
    const float lh = hx * hx + hy * hy + hz * hz; // opposite v2
    // Edges (e, e') leaving the chosen vertex, in winding order, so n = e x e' for every choice.
    float ex, ey, ez, ex2, ey2, ez2;
    if (lf >= lg && lf >= lh) { // at v0: v1 - v0, v2 - v0
        ex = hx, ey = hy, ez = hz, ex2 = -gx, ey2 = -gy, ez2 = -gz;
    } else if (lg >= lh) { // at v1: v2 - v1, v0 - v1
        ex = fx, ey = fy, ez = fz, ex2 = -hx, ey2 = -hy, ez2 = -hz;
    } else { // at v2: v0 - v2, v1 - v2
        ex = gx, ey = gy, ez = gz, ex2 = -fx, ey2 = -fy, ez2 = -fz;
    }
    return make_float4(ey * ez2 - ez * ey2, ez * ex2 - ex * ez2, ex * ey2 - ey * ex2, 0.0f);
}

/// Watertight ray/triangle test for a ray whose dominant axis is `kz` (r->kz). With
/// BVH_AXIS_LOOPS, every caller passes kz as a literal (one copy of each leaf loop per axis), so
/// the component choices fold away. On a hit with tmin <= t <= tmax (closed: callers
/// apply their own half-open or tie rules), writes t and the barycentrics (u weights v1, v
/// weights v2) and returns 1. Degenerate (zero-area) triangles never hit.
TANDEM_INLINE int bvh_triangle_intersect_axis(const RayPre* r, BvhTriangle tri, float tmax, int kz,
                                              float* t_out, float* u_out, float* v_out) {
    const int kp = kz == 2 ? 0 : kz + 1, kq = kp == 2 ? 0 : kp + 1;
    // Step 1: vertices relative to the origin, in the axes (p, q, kz).
    const float ax = tri.v0.x - r->ox, ay = tri.v0.y - r->oy, az = tri.v0.z - r->oz;
    const float bx = tri.v1.x - r->ox, by = tri.v1.y - r->oy, bz = tri.v1.z - r->oz;
    const float cx = tri.v2.x - r->ox, cy = tri.v2.y - r->oy, cz = tri.v2.z - r->oz;
    const float akz = bvh_component(ax, ay, az, kz), bkz = bvh_component(bx, by, bz, kz),
                ckz = bvh_component(cx, cy, cz, kz);
    // Step 2: shear, so the ray becomes the +z axis through the origin.
    const float Ap = bvh_component(ax, ay, az, kp) - r->shear_p * akz;
    const float Aq = bvh_component(ax, ay, az, kq) - r->shear_q * akz;
    const float Bp = bvh_component(bx, by, bz, kp) - r->shear_p * bkz;
    const float Bq = bvh_component(bx, by, bz, kq) - r->shear_q * bkz;
    const float Cp = bvh_component(cx, cy, cz, kp) - r->shear_p * ckz;
    const float Cq = bvh_component(cx, cy, cz, kq) - r->shear_q * ckz;
    // Step 3: scaled barycentrics from 2D edge functions; all one sign means inside. The paper's
    // U = Cx By - Cy Bx (and V, W) with (x, y) = (p, q), or (q, p) when swapped: the same two
    // products, subtracted in the other order (a select, not a negation, which would turn a +0
    // into -0).
    const float u1 = Cp * Bq, u2 = Cq * Bp;
    const float v1 = Ap * Cq, v2 = Aq * Cp;
    const float w1 = Bp * Aq, w2 = Bq * Ap;
    const float U = r->swap ? u2 - u1 : u1 - u2;
    const float V = r->swap ? v2 - v1 : v1 - v2;
    const float W = r->swap ? w2 - w1 : w1 - w2;
    if ((U < 0.0f || V < 0.0f || W < 0.0f) && (U > 0.0f || V > 0.0f || W > 0.0f)) return 0;
    const float det = U + V + W;
    if (det == 0.0f) return 0;
    // Step 4: distance from the plane equation, t = dot(v0 - o, n) / dot(d, n), with the record's
    // plane normal (bvh_triangle_plane_normal).
    const float nx = tri.plane_n.x, ny = tri.plane_n.y, nz = tri.plane_n.z;
    const float den = nx * r->dx + ny * r->dy + nz * r->dz;
    if (den == 0.0f) return 0;
    const float t = (ax * nx + ay * ny + az * nz) / den;
    if (!(t >= r->tmin && t <= tmax)) return 0;
    const float inv_det = 1.0f / det;
    *t_out = t;
    *u_out = V * inv_det;
    *v_out = W * inv_det;
    return 1;
}

/// 1 for x >= 0 (either zero), -1 below.
TANDEM_INLINE float bvh_sign_not_zero(float x) { return x >= 0.0f ? 1.0f : -1.0f; }

/// The octahedral encoding of the nonzero direction (x, y, z), a point of [-1, 1]^2: Cigolle et
/// al., "A Survey of Efficient Representations for Independent Unit Vectors", JCGT 3(2), 2014,
/// section 3.3. Only +, -, x, / and selects, so every device gives the same bits.
TANDEM_INLINE void bvh_oct_encode(float x, float y, float z, float* u, float* v) {
    const float inv_l1 = 1.0f / (fabs(x) + fabs(y) + fabs(z));
    const float px = x * inv_l1, py = y * inv_l1;
    *u = z >= 0.0f ? px : (1.0f - fabs(py)) * bvh_sign_not_zero(px);
    *v = z >= 0.0f ? py : (1.0f - fabs(px)) * bvh_sign_not_zero(py);
}

/// The unit direction whose octahedral encoding is (u, v) (bvh_oct_encode's inverse, to about
/// 1e-7 rad).
TANDEM_INLINE void bvh_oct_decode(float u, float v, float* x, float* y, float* z) {
    const float nz = 1.0f - fabs(u) - fabs(v);
    const float nx = nz >= 0.0f ? u : (1.0f - fabs(v)) * bvh_sign_not_zero(u);
    const float ny = nz >= 0.0f ? v : (1.0f - fabs(u)) * bvh_sign_not_zero(v);
    const float inv_len = 1.0f / sqrt(nx * nx + ny * ny + nz * nz);
    *x = nx * inv_len;
    *y = ny * inv_len;
    *z = nz * inv_len;
}

/// The vector (x, y, z) turned by the unit quaternion (qx, qy, qz, qw), in place:
/// v + qw t + q x t with t = 2 q x v.
TANDEM_INLINE void bvh_quat_rotate(float qx, float qy, float qz, float qw, float* x, float* y,
                                   float* z) {
    const float tx = 2.0f * (qy * *z - qz * *y), ty = 2.0f * (qz * *x - qx * *z),
                tz = 2.0f * (qx * *y - qy * *x);
    const float rx = *x + qw * tx + (qy * tz - qz * ty);
    const float ry = *y + qw * ty + (qz * tx - qx * tz);
    const float rz = *z + qw * tz + (qx * ty - qy * tx);
    *x = rx;
    *y = ry;
    *z = rz;
}

/// Ray/sphere test for a BVH_PRIM_SPHERE record: the nearer root of |f + t d|^2 = r^2 (f = o - c)
/// in [tmin, tmax], closed as the triangle test. The discriminant b^2 - a c is formed as
/// a (r - |l|)(r + |l|), l = f - (b / a) d the centre's offset from the line, and the roots as
/// q / a and c / q with q = -(b + sign(b) sqrt(disc)), which keeps both accurate for distant and
/// for grazing rays: Haines, Guenther and Akenine-Moeller, "Precision Improvements for Ray/Sphere
/// Intersection", Ray Tracing Gems ch. 7, 2019, section 7.2. On a hit, writes t and in (u, v) the
/// octahedral encoding of f + t d, the direction from the centre to the hit point.
///
/// A ray that starts on the sphere to rounding (|c| = ||f|^2 - r^2| within BVH_SPHERE_BAND of
/// r (max |centre| + r): a height of about 2e-6 of that scale) is one leaving its surface, whose
/// offset origin (offset_ray_origin) the rounding of f may have undone on a large or distant
/// sphere. It cannot meet the sphere again going outward (b >= 0), and going inward it meets the
/// far side at the chord -2b / a.
#define BVH_SPHERE_BAND (1.0f / 262144.0f)
TANDEM_INLINE int bvh_sphere_intersect(const RayPre* r, BvhTriangle sphere, float tmax,
                                       float* t_out, float* u_out, float* v_out) {
    const float radius = sphere.v1.x;
    const float fx = r->ox - sphere.v0.x, fy = r->oy - sphere.v0.y, fz = r->oz - sphere.v0.z;
    const float a = r->dx * r->dx + r->dy * r->dy + r->dz * r->dz;
    const float b = fx * r->dx + fy * r->dy + fz * r->dz; // half the quadratic's b
    const float c = fx * fx + fy * fy + fz * fz - radius * radius;
    const float scale =
        bvh_max(bvh_max(fabs(sphere.v0.x), fabs(sphere.v0.y)), fabs(sphere.v0.z)) + radius;
    if (fabs(c) <= radius * scale * BVH_SPHERE_BAND) {
        if (!(b < 0.0f)) return 0;
        const float chord = -2.0f * b / a;
        if (!(chord >= r->tmin && chord <= tmax)) return 0;
        bvh_oct_encode(fx + chord * r->dx, fy + chord * r->dy, fz + chord * r->dz, u_out, v_out);
        *t_out = chord;
        return 1;
    }
    const float k = b / a;
    const float lx = fx - k * r->dx, ly = fy - k * r->dy, lz = fz - k * r->dz;
    const float l = sqrt(lx * lx + ly * ly + lz * lz);
    const float disc = a * ((radius - l) * (radius + l));
    if (!(disc >= 0.0f)) return 0; // also a zero direction (NaN)
    const float root = sqrt(disc);
    const float q = b >= 0.0f ? -(b + root) : root - b;
    if (q == 0.0f) return 0; // a grazing ray whose closest approach is its origin
    const float t0 = q / a, t1 = c / q;
    const float t_near = t0 < t1 ? t0 : t1, t_far = t0 < t1 ? t1 : t0;
    const float t = t_near >= r->tmin ? t_near : t_far;
    if (!(t >= r->tmin && t <= tmax)) return 0;
    bvh_oct_encode(fx + t * r->dx, fy + t * r->dy, fz + t * r->dz, u_out, v_out);
    *t_out = t;
    return 1;
}

/// Ray/disk test for a BVH_PRIM_DISK record: the ray meets the disk's plane at
/// t = n.(c - o) / n.d, n = x_axis x y_axis, within [tmin, tmax], at local coordinates
/// (p.x_axis, p.y_axis) / radius^2 (p = o + t d - c) inside the unit circle. Writes t and the
/// local (x, y) on a hit.
TANDEM_INLINE int bvh_disk_intersect(const RayPre* r, BvhTriangle disk, float tmax, float* t_out,
                                     float* u_out, float* v_out) {
    const float ax = disk.v1.x, ay = disk.v1.y, az = disk.v1.z;
    const float bx = disk.v2.x, by = disk.v2.y, bz = disk.v2.z;
    const float nx = ay * bz - az * by, ny = az * bx - ax * bz, nz = ax * by - ay * bx;
    const float den = nx * r->dx + ny * r->dy + nz * r->dz;
    if (den == 0.0f) return 0;
    const float cx = disk.v0.x - r->ox, cy = disk.v0.y - r->oy, cz = disk.v0.z - r->oz;
    const float t = (cx * nx + cy * ny + cz * nz) / den;
    if (!(t >= r->tmin && t <= tmax)) return 0;
    const float px = t * r->dx - cx, py = t * r->dy - cy, pz = t * r->dz - cz;
    const float inv_r2 = 1.0f / (ax * ax + ay * ay + az * az);
    const float lx = (px * ax + py * ay + pz * az) * inv_r2;
    const float ly = (px * bx + py * by + pz * bz) * inv_r2;
    if (!(lx * lx + ly * ly <= 1.0f)) return 0;
    *t_out = t;
    *u_out = lx;
    *v_out = ly;
    return 1;
}

/// The test of one leaf record for a ray whose dominant axis is `kz`: a triangle, or with
/// BVH_ANALYTIC a sphere or a disk where the record says so.
TANDEM_INLINE int bvh_primitive_intersect_axis(const RayPre* r, BvhTriangle prim, float tmax,
                                               int kz, float* t_out, float* u_out, float* v_out) {
#if BVH_ANALYTIC
    const uint kind = as_uint(prim.v1.w);
    if (kind == BVH_PRIM_SPHERE) return bvh_sphere_intersect(r, prim, tmax, t_out, u_out, v_out);
    if (kind == BVH_PRIM_DISK) return bvh_disk_intersect(r, prim, tmax, t_out, u_out, v_out);
#endif
    return bvh_triangle_intersect_axis(r, prim, tmax, kz, t_out, u_out, v_out);
}

/// bvh_leaf_closest for a ray whose dominant axis is the constant `kz`.
TANDEM_INLINE void bvh_leaf_closest_axis(const RayPre* r, TANDEM_GLOBAL const BvhTriangle* tris,
                                         uint first, uint count, Hit* hit, int kz) {
    for (uint i = first; i < first + count; ++i) {
        const BvhTriangle tri = tris[i];
        float t, u, v;
        if (!bvh_primitive_intersect_axis(r, tri, hit->t, kz, &t, &u, &v)) continue;
        const uint prim = as_uint(tri.v0.w);
        if (t < hit->t || (hit->prim != HIT_NONE && prim < hit->prim)) {
            hit->t = t;
            hit->prim = prim;
            hit->u = u;
            hit->v = v;
        }
    }
}

/// Tests primitives [first, first + count) and keeps the closest hit in *hit. Among hits at the
/// same t the lowest primitive id wins, so the result does not depend on the BVH's layout or
/// traversal order (duplicate triangles are common in real meshes). The ray's own tmax is
/// exclusive: a hit at exactly tmax counts only once something has been hit. With
/// BVH_AXIS_LOOPS, one copy of the loop per dominant axis.
TANDEM_INLINE void bvh_leaf_closest(const RayPre* r, TANDEM_GLOBAL const BvhTriangle* tris,
                                    uint first, uint count, Hit* hit) {
#if BVH_AXIS_LOOPS
    if (r->kz == 0) bvh_leaf_closest_axis(r, tris, first, count, hit, 0);
    else if (r->kz == 1) bvh_leaf_closest_axis(r, tris, first, count, hit, 1);
    else bvh_leaf_closest_axis(r, tris, first, count, hit, 2);
#else
    bvh_leaf_closest_axis(r, tris, first, count, hit, r->kz);
#endif
}

/// bvh_leaf_any for a ray whose dominant axis is the constant `kz`.
TANDEM_INLINE int bvh_leaf_any_axis(const RayPre* r, TANDEM_GLOBAL const BvhTriangle* tris,
                                    uint first, uint count, int kz) {
    for (uint i = first; i < first + count; ++i) {
        float t, u, v;
        if (bvh_primitive_intersect_axis(r, tris[i], r->tmax, kz, &t, &u, &v) && t < r->tmax)
            return 1;
    }
    return 0;
}

/// 1 if any of primitives [first, first + count) is hit in [tmin, tmax).
TANDEM_INLINE int bvh_leaf_any(const RayPre* r, TANDEM_GLOBAL const BvhTriangle* tris, uint first,
                               uint count) {
#if BVH_AXIS_LOOPS
    if (r->kz == 0) return bvh_leaf_any_axis(r, tris, first, count, 0);
    if (r->kz == 1) return bvh_leaf_any_axis(r, tris, first, count, 1);
    return bvh_leaf_any_axis(r, tris, first, count, 2);
#else
    return bvh_leaf_any_axis(r, tris, first, count, r->kz);
#endif
}

/// No hit before tmax (prim == HIT_NONE).
TANDEM_INLINE Hit bvh_miss(float tmax) {
    Hit hit;
    hit.t = tmax;
    hit.prim = HIT_NONE;
    hit.u = 0.0f;
    hit.v = 0.0f;
    return hit;
}

/// The closest hit along the ray in [tmin, tmax), or prim == HIT_NONE, written to *out (through a
/// pointer for Oclgrind: see TANDEM_INLINE in compat.h). The current entry is a node or a leaf
/// (`count` triangles from `first`; an interior node `first` when count is 0): of two children
/// entered, the nearer is next and the farther waits on the stack, so a leaf is tested only once
/// everything nearer has been and its box still starts before the closest hit found so far.
TANDEM_INLINE void bvh_intersect_closest_into(TANDEM_GLOBAL const BvhNode* nodes,
                                              TANDEM_GLOBAL const BvhTriangle* tris, Ray ray,
                                              Hit* out) {
    const RayPre r = bvh_ray_prepare(ray);
    Hit hit = bvh_miss(r.tmax);
    uint stack_first[BVH_MAX_DEPTH];
    uint stack_count[BVH_MAX_DEPTH];
    float stack_dist[BVH_MAX_DEPTH];
    int sp = 0;
    uint first = 0, count = 0; // the root
    for (;;) {
        if (count != 0) {
            bvh_leaf_closest(&r, tris, first, count, &hit);
        } else {
            const BvhNode n = nodes[first];
            const float dl = bvh_box_enter(&r, n.lmin, n.lmax, hit.t);
            const float dr = bvh_box_enter(&r, n.rmin, n.rmax, hit.t);
            const uint lfirst = as_uint(n.lmin.w), lcount = as_uint(n.lmax.w);
            const uint rfirst = as_uint(n.rmin.w), rcount = as_uint(n.rmax.w);
            if (dl != INFINITY && dr != INFINITY) { // both: the nearer first
                const int left_first = dl <= dr;
                stack_first[sp] = left_first ? rfirst : lfirst;
                stack_count[sp] = left_first ? rcount : lcount;
                stack_dist[sp] = left_first ? dr : dl;
                ++sp;
                first = left_first ? lfirst : rfirst;
                count = left_first ? lcount : rcount;
                continue;
            }
            if (dl != INFINITY) {
                first = lfirst;
                count = lcount;
                continue;
            }
            if (dr != INFINITY) {
                first = rfirst;
                count = rcount;
                continue;
            }
        }
        // Pop, skipping entries that start beyond the closest hit found since they were pushed.
        for (;;) {
            if (sp == 0) {
                *out = hit;
                return;
            }
            --sp;
            if (stack_dist[sp] <= bvh_cull_limit(hit.t)) break;
        }
        first = stack_first[sp];
        count = stack_count[sp];
    }
}

/// bvh_intersect_closest_into, returned.
TANDEM_INLINE Hit bvh_intersect_closest(TANDEM_GLOBAL const BvhNode* nodes,
                                        TANDEM_GLOBAL const BvhTriangle* tris, Ray ray) {
    Hit hit;
    bvh_intersect_closest_into(nodes, tris, ray, &hit);
    return hit;
}

/// 1 if anything is hit along the ray in [tmin, tmax), else 0. Stops at the first hit found.
TANDEM_INLINE int bvh_intersect_any(TANDEM_GLOBAL const BvhNode* nodes,
                                    TANDEM_GLOBAL const BvhTriangle* tris, Ray ray) {
    const RayPre r = bvh_ray_prepare(ray);
    uint stack_node[BVH_MAX_DEPTH];
    int sp = 0;
    uint node = 0;
    for (;;) {
        const BvhNode n = nodes[node];
        const float dl = bvh_box_enter(&r, n.lmin, n.lmax, r.tmax);
        const float dr = bvh_box_enter(&r, n.rmin, n.rmax, r.tmax);
        const uint lcount = as_uint(n.lmax.w), rcount = as_uint(n.rmax.w);
        // A loop over the two sides, not two unrolled `&&` tests: PoCL 3.1 compiled the unrolled
        // form to much slower code.
        for (int side = 0; side < 2; ++side) {
            const uint count = side == 0 ? lcount : rcount;
            const float d = side == 0 ? dl : dr;
            if (count == 0 || d == INFINITY) continue;
            if (bvh_leaf_any(&r, tris, as_uint(side == 0 ? n.lmin.w : n.rmin.w), count)) return 1;
        }
        const int go_l = lcount == 0 && dl != INFINITY;
        const int go_r = rcount == 0 && dr != INFINITY;
        const uint lchild = as_uint(n.lmin.w), rchild = as_uint(n.rmin.w);
        if (go_l && go_r) {
            stack_node[sp++] = rchild;
            node = lchild;
        } else if (go_l) {
            node = lchild;
        } else if (go_r) {
            node = rchild;
        } else {
            if (sp == 0) return 0;
            node = stack_node[--sp];
        }
    }
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_BVH_TRAVERSE_H
