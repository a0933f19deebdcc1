// Path-tracing megakernel (the path itself is kernels/path.h). One work item per pixel; each owns
// its accumulator, so there are no atomics and the sum order is fixed (deterministic).
#pragma OPENCL FP_CONTRACT OFF

#include "path.h"

/// Adds the radiance of samples [sample_begin, sample_begin + sample_count) of every pixel to
/// accum[pixel] (rgb, w = sample count), and counts non-finite samples, which are dropped, in
/// guards[pixel]. scene_params: the flat parameter buffer (core/params.h).
__kernel void render_pass(SCENE_ARGS, __global const float* scene_params, __global float4* accum,
                          __global uint* guards) {
    SCENE_REFS(s);
    const uint pixel = get_global_id(0);
    if (pixel >= cam.width * cam.height) return;
    const uint px = pixel % cam.width, py = pixel / cam.width;
    float4 sum = accum[pixel];
    uint caught = guards[pixel];
    for (uint k = 0; k < params.sample_count; ++k) {
        const PathRng rng = path_rng(params.seed, pixel, params.sample_begin + k);
        const float3 L = trace_path(&s, scene_params, rng, px, py, 0, 0);
        if (all_finite(L)) {
            sum += make_float4(L.x, L.y, L.z, 0.0f);
        } else {
            ++caught;
        }
        sum.w += 1.0f;
    }
    accum[pixel] = sum;
    guards[pixel] = caught;
}

/// The fused two-state kernel (CV-PS, papers/000 Appendix B, METHOD.md section 3): each path is
/// sampled from scene_params (the new state theta_n) and also estimates params_old (theta_{n-1}):
/// one launch adds <F_n>_n to accum and <F_{n-1}>_n to accum_old. A sample is dropped from both
/// when either estimate is not finite, so the two stay paired.
__kernel void render_two_state(SCENE_ARGS, __global const float* scene_params,
                               __global const float* params_old, __global float4* accum,
                               __global float4* accum_old, __global uint* guards) {
    SCENE_REFS(s);
    const uint pixel = get_global_id(0);
    if (pixel >= cam.width * cam.height) return;
    const uint px = pixel % cam.width, py = pixel / cam.width;
    float4 sum = accum[pixel], sum_old = accum_old[pixel];
    uint caught = guards[pixel];
    for (uint k = 0; k < params.sample_count; ++k) {
        const PathRng rng = path_rng(params.seed, pixel, params.sample_begin + k);
        TwoState two;
        two.params_old = params_old;
        two.beta_old = make_float3(1.0f, 1.0f, 1.0f);
        two.L_old = make_float3(0.0f, 0.0f, 0.0f);
        const float3 L = trace_path(&s, scene_params, rng, px, py, 0, &two);
        if (all_finite(L) && all_finite(two.L_old)) {
            sum += make_float4(L.x, L.y, L.z, 0.0f);
            sum_old += make_float4(two.L_old.x, two.L_old.y, two.L_old.z, 0.0f);
        } else {
            ++caught;
        }
        sum.w += 1.0f;
        sum_old.w += 1.0f;
    }
    accum[pixel] = sum;
    accum_old[pixel] = sum_old;
    guards[pixel] = caught;
}

/// rgb[3 pixel + c] = accum[pixel].c / accum[pixel].w: the image as the losses read it.
__kernel void resolve_image(__global const float4* accum, __global float* rgb, uint pixels) {
    const uint i = get_global_id(0);
    if (i >= pixels) return;
    const float4 a = accum[i];
    const float inv = a.w > 0.0f ? 1.0f / a.w : 0.0f;
    rgb[3u * i] = a.x * inv;
    rgb[3u * i + 1u] = a.y * inv;
    rgb[3u * i + 2u] = a.z * inv;
}
