// Optimizer kernels on the flat parameter buffer: one work item per parameter element; and the
// resampling of grids that the resolution schedule steps (core/inverse/grid_schedule.h).
#pragma OPENCL FP_CONTRACT OFF

#include "shared/medium.h"
#include "shared/optim.h"

/// Reads grads, the learning rate and range of each element (lr, lower, upper); updates params
/// and the Adam moments m, v in place, for elements [0, count).
__kernel void adam_update(__global float* params, __global const float* grads,
                          __global float* m, __global float* v, __global const float* lr,
                          __global const float* lower, __global const float* upper,
                          AdamConfig config, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    float mi = m[i], vi = v[i];
    params[i] = adam_step(params[i], grads[i], lr[i], lower[i], upper[i], config, &mi, &vi);
    m[i] = mi;
    v[i] = vi;
}

/// Gradient descent: params[i] -= lr[i] grads[i], clamped to [lower[i], upper[i]].
__kernel void sgd_update(__global float* params, __global const float* grads,
                         __global const float* lr, __global const float* lower,
                         __global const float* upper, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    params[i] = sgd_step(params[i], grads[i], lr[i], lower[i], upper[i]);
}

/// dst[dst_offset + e] = element e of the grid of (dx, dy, dz) voxels resampled from the grid at
/// src[src_offset] of (sx, sy, sz) voxels, both of `channels` channels (grid_resample_at): one
/// work item per element. The resolution schedule's prolongation (core/inverse/grid_schedule.h).
__kernel void grid_resample(__global const float* src, uint src_offset, uint sx, uint sy, uint sz,
                            __global float* dst, uint dst_offset, uint dx, uint dy, uint dz,
                            uint channels) {
    const uint e = get_global_id(0);
    if (e >= dx * dy * dz * channels) return;
    const uint c = e % channels, voxel = e / channels;
    const uint x = voxel % dx, y = voxel / dx % dy, z = voxel / (dx * dy);
    dst[dst_offset + e] =
        grid_resample_at(src + src_offset, sx, sy, sz, channels, x, y, z, dx, dy, dz, c);
}

/// g_src[src_offset + e] = the adjoint of grid_resample at source element e
/// (grid_resample_adjoint_at) from the resampled grid's adjoint at g_dst[dst_offset]: one work
/// item per source element, each summing in a fixed order (no atomics).
__kernel void grid_resample_adjoint(__global const float* g_dst, uint dst_offset, uint dx, uint dy,
                                    uint dz, __global float* g_src, uint src_offset, uint sx,
                                    uint sy, uint sz, uint channels) {
    const uint e = get_global_id(0);
    if (e >= sx * sy * sz * channels) return;
    const uint c = e % channels, voxel = e / channels;
    const uint x = voxel % sx, y = voxel / sx % sy, z = voxel / (sx * sy);
    g_src[src_offset + e] = grid_resample_adjoint_at(g_dst + dst_offset, dx, dy, dz, channels, x,
                                                     y, z, sx, sy, sz, c);
}
