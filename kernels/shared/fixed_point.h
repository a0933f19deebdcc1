// Deterministic gradient accumulation: 64-bit fixed-point sums built from 32-bit integer atomics,
// in units that follow the gradient's magnitude, with wrap detection.
//
// Float atomics give sums that depend on the order work items arrive in. Integer addition is
// associative, so a fixed-point sum is exact and bit-identical in any order. Each gradient element
// is one signed 64-bit integer in units of 2^-(40 + s) (s: the scale below), stored as two 32-bit
// words (lo, hi), plus a third word that counts wraps. Adding a 64-bit value v takes two core
// OpenCL 1.1 atomics, no 64-bit atomics extension:
//   old = atomic_add(lo, (uint)v); carry = (old + (uint)v wraps);
//   atomic_add(hi, (v >> 32) + carry).
// Every add carries out of the low word at most once and adds that carry to the high word once,
// so the pair ends as the exact sum mod 2^64 whatever the interleaving (nobody reads the pair
// before the launch ends).
//
// Scaling. A contribution c rounds to the nearest unit, so one below half a unit (2^-41) is lost
// every time: with an L2 loss at 1024x1024, dark texels near convergence receive nothing but such
// contributions, and their gradients round to zero. So each backward() multiplies every
// contribution by 2^s before encoding and the decode multiplies by 2^-s: both exact (powers of
// two, built from their bits; in the clamped range of s below nothing overflows, and a value that
// would go subnormal is far below a unit either way), so sums stay exact, order-independent and
// bit-identical. The scaling is applied once, to the adjoint
// delta / spp at the start of each work item: every contribution is delta times factors of the
// path (kernels/path/adjoint.h), and a float product scaled by a power of two rounds to the same
// bits scaled. s comes from S = sum |delta| over the image (finite elements, a fixed-order
// reduction on the device: kernels/adjoint.cl, grad_delta_sums and grad_exponent; no host read):
//   s = GRAD_TARGET_EXPONENT - floor(log2 S), so that S 2^s is in [2^4, 2^5),
// clamped to [-GRAD_MAX_EXPONENT, GRAD_MAX_EXPONENT] (0 when S is 0). Why 2^4: a gradient element
// is sum_pixels delta_p (1/spp) sum_samples phi, where phi (the path's factor: beta w for a
// radiance, L_rem / albedo for an albedo, summed over the path's vertices) is radiance-sized, so
// |element| 2^s < 2^5 max(phi), and a single scaled contribution is < 2^5 phi / spp even when all
// of delta sits in one pixel (a firefly under an L2 loss). Sums are exact within 2^23, so no sum
// can wrap below phi = 2^18 and no contribution saturates below phi = 2^17 spp (a diffuse albedo
// of 0.01 under radiance 10 with roulette factors of 20 gives phi ~ 2e4 ~ 2^14.3). Precision: a
// contribution of a uniform |delta| over N elements at spp samples is ~2^4 phi / (N spp) after
// scaling; at 1024x1024 (N = 3 2^20), 1 spp and phi = 0.01, ~2^-24, i.e. 2^16 units, rounded to
// nearest without bias. Unscaled (s = 0, the units before this scaling) it is S 2^-4 times that,
// below half a unit (2^-41) once S < 2^-9: an L2 loss near convergence (S = 2 mean |x - r|; ~1e-6
// in tests/core/inverse/test_gradient_scale.cpp), whose contributions rounded to zero every time.
// A larger target buys precision with headroom: 2^8 kept the darkest texels of that test within
// 1e-5 of their |delta|, but let a one-pixel delta saturate from phi = 2^13 spp. The choice depends
// only on delta, so the same inputs give the same s, and delta 2^k gives s - k: the same
// contributions, the same integer sums, a gradient exactly 2^k times as large. Nothing about s
// needs saving in a checkpoint.
//
// Range. A scaled contribution beyond GRAD_MAX_CONTRIBUTION = 2^22, or a non-finite one, is
// counted as saturated: clamped to +-2^22 (non-finite ones are dropped). A sum of many can still
// leave the 64-bit range (|sum| >= 2^23 after scaling) and wrap mod 2^64. That is detected exactly
// in the high word: every add moves it by less than 2^31 (|v| <= 2^62), so the 64-bit sum crosses
// +-2^63 exactly when the high word's atomic_add overflows as a signed 32-bit add, and the add
// that did it counts +1 (upwards) or -1 (downwards) in the element's third word. Interleavings
// cross the boundary a different number of times, but the net count is floor((T + 2^63) / 2^64)
// for the true (unwrapped) sum T in units, the same in any order: nonzero exactly when the
// element wrapped. The decode then saturates the element to +-2^23
// times 2^-s (by the sign of the count) and counts it with the saturated contributions, and the
// host reports the count (guards: `tandem grad` and `tandem optimize` warn, and their JSON has it).
// The check costs a compare per add to the high word, and an atomic only on a crossing.
#ifndef TANDEM_SHARED_FIXED_POINT_H
#define TANDEM_SHARED_FIXED_POINT_H

#include "shared/compat.h"

TANDEM_NAMESPACE_BEGIN

#define GRAD_FIXED_SCALE 1099511627776.0f /* 2^40 */
#define GRAD_MAX_CONTRIBUTION 4194304.0f  /* 2^22 */
#define GRAD_RANGE 8388608.0f             /* 2^23: sums are exact within +-GRAD_RANGE */
#define GRAD_WORDS 3u                     /* words per element: lo, hi and the net wrap count */
#define GRAD_TARGET_EXPONENT 4           /* sum |delta| 2^s in [2^4, 2^5): see above */
#define GRAD_MAX_EXPONENT 80              /* |s| <= 80: 2^(s+40) and 2^-(s+40) stay normal floats */

#if TANDEM_DEVICE
typedef long fixed64;
typedef ulong ufixed64;
#else
typedef std::int64_t fixed64;
typedef std::uint64_t ufixed64;
#endif

/// 2^e for -126 <= e <= 127, built from its bits (exact; no pow or ldexp on the device).
TANDEM_INLINE float grad_pow2(int e) {
    return as_float((uint)(e + 127) << 23);
}

/// The scale exponent s for a sum of |delta| (see the comment above): S 2^s in
/// [2^GRAD_TARGET_EXPONENT, 2^(GRAD_TARGET_EXPONENT + 1)), clamped to +-GRAD_MAX_EXPONENT; 0 for
/// S = 0 or NaN. From the float's exponent bits, so host and device agree.
TANDEM_INLINE int grad_exponent_for(float abs_delta_sum) {
    if (!(abs_delta_sum > 0.0f)) return 0;
    const int biased = (int)((as_uint(abs_delta_sum) >> 23) & 0xFFu); // 255: +inf, 0: subnormal
    const int s = GRAD_TARGET_EXPONENT - (biased - 127);
    return s < -GRAD_MAX_EXPONENT ? -GRAD_MAX_EXPONENT
                                  : (s > GRAD_MAX_EXPONENT ? GRAD_MAX_EXPONENT : s);
}

/// round-to-nearest-even(v 2^40) for |v| <= 2^22 (exact scaling by a power of two, then one
/// rounding; the host and device round the same way). v is already scaled by 2^s.
TANDEM_INLINE fixed64 fixed_encode(float v) {
#if TANDEM_DEVICE
    return convert_long_rte(v * GRAD_FIXED_SCALE);
#else
    return static_cast<fixed64>(std::nearbyint(static_cast<double>(v * GRAD_FIXED_SCALE)));
#endif
}

/// The float nearest to the sum in slot (lo, hi, wraps) of contributions scaled by 2^exponent:
/// one rounding to float, then exact scaling by 2^-(40 + exponent). A wrapped sum (wraps != 0)
/// decodes to +-2^23 2^-exponent, the end of the range on its true side; *wrapped says so.
TANDEM_INLINE float fixed_decode(TANDEM_GLOBAL const uint* slot, int exponent, uint* wrapped) {
    const fixed64 v = (fixed64)(((ufixed64)slot[1] << 32) | (ufixed64)slot[0]);
    const float inv = grad_pow2(-(40 + exponent));
    *wrapped = slot[2] != 0u ? 1u : 0u;
    if (slot[2] != 0u) // the count's sign bit: the side the sum left the range on
        return ((slot[2] >> 31) == 0u ? GRAD_RANGE : -GRAD_RANGE) * grad_pow2(-exponent);
#if TANDEM_DEVICE
    return convert_float_rte(v) * inv;
#else
    return static_cast<float>(v) * inv;
#endif
}

/// Adds v (|v| <= 2^62) to the element at slot: slot[0] (low word), slot[1] (high word) without
/// 64-bit atomics, and the net count of signed overflows of the high word (wraps of the 64-bit
/// sum) to slot[2]; the host version (tests) does the same arithmetic without atomics.
TANDEM_INLINE void fixed_add(TANDEM_GLOBAL uint* slot, fixed64 v) {
    const uint lo = (uint)v;
    const uint hi = (uint)((ufixed64)v >> 32);
#if TANDEM_DEVICE
    const uint old = atomic_add((volatile __global uint*)slot, lo);
#else
    const uint old = slot[0];
    slot[0] = old + lo;
#endif
    const uint carry = (uint)(old + lo < old);
    const uint high = hi + carry; // |high| <= 2^30 + 1 as a signed value
    if (high == 0u) return;
#if TANDEM_DEVICE
    const uint old_high = atomic_add((volatile __global uint*)slot + 1, high);
#else
    const uint old_high = slot[1];
    slot[1] = old_high + high;
#endif
    const uint sum = old_high + high;
    // signed overflow: both operands have the sign the result lacks
    if ((((old_high ^ sum) & (high ^ sum)) >> 31) != 0u) {
        const uint step = (high >> 31) != 0u ? 0xFFFFFFFFu : 1u; // -1 downwards, +1 upwards
#if TANDEM_DEVICE
        atomic_add((volatile __global uint*)slot + 2, step);
#else
        slot[2] += step;
#endif
    }
}

/// Adds the element `from` (lo, hi, wraps: another accumulator's sum of the same element, at the
/// same scale) into `into`: the 64-bit words add mod 2^64 and the net wrap counts add, plus the
/// crossing of +-2^63 that this add makes, if any (signed overflow of the 64-bit add). A slot
/// holds T = v + 2^64 w exactly (v: the words as a signed 64-bit value, w: the count), so merging
/// adds the true sums: the result is the slot a single accumulator of every contribution holds,
/// bit for bit, whatever the grouping of the merges (the processes of an MPI all-reduce). A
/// partial sum that wrapped merges exactly with one that brings the total back into the range.
TANDEM_INLINE void fixed_merge(TANDEM_GLOBAL uint* into, const uint* from) {
    const ufixed64 a = ((ufixed64)into[1] << 32) | (ufixed64)into[0];
    const ufixed64 b = ((ufixed64)from[1] << 32) | (ufixed64)from[0];
    const ufixed64 sum = a + b;
    uint step = 0u;
    if ((((a ^ sum) & (b ^ sum)) >> 63) != 0u) // both operands have the sign the result lacks
        step = (b >> 63) != 0u ? 0xFFFFFFFFu : 1u; // -1 downwards, +1 upwards
    into[0] = (uint)sum;
    into[1] = (uint)(sum >> 32);
    into[2] = into[2] + from[2] + step;
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_FIXED_POINT_H
