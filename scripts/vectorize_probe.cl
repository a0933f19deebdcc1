// Probe kernels for PoCL's work-group vectoriser (scripts/vectorize_probe.py): the same small
// computations written in the forms a wavefront stage could take, to see which of them PoCL 3.1
// turns into SIMD across work items. Each kernel reads in[i] and writes out0[i], out1[i].
#pragma OPENCL FP_CONTRACT OFF

#include "shared/det_math.h"
#include "shared/rng.h"
#include "shared/sampling.h"

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

// The kernels of "CPU: a wavefront whose shading PoCL vectorises": what PoCL's SLP vectoriser,
// which runs first, does to scalar code (compare a run with --no-slp).

/// A diffuse shading stage in scalars: gathers, the concentric disk map with branches, det_sincos,
/// the power heuristic, an early exit and a masked store.
__kernel void shade_like(__global const float* in, __global float* out0, __global float* out1,
                         uint seed) {
    const uint i = get_global_id(0);
    const float t = in[i];
    if (!(t > -2.0f)) return; // an ended path
    const uint prim = ((uint)(fabs(t) * 7.0f)) & 31u;
    __global const float* mat = in + prim * 24u; // a gathered "material"
    const float ax = mat[0], ay = mat[1], az = mat[2];
    const float u1 = rng_uniform(seed, i, 0u, 3u), u2 = rng_uniform(seed, i, 0u, 4u);
    const float x = 2.0f * u1 - 1.0f, y = 2.0f * u2 - 1.0f;
    float r, phi;
    if (fabs(x) > fabs(y)) {
        r = x;
        phi = 0.785398f * (y / x);
    } else {
        r = y;
        phi = 1.570796f - 0.785398f * (x / y);
    }
    float s, c;
    det_sincos(phi, &s, &c);
    float dx = r * c, dy = r * s;
    if (x == 0.0f && y == 0.0f) {
        dx = 0.0f;
        dy = 0.0f;
    }
    const float dz = sqrt(fmax(0.0f, 1.0f - dx * dx - dy * dy));
    const float pa = dz * 0.3183f, pb = t * t;
    float w;
    if (!(pa > 0.0f))
        w = 0.0f;
    else if (pa == pb)
        w = 0.5f;
    else if (pa > pb) {
        const float q = pb / pa;
        w = 1.0f / (1.0f + q * q);
    } else {
        const float q = pa / pb;
        w = q * q / (1.0f + q * q);
    }
    out0[4u * i] = ax * w * dx;
    out0[4u * i + 1u] = ay * w * dy;
    out0[4u * i + 2u] = az * w * dz;
    if (dz > 0.5f) out1[i] = w;
}

/// |x| > |y| by bit masks, then a select: two like operations that SLP packs into one <2 x i32>.
__kernel void absbits(__global const float* in, __global float* out0, __global float* out1,
                      uint seed) {
    const uint i = get_global_id(0);
    const float t = in[i];
    const float x = t - 1.0f, y = t * t;
    out0[i] = as_float(as_uint(x) & 0x7fffffffu) > as_float(as_uint(y) & 0x7fffffffu) ? x : y;
    out1[i] = (float)seed;
}

/// The concentric disk map's radius and angle, with selects.
__kernel void disk_select(__global const float* in, __global float* out0, __global float* out1,
                          uint seed) {
    const uint i = get_global_id(0);
    const float t = in[i];
    const float x = 2.0f * t - 1.0f, y = 2.0f * (t * t) - 1.0f;
    const int wide = fabs(x) > fabs(y);
    const float r = wide ? x : y;
    const float q = (wide ? y : x) / r;
    out0[i] = r;
    out1[i] = wide ? 0.785398f * q : 1.570796f - 0.785398f * q;
}

/// The same kind of arithmetic on float3 (normalize, a frame, a change of basis).
__kernel void float3_frame(__global const float* in, __global float* out0, __global float* out1,
                           uint seed) {
    const uint i = get_global_id(0);
    const float t = in[i];
    const float3 n = vnormalize(make_float3(t, t * 2.0f, t - 1.0f));
    const Frame f = frame_from_normal(n);
    const float3 w = frame_to_world(f, make_float3(0.3f, t, 0.5f));
    out0[i] = w.x;
    out1[i] = w.y + w.z;
}
