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

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_RNG_H
