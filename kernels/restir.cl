// ReSTIR across gradient iterations ("Amortizing Samples in Physics-Based Inverse Rendering using
// ReSTIR", Wang, Wyman, Wu, Zhao, SIGGRAPH Asia 2023, Sec. 4; docs/restir.md): the resampling
// pass on its own (path/resample.h), for burn-in and for the paths that cannot run it fused (the
// wavefront). One work item writes each pixel's slots: no atomics, the same bits on every run.
#pragma OPENCL FP_CONTRACT OFF

#include "path/resample.h"

/// One resampling pass: for each pixel, writes cur[pixel rs.spp + k] for its rs.spp slots k.
/// rp.seed is the adjoint's seed of this iteration (the slot's camera ray and candidate 0 are its
/// path's), params theta_n, params_old theta_{n-1} (the previous reservoirs' domain; where shapes
/// move, nodes_old, tris_old and normals_old are the geometry under it), prev the
/// reservoirs of the previous iteration (all empty on the first). Slots whose primary vertex
/// restir_serves() rejects are left without a shading point, unless serve_all (set where a
/// light's radiance is differentiated; active: the adjoint's bits of differentiated elements).
/// Adds to guards[pixel] the targets and weights that were not finite (set to zero).
__kernel void restir_resample(SCENE_ARGS RenderParams rp, __global const float* scene_params,
                              __global const float* params_old, __global const float4* nodes_old,
                              __global const BvhTriangle* tris_old,
                              __global const TriangleNormals* normals_old, RestirParams rs,
                              __global const Reservoir* prev, __global Reservoir* cur,
                              __global const uint* active, uint serve_all, __global uint* guards) {
    const SceneRefs s = SCENE_REFS(rp);
    const uint pixel = get_global_id(0);
    if (pixel >= cam.width * cam.height) return;
    const uint px = pixel % cam.width, py = pixel / cam.width;
    const PathResample pass = {
        scene_params, params_old, nodes_old, tris_old, normals_old, &rs, prev, active, serve_all,
    };
    uint dropped = 0u;
    for (uint k = 0; k < rs.spp; ++k) {
        Ray ray;
        restir_first_hit(&s, &pass, cur, px, py, k, path_rng(rp.seed, pixel, k), &ray, &dropped);
    }
    if (dropped) guards[pixel] += dropped;
}
