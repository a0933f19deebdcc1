// Texture evaluation (bitmap with bilinear or nearest filtering and repeat wrapping, checkerboard),
// shared by host and device: the host reference in tests/core/render/test_textures.cpp runs this code.
#ifndef TANDEM_SHARED_TEXTURES_H
#define TANDEM_SHARED_TEXTURES_H

#include "shared/det_math.h"
#include "shared/sampling.h"
#include "shared/scene_layout.h"

TANDEM_NAMESPACE_BEGIN

/// i mod n in [0, n) for any int i (repeat wrapping).
TANDEM_INLINE uint texture_wrap(int i, uint n) {
    const int m = i % (int)n;
    return (uint)(m < 0 ? m + (int)n : m);
}

/// Index of texel (x, y) of a bitmap of w x h texels, wrapped, counted from its first texel.
TANDEM_INLINE uint texture_wrapped_index(int x, int y, uint w, uint h) {
    return texture_wrap(y, h) * w + texture_wrap(x, w);
}

/// Index of texel (x, y) of bitmap t, wrapped, counted from its first texel.
TANDEM_INLINE uint texture_index(TANDEM_GLOBAL const TextureInfo* t, int x, int y) {
    return texture_wrapped_index(x, y, t->width, t->height);
}

// The pieces of a texture lookup, in scalars, the one definition of each: texture_footprint and
// texture_eval (the megakernels, the adjoint, the host's reference) branch between them, and the
// wavefront's shading stage (path/wavefront_lookup.h: wf_texture) selects between them, one
// channel at a time, so that PoCL's loop vectoriser can run it. A record is read as floats (tf)
// or words: its colours at 0-3 and 4-7, its uv transform's rows at 8-10 and 12-14 (scalar loads:
// the vectoriser refuses a float4 loaded whole).

/// The texture coordinates (u, v) through the texture's transform (its record as floats, tf).
TANDEM_INLINE void texture_transform(TANDEM_GLOBAL const float* tf, float u, float v, float* tu,
                                     float* tv) {
    *tu = tf[8] * u + tf[9] * v + tf[10];
    *tv = tf[12] * u + tf[13] * v + tf[14];
}

/// Channel c of a checkerboard (its record as floats, tf) at transformed coordinates (tu, tv):
/// color0 where both halves agree, else color1. (det_floor is floor, the same bits everywhere.)
TANDEM_INLINE float texture_checker(TANDEM_GLOBAL const float* tf, float tu, float tv, uint c) {
    const int mu = tu - det_floor(tu) > 0.5f, mv = tv - det_floor(tv) > 0.5f;
    return tf[(mu == mv ? 0u : 4u) + c];
}

/// The texel of a w x h bitmap nearest to texel-space point (x, y).
TANDEM_INLINE uint texture_nearest(float x, float y, uint w, uint h) {
    return texture_wrapped_index((int)det_floor(x), (int)det_floor(y), w, h);
}

/// The four texel centres around texel-space point (x, y) of a w x h bitmap, into index[0..4),
/// and their bilinear weights, into weight[0..4).
TANDEM_INLINE void texture_bilinear(float x, float y, uint w, uint h, uint* index, float* weight) {
    const float fx = x - 0.5f, fy = y - 0.5f;
    const float x0 = det_floor(fx), y0 = det_floor(fy);
    const float ax = fx - x0, ay = fy - y0;
    const int ix = (int)x0, iy = (int)y0;
    index[0] = texture_wrapped_index(ix, iy, w, h);
    index[1] = texture_wrapped_index(ix + 1, iy, w, h);
    index[2] = texture_wrapped_index(ix, iy + 1, w, h);
    index[3] = texture_wrapped_index(ix + 1, iy + 1, w, h);
    weight[0] = (1.0f - ax) * (1.0f - ay);
    weight[1] = ax * (1.0f - ay);
    weight[2] = (1.0f - ax) * ay;
    weight[3] = ax * ay;
}

/// Channel c of texel i of the bitmap at texel offset `offset`, or from the parameter buffer at
/// `param` when the bitmap is a parameter (not NO_PARAM). A branch, not a select of two loads:
/// the vectoriser makes it two masked gathers, each touching only its lanes' memory.
TANDEM_INLINE float texture_texel_channel(TANDEM_GLOBAL const float* params,
                                          TANDEM_GLOBAL const float4* texels, uint param,
                                          uint offset, uint i, uint c) {
    float value;
    if (param != NO_PARAM)
        value = params[param + 3u * i + c];
    else
        value = ((TANDEM_GLOBAL const float*)texels)[4u * (offset + i) + c];
    return value;
}

/// Texel i of bitmap t: from the parameter buffer when the bitmap is a parameter, else from texels.
TANDEM_INLINE float3 texture_texel(TANDEM_GLOBAL const TextureInfo* t,
                                   TANDEM_GLOBAL const float4* texels,
                                   TANDEM_GLOBAL const float* params, uint i) {
    return make_float3(texture_texel_channel(params, texels, t->param, t->offset, i, 0u),
                       texture_texel_channel(params, texels, t->param, t->offset, i, 1u),
                       texture_texel_channel(params, texels, t->param, t->offset, i, 2u));
}

/// The texels a bitmap lookup at (u, v) blends and their weights: index[k] (as texture_index),
/// weight[k], k < the returned count (4 bilinear, 1 nearest, 0 for a checkerboard). texture_eval
/// is the weighted sum, so d(value)/d(texel index[k]) = weight[k] per channel.
TANDEM_INLINE uint texture_footprint(TANDEM_GLOBAL const TextureInfo* t, float u, float v,
                                     uint* index, float* weight) {
    if (t->kind == TEXTURE_CHECKERBOARD) return 0u;
    float tu, tv;
    texture_transform((TANDEM_GLOBAL const float*)t, u, v, &tu, &tv);
    const float x = tu * (float)t->width, y = tv * (float)t->height;
    if (t->filter == TEXTURE_FILTER_NEAREST) {
        index[0] = texture_nearest(x, y, t->width, t->height);
        weight[0] = 1.0f;
        return 1u;
    }
    texture_bilinear(x, y, t->width, t->height, index, weight);
    return 4u;
}

/// The derivatives of texture t's value at texture coordinates (u, v) (before its transform) in
/// u and v, per channel, into *du and *dv. A bilinear lookup is bilinear in the texel-space
/// point between four texel centres, d/dax = (1 - ay)(T1 - T0) + ay (T3 - T2) and d/day =
/// (1 - ax)(T2 - T0) + ax (T3 - T1), and the point moves by (width, height) times the
/// transform's rows; nearest texels and the checkerboard are piecewise constant: zero (their
/// jumps are discontinuities that no interior term sees).
TANDEM_INLINE void texture_eval_duv(TANDEM_GLOBAL const TextureInfo* t,
                                    TANDEM_GLOBAL const float4* texels,
                                    TANDEM_GLOBAL const float* params, float u, float v,
                                    float3* du, float3* dv) {
    *du = *dv = make_float3(0.0f, 0.0f, 0.0f);
    if (t->kind == TEXTURE_CHECKERBOARD || t->filter == TEXTURE_FILTER_NEAREST) return;
    TANDEM_GLOBAL const float* tf = (TANDEM_GLOBAL const float*)t;
    float tu, tv;
    texture_transform(tf, u, v, &tu, &tv);
    const float x = tu * (float)t->width, y = tv * (float)t->height;
    uint index[4];
    float weight[4];
    texture_bilinear(x, y, t->width, t->height, index, weight);
    const float ax = (x - 0.5f) - det_floor(x - 0.5f), ay = (y - 0.5f) - det_floor(y - 0.5f);
    const float3 c0 = texture_texel(t, texels, params, index[0]),
                 c1 = texture_texel(t, texels, params, index[1]),
                 c2 = texture_texel(t, texels, params, index[2]),
                 c3 = texture_texel(t, texels, params, index[3]);
    const float3 d_ax = (c1 - c0) * (1.0f - ay) + (c3 - c2) * ay,
                 d_ay = (c2 - c0) * (1.0f - ax) + (c3 - c1) * ax;
    const float sx = (float)t->width, sy = (float)t->height;
    *du = d_ax * (sx * tf[8]) + d_ay * (sy * tf[12]);
    *dv = d_ax * (sx * tf[9]) + d_ay * (sy * tf[13]);
}

/// Linear RGB of texture t at texture coordinates (u, v). params: the parameter buffer (read when
/// t->param != NO_PARAM; may be null otherwise).
TANDEM_INLINE float3 texture_eval(TANDEM_GLOBAL const TextureInfo* t,
                                  TANDEM_GLOBAL const float4* texels,
                                  TANDEM_GLOBAL const float* params, float u, float v) {
    if (t->kind == TEXTURE_CHECKERBOARD) {
        TANDEM_GLOBAL const float* tf = (TANDEM_GLOBAL const float*)t;
        float tu, tv;
        texture_transform(tf, u, v, &tu, &tv);
        return make_float3(texture_checker(tf, tu, tv, 0u), texture_checker(tf, tu, tv, 1u),
                           texture_checker(tf, tu, tv, 2u));
    }
    uint index[4];
    float weight[4];
    const uint n = texture_footprint(t, u, v, index, weight);
    float3 c = texture_texel(t, texels, params, index[0]) * weight[0];
    for (uint k = 1; k < n; ++k) c += texture_texel(t, texels, params, index[k]) * weight[k];
    return c;
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_TEXTURES_H
