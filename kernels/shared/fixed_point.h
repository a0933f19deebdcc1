// Deterministic gradient accumulation: 64-bit fixed-point sums built from 32-bit integer atomics.
//
// Float atomics give sums that depend on the order work items arrive in. Integer addition is
// associative, so a fixed-point sum is exact and bit-identical in any order. Each gradient element
// is one signed 64-bit integer in units of 2^-40, stored as two 32-bit words (lo, hi). Adding a
// 64-bit value v takes two core OpenCL 1.1 atomics, no 64-bit atomics extension:
//   old = atomic_add(lo, (uint)v); carry = (old + (uint)v wraps); atomic_add(hi, (v >> 32) + carry).
// Every add carries out of the low word at most once and adds that carry to the high word once,
// so the pair ends as the exact sum mod 2^64 whatever the interleaving (nobody reads the pair
// before the launch ends).
//
// Range and precision: a contribution c is stored as round-to-nearest(c 2^40), off by at most
// 2^-41 ~ 4.5e-13 absolute. Contributions are delta (~ 1 / (3 pixels spp) for a mean loss) times
// radiance-sized factors: ~1e-6 for a 128x128 image at 4 spp, where the rounding is ~5e-7
// relative, and ~1e-9 for 1024x1024 at 16 spp, where it grows to ~5e-4 relative per
// contribution. The roundings are unbiased on average (round to nearest), so the sums of many
// stay far more accurate than that. Sums are exact within |sum| < 2^23 ~ 8.4e6 and wrap beyond
// it; a single contribution beyond GRAD_MAX_CONTRIBUTION = 2^22, or a non-finite one, is counted
// as saturated: clamped to +-2^22 (non-finite ones are dropped), and the host reports the count.
// Losses here are means over pixels, so a gradient element near 2^22 would mean a loss scale far
// outside what the optimizers expect; the saturation count is the warning that the range was
// reached (two saturated contributions of the same sign are enough to wrap a sum).
#ifndef TANDEM_SHARED_FIXED_POINT_H
#define TANDEM_SHARED_FIXED_POINT_H

#include "shared/compat.h"

TANDEM_NAMESPACE_BEGIN

#define GRAD_FIXED_SCALE 1099511627776.0f        /* 2^40 */
#define GRAD_FIXED_INV_SCALE 9.094947017729282e-13f /* 2^-40, exact */
#define GRAD_MAX_CONTRIBUTION 4194304.0f        /* 2^22 */

#if TANDEM_DEVICE
typedef long fixed64;
typedef ulong ufixed64;
#else
typedef std::int64_t fixed64;
typedef std::uint64_t ufixed64;
#endif

/// round-to-nearest-even(v 2^40) for |v| <= 2^22 (exact scaling by a power of two, then one
/// rounding; the host and device round the same way).
TANDEM_INLINE fixed64 fixed_encode(float v) {
#if TANDEM_DEVICE
    return convert_long_rte(v * GRAD_FIXED_SCALE);
#else
    return static_cast<fixed64>(std::nearbyint(static_cast<double>(v * GRAD_FIXED_SCALE)));
#endif
}

/// The float nearest to the fixed-point value (lo, hi) (one rounding, then exact scaling).
TANDEM_INLINE float fixed_decode(uint lo, uint hi) {
    const fixed64 v = (fixed64)(((ufixed64)hi << 32) | (ufixed64)lo);
#if TANDEM_DEVICE
    return convert_float_rte(v) * GRAD_FIXED_INV_SCALE;
#else
    return static_cast<float>(v) * GRAD_FIXED_INV_SCALE;
#endif
}

/// Adds v to the pair slot[0] (low word), slot[1] (high word) without 64-bit atomics; the host
/// version (tests) does the same arithmetic without atomics.
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
    const uint high = hi + carry;
    if (high != 0u) {
#if TANDEM_DEVICE
        atomic_add((volatile __global uint*)slot + 1, high);
#else
        slot[1] += high;
#endif
    }
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_FIXED_POINT_H
