// Probe kernels for PoCL's work-group vectoriser (bench/vectorize_probe.py): the same small
// computations written in the forms a wavefront stage could take, to see which of them PoCL 3.1
// turns into SIMD across work items. Each kernel reads in[i] and writes out0[i], out1[i].
#pragma OPENCL FP_CONTRACT OFF

#include "shared/det_math.h"
#include "shared/rng.h"

/// Scalars in and out (structure of arrays), one branch that is a select.
__kernel void soa_arithmetic(__global const float* in, __global float* out0, __global float* out1,
                             uint seed) {
    const uint i = get_global_id(0);
    const float x = in[i] * in[i] + 0.5f;
    out0[i] = x;
    out1[i] = x > 0.7f ? sqrt(x) : -x;
}

/// The same arithmetic with a float4 store (an array of structures).
__kernel void aos_arithmetic(__global const float* in, __global float4* out0, __global float* out1,
                             uint seed) {
    const uint i = get_global_id(0);
    const float x = in[i] * in[i] + 0.5f;
    out0[i] = (float4)(x, x > 0.7f ? sqrt(x) : -x, 0.0f, 0.0f);
}

/// The path RNG (PCG4D hash), two dimensions.
__kernel void soa_rng(__global const float* in, __global float* out0, __global float* out1,
                      uint seed) {
    const uint i = get_global_id(0);
    out0[i] = rng_uniform(seed, i, 0u, 0u);
    out1[i] = rng_uniform(seed, i, 0u, 1u);
}

/// The project's deterministic sin and cos (shared/det_math.h).
__kernel void soa_sincos(__global const float* in, __global float* out0, __global float* out1,
                         uint seed) {
    const uint i = get_global_id(0);
    float s, c;
    det_sincos(in[i] * 3.0f, &s, &c);
    out0[i] = s;
    out1[i] = c;
}

/// det_sincos as it was before 2026-11-24 (8e22954): floor() from the library, and the quadrant
/// chosen by a chain of comparisons, which compilers make a switch.
inline void det_sincos_switch(float x, float* s, float* c) {
    if (!isfinite(x)) {
        *s = *c = x - x;
        return;
    }
    const float k = floor(x * 0.636619772367581f + 0.5f);
    const float r = ((x - k * 1.5703125f) - k * 4.837512969970703125e-4f) -
                    k * 7.54978995489188216e-8f;
    const int q = (int)(k - 4.0f * floor(k * 0.25f));
    const float sr = det_sin_poly(r), cr = det_cos_poly(r);
    *s = q == 0 ? sr : (q == 1 ? cr : (q == 2 ? -sr : -cr));
    *c = q == 0 ? cr : (q == 1 ? -sr : (q == 2 ? -cr : sr));
}

__kernel void soa_sincos_switch(__global const float* in, __global float* out0,
                                __global float* out1, uint seed) {
    const uint i = get_global_id(0);
    float s, c;
    det_sincos_switch(in[i] * 3.0f, &s, &c);
    out0[i] = s;
    out1[i] = c;
}
