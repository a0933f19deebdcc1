// Path-tracing megakernels (the estimators are kernels/path/primal.h and two_state.h). One work
// item per pixel; each owns its accumulator, so there are no atomics and the sum order is fixed.
#pragma OPENCL FP_CONTRACT OFF

#include "path/primal.h"
#include "path/two_state.h"
#if RESTIR
#include "path/resample.h"
#endif

/// Reads the scene, rp and scene_params (the flat parameter buffer, core/scene/params.h); adds the
/// radiance of samples [rp.sample_begin, rp.sample_begin + rp.sample_count) of every pixel to
/// accum[pixel] (rgb, w = sample count), and counts non-finite samples, which are dropped, in
/// guards[pixel].
__kernel void render_pass(SCENE_ARGS RenderParams rp, __global const float* scene_params,
                          __global float4* accum, __global uint* guards) {
    const SceneRefs s = SCENE_REFS(rp);
    const uint pixel = get_global_id(0);
    if (pixel >= cam.width * cam.height) return;
    const uint px = pixel % cam.width, py = pixel / cam.width;
    float4 sum = accum[pixel];
    uint caught = guards[pixel];
#if CAMERA_PACKETS
    // The camera rays of up to eight samples traced as one packet (kernels/shared/bvh8_packet.h),
    // then each path on its own, in sample order: the same hits, so the same sums.
    const uint offset = pixel_quadrant_offset(rp.seed, pixel); // path_camera_ray's quadrants
    for (uint k0 = 0; k0 < rp.sample_count; k0 += BVH8_PACKET) {
        const uint n = min(rp.sample_count - k0, (uint)BVH8_PACKET);
        Ray rays[BVH8_PACKET];
        Hit hits[BVH8_PACKET];
        // path_camera_ray's random numbers for the eight samples, hashed at once (shared/rng.h)
        float u0[BVH8_PACKET], u1[BVH8_PACKET];
        vstore8(rng_uniform8_samples(rp.seed, pixel, rp.sample_begin + k0, 0u), 0, u0);
        vstore8(rng_uniform8_samples(rp.seed, pixel, rp.sample_begin + k0, 1u), 0, u1);
        for (uint j = 0; j < n; ++j)
            rays[j] =
                path_camera_ray_sample(&s, px, py, rp.sample_begin + k0 + j, offset, u0[j], u1[j]);
        bvh8_packet_closest((__global const Bvh8Node*)s.nodes, s.tris, rays, n, hits);
        for (uint j = 0; j < n; ++j) {
            const PathRng rng = path_rng(rp.seed, pixel, rp.sample_begin + k0 + j);
            const float3 L =
                path_primal_from(&s, scene_params, rng, rays[j], &hits[j], no_reservoir(), 0);
            sum = add_sample(sum, L);
            caught += all_finite(L) ? 0u : 1u;
        }
    }
#else
    for (uint k = 0; k < rp.sample_count; ++k) {
        const PathRng rng = path_rng(rp.seed, pixel, rp.sample_begin + k);
        const float3 L = path_primal(&s, scene_params, rng, px, py, no_reservoir(), 0);
        sum = add_sample(sum, L);
        caught += all_finite(L) ? 0u : 1u;
    }
#endif
    accum[pixel] = sum;
    guards[pixel] = caught;
}

#if RESTIR
/// render_pass for the primal chain of ReSTIR (core/inverse/restir.h; docs/restir.md, "Reuse in
/// the primal"), with the iteration's resampling pass fused into it ("One pass fewer"): sample
/// k's reservoir is resampled at its path's own first hit, stored in its slot of `reservoirs`
/// (path/resample.h: restir_first_hit), and the path takes its primary NEE term from there (read
/// as `reservoir_mode`: path/restir.h). The camera ray is traced once for both, one by one.
/// params_old, nodes_old, tris_old, normals_old, rs, prev, active and serve_all are
/// restir_resample's (kernels/restir.cl), with rs.spp == reservoir_spp; guards[pixel] counts the
/// pass's non-finite targets and weights as well as the non-finite samples. RESTIR builds only.
__kernel void render_pass_resample(SCENE_ARGS RenderParams rp, __global const float* scene_params,
                                   __global Reservoir* reservoirs, uint reservoir_mode,
                                   uint reservoir_spp, __global const float* params_old,
                                   __global const float4* nodes_old,
                                   __global const BvhTriangle* tris_old,
                                   __global const TriangleNormals* normals_old, RestirParams rs,
                                   __global const Reservoir* prev, __global const uint* active,
                                   uint serve_all, __global float4* accum, __global uint* guards) {
    const SceneRefs s = SCENE_REFS(rp);
    const uint pixel = get_global_id(0);
    if (pixel >= cam.width * cam.height) return;
    const uint px = pixel % cam.width, py = pixel / cam.width;
    const PathResample pass = {
        scene_params, params_old, nodes_old, tris_old, normals_old, &rs, prev, active, serve_all,
    };
    float4 sum = accum[pixel];
    uint caught = guards[pixel];
    for (uint k = 0; k < rp.sample_count; ++k) {
        const uint sample = rp.sample_begin + k;
        const PathRng rng = path_rng(rp.seed, pixel, sample);
        Ray ray;
        const Hit first =
            restir_first_hit(&s, &pass, reservoirs, px, py, sample, rng, &ray, &caught);
        const PrimaryReservoir pr =
            sample_reservoir(reservoirs, reservoir_mode, reservoir_spp, pixel, sample);
        const float3 L = path_primal_from(&s, scene_params, rng, ray, &first, pr, 0);
        sum = add_sample(sum, L);
        caught += all_finite(L) ? 0u : 1u;
    }
    accum[pixel] = sum;
    guards[pixel] = caught;
}
#endif

/// The fused two-state kernel (CV-PS, "Recursive Control Variates for Inverse Rendering",
/// Appendix B): each path is sampled from scene_params (the new state theta_n) and also estimates
/// params_old (theta_{n-1}). Reads the scene, rp and both parameter buffers; one launch adds
/// <F_n>_n to accum and <F_{n-1}>_n to accum_old, as render_pass does. A sample is dropped from
/// both (and counted in guards) when either estimate is not finite, so the two stay paired.
__kernel void render_two_state(SCENE_ARGS RenderParams rp, __global const float* scene_params,
                               __global const float* params_old, __global float4* accum,
                               __global float4* accum_old, __global uint* guards) {
    const SceneRefs s = SCENE_REFS(rp);
    const uint pixel = get_global_id(0);
    if (pixel >= cam.width * cam.height) return;
    const uint px = pixel % cam.width, py = pixel / cam.width;
    float4 sum = accum[pixel], sum_old = accum_old[pixel];
    uint caught = guards[pixel];
    for (uint k = 0; k < rp.sample_count; ++k) {
        const PathRng rng = path_rng(rp.seed, pixel, rp.sample_begin + k);
        const TwoStateRadiance r = path_two_state(&s, scene_params, params_old, rng, px, py);
        if (!add_sample_two_state(&sum, &sum_old, r.L, r.L_old)) ++caught;
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

/// partial[j] = the sum of guards[j chunk, min((j + 1) chunk, count)), in index order: the
/// per-pixel guard counters reduced on the device, so that a report reads a few numbers.
__kernel void sum_guards(__global const uint* guards, __global ulong* partial, uint chunk,
                         uint count) {
    const uint j = get_global_id(0);
    const uint begin = j * chunk;
    if (begin >= count) return;
    const uint end = min(begin + chunk, count);
    ulong s = 0;
    for (uint i = begin; i < end; ++i)
        s += guards[i];
    partial[j] = s;
}

#if HAS_MEDIA
/// Cell `get_global_id(0)` of majorant grid `majorant_grid` (in medium_data) = the largest voxel,
/// every channel, of grid `value_grid` (a parameter: its voxels in params, and in params_b) that
/// the trilinear interpolant blends over the cell (majorant_cell_voxels): the bound free flights
/// and ratio tracking draw against (kernels/path/media.h), recomputed from the parameters a pass
/// renders (DeviceScene::refresh_majorants). A two-state pass bounds both states: params_b is the
/// old state's buffer (else params again). core/scene/media.cpp builds the same on the host.
__kernel void media_majorant(__global const DeviceGrid* grids, __global const float* params,
                             __global const float* params_b, __global float* medium_data,
                             uint value_grid, uint majorant_grid) {
    const uint cell = get_global_id(0);
    const DeviceGrid g = grids[value_grid], m = grids[majorant_grid];
    if (cell >= m.nx * m.ny * m.nz) return;
    const uint cx = cell % m.nx, cy = cell / m.nx % m.ny, cz = cell / (m.nx * m.ny);
    uint x0, x1, y0, y1, z0, z1;
    majorant_cell_voxels(cx, m.nx, g.nx, &x0, &x1);
    majorant_cell_voxels(cy, m.ny, g.ny, &y0, &y1);
    majorant_cell_voxels(cz, m.nz, g.nz, &z0, &z1);
    float v = 0.0f;
    for (uint z = z0; z <= z1; ++z)
        for (uint y = y0; y <= y1; ++y)
            for (uint x = x0; x <= x1; ++x)
                for (uint c = 0; c < g.channels; ++c) {
                    const uint i = g.offset + ((z * g.ny + y) * g.nx + x) * g.channels + c;
                    v = fmax(v, fmax(params[i], params_b[i]));
                }
    medium_data[m.offset + cell] = v;
}
#endif
