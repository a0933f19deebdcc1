// The surface interaction at a ray's hit: position, geometric normal and what the triangle is
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

/// The surface point where `ray` (unit direction) found `hit`: position, geometric normal, wi and
/// the triangle's record, in *it (through a pointer, not returned, for Oclgrind: see TANDEM_INLINE
/// in compat.h).
TANDEM_INLINE void interaction_at(const SceneRefs* s, Ray ray, Hit hit, Interaction* it) {
    const BvhTriangle tri = s->prims[hit.prim];
    const float3 p0 = xyz(tri.v0), p1 = xyz(tri.v1), p2 = xyz(tri.v2);
    it->hit = hit;
    it->x = p0 * (1.0f - hit.u - hit.v) + p1 * hit.u + p2 * hit.v;
    it->n_front = vnormalize(vcross(p1 - p0, p2 - p0));
    it->wi = -xyz(ray.dir);
    it->info = s->infos[hit.prim];
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
    if (it->mat.texture != NO_TEXTURE) {
        const TriangleUV tuv = s->uvs[it->hit.prim];
        const float u = it->hit.u, v = it->hit.v, b0 = 1.0f - u - v;
        it->tu = tuv.uv01.x * b0 + tuv.uv01.z * u + tuv.uv2.x * v;
        it->tv = tuv.uv01.y * b0 + tuv.uv01.w * u + tuv.uv2.y * v;
    }
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
