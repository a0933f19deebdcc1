// Texture evaluation (bitmap with bilinear or nearest filtering and repeat wrapping, checkerboard),
// shared by host and device: the host reference in tests/core/test_textures.cpp runs this code.
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

TANDEM_INLINE float3 texture_texel(TANDEM_GLOBAL const TextureInfo* t,
                                   TANDEM_GLOBAL const float4* texels, int x, int y) {
    const float4 c = texels[t->offset + texture_wrap(y, t->height) * t->width + texture_wrap(x, t->width)];
    return make_float3(c.x, c.y, c.z);
}

/// Linear RGB of texture t at texture coordinates (u, v).
TANDEM_INLINE float3 texture_eval(TANDEM_GLOBAL const TextureInfo* t,
                                  TANDEM_GLOBAL const float4* texels, float u, float v) {
    const float tu = t->uv_row0.x * u + t->uv_row0.y * v + t->uv_row0.z;
    const float tv = t->uv_row1.x * u + t->uv_row1.y * v + t->uv_row1.z;
    if (t->kind == TEXTURE_CHECKERBOARD) {
        const int mu = tu - floor(tu) > 0.5f, mv = tv - floor(tv) > 0.5f;
        return mu == mv ? xyz(t->color0) : xyz(t->color1);
    }
    const float x = tu * (float)t->width, y = tv * (float)t->height;
    if (t->filter == TEXTURE_FILTER_NEAREST) return texture_texel(t, texels, (int)floor(x), (int)floor(y));
    // bilinear between the four texel centres around (x, y)
    const float fx = x - 0.5f, fy = y - 0.5f;
    const float x0 = floor(fx), y0 = floor(fy);
    const float ax = fx - x0, ay = fy - y0;
    const int ix = (int)x0, iy = (int)y0;
    const float3 c00 = texture_texel(t, texels, ix, iy), c10 = texture_texel(t, texels, ix + 1, iy);
    const float3 c01 = texture_texel(t, texels, ix, iy + 1), c11 = texture_texel(t, texels, ix + 1, iy + 1);
    return (c00 * (1.0f - ax) + c10 * ax) * (1.0f - ay) + (c01 * (1.0f - ax) + c11 * ax) * ay;
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_TEXTURES_H
