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

/// The point of primitive `prim` at its hit coordinates (u, v) (Hit), and the primitive's unit
/// normal on its front side there: a triangle's (p1 - p0) x (p2 - p0), a sphere's outward normal
/// or a disk's x_axis x y_axis, times the shape's orientation. An analytic shape's point is
/// rebuilt from its own coordinates (the direction from a sphere's centre, a disk's local x and
/// y), so it lies on the surface to rounding wherever along the ray the hit was found.
TANDEM_INLINE void primitive_point(const SceneRefs* s, uint prim, float u, float v, float3* x,
                                   float3* n_front) {
#if BVH_ANALYTIC
    const ShadingPrimitive tri = s->prims[prim];
    if (as_uint(tri.v1.w) == BVH_PRIM_SPHERE) {
        float nx, ny, nz;
        bvh_oct_decode(u, v, &nx, &ny, &nz);
        const float3 n = make_float3(nx, ny, nz);
        *x = xyz(tri.v0) + n * tri.v1.x;
        *n_front = n * tri.v1.y;
        return;
    }
    if (as_uint(tri.v1.w) == BVH_PRIM_DISK) {
        const float3 ax = xyz(tri.v1), ay = xyz(tri.v2);
        *x = xyz(tri.v0) + ax * u + ay * v;
        *n_front = vnormalize(vcross(ax, ay)) * tri.v2.w;
        return;
    }
#endif
    // n_front: triangle_front_normal(p0, p1, p2), from the host
    float p[3], n[3];
    triangle_point((__global const float*)(s->prims + prim), 1.0f - u - v, u, v, p, n);
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
/// Texture coordinates of `hit`: a triangle's interpolated vertex uvs; on a sphere Mitsuba's
/// (phi / 2pi, theta / pi) of the direction from its centre, theta from +z and phi from +x
/// toward +y in the sphere's own axes (its record's quaternion); on a disk
/// Mitsuba's (r, phi / 2pi) of the local point, phi from local +x toward +y.
TANDEM_INLINE void primitive_uv(const SceneRefs* s, Hit hit, float* tu, float* tv) {
#if BVH_ANALYTIC
    const uint kind = as_uint(s->prims[hit.prim].v1.w);
    if (kind == BVH_PRIM_DISK) {
        const float phi = det_atan2(hit.v, hit.u);
        *tu = sqrt(hit.u * hit.u + hit.v * hit.v);
        *tv = (phi < 0.0f ? phi + 2.0f * TANDEM_PI : phi) * (0.5f * TANDEM_INV_PI);
        return;
    }
    if (kind == BVH_PRIM_SPHERE) {
        const float4 q = s->prims[hit.prim].v2;
        float nx, ny, nz;
        bvh_oct_decode(hit.u, hit.v, &nx, &ny, &nz);
        bvh_quat_rotate(q.x, q.y, q.z, q.w, &nx, &ny, &nz);
        const float phi = det_atan2(ny, nx);
        *tu = (phi < 0.0f ? phi + 2.0f * TANDEM_PI : phi) * (0.5f * TANDEM_INV_PI);
        *tv = det_acos(fmin(fmax(nz, -1.0f), 1.0f)) * TANDEM_INV_PI;
        return;
    }
#endif
    triangle_uv((__global const float*)(s->uvs + hit.prim), hit.u, hit.v, tu, tv);
}
#endif

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
    // A dielectric is two-sided by nature (wi_local.z < 0: inside); other BSDFs are one-sided
    // unless wrapped in twosided, and black from behind.
    if (it->mat.type != MATERIAL_DIELECTRIC) {
        if ((it->mat.flags & MATERIAL_FLAG_TWOSIDED) && vdot(it->wi, n) < 0.0f) n = -n;
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
    it->n_out = vdot(it->wi, n) >= 0.0f ? n : -n;
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
