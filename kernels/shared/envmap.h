// Environment map lookup and importance sampling, shared by host and device, as Mitsuba 3's
// `envmap` (src/emitters/envmap.cpp): a bilinear lookup between texel centres, and a sampler whose
// density is the bilinear interpolant of luminance x sin(theta) over the same grid (its
// Hierarchical2D warp; here a 2D CDF over cells, then the bilinear patch inverted in closed form).
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

/// a + (b - a) t: exactly a where a == b, so a constant map looks up exactly its constant.
TANDEM_INLINE float envmap_lerp(float a, float b, float t) {
    return a + (b - a) * t;
}

/// The bilinear footprint of local direction l, at u = atan2(l.x, -l.z) / 2pi (mod 1) and
/// v = acos(l.y) / pi: texels index[0..3] = (x0, y0), (x1, y0), (x0, y1), (x1, y1), counted from
/// the map's first texel, and the fractions ax, ay toward x1 and y1. As in Mitsuba, column x sits
/// at u = (x + 1/2) / W and wraps; row y sits at v = y / (H - 1) (rows 0 and H - 1 are the poles).
/// Needs H >= 2 (build_envmap pads every map to at least 2 x 3).
TANDEM_INLINE void envmap_footprint(const EnvMap* env, float3 l, uint* index, float* ax,
                                    float* ay) {
    const uint w = env->width, h = env->height;
    float u = det_atan2(l.x, -l.z) * (0.5f * TANDEM_INV_PI);
    u = u - floor(u);
    const float v = det_acos(fmin(fmax(l.y, -1.0f), 1.0f)) * TANDEM_INV_PI;
    const float fx = u * (float)w - 0.5f; // in [-1/2, W - 1/2]
    const float x0f = floor(fx);
    *ax = fx - x0f;
    const uint x0 = x0f < 0.0f ? w - 1u : min((uint)x0f, w - 1u);
    const uint x1 = x0 + 1u < w ? x0 + 1u : 0u;
    const float fy = fmin(fmax(v, 0.0f) * (float)(h - 1u), (float)(h - 1u)); // in [0, H - 1]
    const uint y0 = min((uint)fy, h - 2u);
    *ay = fy - (float)y0;
    index[0] = y0 * w + x0;
    index[1] = y0 * w + x1;
    index[2] = (y0 + 1u) * w + x0;
    index[3] = (y0 + 1u) * w + x1;
}

/// Radiance (linear RGB) arriving from world direction d, the texels' rgb bilinearly filtered, and
/// in *pdf the solid-angle density with which envmap_sample_eval produces d: the texels' sampling
/// weights (.w) filtered with the same footprint, a density in (u, v), divided by the Jacobian
/// d(omega) / d(u, v) = 2 pi^2 sin(theta); zero at the poles. One footprint (an atan2 and an acos)
/// for both: an escaped ray, which needs the two for its MIS weight, calls this (NEE's environment
/// sample takes its own, envmap_sample_eval), and envmap_eval and envmap_pdf are its halves, with
/// the same bits.
TANDEM_INLINE float3 envmap_eval_pdf(const EnvMap* env, TANDEM_GLOBAL const float4* texels,
                                     float3 d, float* pdf) {
    const float3 l = envmap_to_local(env, d);
    uint i[4];
    float ax, ay;
    envmap_footprint(env, l, i, &ax, &ay);
    TANDEM_GLOBAL const float4* t = texels + env->texel_offset;
    const float4 t00 = t[i[0]], t10 = t[i[1]], t01 = t[i[2]], t11 = t[i[3]];
    const float pdf_uv =
        envmap_lerp(envmap_lerp(t00.w, t10.w, ax), envmap_lerp(t01.w, t11.w, ax), ay);
    const float sin_theta = sqrt(fmax(0.0f, 1.0f - l.y * l.y));
    *pdf = sin_theta > 0.0f ? pdf_uv / (2.0f * TANDEM_PI * TANDEM_PI * sin_theta) : 0.0f;
    return make_float3(
        envmap_lerp(envmap_lerp(t00.x, t10.x, ax), envmap_lerp(t01.x, t11.x, ax), ay),
        envmap_lerp(envmap_lerp(t00.y, t10.y, ax), envmap_lerp(t01.y, t11.y, ax), ay),
        envmap_lerp(envmap_lerp(t00.z, t10.z, ax), envmap_lerp(t01.z, t11.z, ax), ay));
}

/// Radiance (linear RGB) arriving from world direction d (envmap_eval_pdf's radiance).
TANDEM_INLINE float3 envmap_eval(const EnvMap* env, TANDEM_GLOBAL const float4* texels, float3 d) {
    float pdf;
    return envmap_eval_pdf(env, texels, d, &pdf);
}

/// Solid-angle density with which envmap_sample_eval produces world direction d (envmap_eval_pdf's
/// density).
TANDEM_INLINE float envmap_pdf(const EnvMap* env, TANDEM_GLOBAL const float4* texels, float3 d) {
    float pdf;
    (void)envmap_eval_pdf(env, texels, d, &pdf);
    return pdf;
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

/// The t in [0, 1] where the CDF of the density proportional to (1 - t) a + t b (a, b >= 0)
/// reaches xi: the root of a t + (b - a) t^2 / 2 = xi (a + b) / 2, written without cancellation
/// (exact for a = b, sqrt(xi) for a = 0).
TANDEM_INLINE float envmap_invert_linear(float a, float b, float xi) {
    const float den = a + sqrt(envmap_lerp(a * a, b * b, xi));
    return den > 0.0f ? fmin(xi * (a + b) / den, 1.0f) : xi;
}

/// Samples a world direction with the density envmap_pdf; writes that density, and in *radiance
/// the map's radiance along it. The cell (x, y) between texel columns x, x + 1 and rows y, y + 1
/// comes from the CDFs (u1: its row among the H - 1, u2: its column among the W); the point inside
/// it from the leftovers of u1 and u2, by inverting the bilinear patch (Mitsuba's
/// square_to_bilinear: the row marginal, then the column).
///
/// The radiance and the density are those of the point drawn in the cell, where envmap_eval_pdf
/// would find the direction again through an atan2 and an acos: the same bilinear filter of the
/// same four texels at the same fractions, but for rounding (as Mitsuba's envmap evaluates the
/// sampled uv). NEE takes both from here; an escaped ray still looks its direction up.
TANDEM_INLINE float3 envmap_sample_eval(const EnvMap* env, TANDEM_GLOBAL const float4* texels,
                                        TANDEM_GLOBAL const float* cdf, float u1, float u2,
                                        float3* radiance, float* pdf) {
    const uint w = env->width, cells_y = env->height - 1u;
    TANDEM_GLOBAL const float* rows = cdf + env->cdf_offset;
    const uint y = envmap_find(rows, cells_y, u1);
    TANDEM_GLOBAL const float* cols = rows + (cells_y + 1u) + y * (w + 1u);
    const uint x = envmap_find(cols, w, u2);
    // the leftover of each uniform number, uniform in [0, 1) again
    const float ry = fmin((u1 - rows[y]) / fmax(rows[y + 1u] - rows[y], 1e-30f), 1.0f);
    const float rx = fmin((u2 - cols[x]) / fmax(cols[x + 1u] - cols[x], 1e-30f), 1.0f);
    // the cell's corner weights, then the bilinear patch inverted: row marginal, column conditional
    TANDEM_GLOBAL const float4* t = texels + env->texel_offset;
    const uint x1 = x + 1u < w ? x + 1u : 0u;
    const float4 t00 = t[y * w + x], t10 = t[y * w + x1];
    const float4 t01 = t[(y + 1u) * w + x], t11 = t[(y + 1u) * w + x1];
    const float ty = envmap_invert_linear(t00.w + t10.w, t01.w + t11.w, ry);
    const float c0 = envmap_lerp(t00.w, t01.w, ty), c1 = envmap_lerp(t10.w, t11.w, ty);
    const float tx = envmap_invert_linear(c0, c1, rx);
    // column x is at u = (x + 1/2) / W (u past 1 wraps through phi); row y at v = y / (H - 1)
    const float u = ((float)x + 0.5f + tx) / (float)w;
    const float v = ((float)y + ty) / (float)cells_y;
    const float theta = v * TANDEM_PI, phi = 2.0f * TANDEM_PI * u;
    float st, ct, sp, cp;
    det_sincos(theta, &st, &ct);
    det_sincos(phi, &sp, &cp);
    const float3 l = make_float3(st * sp, ct, -st * cp);
    // to_world is the transpose of the rotation to_local
    const float3 d = xyz(env->to_local0) * l.x + xyz(env->to_local1) * l.y + xyz(env->to_local2) * l.z;
    const float pdf_uv = envmap_lerp(c0, c1, tx);
    *pdf = st > 0.0f ? pdf_uv / (2.0f * TANDEM_PI * TANDEM_PI * st) : 0.0f;
    // envmap_eval_pdf's filter, columns first, at the fractions (tx, ty) of the cell
    *radiance = make_float3(
        envmap_lerp(envmap_lerp(t00.x, t10.x, tx), envmap_lerp(t01.x, t11.x, tx), ty),
        envmap_lerp(envmap_lerp(t00.y, t10.y, tx), envmap_lerp(t01.y, t11.y, tx), ty),
        envmap_lerp(envmap_lerp(t00.z, t10.z, tx), envmap_lerp(t01.z, t11.z, tx), ty));
    return d;
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_ENVMAP_H
