// The replay check (tests/core/inverse/test_gradient.cpp, test_restir.cpp): a probe of the PRB
// adjoint's path pieces that only the tests build, with a scene's features, on a device scene
// whose kernel library holds the probes (tests/kernels/probes/probes.h).
#pragma OPENCL FP_CONTRACT OFF

#include "path/primal.h"
#include "path/replay.h"
#include "path/restir.h"

/// A check that the replay retraces its primal (tests/core/inverse/test_gradient.cpp): for samples
/// [rp.sample_begin, rp.sample_begin + rp.sample_count) of each pixel, replays the path with a
/// unit adjoint (gradients into grad, scratch) and writes residual[pixel], the largest |L_rem| / L
/// over the samples and channels: what is left of the primal radiance L once every replayed term
/// was subtracted (0 where L and L_rem are 0, +inf where only L_rem is not). Float rounding leaves
/// ~1e-7 relative; a replay that took another branch than its primal leaves whole terms. Neither
/// keeps a record (path/record.h): the replay traces every ray again, so that a shadow ray or a
/// hit it would find otherwise shows. reservoirs, reservoir_mode and reservoir_spp as
/// adjoint_primal's.
__kernel void replay_residual(SCENE_ARGS RenderParams rp, __global const float* scene_params,
                              __global const Reservoir* reservoirs, uint reservoir_mode,
                              uint reservoir_spp, __global uint* grad, __global float* residual) {
    const SceneRefs s = SCENE_REFS(rp);
    const uint pixel = get_global_id(0);
    if (pixel >= cam.width * cam.height) return;
    const uint px = pixel % cam.width, py = pixel / cam.width;
    float worst = 0.0f;
    for (uint k = 0; k < rp.sample_count; ++k) {
        const PathRng rng = path_rng(rp.seed, pixel, rp.sample_begin + k);
        const PrimaryReservoir pr = sample_reservoir(reservoirs, reservoir_mode, reservoir_spp,
                                                     pixel, rp.sample_begin + k);
        const float3 L = path_primal(&s, scene_params, rng, px, py, pr, 0);
        if (!all_finite(L)) continue;
        Adjoint adj;
        adj.grad = grad;
        adj.active = 0; // every element
        adj.delta = make_float3(1.0f, 1.0f, 1.0f);
        adj.L_rem = L;
        adj.saturated = 0u;
        path_replay(&s, scene_params, rng, px, py, pr, &adj, 0);
        const float r[3] = {fabs(adj.L_rem.x), fabs(adj.L_rem.y), fabs(adj.L_rem.z)};
        const float l[3] = {fabs(L.x), fabs(L.y), fabs(L.z)};
        for (uint c = 0; c < 3u; ++c)
            worst = fmax(worst, l[c] > 0.0f ? r[c] / l[c] : (r[c] > 0.0f ? INFINITY : 0.0f));
    }
    residual[pixel] = worst;
}
