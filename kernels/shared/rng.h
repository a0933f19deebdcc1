// Counter-based random numbers: a stateless hash of (seed, a, b, dimension), so any sample of any
// path can be regenerated anywhere. pcg4d of Jarzynski and Olano, "Hash Functions for GPU
// Rendering", JCGT 9(3), 2020.
#ifndef TANDEM_SHARED_RNG_H
#define TANDEM_SHARED_RNG_H

#include "shared/compat.h"

TANDEM_NAMESPACE_BEGIN

/// pcg4d: hashes four 32-bit words into four well-mixed 32-bit words (returned in out[0..4)).
TANDEM_INLINE void rng_pcg4d(uint x, uint y, uint z, uint w, uint* out) {
    x = x * 1664525u + 1013904223u;
    y = y * 1664525u + 1013904223u;
    z = z * 1664525u + 1013904223u;
    w = w * 1664525u + 1013904223u;
    x += y * w;
    y += z * x;
    z += x * y;
    w += y * z;
    x ^= x >> 16;
    y ^= y >> 16;
    z ^= z >> 16;
    w ^= w >> 16;
    x += y * w;
    y += z * x;
    z += x * y;
    w += y * z;
    out[0] = x;
    out[1] = y;
    out[2] = z;
    out[3] = w;
}

/// Uniform float in [0, 1) for (seed, a, b, dim): 24 random mantissa bits, exactly representable.
TANDEM_INLINE float rng_uniform(uint seed, uint a, uint b, uint dim) {
    uint h[4];
    rng_pcg4d(seed, a, b, dim, h);
    return (float)(h[0] >> 8) * (1.0f / 16777216.0f);
}

/// rng_uniform of the four words of each lane: pcg4d lane for lane, computing only what its first
/// output word needs. The same integer operations as rng_uniform in every lane, so the same bits;
/// on a CPU the eight hashes take about the instructions of one
/// (tests/kernels/shared/test_rng.cpp).
TANDEM_INLINE float8 rng_uniform8v(uint8 seed, uint8 a, uint8 b, uint8 dim) {
    const uint8 mul = splat_uint8(1664525u), inc = splat_uint8(1013904223u);
    const uint8 x0 = seed * mul + inc, y0 = a * mul + inc, z0 = b * mul + inc, w0 = dim * mul + inc;
    uint8 x = x0 + y0 * w0;
    uint8 y = y0 + z0 * x;
    const uint8 z = z0 + x * y;
    uint8 w = w0 + y * z;
    x = x ^ (x >> 16u);
    y = y ^ (y >> 16u);
    w = w ^ (w >> 16u);
    // pcg4d's second round, up to its first word (the z and w it goes on to are not returned)
    x = x + y * w;
    return convert_float8(x >> 8u) * (1.0f / 16777216.0f);
}

/// The lane numbers 0..7.
TANDEM_INLINE uint8 rng_lanes(void) {
    return make_uint8(0u, 1u, 2u, 3u, 4u, 5u, 6u, 7u);
}

/// rng_uniform(seed, a, b, dim0 + k) in lane k (k = 0..7): eight dimensions of one sample.
TANDEM_INLINE float8 rng_uniform8(uint seed, uint a, uint b, uint dim0) {
    return rng_uniform8v(splat_uint8(seed), splat_uint8(a), splat_uint8(b),
                         splat_uint8(dim0) + rng_lanes());
}

/// rng_uniform(seed, a, b0 + k, dim) in lane k (k = 0..7): one dimension of eight samples.
TANDEM_INLINE float8 rng_uniform8_samples(uint seed, uint a, uint b0, uint dim) {
    return rng_uniform8v(splat_uint8(seed), splat_uint8(a), splat_uint8(b0) + rng_lanes(),
                         splat_uint8(dim));
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_RNG_H
