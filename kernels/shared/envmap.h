// Environment map lookup and importance sampling: a piecewise-constant 2D distribution over the
// latitude-longitude image (pbrt-v3 13.6.5; Mitsuba's envmap), shared by host and device.
#ifndef TANDEM_SHARED_ENVMAP_H
#define TANDEM_SHARED_ENVMAP_H

#include "shared/sampling.h"
#include "shared/scene_layout.h"

TANDEM_NAMESPACE_BEGIN

/// Local direction of world direction d.
TANDEM_INLINE float3 envmap_to_local(const EnvMap* env, float3 d) {
    return make_float3(vdot(xyz(env->to_local0), d), vdot(xyz(env->to_local1), d),
                       vdot(xyz(env->to_local2), d));
}

/// Texel (x, y) that the local direction l falls in.
TANDEM_INLINE void envmap_texel_of(const EnvMap* env, float3 l, uint* x, uint* y) {
    float u = atan2(l.x, -l.z) * (0.5f * TANDEM_INV_PI);
    u = u - floor(u);
    const float v = acos(fmin(fmax(l.y, -1.0f), 1.0f)) * TANDEM_INV_PI;
    *x = min((uint)(u * (float)env->width), env->width - 1u);
    *y = min((uint)(v * (float)env->height), env->height - 1u);
}

/// Radiance arriving from world direction d (nearest texel).
TANDEM_INLINE float3 envmap_eval(const EnvMap* env, TANDEM_GLOBAL const float4* texels, float3 d) {
    uint x, y;
    envmap_texel_of(env, envmap_to_local(env, d), &x, &y);
    return xyz(texels[env->texel_offset + y * env->width + x]);
}

/// Density in (u, v) of texel (x, y): the product of its row's and column's CDF steps, W H.
TANDEM_INLINE float envmap_pdf_uv(const EnvMap* env, TANDEM_GLOBAL const float* cdf, uint x, uint y) {
    TANDEM_GLOBAL const float* rows = cdf + env->cdf_offset;
    TANDEM_GLOBAL const float* cols = rows + (env->height + 1u) + y * (env->width + 1u);
    return (rows[y + 1u] - rows[y]) * (cols[x + 1u] - cols[x]) * (float)env->width * (float)env->height;
}

/// Solid-angle density with which envmap_sample produces world direction d:
/// pdf_uv / (2 pi^2 sin(theta)), since d(omega) = 2 pi^2 sin(theta) du dv.
TANDEM_INLINE float envmap_pdf(const EnvMap* env, TANDEM_GLOBAL const float* cdf, float3 d) {
    const float3 l = envmap_to_local(env, d);
    uint x, y;
    envmap_texel_of(env, l, &x, &y);
    const float sin_theta = sqrt(fmax(0.0f, 1.0f - l.y * l.y));
    return sin_theta > 0.0f ? envmap_pdf_uv(env, cdf, x, y) / (2.0f * TANDEM_PI * TANDEM_PI * sin_theta)
                            : 0.0f;
}

/// The largest i in [0, n) with c[i] <= u, for a CDF c[0..n] with c[0] = 0 and c[n] = 1.
TANDEM_INLINE uint envmap_find(TANDEM_GLOBAL const float* c, uint n, float u) {
    uint lo = 0u, hi = n; // invariant: c[lo] <= u < c[hi] (c[n] = 1 > u)
    while (hi - lo > 1u) {
        const uint mid = (lo + hi) / 2u;
        if (c[mid] <= u) lo = mid;
        else hi = mid;
    }
    return lo;
}

/// Samples a world direction by the image's importance; writes its solid-angle density.
TANDEM_INLINE float3 envmap_sample(const EnvMap* env, TANDEM_GLOBAL const float* cdf, float u1,
                                   float u2, float* pdf) {
    TANDEM_GLOBAL const float* rows = cdf + env->cdf_offset;
    const uint y = envmap_find(rows, env->height, u1);
    TANDEM_GLOBAL const float* cols = rows + (env->height + 1u) + y * (env->width + 1u);
    const uint x = envmap_find(cols, env->width, u2);
    // continuous position inside the texel, from the leftover of each uniform number
    const float dy = (u1 - rows[y]) / fmax(rows[y + 1u] - rows[y], 1e-30f);
    const float dx = (u2 - cols[x]) / fmax(cols[x + 1u] - cols[x], 1e-30f);
    const float v = ((float)y + fmin(dy, 0.99999994f)) / (float)env->height;
    const float u = ((float)x + fmin(dx, 0.99999994f)) / (float)env->width;
    const float theta = v * TANDEM_PI, phi = 2.0f * TANDEM_PI * u;
    const float st = sin(theta);
    const float3 l = make_float3(st * sin(phi), cos(theta), -st * cos(phi));
    // to_world is the transpose of the rotation to_local
    const float3 d = xyz(env->to_local0) * l.x + xyz(env->to_local1) * l.y + xyz(env->to_local2) * l.z;
    *pdf = st > 0.0f ? envmap_pdf_uv(env, cdf, x, y) / (2.0f * TANDEM_PI * TANDEM_PI * st) : 0.0f;
    return d;
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_ENVMAP_H
