// Path Replay Backpropagation ("Path Replay Backpropagation: Differentiating Light Paths using
// Constant Memory and Linear Time", Vicini, Speierer, Jakob, SIGGRAPH 2021, Sec. 4). One work item
// per pixel and sample loop: pass 1 (adjoint_primal) traces the path for its primal radiance L
// (path/primal.h) and stores L with its record (path/record.h: the outcomes of its shadow rays,
// one bit per vertex, and the hits of its first hit_bounces bounces), pass 2 (adjoint_pass)
// replays the same path (same random numbers) with L_rem = L, reads what the record holds instead
// of tracing it again, and pushes delta times each term's derivative into the gradients
// (path/replay.h). No derivatives are stored: 16 bytes per sample of a launch, and 16 per
// recorded bounce (max_depth of them at most). Gradients are 64-bit
// fixed-point sums (shared/fixed_point.h): bit-identical whatever order the work items finish in,
// in units scaled by 2^s, s chosen from sum |delta| on the device (grad_delta_sums, grad_exponent).
#pragma OPENCL FP_CONTRACT OFF

#include "path/primal.h"
#include "path/replay.h"
#include "path/restir.h"
#if RESTIR
#include "path/resample.h"
#endif

/// The first of the adjoint's two kernels: record[k pixels + pixel] = the primal radiance L of
/// sample rp.sample_begin + k of the pixel (path/primal.h; the bits of its rgb in .xyz) and the
/// bits of its record's shadow rays in .w, for k < rp.sample_count, where delta is not zero there
/// (elsewhere adjoint_pass reads nothing); and the hit of bounce d < hit_bounces of that sample
/// at hits[(d rp.sample_count + k) pixels + pixel]. A separate kernel, so that the replay
/// kernel does not also hold the primal path's state (on a GPU, one kernel with both is much
/// slower). With reservoir_mode != 0 (RESTIR builds), each
/// sample's primary NEE term comes from its slot of `reservoirs` (reservoir_spp slots per pixel;
/// path/restir.h), in this kernel and in adjoint_pass alike.
__kernel void adjoint_primal(SCENE_ARGS RenderParams rp, __global const float* scene_params,
                             __global const float* delta, __global const Reservoir* reservoirs,
                             uint reservoir_mode, uint reservoir_spp, __global uint4* record,
                             __global Hit* hits, uint hit_bounces) {
    const SceneRefs s = SCENE_REFS(rp);
    const uint pixel = get_global_id(0);
    const uint pixels = cam.width * cam.height;
    if (pixel >= pixels) return;
    if (delta[3u * pixel] == 0.0f && delta[3u * pixel + 1u] == 0.0f &&
        delta[3u * pixel + 2u] == 0.0f)
        return;
    const uint px = pixel % cam.width, py = pixel / cam.width;
    for (uint k = 0; k < rp.sample_count; ++k) {
        const PathRng rng = path_rng(rp.seed, pixel, rp.sample_begin + k);
        const PrimaryReservoir pr =
            sample_reservoir(reservoirs, reservoir_mode, reservoir_spp, pixel, rp.sample_begin + k);
        PathRecord rec = path_record(0, 0u, hit_bounces ? hits + (k * pixels + pixel) : 0,
                                     rp.sample_count * pixels, hit_bounces);
        const float3 L = path_primal(&s, scene_params, rng, px, py, pr, &rec);
        // bits, not floats: the shadow bits are no number, and a device that flushes denormals
        // must not touch them
        record[k * pixels + pixel] = (uint4)(as_uint(L.x), as_uint(L.y), as_uint(L.z), rec.shadow);
    }
}

#if RESTIR
/// adjoint_primal with the iteration's resampling pass fused into it (RESTIR builds;
/// docs/restir.md, "One pass fewer"): sample k's reservoir is resampled at its path's own first
/// hit and stored in its slot of `reservoirs` (path/resample.h: restir_first_hit), which the path
/// then reads as adjoint_primal's reads it, and adjoint_pass after it. The camera ray is traced
/// once for both.
/// params_old, nodes_old, tris_old, normals_old, rs, prev, active and serve_all are
/// restir_resample's (kernels/restir.cl), with rs.spp == reservoir_spp. A pixel whose delta is 0
/// takes no path, but its slots are resampled all the same: they are the next iteration's
/// neighbours. Adds to guards[pixel] the targets and weights that were not finite, as
/// restir_resample does.
__kernel void adjoint_primal_resample(
    SCENE_ARGS RenderParams rp, __global const float* scene_params, __global const float* delta,
    __global Reservoir* reservoirs, uint reservoir_mode, uint reservoir_spp, __global uint4* record,
    __global Hit* hits, uint hit_bounces, __global const float* params_old,
    __global const float4* nodes_old, __global const BvhTriangle* tris_old,
    __global const TriangleNormals* normals_old, RestirParams rs, __global const Reservoir* prev,
    __global const uint* active, uint serve_all, __global uint* guards) {
    const SceneRefs s = SCENE_REFS(rp);
    const uint pixel = get_global_id(0);
    const uint pixels = cam.width * cam.height;
    if (pixel >= pixels) return;
    const int paths = delta[3u * pixel] != 0.0f || delta[3u * pixel + 1u] != 0.0f ||
                      delta[3u * pixel + 2u] != 0.0f;
    const uint px = pixel % cam.width, py = pixel / cam.width;
    const PathResample pass = {
        scene_params, params_old, nodes_old, tris_old, normals_old, &rs, prev, active, serve_all,
    };
    uint dropped = 0u;
    for (uint k = 0; k < rp.sample_count; ++k) {
        const uint sample = rp.sample_begin + k;
        const PathRng rng = path_rng(rp.seed, pixel, sample);
        Ray ray;
        const Hit first =
            restir_first_hit(&s, &pass, reservoirs, px, py, sample, rng, &ray, &dropped);
        if (!paths) continue;
        const PrimaryReservoir pr =
            sample_reservoir(reservoirs, reservoir_mode, reservoir_spp, pixel, sample);
        PathRecord rec = path_record(0, 0u, hit_bounces ? hits + (k * pixels + pixel) : 0,
                                     rp.sample_count * pixels, hit_bounces);
        const float3 L = path_primal_from(&s, scene_params, rng, ray, &first, pr, &rec);
        record[k * pixels + pixel] = (uint4)(as_uint(L.x), as_uint(L.y), as_uint(L.z), rec.shadow);
    }
    if (dropped) guards[pixel] += dropped;
}
#endif

/// Reads the scene, rp, scene_params, delta: dloss/dimage (rgb per pixel), record: the primal
/// radiance and shadow bits of each sample, and hits: the hits of its first hit_bounces bounces
/// (adjoint_primal, same rp and hit_bounces). This launch replays samples
/// [rp.sample_begin, rp.sample_begin + rp.sample_count) of each pixel; inv_spp is 1 / the samples
/// per pixel of the whole adjoint, so each sample carries delta / spp, times 2^s for the exponent
/// s = exponent[0] (grad_exponent). Adds to grad (GRAD_WORDS words per parameter element) for the
/// elements whose bit is set in active (one bit per element), and to guards[pixel], which counts
/// non-finite primal samples (skipped) and saturated gradient contributions. reservoirs,
/// reservoir_mode and reservoir_spp as adjoint_primal's.
__kernel void adjoint_pass(SCENE_ARGS RenderParams rp, __global const float* scene_params,
                           __global const float* delta, __global const Reservoir* reservoirs,
                           uint reservoir_mode, uint reservoir_spp, float inv_spp,
                           __global const int* exponent, __global const uint4* record,
                           __global Hit* hits, uint hit_bounces, __global const uint* active,
                           __global uint* grad, __global uint* guards) {
    const SceneRefs s = SCENE_REFS(rp);
    const uint pixel = get_global_id(0);
    const uint pixels = cam.width * cam.height;
    if (pixel >= pixels) return;
    const uint px = pixel % cam.width, py = pixel / cam.width;
    // (delta 2^s) / spp: the scaling is exact, so d is the unscaled value's bits times 2^s
    const float scale = grad_pow2(exponent[0]);
    const float3 d = make_float3(delta[3u * pixel] * scale, delta[3u * pixel + 1u] * scale,
                                 delta[3u * pixel + 2u] * scale) *
                     inv_spp;
    uint caught = guards[pixel];
    if (d.x == 0.0f && d.y == 0.0f && d.z == 0.0f) return; // nothing to propagate
    for (uint k = 0; k < rp.sample_count; ++k) {
        const PathRng rng = path_rng(rp.seed, pixel, rp.sample_begin + k);
        const uint4 primal = record[k * pixels + pixel];
        const float3 L = make_float3(as_float(primal.x), as_float(primal.y), as_float(primal.z));
        if (!all_finite(L)) { // the primal dropped this sample; so does its gradient
            ++caught;
            continue;
        }
        Adjoint adj;
        adj.grad = grad;
        adj.active = active;
        adj.delta = d;
        adj.L_rem = L;
        adj.saturated = 0u;
#if SHAPE_GRAD
        adj.shape = shape_vertex_none();
#endif
        PathRecord rec = path_record(1, primal.w, hit_bounces ? hits + (k * pixels + pixel) : 0,
                                     rp.sample_count * pixels, hit_bounces);
        path_replay(
            &s, scene_params, rng, px, py,
            sample_reservoir(reservoirs, reservoir_mode, reservoir_spp, pixel, rp.sample_begin + k),
            &adj, &rec);
        caught += adj.saturated;
    }
    guards[pixel] = caught;
}

/// The scale of the next adjoint launches, first step: partial[first + j] = sum of |delta[i]|
/// over the chunk [j chunk, (j + 1) chunk), in index order (a batch of views writes each view's
/// delta's chunks after the previous view's); non-finite elements are left out (their
/// contributions are dropped anyway).
__kernel void grad_delta_sums(__global const float* delta, __global float* partial, uint first,
                              uint chunk, uint count) {
    const uint j = get_global_id(0);
    const uint begin = j * chunk;
    if (begin >= count) return;
    const uint end = min(begin + chunk, count);
    float s = 0.0f;
    for (uint i = begin; i < end; ++i) {
        const float a = fabs(delta[i]);
        // a select, not a conditional add (the same bits: s + 0 is s): PoCL compiled the latter
        // to a merge-masked load, far slower on x86 CPUs
        s += isfinite(a) ? a : 0.0f;
    }
    partial[first + j] = s;
}

/// Second step, one work item: exponent[0] = s for the sum of partial[0, chunks) in order
/// (shared/fixed_point.h: grad_exponent_for). The same delta gives the same s on every run.
__kernel void grad_exponent(__global const float* partial, uint chunks, __global int* exponent) {
    if (get_global_id(0) != 0u) return;
    float s = 0.0f;
    for (uint j = 0; j < chunks; ++j)
        s += partial[j];
    exponent[0] = grad_exponent_for(s);
}

/// grad[i] = the float value of the fixed-point sum i of contributions scaled by 2^exponent[0];
/// the sums are reset to zero. A sum that wrapped decodes to the end of the range on its side and
/// counts one in guards[0], with the saturated contributions.
__kernel void decode_gradients(__global uint* fixed, __global const int* exponent,
                               __global float* grad, uint count, __global uint* guards) {
    const uint i = get_global_id(0);
    if (i >= count) return;
    __global uint* slot = fixed + GRAD_WORDS * i;
    uint wrapped;
    grad[i] = fixed_decode(slot, exponent[0], &wrapped);
    if (wrapped) atomic_inc(guards);
    slot[0] = 0u;
    slot[1] = 0u;
    slot[2] = 0u;
}
