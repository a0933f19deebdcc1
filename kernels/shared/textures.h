// Texture evaluation (bitmap with bilinear or nearest filtering and repeat wrapping, checkerboard),
// shared by host and device: the host reference in tests/core/render/test_textures.cpp runs this code.
#ifndef TANDEM_SHARED_TEXTURES_H
#define TANDEM_SHARED_TEXTURES_H

#include "shared/sampling.h"
#include "shared/scene_layout.h"

TANDEM_NAMESPACE_BEGIN

/// i mod n in [0, n) for any int i (repeat wrapping).
TANDEM_INLINE uint texture_wrap(int i, uint n) {
    const int m = i % (int)n;
    return (uint)(m < 0 ? m + (int)n : m);
}

/// Index of texel (x, y) of bitmap t, wrapped, counted from its first texel.
TANDEM_INLINE uint texture_index(TANDEM_GLOBAL const TextureInfo* t, int x, int y) {
    return texture_wrap(y, t->height) * t->width + texture_wrap(x, t->width);
}

/// Texel i of bitmap t: from the parameter buffer when the bitmap is a parameter, else from texels.
TANDEM_INLINE float3 texture_texel(TANDEM_GLOBAL const TextureInfo* t,
                                   TANDEM_GLOBAL const float4* texels,
                                   TANDEM_GLOBAL const float* params, uint i) {
    if (t->param != NO_PARAM) {
        TANDEM_GLOBAL const float* p = params + t->param + 3u * i;
        return make_float3(p[0], p[1], p[2]);
    }
    const float4 c = texels[t->offset + i];
    return make_float3(c.x, c.y, c.z);
}

/// The texels a bitmap lookup at (u, v) blends and their weights: index[k] (as texture_index),
/// weight[k], k < the returned count (4 bilinear, 1 nearest, 0 for a checkerboard). texture_eval
/// is the weighted sum, so d(value)/d(texel index[k]) = weight[k] per channel.
TANDEM_INLINE uint texture_footprint(TANDEM_GLOBAL const TextureInfo* t, float u, float v,
                                     uint* index, float* weight) {
    if (t->kind == TEXTURE_CHECKERBOARD) return 0u;
    const float tu = t->uv_row0.x * u + t->uv_row0.y * v + t->uv_row0.z;
    const float tv = t->uv_row1.x * u + t->uv_row1.y * v + t->uv_row1.z;
    const float x = tu * (float)t->width, y = tv * (float)t->height;
    if (t->filter == TEXTURE_FILTER_NEAREST) {
        index[0] = texture_index(t, (int)floor(x), (int)floor(y));
        weight[0] = 1.0f;
        return 1u;
    }
    // bilinear between the four texel centres around (x, y)
    const float fx = x - 0.5f, fy = y - 0.5f;
    const float x0 = floor(fx), y0 = floor(fy);
    const float ax = fx - x0, ay = fy - y0;
    const int ix = (int)x0, iy = (int)y0;
    index[0] = texture_index(t, ix, iy);
    index[1] = texture_index(t, ix + 1, iy);
    index[2] = texture_index(t, ix, iy + 1);
    index[3] = texture_index(t, ix + 1, iy + 1);
    weight[0] = (1.0f - ax) * (1.0f - ay);
    weight[1] = ax * (1.0f - ay);
    weight[2] = (1.0f - ax) * ay;
    weight[3] = ax * ay;
    return 4u;
}

/// Linear RGB of texture t at texture coordinates (u, v). params: the parameter buffer (read when
/// t->param != NO_PARAM; may be null otherwise).
TANDEM_INLINE float3 texture_eval(TANDEM_GLOBAL const TextureInfo* t,
                                  TANDEM_GLOBAL const float4* texels,
                                  TANDEM_GLOBAL const float* params, float u, float v) {
    if (t->kind == TEXTURE_CHECKERBOARD) {
        const float tu = t->uv_row0.x * u + t->uv_row0.y * v + t->uv_row0.z;
        const float tv = t->uv_row1.x * u + t->uv_row1.y * v + t->uv_row1.z;
        const int mu = tu - floor(tu) > 0.5f, mv = tv - floor(tv) > 0.5f;
        return mu == mv ? xyz(t->color0) : xyz(t->color1);
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
