// Image loss on the device: per element value and derivative, then a barrier-free reduction in a
// fixed order (each work item sums one contiguous chunk), so the loss is the same bits every run.
#pragma OPENCL FP_CONTRACT OFF

#include "shared/cv.h"
#include "shared/loss.h"

/// Reads image and reference (float RGB, `count` elements; the reference is ignored by
/// LOSS_MEAN); writes terms[i] (the element's loss term) and delta[i] = dloss/dimage[i].
__kernel void loss_terms(__global const float* image, __global const float* reference,
                         __global float* terms, __global float* delta, uint kind, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    const float r = kind == LOSS_MEAN ? 0.0f : reference[i];
    float d;
    terms[i] = loss_element(kind, image[i], r, 1.0f / (float)count, &d);
    delta[i] = d;
}

/// The recursive control variate and the loss in one pass ("Recursive Control Variates
/// for Inverse Rendering", eq. 6, 8 and 10; docs/method.md): for each element, h = <F_{n-1}>_n and f = <F_n>_n of this iteration update the
/// control-variate estimate in state[i] (shared/cv.h), and the loss term and delta are taken on
/// that estimate. No derivative flows through alpha or h.
__kernel void cv_loss_terms(__global const float* f, __global const float* h,
                            __global CvState* state, __global const float* reference,
                            __global float* terms, __global float* delta, uint kind, uint count,
                            CvConfig config) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    CvState st = state[i];
    const float c = cv_step(&st, h[i], f[i], &config);
    state[i] = st;
    const float r = kind == LOSS_MEAN ? 0.0f : reference[i];
    float d;
    terms[i] = loss_element(kind, c, r, 1.0f / (float)count, &d);
    delta[i] = d;
}

/// Sums values[j * chunk, (j + 1) * chunk) in order into partial[j], for j < ceil(count / chunk).
/// A target's mask (a photograph's: one weight in [0, 1] per pixel): terms[i] and delta[i] of the
/// pixel's three elements times its weight, so that a pixel of weight 0 adds nothing to the loss
/// and sends no gradient.
__kernel void mask_terms(__global float* terms, __global float* delta, __global const float* mask,
                         uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    const float w = mask[i / 3u];
    terms[i] = terms[i] * w;
    delta[i] = delta[i] * w;
}

__kernel void sum_chunks(__global const float* values, __global float* partial, uint chunk,
                         uint count) {
    const uint j = get_global_id(0);
    const uint begin = j * chunk;
    if (begin >= count) return;
    const uint end = min(begin + chunk, count);
    float s = 0.0f;
    for (uint i = begin; i < end; ++i) s += values[i];
    partial[j] = s;
}

/// alpha[i] = state[i].alpha: the control weights, for metrics and images.
__kernel void cv_alpha_image(__global const CvState* state, __global float* alpha, uint count) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    alpha[i] = state[i].alpha;
}
