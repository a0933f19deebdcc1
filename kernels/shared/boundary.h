// The primary boundary term of shape gradients by edge sampling on the image plane ("Differentiable
// Monte Carlo Ray Tracing through Edge Sampling", Li, Aittala, Durand, Lehtinen, SIGGRAPH Asia
// 2018, Sec. 4.1; docs/method.md, "Shape gradients"): the camera's projection of a world point
// and its Jacobian, and the record of one sampled edge. Shared by host and device: the host builds
// the edge table with the same projection the kernel differentiates (core/render/boundary.h).
#ifndef TANDEM_SHARED_BOUNDARY_H
#define TANDEM_SHARED_BOUNDARY_H

#include "shared/sampling.h"
#include "shared/scene_layout.h"

TANDEM_NAMESPACE_BEGIN

/// A piece of a mesh edge as the camera sees it, 48 bytes: its ends a and b (world space, in
/// front of the near plane and clipped to the film), at parameters ta and tb of the whole edge
/// v0 + t (v1 - v0), whose vertices' positions are parameters at param0 and param1 (NO_PARAM: a
/// vertex that does not move). `length` is the piece's length on the film in pixels; `pmf` the
/// probability that the sampler picks it (proportional to its length).
typedef struct BoundaryEdge {
    float4 a; ///< w: ta
    float4 b; ///< w: tb
    uint param0;
    uint param1;
    float length;
    float pmf;
} BoundaryEdge;
TANDEM_STATIC_ASSERT_SIZE(BoundaryEdge, 48);

/// A mesh edge for the secondary term, 64 bytes: its ends, with their vertices' parameter offsets
/// (as_float of a uint; NO_PARAM: still) in p0.w and p1.w; its faces' unit normals n0 and n1;
/// n0.w: the probability that the sampler picks it (in proportion to length); n1.w: 1 where it has
/// two faces, 0 on a border.
typedef struct SecondaryEdge {
    float4 p0;
    float4 p1;
    float4 n0;
    float4 n1;
} SecondaryEdge;
TANDEM_STATIC_ASSERT_SIZE(SecondaryEdge, 64);

/// The guide of the secondary term's directions (core/render/boundary_guide.h), 16 bytes: each
/// edge that the training found is cut into `bins` equal parts, each a slot holding a
/// piecewise-constant density of directions over dir_res^2 cells of equal solid angle
/// (secondary_guide_cell), as a CDF in cell order. `fraction` is the share of the directions drawn
/// from it where the edge point has one (0: no guide).
typedef struct SecondaryGuide {
    float fraction;
    uint bins;
    uint dir_res;
    uint slots;
} SecondaryGuide;
TANDEM_STATIC_ASSERT_SIZE(SecondaryGuide, 16);

/// An edge without a density of its own.
#define GUIDE_NO_SLOT 0xFFFFFFFFu

/// No emissive triangle.
#define NO_EMISSIVE 0xFFFFFFFFu

/// The secondary term's density of light-sampled directions (path/boundary_secondary.h:
/// secondary_direction_pdf) looks for the emissive triangles a ray crosses in chunks of this many
/// consecutive ones, each behind a bounding sphere (xyz its centre, w its radius), and skips the
/// chunks the ray misses: with many lights, most.
#define EMISSIVE_CHUNK 32u
/// and first in groups of at most this many consecutive chunks, each behind a sphere bounding its
/// triangles (stored after the chunks' spheres, each with its range of chunks), a group ending
/// where the box of its chunks' spheres would reach past EMISSIVE_GROUP_SPREAD times its widest
/// chunk's radius from its middle (a chunk of another light, far away): twelve sphere lights of
/// 124 chunks are 48 groups.
#define EMISSIVE_GROUP 32u
#define EMISSIVE_GROUP_SPREAD 8.0f

/// Whether the ray o + t w, t > 0, may pass through the sphere `b` (xyz its centre, w its radius):
/// false only where the line misses it or it lies wholly behind o, each by more than a margin of
/// the rounding of the squared distances (1e-5 of |c - o|^2), so that no triangle inside is skipped
/// that the intersection test would find.
TANDEM_INLINE int emissive_chunk_near(float3 o, float3 w, float4 b) {
    const float3 oc = xyz(b) - o;
    const float tc = vdot(oc, w), oc2 = vdot(oc, oc), r = b.w;
    const float margin = 1e-5f * oc2;
    if (oc2 <= r * r + margin) return 1; // o inside
    if (tc < 0.0f && tc * tc > r * r + margin) return 0; // wholly behind
    return oc2 - tc * tc <= r * r + margin;
}

/// The cell of unit direction w among n^2 of equal solid angle: row i of cos theta = w.z in
/// (1 - 2 (i + 1) / n, 1 - 2 i / n], column j of phi = atan2(w.y, w.x) in [2 pi j / n,
/// 2 pi (j + 1) / n): the cells of uniform_sphere's (u1, u2) square, i * n + j.
TANDEM_INLINE uint secondary_guide_cell(float3 w, uint n) {
    const float z = fmin(fmax(w.z, -1.0f), 1.0f);
    const uint i = min((uint)((1.0f - z) * 0.5f * (float)n), n - 1u);
    float phi = det_atan2(w.y, w.x);
    if (phi < 0.0f) phi += 2.0f * TANDEM_PI;
    const uint j = min((uint)(phi * (0.5f * TANDEM_INV_PI) * (float)n), n - 1u);
    return i * n + j;
}

/// The film position of world point p in pixels, (x right, y down: camera_ray's px + u0 and
/// py + u1), into *fx, *fy, and its depth along the view axis into *z (> 0: in front). The inverse
/// of camera_ray: dir_z + dir_x sx + dir_y sy points at p for sx = 1 - 2 fx / width (its axes are
/// orthogonal, dir_z unit).
TANDEM_INLINE void camera_project(const DeviceCamera* cam, float3 p, float* fx, float* fy,
                                  float* z) {
    const float3 d = p - xyz(cam->origin);
    const float3 ax = xyz(cam->dir_x), ay = xyz(cam->dir_y);
    *z = vdot(d, xyz(cam->dir_z));
    const float sx = vdot(d, ax) / (vdot(ax, ax) * *z);
    const float sy = vdot(d, ay) / (vdot(ay, ay) * *z);
    *fx = 0.5f * (1.0f - sx) * (float)cam->width;
    *fy = 0.5f * (1.0f - sy) * (float)cam->height;
}

/// The derivative of camera_project's film position along the film direction (nx, ny) with respect
/// to the world point p: d(n . f)/dp, a world vector. f = (W/2 (1 - sx), H/2 (1 - sy)) with
/// sx = (d.ax) / (|ax|^2 z), so dsx/dp = (ax / |ax|^2 - sx dir_z) / z.
TANDEM_INLINE float3 camera_project_gradient(const DeviceCamera* cam, float3 p, float nx,
                                             float ny) {
    const float3 d = p - xyz(cam->origin);
    const float3 ax = xyz(cam->dir_x), ay = xyz(cam->dir_y), az = xyz(cam->dir_z);
    const float z = vdot(d, az);
    const float ax2 = vdot(ax, ax), ay2 = vdot(ay, ay);
    const float sx = vdot(d, ax) / (ax2 * z), sy = vdot(d, ay) / (ay2 * z);
    const float3 dsx = (ax * (1.0f / ax2) - az * sx) * (1.0f / z);
    const float3 dsy = (ay * (1.0f / ay2) - az * sy) * (1.0f / z);
    const float kx = -0.5f * (float)cam->width * nx, ky = -0.5f * (float)cam->height * ny;
    return dsx * kx + dsy * ky;
}

/// The parameter along the piece a -> b of the point whose film position is the fraction u of the
/// way between theirs, for depths za and zb: perspective maps the segment to the film with 1/z
/// linear, so tau = u za / ((1 - u) zb + u za).
TANDEM_INLINE float edge_perspective_tau(float u, float za, float zb) {
    return u * za / ((1.0f - u) * zb + u * za);
}

/// One light vertex of the secondary term's reuse across iterations ("Amortizing Samples in
/// Physics-Based Inverse Rendering using ReSTIR", Wang et al. 2023, Sec. 5.2, Alg. 6): the boundary
/// point p^B it was resampled at, as an edge of that iteration's table and the point's parameter
/// along it (nothing in world space, which moves with the parameters), and the point y on an
/// emissive triangle it chose, as the triangle and the random numbers that place y on it
/// (nee_triangle_sample), with its unbiased contribution weight W in the lights' area measure and
/// its confidence M. `cell`: the grid cell of p^B (secondary_reuse_cell), by which the next
/// iteration finds it; 32 bytes.
typedef struct BoundaryReservoir {
    uint edge;  ///< SecondaryEdge index of its iteration's table; NO_EMISSIVE in `light`: empty
    float t;    ///< p^B = p0 + t (p1 - p0)
    uint light; ///< emissive triangle; NO_EMISSIVE: an empty reservoir (it estimates 0)
    float u1, u2;
    float W;
    float M;
    uint cell;
} BoundaryReservoir;
TANDEM_STATIC_ASSERT_SIZE(BoundaryReservoir, 32);

/// SecondaryReuse::flags: the target weighs down light points that neither side of the edge sees
#define SECONDARY_REUSE_LIGHT_VISIBLE 1u
/// and directions whose receiver the camera does not see directly
#define SECONDARY_REUSE_RECEIVER_SEEN 2u

/// What the secondary term's reuse does in one pass (core/render/boundary_reuse.h), 32 bytes.
typedef struct SecondaryReuse {
    uint enabled;    ///< 0: the plain estimator, bit for bit
    uint candidates; ///< fresh light points per sample (streaming RIS), at least 1
    uint neighbours; ///< previous reservoirs of p^B's cell to combine with, at most
    uint buckets;    ///< the previous reservoirs' hash table size, a power of two (0: none)
    float cell;      ///< the grid's cell size, world units
    float m_cap;     ///< a previous reservoir's confidence is capped at this when read
    float lum_floor; ///< added to each light's luminance in the target (reflected light)
    uint flags;      ///< SECONDARY_REUSE_*: what the target weighs down by SECONDARY_REUSE_HIDDEN
} SecondaryReuse;
TANDEM_STATIC_ASSERT_SIZE(SecondaryReuse, 32);

/// The hash of the grid cell of p (cells of side `cell`): the cell's integer coordinates times three
/// large primes, xor-ed ("Optimized Spatial Hashing for Collision Detection of Deformable Objects",
/// Teschner et al. 2003, Sec. 4). Reservoirs share a bucket by its low bits, and a lookup keeps
/// only those of its own hash.
TANDEM_INLINE uint secondary_reuse_cell(float3 p, float cell) {
    const int ix = (int)floor(p.x / cell), iy = (int)floor(p.y / cell), iz = (int)floor(p.z / cell);
    return ((uint)ix * 73856093u) ^ ((uint)iy * 19349663u) ^ ((uint)iz * 83492791u);
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_BOUNDARY_H
