// The surface interaction at a ray's hit: position, geometric normal and what the primitive is
// (interaction_at), then the material, shading side and frame, and albedo (interaction_shade), and
// for the adjoint the parameters the albedo comes from (interaction_albedo_source).
#ifndef TANDEM_KERNELS_PATH_INTERACTION_H
#define TANDEM_KERNELS_PATH_INTERACTION_H

#include "path/scene.h"

typedef struct Interaction {
    // the hit (interaction_at)
    Hit hit;
    float3 x;       ///< position, world space
    float3 n_front; ///< unit geometric normal, (p1 - p0) x (p2 - p0): an emitter's front side
    float3 wi;      ///< unit, toward where the ray came from
    TriangleInfo info;
    // the shading (interaction_shade)
    Material mat;    ///< with its differentiable values from the path's parameters
    __global const float* plastic_tables; ///< the scene's, for bsdf_eval and its kin
    Frame frame;     ///< around the geometric normal on the shading side
    float3 wi_local; ///< wi in `frame`
    float tu, tv;    ///< texture coordinates (0 when the material has no texture)
    float3 albedo;   ///< the material's albedo at (tu, tv)
    float3 n_out;    ///< the geometric normal on the side wi leaves from
    float3 origin;   ///< origin of rays leaving on that side
} Interaction;

/// The point of the triangle whose record (ShadingPrimitive or EmissiveTriangle: three float4
/// vertices, then its unit normal (p1 - p0) x (p2 - p0) at floats 12-14) starts at t, with
/// barycentric weights b0, b1, b2 of its vertices, into p[0..3), and that normal into n[0..3).
TANDEM_INLINE void triangle_point(__global const float* t, float b0, float b1, float b2, float* p,
                                  float* n) {
    p[0] = t[0] * b0 + t[4] * b1 + t[8] * b2;
    p[1] = t[1] * b0 + t[5] * b1 + t[9] * b2;
    p[2] = t[2] * b0 + t[6] * b1 + t[10] * b2;
    n[0] = t[12];
    n[1] = t[13];
    n[2] = t[14];
}

/// triangle_point at hit coordinates (u, v): barycentric weights 1 - u - v, u and v.
TANDEM_INLINE void triangle_hit_point(__global const float* t, float u, float v, float* p,
                                      float* n) {
    triangle_point(t, 1.0f - u - v, u, v, p, n);
}

#if BVH_ANALYTIC
/// The point of the sphere whose record (ShadingPrimitive, as floats: centre at 0-2, radius at 4,
/// orientation at 5) starts at t, at its hit coordinates (u, v) (the octahedral direction from
/// its centre), into p[0..3), and its front normal (the direction times the orientation) into
/// n[0..3).
TANDEM_INLINE void sphere_point(__global const float* t, float u, float v, float* p, float* n) {
    float sx, sy, sz;
    bvh_oct_decode(u, v, &sx, &sy, &sz);
    p[0] = t[0] + sx * t[4];
    p[1] = t[1] + sy * t[4];
    p[2] = t[2] + sz * t[4];
    n[0] = sx * t[5];
    n[1] = sy * t[5];
    n[2] = sz * t[5];
}

/// The point of the disk whose record (centre at 0-2, x axis at 4-6, y axis at 8-10, orientation
/// at 11) starts at t, at local coordinates (u, v): centre + u x_axis + v y_axis, into p[0..3);
/// its front normal normalize(x_axis x y_axis) times the orientation into n[0..3).
TANDEM_INLINE void disk_point(__global const float* t, float u, float v, float* p, float* n) {
    const float ax = t[4], ay = t[5], az = t[6], bx = t[8], by = t[9], bz = t[10];
    const float qx = ay * bz - az * by, qy = az * bx - ax * bz, qz = ax * by - ay * bx;
    const float inv_q = 1.0f / sqrt(qx * qx + qy * qy + qz * qz);
    p[0] = t[0] + ax * u + bx * v;
    p[1] = t[1] + ay * u + by * v;
    p[2] = t[2] + az * u + bz * v;
    n[0] = qx * inv_q * t[11];
    n[1] = qy * inv_q * t[11];
    n[2] = qz * inv_q * t[11];
}
#endif

/// The point of primitive `prim` at its hit coordinates (u, v) (Hit), and the primitive's unit
/// normal on its front side there: a triangle's (p1 - p0) x (p2 - p0) (triangle_point; the host
/// computes it: triangle_front_normal), a sphere's outward normal or a disk's x_axis x y_axis,
/// times the shape's orientation (sphere_point, disk_point). An analytic shape's point is rebuilt
/// from its own coordinates (the direction from a sphere's centre, a disk's local x and y), so it
/// lies on the surface to rounding wherever along the ray the hit was found.
TANDEM_INLINE void primitive_point(const SceneRefs* s, uint prim, float u, float v, float3* x,
                                   float3* n_front) {
    __global const float* t = (__global const float*)(s->prims + prim);
    float p[3], n[3];
#if BVH_ANALYTIC
    const uint kind = as_uint(t[7]);
    if (kind == BVH_PRIM_SPHERE)
        sphere_point(t, u, v, p, n);
    else if (kind == BVH_PRIM_DISK)
        disk_point(t, u, v, p, n);
    else
#endif
        triangle_hit_point(t, u, v, p, n);
    *x = make_float3(p[0], p[1], p[2]);
    *n_front = make_float3(n[0], n[1], n[2]);
}

/// The surface point where `ray` (unit direction) found `hit`: position, geometric normal, wi and
/// the primitive's record, in *it (through a pointer, not returned, for Oclgrind: see
/// TANDEM_INLINE in compat.h).
TANDEM_INLINE void interaction_at(const SceneRefs* s, Ray ray, Hit hit, Interaction* it) {
    it->hit = hit;
    primitive_point(s, hit.prim, hit.u, hit.v, &it->x, &it->n_front);
    it->wi = -xyz(ray.dir);
    it->info = s->infos[hit.prim];
}

#if HAS_TEXTURES
/// Texture coordinates at (u, v) of the triangle whose TriangleUV record starts at uv (as floats:
/// u0, v0, u1, v1, u2, v2): its vertices' uvs, interpolated.
TANDEM_INLINE void triangle_uv(__global const float* uv, float u, float v, float* tu, float* tv) {
    const float b0 = 1.0f - u - v;
    *tu = uv[0] * b0 + uv[2] * u + uv[4] * v;
    *tv = uv[1] * b0 + uv[3] * u + uv[5] * v;
}

#endif

#if HAS_TEXTURES
#if BVH_ANALYTIC
/// An angle phi in (-pi, pi] as a fraction of the turn from 0, in [0, 1): the u of a sphere's
/// and the v of a disk's texture coordinates.
TANDEM_INLINE float angle_fraction(float phi) {
    return (phi < 0.0f ? phi + 2.0f * TANDEM_PI : phi) * (0.5f * TANDEM_INV_PI);
}

/// The direction from the centre of the sphere whose record starts at t to its point at hit
/// coordinates (u, v), in the sphere's own axes (its record's quaternion, floats 8-11).
TANDEM_INLINE void sphere_local_direction(__global const float* t, float u, float v, float* x,
                                          float* y, float* z) {
    bvh_oct_decode(u, v, x, y, z);
    bvh_quat_rotate(t[8], t[9], t[10], t[11], x, y, z);
}

/// A sphere's texture v at local direction z: theta / pi, theta from +z.
TANDEM_INLINE float sphere_texture_v(float z) {
    return det_acos(fmin(fmax(z, -1.0f), 1.0f)) * TANDEM_INV_PI;
}

/// A disk's texture u at local point (u, v): its radius.
TANDEM_INLINE float disk_texture_u(float u, float v) { return sqrt(u * u + v * v); }
#endif

/// Texture coordinates of `hit`: a triangle's interpolated vertex uvs (triangle_uv); on a sphere
/// Mitsuba's (phi / 2pi, theta / pi) of the direction from its centre, theta from +z and phi from
/// +x toward +y in the sphere's own axes (sphere_local_direction); on a disk Mitsuba's
/// (r, phi / 2pi) of the local point, phi from local +x toward +y.
TANDEM_INLINE void primitive_uv(const SceneRefs* s, Hit hit, float* tu, float* tv) {
#if BVH_ANALYTIC
    __global const float* t = (__global const float*)(s->prims + hit.prim);
    const uint kind = as_uint(t[7]);
    if (kind == BVH_PRIM_DISK) {
        const float phi = det_atan2(hit.v, hit.u);
        *tu = disk_texture_u(hit.u, hit.v);
        *tv = angle_fraction(phi);
        return;
    }
    if (kind == BVH_PRIM_SPHERE) {
        float nx, ny, nz;
        sphere_local_direction(t, hit.u, hit.v, &nx, &ny, &nz);
        const float phi = det_atan2(ny, nx);
        *tu = angle_fraction(phi);
        *tv = sphere_texture_v(nz);
        return;
    }
#endif
    triangle_uv((__global const float*)(s->uvs + hit.prim), hit.u, hit.v, tu, tv);
}
#endif

#if HAS_SHADING_NORMALS
/// Whether the primitive is shaded with its vertex normals (core/scene/vertex_normals.h).
TANDEM_INLINE int primitive_smooth(const SceneRefs* s, uint prim) {
    return s->normals[prim].link.x != 0u;
}

/// The unit shading normal of a smooth primitive at hit coordinates (u, v): its vertex normals
/// interpolated with the barycentric weights 1 - u - v, u, v and normalised, as Mitsuba 3's mesh
/// interaction; the interpolation itself (before normalising) into *m.
TANDEM_INLINE float3 interpolated_normal(const SceneRefs* s, uint prim, float u, float v,
                                         float3* m) {
    __global const TriangleNormals* t = s->normals + prim;
    *m = xyz(t->n0) * (1.0f - u - v) + xyz(t->n1) * u + xyz(t->n2) * v;
    return *m * (1.0f / vlength(*m));
}
#endif

/// Whether a surface of material flags `flags`, seen at cosine cos_front to its front normal, is
/// shaded from its back: a two-sided material seen from behind (its normal flips). A one-sided
/// one seen from behind (cosine <= 0 after the flip) is black.
TANDEM_INLINE int interaction_flips(uint flags, float cos_front) {
    return (flags & MATERIAL_FLAG_TWOSIDED) && cos_front < 0.0f;
}

/// Shades `it` with the material under `params`: the side it is seen from, the frame, texture
/// coordinates and albedo, and the origin of the rays that leave it. Returns 0 where the path
/// ends: the back of a one-sided surface, which is black, and a black material (an emitter's
/// default bsdf), whose light samples and continuation would all weigh 0.
TANDEM_INLINE int interaction_shade(const SceneRefs* s, __global const float* params,
                                    Interaction* it) {
    it->mat = material_load(s, params, it->info.material);
    it->plastic_tables = s->plastic_tables;
    if (it->mat.flags & MATERIAL_FLAG_BLACK) return 0;
    float3 n = it->n_front;
#if HAS_SHADING_NORMALS
    // As Mitsuba: the side a smooth surface is seen from, its frame and its BSDF follow the
    // interpolated normal; its rays leave on wi's side of the triangle itself (n_out).
    if (primitive_smooth(s, it->hit.prim)) {
        float3 m;
        n = interpolated_normal(s, it->hit.prim, it->hit.u, it->hit.v, &m);
    }
#endif
    // A dielectric is two-sided by nature (wi_local.z < 0: inside); other BSDFs are one-sided
    // unless wrapped in twosided, and black from behind.
    if (it->mat.type != MATERIAL_DIELECTRIC) {
        if (interaction_flips(it->mat.flags, vdot(it->wi, n))) n = -n;
        if (vdot(it->wi, n) <= 0.0f) return 0;
    }
    it->frame = frame_from_normal(n);
    it->wi_local = frame_to_local(it->frame, it->wi);
    it->tu = 0.0f;
    it->tv = 0.0f;
#if HAS_TEXTURES
    if (it->mat.texture != NO_TEXTURE) primitive_uv(s, it->hit, &it->tu, &it->tv);
#endif
    it->albedo = material_albedo(s, &it->mat, params, it->tu, it->tv);
    it->n_out = vdot(it->wi, it->n_front) >= 0.0f ? it->n_front : -it->n_front;
    it->origin = offset_ray_origin(it->x, it->n_out);
    return 1;
}

/// Where the albedo of a surface point comes from: an rgb parameter, or up to four texels of a
/// bitmap parameter with their bilinear weights.
typedef struct AlbedoSource {
    uint param;       ///< rgb parameter, or NO_PARAM
    uint texel_param; ///< first texel of a bitmap parameter, or NO_PARAM
    uint count;
    uint index[4];
    float weight[4];
} AlbedoSource;

/// The parameters the albedo of shaded `it` is read from, in *src (through a pointer, as
/// interaction_at).
TANDEM_INLINE void interaction_albedo_source(const SceneRefs* s, const Interaction* it,
                                             AlbedoSource* src) {
    src->param = it->mat.reflectance_param;
    src->texel_param = NO_PARAM;
    src->count = 0u;
#if HAS_TEXTURES
    if (it->mat.texture != NO_TEXTURE) {
        __global const TextureInfo* t = &s->textures[it->mat.texture];
        src->param = NO_PARAM;
        if (t->param != NO_PARAM) {
            src->texel_param = t->param;
            src->count = texture_footprint(t, it->tu, it->tv, src->index, src->weight);
        }
    }
#else
    (void)s;
#endif
}

#endif // TANDEM_KERNELS_PATH_INTERACTION_H
