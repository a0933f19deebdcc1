// Optimizer kernels on the flat parameter buffer: one work item per parameter element.
#pragma OPENCL FP_CONTRACT OFF

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
