// The lookups of the wavefront's shading stage (path/wavefront.h) where the megakernels branch on
// a kind: a texture's (checkerboard, bilinear or nearest bitmap) and, with analytic shapes, a
// primitive's point and texture coordinates (triangle, sphere or disk). Each computes the pieces
// of every kind with the functions the megakernels call (shared/textures.h,
// path/interaction.h) and selects the one of the record's kind, so that PoCL's loop vectoriser
// can run the stage with one path of code.
#ifndef TANDEM_KERNELS_PATH_WAVEFRONT_LOOKUP_H
#define TANDEM_KERNELS_PATH_WAVEFRONT_LOOKUP_H

#include "path/primal.h"

#if HAS_TEXTURES
/// Channel c of texture_eval of texture `index` at texture coordinates (u, v), with selects:
/// checkerboard, or a bitmap filtered bilinearly or by the nearest texel (shared/textures.h:
/// texture_transform, texture_checker, texture_bilinear, texture_nearest,
/// texture_texel_channel). (The three channels' calls share their address arithmetic once
/// inlined.)
TANDEM_INLINE float wf_texture(__global const TextureInfo* textures, __global const float4* texels,
                               __global const float* params, uint index, float u, float v, uint c) {
    __global const float* tf = (__global const float*)(textures + index);
    __global const uint* tw = (__global const uint*)(textures + index);
    const uint kind = tw[16], offset = tw[17], filter = tw[20], param = tw[21];
    // a checkerboard has no texels: its wrapping divides by 1
    const uint width = max(tw[18], 1u), height = max(tw[19], 1u);
    float tu, tv;
    texture_transform(tf, u, v, &tu, &tv);
    const float checker = texture_checker(tf, tu, tv, c);
#if !HAS_BITMAPS
    // no bitmap in the scene: no texel gathers, which every lane would do (masked) below
    (void)texels;
    (void)params;
    (void)kind;
    (void)offset;
    (void)filter;
    (void)param;
    (void)width;
    (void)height;
    return checker;
#else
    const float x = tu * (float)width, y = tv * (float)height;
    uint i[4];
    float w[4];
    texture_bilinear(x, y, width, height, i, w);
    const float blend = texture_texel_channel(params, texels, param, offset, i[0], c) * w[0] +
                        texture_texel_channel(params, texels, param, offset, i[1], c) * w[1] +
                        texture_texel_channel(params, texels, param, offset, i[2], c) * w[2] +
                        texture_texel_channel(params, texels, param, offset, i[3], c) * w[3];
    // the nearest texel's weight is 1: texel * 1.0f is the texel
    const float bitmap =
        filter != TEXTURE_FILTER_NEAREST
            ? blend
            : texture_texel_channel(params, texels, param, offset,
                                    texture_nearest(x, y, width, height), c);
    return kind == TEXTURE_CHECKERBOARD ? checker : bitmap;
#endif
}
#endif

#if BVH_ANALYTIC
/// primitive_point (path/interaction.h) for the record at t (ShadingPrimitive) with selects: the
/// triangle's point and normal, the sphere's and the disk's are all computed (triangle_point,
/// sphere_point, disk_point), and the record's kind picks one, so that the vectoriser keeps a
/// single path of code.
TANDEM_INLINE void wf_primitive_point(__global const float* t, float u, float v, float* p,
                                      float* n) {
    float tp[3], tn[3], sp[3], sn[3], dp[3], dn[3];
    triangle_hit_point(t, u, v, tp, tn);
    sphere_point(t, u, v, sp, sn);
    disk_point(t, u, v, dp, dn);
    // bit tests, not comparisons: LLVM turned two comparisons of `kind` into a switch, which
    // the loop vectoriser refuses (BVH_PRIM_SPHERE and BVH_PRIM_DISK are single bits)
    const uint kind = as_uint(t[7]);
    const int sphere = (kind & BVH_PRIM_SPHERE) != 0u, disk = (kind & BVH_PRIM_DISK) != 0u;
    p[0] = sphere ? sp[0] : (disk ? dp[0] : tp[0]);
    p[1] = sphere ? sp[1] : (disk ? dp[1] : tp[1]);
    p[2] = sphere ? sp[2] : (disk ? dp[2] : tp[2]);
    n[0] = sphere ? sn[0] : (disk ? dn[0] : tn[0]);
    n[1] = sphere ? sn[1] : (disk ? dn[1] : tn[1]);
    n[2] = sphere ? sn[2] : (disk ? dn[2] : tn[2]);
}

#if HAS_TEXTURES
/// primitive_uv with selects, as wf_primitive_point: the triangle's interpolated uvs from its
/// record in uvs (TriangleUV) at `uv`, the sphere's or the disk's, picked by the kind of the
/// primitive record at t.
TANDEM_INLINE void wf_primitive_uv(__global const float* t, __global const float* uv, float u,
                                   float v, float* tu, float* tv) {
    const uint kind = as_uint(t[7]);
    float sx, sy, sz;
    sphere_local_direction(t, u, v, &sx, &sy, &sz);
    const int sphere = (kind & BVH_PRIM_SPHERE) != 0u, disk = (kind & BVH_PRIM_DISK) != 0u;
    // the angle: of the direction from a sphere's centre, or of a disk's local point (one
    // atan2 of selected arguments, not two selected results: every lane computes both)
    const float phi_u = angle_fraction(det_atan2(sphere ? sy : v, sphere ? sx : u));
    float ttu, ttv;
    triangle_uv(uv, u, v, &ttu, &ttv);
    *tu = sphere ? phi_u : (disk ? disk_texture_u(u, v) : ttu);
    *tv = sphere ? sphere_texture_v(sz) : (disk ? phi_u : ttv);
}
#endif
#endif

#endif // TANDEM_KERNELS_PATH_WAVEFRONT_LOOKUP_H
