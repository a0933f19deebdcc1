// Probes of shared code that tests compare bit for bit with the host's: the deterministic
// transcendentals (shared/det_math.h; tests/kernels/shared/test_det_math.cpp) and the eight-lane
// hash (shared/rng.h; tests/kernels/shared/test_rng.cpp).
#pragma OPENCL FP_CONTRACT OFF

#include "shared/det_math.h"
#include "shared/rng.h"

/// out[7 i ...] = det_sin(x[i]), det_cos(x[i]), det_acos(x[i]), det_atan2(y[i], x[i]),
/// det_floor(x[i]), and det_sincos_quarter_pi(y[i]) (sin, cos) where |y[i]| <= 1, else 0.
__kernel void det_math_probe(__global const float* x, __global const float* y, __global float* out,
                             uint n) {
    const uint i = get_global_id(0);
    if (i >= n) return;
    float s, c;
    det_sincos(x[i], &s, &c);
    out[7 * i + 0] = s;
    out[7 * i + 1] = c;
    out[7 * i + 2] = det_acos(x[i]);
    out[7 * i + 3] = det_atan2(y[i], x[i]);
    out[7 * i + 4] = det_floor(x[i]);
    float sq = 0.0f, cq = 0.0f;
    if (fabs(y[i]) <= 1.0f) det_sincos_quarter_pi(y[i], &sq, &cq);
    out[7 * i + 5] = sq;
    out[7 * i + 6] = cq;
}

/// out[16 i + k] = lane k of rng_uniform8 and out[16 i + 8 + k] lane k of rng_uniform8_samples,
/// both of the key (key[4 i], key[4 i + 1], key[4 i + 2], key[4 i + 3]).
__kernel void rng_probe(__global const uint* key, __global float* out, uint n) {
    const uint i = get_global_id(0);
    if (i >= n) return;
    const uint seed = key[4 * i], a = key[4 * i + 1], b = key[4 * i + 2], d = key[4 * i + 3];
    vstore8(rng_uniform8(seed, a, b, d), 2 * i, out);
    vstore8(rng_uniform8_samples(seed, a, b, d), 2 * i + 1, out);
}
