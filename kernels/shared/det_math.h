// Transcendental functions that give the same bits on every OpenCL implementation and on the host.
//
// OpenCL lets each implementation round sin, cos, acos, atan2 (and the rest) its own way, within a
// few ulp: PoCL, Oclgrind, NVIDIA and the host's libm all differ somewhere, and a path that takes
// another branch on one ulp then differs by a whole sample. These are built from the operations
// OpenCL requires to be correctly rounded (+, -, *, fma, comparisons, floor, fabs, and / and sqrt
// with -cl-fp32-correctly-rounded-divide-sqrt, which the runtime passes where the device supports
// it), in a fixed order (FP_CONTRACT OFF: the compiler fuses nothing on its own), so every IEEE
// single-precision implementation computes the same bits.
//
// The polynomials are evaluated by Horner's rule with explicit fma. The OpenCL C specification
// (1.2, section 7.4, table 7.1) requires fma to be correctly rounded on every full-profile device,
// with or without the hardware instruction, and C's fmaf on the host is too, so a fused step is as
// deterministic as a multiply and an add, and rounds once instead of twice. It is also one
// instruction where the two are two: GPUs and x86 since AVX2 fuse in hardware, and their built-in
// transcendentals, which `tandem bench render` measures these against, are written with fma.
// Devices without the hardware (CL_FP_FMA, `tandem devices`) compute the same bits in software,
// more slowly.
//
// The polynomials are the minimax fits of Cephes' single-precision library (S. L. Moshier, "Methods
// and Programs for Mathematical Functions", 1989: sinf.c, acosf.c/asinf.c), with Cody-Waite range
// reduction by pi/2 in three parts, and fdlibm's atanf and atan2f (Sun Microsystems, 1993).
// Accuracy against long double on the host, the largest error at every float argument (a one-off
// sweep), rounded up in the last digit; tests/kernels/shared/test_det_math.cpp asserts these
// bounds on its samples:
//   det_sincos              |x| < 2^13: sin 1.533 ulp, cos 1.529 (in ulps of at least 2^-6 near
//                           their zeros, where the reduction's absolute error shows)
//   det_sincos_quarter_pi   [-1, 1]: sin 0.966, cos 1.290
//   det_acos                [-1, 1]: 1.513
//   det_atan2               1.49, the largest of 10^9 random pairs (1.486) rounded up: a function
//                           of two floats cannot be swept
// The fused reduction holds to about 2^20, past which the nearest multiple k of pi/2 itself comes
// out wrong (the results stay deterministic).
#ifndef TANDEM_SHARED_DET_MATH_H
#define TANDEM_SHARED_DET_MATH_H

#include "shared/compat.h"

TANDEM_NAMESPACE_BEGIN

// DET_MATH=0 (a build flag; render_features passes 1) makes them the implementation's builtins
// again, only so that `tandem bench render` can measure what determinism costs.
#if TANDEM_DEVICE && defined(DET_MATH) && DET_MATH == 0
#define DET_MATH_BUILTINS 1
#else
#define DET_MATH_BUILTINS 0
#endif

#define DET_PI 3.14159265358979f
#define DET_PI_2 1.57079632679490f
#define DET_PI_4 0.785398163397448f

/// floor(x) for finite x, exact, from a truncating conversion and a select: a form every compiler
/// keeps inline and can vectorise. PoCL 3.1 leaves its library floor() a call inside a work-group
/// loop ("call instruction cannot be vectorized", POCL_VECTORIZER_REMARKS=1), and Oclgrind 21.10
/// cannot run LLVM's floor intrinsic (__builtin_floorf). |x| >= 2^23 is already an integer; a
/// zero keeps its sign, as floor's does. Where the compiler is Clang for x86 with AVX
/// (TANDEM_X86_CLANG, compat.h), the intrinsic is one roundss (or roundps, vectorised) instead of
/// eighteen instructions, with the same result for every input
/// (tests/kernels/shared/test_det_math.cpp).
TANDEM_INLINE float det_floor(float x) {
#if TANDEM_X86_CLANG
    return __builtin_floorf(x);
#endif
    const float t = (float)(int)(fabs(x) < 8388608.0f ? x : 0.0f); // x truncated toward zero
    const float f = t > x ? t - 1.0f : t;
    return fabs(x) < 8388608.0f && x != 0.0f ? f : x;
}

/// x reduced to r in about [-pi/4, pi/4] with x = r + k pi/2; *quadrant = k mod 4. x finite.
TANDEM_INLINE float det_reduce_pi_2(float x, int* quadrant) {
    const float k = det_floor(x * 0.636619772367581f + 0.5f); // nearest integer to x / (pi/2)
    // pi/2 = 1.57079637 - 4.37113883e-8 - 1.71509942e-15, each part the float nearest what is left:
    // each fused step subtracts k times a part exactly and rounds once
    const float r =
        fma(-k, -1.715099417e-15f, fma(-k, -4.371138829e-08f, fma(-k, 1.570796371f, x)));
    *quadrant = (int)(k - 4.0f * det_floor(k * 0.25f)); // 0..3, exact for integral k
    return r;
}

/// sin(r) for |r| <= pi/4 (Cephes sinf's polynomial).
TANDEM_INLINE float det_sin_poly(float r) {
    const float z = r * r;
    const float q = fma(fma(-1.9515295891e-4f, z, 8.3321608736e-3f), z, -1.6666654611e-1f);
    return fma(z * r, q, r);
}

/// cos(r) for |r| <= pi/4 (Cephes cosf's polynomial).
TANDEM_INLINE float det_cos_poly(float r) {
    const float z = r * r;
    const float q = fma(fma(2.443315711809948e-5f, z, -1.388731625493765e-3f), z,
                        4.166664568298827e-2f);
    return fma(z * z, q, -0.5f * z) + 1.0f;
}

/// sin(x) and cos(x) at once; NaN for a non-finite x.
TANDEM_INLINE void det_sincos(float x, float* s, float* c) {
#if DET_MATH_BUILTINS
    *s = sin(x);
    *c = cos(x);
    return;
#endif
    if (!isfinite(x)) {
        *s = *c = x - x;
        return;
    }
    int q;
    const float r = det_reduce_pi_2(x, &q);
    const float sr = det_sin_poly(r), cr = det_cos_poly(r);
    // sin(r + q pi/2) and cos(r + q pi/2) by the quadrant's bits: odd q swaps sin and cos; sin is
    // negated for q = 2, 3 and cos for q = 1, 2. Selects, not a chain of comparisons, which
    // compilers turn into a switch (a branch per call, and no vectorisation).
    const float s_abs = (q & 1) ? cr : sr, c_abs = (q & 1) ? sr : cr;
    *s = (q & 2) ? -s_abs : s_abs;
    *c = ((q + 1) & 2) ? -c_abs : c_abs;
}

/// sin and cos of (pi/4) a for |a| <= 1: the angle is already in the polynomials' range, so it
/// needs no reduction (the concentric disk's angle, sample_concentric_disk). Cephes' polynomials
/// with each coefficient times its power of pi/4, so that a itself is the variable: the first
/// term takes pi/4 in two parts (a times the high part is exact inside the fma) and nothing
/// rounds the angle. Every float a in [0, 1]: sin within 0.966 ulp, cos 1.290 ulp (both are
/// symmetric).
TANDEM_INLINE void det_sincos_quarter_pi(float a, float* s, float* c) {
#if DET_MATH_BUILTINS
    *s = sin(a * DET_PI_4);
    *c = cos(a * DET_PI_4);
    return;
#endif
    const float z = a * a;
    const float q = fma(fma(-3.5975290538e-05f, z, 2.4900441837e-03f), z, -8.0745453782e-02f);
    *s = fma(a, 7.853981853e-01f, fma(a * z, q, a * -2.185569500e-08f));
    const float p = fma(fma(3.5375178396e-06f, z, -3.2595497498e-04f), z, 1.5854336259e-02f);
    *c = fma(z * z, p, z * -3.0842513753e-01f) + 1.0f;
}

TANDEM_INLINE float det_sin(float x) {
    float s, c;
    det_sincos(x, &s, &c);
    return s;
}

TANDEM_INLINE float det_cos(float x) {
    float s, c;
    det_sincos(x, &s, &c);
    return c;
}

/// asin(a) for |a| <= 0.5 (Cephes asinf's polynomial).
TANDEM_INLINE float det_asin_poly(float a) {
    const float z = a * a;
    const float q =
        fma(fma(fma(fma(4.2163199048e-2f, z, 2.4181311049e-2f), z, 4.5470025998e-2f), z,
                7.4953002686e-2f),
            z, 1.6666752422e-1f);
    return fma(z * a, q, a);
}

/// acos(x) in [0, pi]; NaN outside [-1, 1] (Cephes acosf's reduction).
TANDEM_INLINE float det_acos(float x) {
#if DET_MATH_BUILTINS
    return acos(x);
#endif
    if (!(fabs(x) <= 1.0f)) return (x - x) / (x - x); // NaN, also for a NaN or infinite x
    if (x < -0.5f) return fma(-2.0f, det_asin_poly(sqrt(0.5f * (1.0f + x))), DET_PI);
    if (x > 0.5f) return 2.0f * det_asin_poly(sqrt(0.5f * (1.0f - x)));
    return (DET_PI_4 - det_asin_poly(x)) + DET_PI_4;
}

/// atan(y / x) for finite y >= 0, x > 0: fdlibm's s_atanf.c (Sun Microsystems, 1993). The ratio
/// a = y / x is reduced about one of atan(1/2), atan(1), atan(3/2), atan(inf) (each in a high and
/// a low part) to t = (a - c) / (1 + c a), in [-7/16, 7/16], and atan(t) is an odd polynomial.
/// fdlibm divides twice, for a and then for t; here t comes from y and x in one division,
/// t = (y - c x) / (x + c y), whose numerator is exact where it cancels (Sterbenz's lemma for
/// c = 1/2 and 1, one rounding inside an fma for 3/2), so it is also a little more accurate.
/// Selects, not branches: the one division serves every interval.
TANDEM_INLINE float det_atan_ratio(float y, float x) {
    // y and x scaled by a power of two (exact) so that x + c y neither overflows nor rounds among
    // denormals; the reduced quotients do not change
    const float m = fmax(y, x);
    const float scale = m > 0x1p100f ? 0x1p-2f : (m < 0x1p-100f ? 0x1p24f : 1.0f);
    y *= scale;
    x *= scale;
    // the interval of a = y / x, from products that may round: t stays within the polynomial's
    // range on either side of a boundary. Nested selects on four comparisons, not an interval
    // number: compilers turn a chain of tests of one integer into a switch, which PoCL's
    // vectoriser refuses ("loop contains a switch statement").
    const int above_7_16 = y >= 0.4375f * x, above_11_16 = y >= 0.6875f * x;
    const int above_19_16 = y >= 1.1875f * x, above_39_16 = y >= 2.4375f * x;
    const float num = above_39_16   ? -x
                      : above_19_16 ? fma(-1.5f, x, y)
                      : above_11_16 ? y - x
                      : above_7_16  ? 2.0f * y - x
                                    : y;
    const float den = above_39_16   ? y
                      : above_19_16 ? fma(1.5f, y, x)
                      : above_11_16 ? x + y
                      : above_7_16  ? 2.0f * x + y
                                    : x;
    const float t = num / den;
    // fdlibm's odd polynomial in two halves, the even and odd powers of w = t^4, for parallelism
    const float z = t * t, w = z * z;
    const float s1 =
        z * fma(fma(fma(fma(fma(1.6285819933e-02f, w, 4.9768779427e-02f), w, 6.6610731184e-02f),
                        w, 9.0908870101e-02f),
                    w, 1.4285714924e-01f),
                w, 3.3333334327e-01f);
    const float s2 =
        w * fma(fma(fma(fma(-3.6531571299e-02f, w, -5.8335702866e-02f), w, -7.6918758452e-02f), w,
                    -1.1111110449e-01f),
                w, -2.0000000298e-01f);
    // atan(c) of the interval's centre in a high and a low part
    const float hi = above_39_16   ? 1.5707962513e+00f
                     : above_19_16 ? 9.8279368877e-01f
                     : above_11_16 ? 7.8539812565e-01f
                                   : 4.6364760399e-01f;
    const float lo = above_39_16   ? 7.5497894159e-08f
                     : above_19_16 ? 3.4473217170e-08f
                     : above_11_16 ? 3.7748947079e-08f
                                   : 5.0121582440e-09f;
    return above_7_16 ? hi - (fma(t, s1 + s2, -lo) - t) : fma(-t, s1 + s2, t);
}

/// atan2(y, x) in [-pi, pi], with atan2's conventions for zeros and infinities; NaN if either is.
TANDEM_INLINE float det_atan2(float y, float x) {
#if DET_MATH_BUILTINS
    return atan2(y, x);
#endif
    if (x != x || y != y) return x + y;
    const float ay = fabs(y), ax = fabs(x);
    const int y_negative = as_int(y) < 0, x_negative = as_int(x) < 0;
    float a;
    if (ay == 0.0f) {
        a = x_negative ? DET_PI : 0.0f; // atan2(+-0, -0 or x < 0) = +-pi, atan2(+-0, +0 or x > 0) = +-0
    } else if (ax == 0.0f || (!isfinite(ay) && isfinite(ax))) {
        a = DET_PI_2;
    } else if (!isfinite(ax)) {
        a = !isfinite(ay) ? (x_negative ? 3.0f * DET_PI_4 : DET_PI_4) : (x_negative ? DET_PI : 0.0f);
    } else {
        const float t = det_atan_ratio(ay, ax);
        // pi - t with pi in two parts (fdlibm's e_atan2f.c): pi = 3.1415925026 + 1.5099578e-07
        a = x_negative ? 3.1415925026e+00f - (t - 1.5099578e-07f) : t;
    }
    return y_negative ? -a : a;
}

/// log(x) for x > 0 (Cephes logf: the mantissa m in [sqrt(1/2), sqrt(2)) and exponent e of x,
/// log(m) by its polynomial in m - 1, plus e log 2 in two parts); -inf at 0, NaN below, +inf at
/// +inf. Subnormal x is scaled into the normal range first. The free flights of media draw their
/// distances with it (kernels/path/media.h).
TANDEM_INLINE float det_log(float x) {
    if (!(x > 0.0f)) return x == 0.0f ? -INFINITY : NAN;
    if (x == INFINITY) return x;
    int e = 0;
    if (x < 1.17549435e-38f) { // subnormal: times 2^23
        x = x * 8388608.0f;
        e = -23;
    }
    const uint bits = as_uint(x);
    e += (int)((bits >> 23) & 0xffu) - 126;
    float m = as_float((bits & 0x007fffffu) | 0x3f000000u); // [0.5, 1)
    if (m < 0.707106781186547524f) {
        e -= 1;
        m = m + m - 1.0f;
    } else {
        m = m - 1.0f;
    }
    const float z = m * m;
    float y = 7.0376836292e-2f;
    y = fma(y, m, -1.1514610310e-1f);
    y = fma(y, m, 1.1676998740e-1f);
    y = fma(y, m, -1.2420140846e-1f);
    y = fma(y, m, 1.4249322787e-1f);
    y = fma(y, m, -1.6668057665e-1f);
    y = fma(y, m, 2.0000714765e-1f);
    y = fma(y, m, -2.4999993993e-1f);
    y = fma(y, m, 3.3333331174e-1f);
    y = y * m * z;
    const float fe = (float)e;
    y = fma(fe, -2.12194440e-4f, y);
    y = fma(z, -0.5f, y);
    return fma(fe, 0.693359375f, m + y);
}

/// exp(x) (Cephes expf: x = n log 2 + r with |r| <= log(2) / 2, r by two-part Cody-Waite
/// reduction, exp(r) by its polynomial, times 2^n); 0 below -87.3 (where exp(x) would be
/// subnormal), +inf above 88.72. NaN for NaN. Homogeneous media's transmittance uses it.
TANDEM_INLINE float det_exp(float x) {
    if (x != x) return x;
    if (x > 88.7228390520683f) return INFINITY;
    if (x < -87.3365447505531f) return 0.0f;
    const float n = det_floor(fma(x, 1.44269504088896341f, 0.5f));
    float r = fma(n, -0.693359375f, x);
    r = fma(n, 2.12194440e-4f, r);
    const float z = r * r;
    float p = 1.9875691500e-4f;
    p = fma(p, r, 1.3981999507e-3f);
    p = fma(p, r, 8.3334519073e-3f);
    p = fma(p, r, 4.1665795894e-2f);
    p = fma(p, r, 1.6666665459e-1f);
    p = fma(p, r, 5.0000001201e-1f);
    float y = fma(p, z, r) + 1.0f;
    int k = (int)n;
    if (k > 127) { // 2^128 is not a float: scale twice
        y = y * 2.0f;
        k -= 1;
    }
    return y * as_float((uint)(k + 127) << 23);
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_DET_MATH_H
