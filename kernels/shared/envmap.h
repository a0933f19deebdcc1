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

/// Radiance (linear RGB) arriving from world direction (dx, dy, dz), into Le[0..3): the texels'
/// rgb bilinearly filtered; returns the solid-angle density with which envmap_sample produces the
/// direction: the texels' sampling weights (.w) filtered with the same footprint, a density in
/// (u, v), divided by the Jacobian d(omega) / d(u, v) = 2 pi^2 sin(theta); zero at the poles.
///
/// The footprint is at u = atan2(l.x, -l.z) / 2pi (mod 1) and v = acos(l.y) / pi of the local
/// direction l: texels (x0, y0), (x1, y0), (x0, y1), (x1, y1) and the fractions ax, ay toward x1
/// and y1. As in Mitsuba, column x sits at u = (x + 1/2) / W and wraps; row y sits at
/// v = y / (H - 1) (rows 0 and H - 1 are the poles). Needs H >= 2 (build_envmap pads every map to
/// at least 2 x 3). One footprint (an atan2 and an acos) for both: an escaped ray, which needs the
/// two for its MIS weight, calls this (NEE's environment sample takes its own, envmap_sample).
///
/// Scalars, selects and no loop: the megakernels call it through envmap_eval_pdf, and the
/// wavefront's shading stage inlines it into the loop that PoCL vectorises. (det_floor is floor
/// for finite values; x0f < 0 takes no conversion. A loop over the channels would be vectorised
/// on its own, 2 wide, before the loop over work items, which then is not: written out.)
TANDEM_INLINE float envmap_lookup(const EnvMap* env, TANDEM_GLOBAL const float4* texels, float dx,
                                  float dy, float dz, float* Le) {
    // envmap_to_local
    const float lx = env->to_local0.x * dx + env->to_local0.y * dy + env->to_local0.z * dz;
    const float ly = env->to_local1.x * dx + env->to_local1.y * dy + env->to_local1.z * dz;
    const float lz = env->to_local2.x * dx + env->to_local2.y * dy + env->to_local2.z * dz;
    const uint w = env->width, h = env->height;
    float u = det_atan2(lx, -lz) * (0.5f * TANDEM_INV_PI);
    u = u - det_floor(u);
    const float v = det_acos(fmin(fmax(ly, -1.0f), 1.0f)) * TANDEM_INV_PI;
    const float fx = u * (float)w - 0.5f; // in [-1/2, W - 1/2]
    const float x0f = det_floor(fx);
    const float ax = fx - x0f;
    const uint x0 = x0f < 0.0f ? w - 1u : min((uint)fmax(x0f, 0.0f), w - 1u);
    const uint x1 = x0 + 1u < w ? x0 + 1u : 0u;
    const float fy = fmin(fmax(v, 0.0f) * (float)(h - 1u), (float)(h - 1u)); // in [0, H - 1]
    const uint y0 = min((uint)fy, h - 2u);
    const float ay = fy - (float)y0;
    TANDEM_GLOBAL const float* t = (TANDEM_GLOBAL const float*)(texels + env->texel_offset);
    const uint i00 = 4u * (y0 * w + x0), i10 = 4u * (y0 * w + x1);
    const uint i01 = 4u * ((y0 + 1u) * w + x0), i11 = 4u * ((y0 + 1u) * w + x1);
    Le[0] = envmap_lerp(envmap_lerp(t[i00], t[i10], ax), envmap_lerp(t[i01], t[i11], ax), ay);
    Le[1] = envmap_lerp(envmap_lerp(t[i00 + 1u], t[i10 + 1u], ax),
                        envmap_lerp(t[i01 + 1u], t[i11 + 1u], ax), ay);
    Le[2] = envmap_lerp(envmap_lerp(t[i00 + 2u], t[i10 + 2u], ax),
                        envmap_lerp(t[i01 + 2u], t[i11 + 2u], ax), ay);
    const float pdf_uv = envmap_lerp(envmap_lerp(t[i00 + 3u], t[i10 + 3u], ax),
                                     envmap_lerp(t[i01 + 3u], t[i11 + 3u], ax), ay);
    const float sin_theta = sqrt(fmax(0.0f, 1.0f - ly * ly));
    return sin_theta > 0.0f ? pdf_uv / (2.0f * TANDEM_PI * TANDEM_PI * sin_theta) : 0.0f;
}

/// envmap_lookup of world direction d: its radiance, and its density in *pdf; envmap_eval and
/// envmap_pdf are its halves, with the same bits.
TANDEM_INLINE float3 envmap_eval_pdf(const EnvMap* env, TANDEM_GLOBAL const float4* texels,
                                     float3 d, float* pdf) {
    float Le[3];
    *pdf = envmap_lookup(env, texels, d.x, d.y, d.z, Le);
    return make_float3(Le[0], Le[1], Le[2]);
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

/// The steps of envmap_find: the host passes ENVMAP_SEARCH_STEPS with HAS_ENVMAP, ceil(log2(n))
/// for the largest n of the map's two searches (core/render/features.cpp); elsewhere (the host's
/// own build, a probe) enough for any n.
#if TANDEM_DEVICE && defined(HAS_ENVMAP) && HAS_ENVMAP && !defined(ENVMAP_SEARCH_STEPS)
#error "ENVMAP_SEARCH_STEPS must be passed with HAS_ENVMAP (core/render/features.cpp)"
#endif
#ifdef ENVMAP_SEARCH_STEPS
#define ENVMAP_FIND_STEPS ENVMAP_SEARCH_STEPS
#else
#define ENVMAP_FIND_STEPS 32u
#endif

/// The largest i in [0, n) with c[i] <= u, for a CDF c[0..n] with c[0] = 0 and c[n] = 1: a binary
/// search in ENVMAP_FIND_STEPS steps of selects. Each step halves [lo, hi) (invariant:
/// c[lo] <= u < c[hi]), and a step after the interval is down to one cell keeps it, so the cell is
/// the one a loop until hi - lo = 1 finds; with a fixed count no loop is left inside the work-item
/// loop for PoCL's vectoriser to refuse (the wavefront).
TANDEM_INLINE uint envmap_find(TANDEM_GLOBAL const float* c, uint n, float u) {
    uint lo = 0u, hi = n;
#if TANDEM_DEVICE
#pragma unroll
#endif
    for (uint k = 0u; k < ENVMAP_FIND_STEPS; ++k) {
        const uint mid = (lo + hi) / 2u; // lo where hi = lo + 1: a valid index still
        const int below = c[mid] <= u, open = hi - lo > 1u;
        lo = open && below ? mid : lo;
        hi = open && !below ? mid : hi;
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

/// Samples a world direction with the density envmap_lookup gives it, into d[0..3), its radiance
/// into Le[0..3); returns its density. The cell (x, y) between texel columns x, x + 1 and rows
/// y, y + 1 comes from the CDFs (u1: its row among the H - 1, u2: its column among the W); the
/// point inside it from the leftovers of u1 and u2, by inverting the bilinear patch (Mitsuba's
/// square_to_bilinear: the row marginal, then the column).
///
/// The radiance and the density are those of the point drawn in the cell, where envmap_lookup
/// would find the direction again through an atan2 and an acos: the same bilinear filter of the
/// same four texels at the same fractions, but for rounding (as Mitsuba's envmap evaluates the
/// sampled uv). NEE takes both from here; an escaped ray still looks its direction up. Scalars,
/// as envmap_lookup: the megakernels call it through envmap_sample_eval, the wavefront inlines it.
TANDEM_INLINE float envmap_sample(const EnvMap* env, TANDEM_GLOBAL const float4* texels,
                                  TANDEM_GLOBAL const float* cdf, float u1, float u2, float* d,
                                  float* Le) {
    const uint w = env->width, cells_y = env->height - 1u;
    TANDEM_GLOBAL const float* rows = cdf + env->cdf_offset;
    const uint y = envmap_find(rows, cells_y, u1);
    TANDEM_GLOBAL const float* cols = rows + (cells_y + 1u) + y * (w + 1u);
    const uint x = envmap_find(cols, w, u2);
    // the leftover of each uniform number, uniform in [0, 1) again
    const float ry = fmin((u1 - rows[y]) / fmax(rows[y + 1u] - rows[y], 1e-30f), 1.0f);
    const float rx = fmin((u2 - cols[x]) / fmax(cols[x + 1u] - cols[x], 1e-30f), 1.0f);
    // the cell's corner weights, then the bilinear patch inverted: row marginal, column conditional
    TANDEM_GLOBAL const float* t = (TANDEM_GLOBAL const float*)(texels + env->texel_offset);
    const uint x1 = x + 1u < w ? x + 1u : 0u;
    const uint i00 = 4u * (y * w + x), i10 = 4u * (y * w + x1);
    const uint i01 = 4u * ((y + 1u) * w + x), i11 = 4u * ((y + 1u) * w + x1);
    const float w00 = t[i00 + 3u], w10 = t[i10 + 3u], w01 = t[i01 + 3u], w11 = t[i11 + 3u];
    const float ty = envmap_invert_linear(w00 + w10, w01 + w11, ry);
    const float c0 = envmap_lerp(w00, w01, ty), c1 = envmap_lerp(w10, w11, ty);
    const float tx = envmap_invert_linear(c0, c1, rx);
    // column x is at u = (x + 1/2) / W (u past 1 wraps through phi); row y at v = y / (H - 1)
    const float u = ((float)x + 0.5f + tx) / (float)w;
    const float v = ((float)y + ty) / (float)cells_y;
    const float theta = v * TANDEM_PI, phi = 2.0f * TANDEM_PI * u;
    float st, ct, sp, cp;
    det_sincos(theta, &st, &ct);
    det_sincos(phi, &sp, &cp);
    const float l0 = st * sp, l1 = ct, l2 = -st * cp;
    // to_world is the transpose of the rotation to_local
    d[0] = env->to_local0.x * l0 + env->to_local1.x * l1 + env->to_local2.x * l2;
    d[1] = env->to_local0.y * l0 + env->to_local1.y * l1 + env->to_local2.y * l2;
    d[2] = env->to_local0.z * l0 + env->to_local1.z * l1 + env->to_local2.z * l2;
    // envmap_lookup's filter, columns first, at the fractions (tx, ty) of the cell
    Le[0] = envmap_lerp(envmap_lerp(t[i00], t[i10], tx), envmap_lerp(t[i01], t[i11], tx), ty);
    Le[1] = envmap_lerp(envmap_lerp(t[i00 + 1u], t[i10 + 1u], tx),
                        envmap_lerp(t[i01 + 1u], t[i11 + 1u], tx), ty);
    Le[2] = envmap_lerp(envmap_lerp(t[i00 + 2u], t[i10 + 2u], tx),
                        envmap_lerp(t[i01 + 2u], t[i11 + 2u], tx), ty);
    const float pdf_uv = envmap_lerp(c0, c1, tx);
    return st > 0.0f ? pdf_uv / (2.0f * TANDEM_PI * TANDEM_PI * st) : 0.0f;
}

/// envmap_sample as a float3 direction; its density in *pdf, its radiance in *radiance.
TANDEM_INLINE float3 envmap_sample_eval(const EnvMap* env, TANDEM_GLOBAL const float4* texels,
                                        TANDEM_GLOBAL const float* cdf, float u1, float u2,
                                        float3* radiance, float* pdf) {
    float d[3], Le[3];
    *pdf = envmap_sample(env, texels, cdf, u1, u2, d, Le);
    *radiance = make_float3(Le[0], Le[1], Le[2]);
    return make_float3(d[0], d[1], d[2]);
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_ENVMAP_H
