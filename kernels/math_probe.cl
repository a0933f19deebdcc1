// Probe of the deterministic transcendentals (shared/det_math.h): evaluates them on the device for
// tests/kernels/shared/test_det_math.cpp, which compares the bits with the host's.
#pragma OPENCL FP_CONTRACT OFF

#include "shared/det_math.h"

/// out[4 i ...] = det_sin(x[i]), det_cos(x[i]), det_acos(x[i]), det_atan2(y[i], x[i]).
__kernel void det_math_probe(__global const float* x, __global const float* y, __global float* out,
                             uint n) {
    const uint i = get_global_id(0);
    if (i >= n) return;
    float s, c;
    det_sincos(x[i], &s, &c);
    out[4 * i + 0] = s;
    out[4 * i + 1] = c;
    out[4 * i + 2] = det_acos(x[i]);
    out[4 * i + 3] = det_atan2(y[i], x[i]);
}
