// The wavefront, for CPUs: one launch per stage and bounce (generate, intersect, shade, shadow,
// accumulate) over a structure of arrays of path state, one path per pixel per wave. It computes
// the primal render (render_pass), the two-state render (render_two_state) and the adjoint
// (adjoint_primal, adjoint_pass) with the same path pieces in the same order, so images and
// gradients are the same bits.
//
// Why: PoCL runs a kernel as a loop over the work items of a work group and leaves SIMD across
// them to LLVM's loop vectoriser, which gives up on any value of an OpenCL vector type (float3,
// float4), any call, and any inner loop. The megakernels have all three. The shading stage
// (path/wavefront.h) is straight-line code on scalars that calls the megakernels' own path pieces
// in their scalar (per channel) forms, so the vectoriser runs it 8 paths per instruction on
// AVX-512 targets (docs/wavefront.md); on AVX2 targets LLVM's cost model keeps it scalar (its
// gathers), and the megakernels are the default there. Traversal stays one ray per work item.
#pragma OPENCL FP_CONTRACT OFF

#include "path/replay.h"
#include "path/two_state.h"
#include "path/wavefront.h"

/// Stage 1, once per wave: the camera ray of sample rp.sample_begin of every pixel, as
/// path_camera_ray (path/scene.h) draws it: its pixel sample (shared/pixel_sample.h) and
/// camera_ray, in scalars, so that PoCL vectorises it (with float3 values it ran one path per
/// instruction).
__kernel void wf_generate(SCENE_ARGS RenderParams rp, __global float* state,
                          __global uint* ustate, uint n) {
    const uint i = get_global_id(0);
    if (i >= n) return;
    const PathRng rng = path_rng(rp.seed, i, rp.sample_begin);
    const uint q = pixel_quadrant(rp.sample_begin, pixel_quadrant_offset(rp.seed, i));
    float d[3], tmin, tmax;
    camera_ray(&cam, i % cam.width, i / cam.width, pixel_stratified(path_rand(rng, 0), q & 1u),
               pixel_stratified(path_rand(rng, 1), q >> 1u), d, &tmin, &tmax);
    WF_SET3(WF_OX, cam.origin.x, cam.origin.y, cam.origin.z);
    WF_SET3(WF_DX, d[0], d[1], d[2]);
    WF_F(WF_TMIN) = tmin;
    WF_F(WF_TMAX) = tmax;
    WF_SET3(WF_BETA, 1.0f, 1.0f, 1.0f);
    WF_SET3(WF_L, 0.0f, 0.0f, 0.0f);
    WF_SET3(WF_BETA_OLD, 1.0f, 1.0f, 1.0f);
    WF_SET3(WF_L_OLD, 0.0f, 0.0f, 0.0f);
    WF_F(WF_PREV_PDF) = 0.0f;
    WF_U(WF_FLAGS) = rp.max_depth == 0u ? 0u : WF_ALIVE; // Mitsuba: max_depth 0 renders black
}

/// The paths alive at the start of a bounce, in increasing order (wf_live_list): the stages of
/// the bounce run over live[0, count), path i = live[j] for work item j. (The shading stage is
/// vectorised: a path that has ended would still take a lane; with this list none does.)
#define WF_LIVE_PATH()                                                                             \
    const uint j = get_global_id(0);                                                               \
    if (j >= count) return;                                                                        \
    const uint i = live[j]


/// Stage 2, every bounce: the closest hit of every live path's ray (recorded in `hits` at `slot`,
/// unless slot is WF_NO_RECORD).
__kernel void wf_intersect(SCENE_ARGS RenderParams rp, __global float* state,
                           __global uint* ustate, uint n, __global const uint* live, uint count,
                           __global uint* hits, uint slot) {
    const SceneRefs s = SCENE_REFS(rp);
    WF_LIVE_PATH();
    const Ray ray = make_ray(make_float3(WF_F(WF_OX), WF_F(WF_OX + 1u), WF_F(WF_OX + 2u)),
                             make_float3(WF_F(WF_DX), WF_F(WF_DX + 1u), WF_F(WF_DX + 2u)),
                             WF_F(WF_TMIN), WF_F(WF_TMAX));
    const Hit hit = trace_closest(&s, ray);
    WF_F(WF_HIT_T) = hit.t;
    WF_F(WF_HIT_U) = hit.u;
    WF_F(WF_HIT_V) = hit.v;
    WF_U(WF_PRIM) = hit.prim;
    if (slot != WF_NO_RECORD) {
        hits[(4u * slot) * n + i] = as_uint(hit.t);
        hits[(4u * slot + 1u) * n + i] = as_uint(hit.u);
        hits[(4u * slot + 2u) * n + i] = as_uint(hit.v);
        hits[(4u * slot + 3u) * n + i] = hit.prim;
    }
}

/// Stage 2 of the replay, for a bounce the first pass recorded (`slot`): its hit, not traced again.
__kernel void wf_recall(__global float* state, __global uint* ustate, uint n,
                        __global const uint* live, uint count, __global const uint* hits,
                        uint slot) {
    WF_LIVE_PATH();
    WF_F(WF_HIT_T) = as_float(hits[(4u * slot) * n + i]);
    WF_F(WF_HIT_U) = as_float(hits[(4u * slot + 1u) * n + i]);
    WF_F(WF_HIT_V) = as_float(hits[(4u * slot + 2u) * n + i]);
    WF_U(WF_PRIM) = hits[(4u * slot + 3u) * n + i];
}

#define WF_SCENE_ARG_NAME(T, name) name,

/// The reservoir path i's vertex at `depth` reads (sample_reservoir): at depth 0 only. Uses the
/// kernel's arguments reservoirs, reservoir_mode (RESERVOIR_MODE_*; 0: none) and reservoir_spp.
#define WF_RESERVOIR()                                                                             \
    depth == 0u ? sample_reservoir(reservoirs, reservoir_mode, reservoir_spp, i, rp.sample_begin)  \
                : no_reservoir()
/// Whether that reservoir was served, so that wf_shade_general shades the vertex (wf_general_hit).
#if RESTIR
#define WF_SERVED()                                                                                \
    (depth == 0u && reservoir_mode != 0u &&                                                        \
     reservoirs[i * reservoir_spp + rp.sample_begin].prim != HIT_NONE)
#else
#define WF_SERVED() ((void)reservoirs, (void)reservoir_mode, (void)reservoir_spp, 0)
#endif

/// Stage 3 of the primal path (wf_shade_path).
__kernel void wf_shade(SCENE_ARGS RenderParams rp, __global const float* params,
                       __global float* state, __global uint* ustate, uint n, uint depth,
                       __global const uint* live, uint count,
                       __global const Reservoir* reservoirs, uint reservoir_mode,
                       uint reservoir_spp) {
    WF_LIVE_PATH();
    wf_shade_path(TANDEM_SCENE_ARGS(WF_SCENE_ARG_NAME, WF_SCENE_ARG_NAME) rp, params, params,
                  WF_MODE_PRIMAL, state, ustate, n, depth, i, WF_SERVED());
}

/// Stage 3 of the two-state path (wf_shade_path; kernels/render.cl: render_two_state).
__kernel void wf_shade_two_state(SCENE_ARGS RenderParams rp, __global const float* params,
                                 __global const float* params_old, __global float* state,
                                 __global uint* ustate, uint n, uint depth,
                                 __global const uint* live, uint count) {
    WF_LIVE_PATH();
    wf_shade_path(TANDEM_SCENE_ARGS(WF_SCENE_ARG_NAME, WF_SCENE_ARG_NAME) rp, params, params_old,
                  WF_MODE_TWO_STATE, state, ustate, n, depth, i, 0);
}

/// Stage 3 of the PRB replay (wf_shade_path; kernels/adjoint.cl: adjoint_pass).
__kernel void wf_shade_replay(SCENE_ARGS RenderParams rp, __global const float* params,
                              __global float* state, __global uint* ustate, uint n, uint depth,
                              __global const uint* live, uint count,
                              __global const Reservoir* reservoirs, uint reservoir_mode,
                              uint reservoir_spp) {
    WF_LIVE_PATH();
    wf_shade_path(TANDEM_SCENE_ARGS(WF_SCENE_ARG_NAME, WF_SCENE_ARG_NAME) rp, params, params,
                  WF_MODE_REPLAY, state, ustate, n, depth, i, WF_SERVED());
}

#if WF_GENERAL
/// Stage 3 for a path whose ray found a surface wf_shade_path leaves alone (wf_general_hit): the
/// vertex as the megakernels compute it, with their own per-vertex functions, one path per work
/// item. `mode` as wf_shade_path's: path_primal_vertex, path_two_state_vertex or
/// path_replay_vertex (its derivatives into grad, saturated contributions counted in guards),
/// path_primal_vertex and path_replay_vertex reading the primary vertex's light sample from `pr`
/// where it has one (the two-state vertex takes none). Those trace
/// the light sample's shadow ray themselves (unless the reservoir's sample is known visible) and
/// add its term at once, after the emission's; the state is left as wf_shade_path leaves it, with
/// no light sample pending.
TANDEM_INLINE void wf_shade_general_path(const SceneRefs* s, __global const float* params,
                                         __global const float* params_old, const int mode,
                                         __global float* state, __global uint* ustate, uint n,
                                         uint depth, uint i, PrimaryReservoir pr,
                                         __global const uint* active, __global uint* grad,
                                         __global uint* guards) {
    const int two_state = mode == WF_MODE_TWO_STATE;
    const PathRng rng = path_rng(s->rp->seed, i, s->rp->sample_begin);
    Ray ray = make_ray(make_float3(WF_F(WF_OX), WF_F(WF_OX + 1u), WF_F(WF_OX + 2u)),
                       make_float3(WF_F(WF_DX), WF_F(WF_DX + 1u), WF_F(WF_DX + 2u)),
                       WF_F(WF_TMIN), WF_F(WF_TMAX));
    Hit hit;
    hit.t = WF_F(WF_HIT_T);
    hit.u = WF_F(WF_HIT_U);
    hit.v = WF_F(WF_HIT_V);
    hit.prim = WF_U(WF_PRIM);
    float3 beta = make_float3(WF_F(WF_BETA), WF_F(WF_BETA + 1u), WF_F(WF_BETA + 2u));
    TwoStateRadiance r; // r.L: the radiance so far, or the replay's L_rem
    r.L = make_float3(WF_F(WF_L), WF_F(WF_L + 1u), WF_F(WF_L + 2u));
    r.L_old = r.L;
    float3 beta_old = beta;
    if (two_state) {
        beta_old = make_float3(WF_F(WF_BETA_OLD), WF_F(WF_BETA_OLD + 1u), WF_F(WF_BETA_OLD + 2u));
        r.L_old = make_float3(WF_F(WF_L_OLD), WF_F(WF_L_OLD + 1u), WF_F(WF_L_OLD + 2u));
    }
    float prev_bsdf_pdf = WF_F(WF_PREV_PDF);
    int alive;
    if (mode == WF_MODE_PRIMAL) {
        alive = path_primal_vertex(s, params, rng, depth, hit, pr, &ray, &beta, &r.L,
                                   &prev_bsdf_pdf, 0);
    } else if (two_state) {
        alive = path_two_state_vertex(s, params, params_old, rng, depth, hit, &ray, &beta,
                                      &beta_old, &r, &prev_bsdf_pdf);
    } else {
        Adjoint adj;
        adj.grad = grad;
        adj.active = active;
        adj.delta = make_float3(WF_F(WF_DELTA), WF_F(WF_DELTA + 1u), WF_F(WF_DELTA + 2u));
        adj.L_rem = r.L;
        adj.saturated = 0u;
#if SHAPE_GRAD
        adj.shape = shape_vertex_none(); // (the adjoint of moving shapes runs the megakernels)
#endif
        alive = path_replay_vertex(s, params, rng, depth, hit, pr, &adj, &ray, &beta,
                                   &prev_bsdf_pdf, 0);
        r.L = adj.L_rem;
        if (adj.saturated) guards[i] += adj.saturated;
    }
    WF_SET3(WF_L, r.L.x, r.L.y, r.L.z);
    if (two_state) {
        WF_SET3(WF_L_OLD, r.L_old.x, r.L_old.y, r.L_old.z);
    }
    if (alive) {
        WF_SET3(WF_OX, ray.org.x, ray.org.y, ray.org.z);
        WF_SET3(WF_DX, ray.dir.x, ray.dir.y, ray.dir.z);
        WF_F(WF_TMIN) = ray.org.w;
        WF_F(WF_TMAX) = ray.dir.w;
        WF_SET3(WF_BETA, beta.x, beta.y, beta.z);
        if (two_state) {
            WF_SET3(WF_BETA_OLD, beta_old.x, beta_old.y, beta_old.z);
        }
        WF_F(WF_PREV_PDF) = prev_bsdf_pdf;
    }
    WF_U(WF_FLAGS) = alive ? WF_ALIVE : 0u;
}

/// Stage 3b of the primal path: the live paths wf_shade left alone (wf_general_hit). The
/// adjoint's first pass (adjoint_primal) passes its reservoirs (RESERVOIR_MODE_*; mode 0: none).
__kernel void wf_shade_general(SCENE_ARGS RenderParams rp, __global const float* params,
                               __global float* state, __global uint* ustate, uint n, uint depth,
                               __global const uint* live, uint count,
                               __global const Reservoir* reservoirs, uint reservoir_mode,
                               uint reservoir_spp) {
    const SceneRefs s = SCENE_REFS(rp);
    WF_LIVE_PATH();
    if (!wf_general_hit(infos, materials, normals, WF_U(WF_PRIM), depth, WF_SERVED())) return;
    wf_shade_general_path(&s, params, params, WF_MODE_PRIMAL, state, ustate, n, depth, i,
                          WF_RESERVOIR(), 0, 0, 0);
}

/// Stage 3b of the two-state path.
__kernel void wf_shade_general_two_state(SCENE_ARGS RenderParams rp, __global const float* params,
                                         __global const float* params_old, __global float* state,
                                         __global uint* ustate, uint n, uint depth,
                                         __global const uint* live, uint count) {
    const SceneRefs s = SCENE_REFS(rp);
    WF_LIVE_PATH();
    if (!wf_general_hit(infos, materials, normals, WF_U(WF_PRIM), depth, 0)) return;
    wf_shade_general_path(&s, params, params_old, WF_MODE_TWO_STATE, state, ustate, n, depth, i,
                          no_reservoir(), 0, 0, 0);
}

/// Stage 3b of the PRB replay (adjoint_pass), with the first pass' reservoirs.
__kernel void wf_shade_general_replay(SCENE_ARGS RenderParams rp, __global const float* params,
                                      __global float* state, __global uint* ustate, uint n,
                                      uint depth, __global const uint* live, uint count,
                                      __global const Reservoir* reservoirs, uint reservoir_mode,
                                      uint reservoir_spp, __global const uint* active,
                                      __global uint* grad, __global uint* guards) {
    const SceneRefs s = SCENE_REFS(rp);
    WF_LIVE_PATH();
    if (!wf_general_hit(infos, materials, normals, WF_U(WF_PRIM), depth, WF_SERVED())) return;
    wf_shade_general_path(&s, params, params, WF_MODE_REPLAY, state, ustate, n, depth, i,
                          WF_RESERVOIR(), active, grad, guards);
}
#endif

/// The shadow ray wf_shade left for path i, unoccluded.
TANDEM_INLINE int wf_shadow_unoccluded(const SceneRefs* s, __global const float* state, uint n,
                                       uint i) {
    const Ray ray =
        make_ray(make_float3(WF_F(WF_SHADOW_O), WF_F(WF_SHADOW_O + 1u), WF_F(WF_SHADOW_O + 2u)),
                 make_float3(WF_F(WF_SHADOW_D), WF_F(WF_SHADOW_D + 1u), WF_F(WF_SHADOW_D + 2u)),
                 0.0f, WF_F(WF_SHADOW_TMAX));
    return !trace_any(s, ray);
}

/// Stage 4, every bounce: the shadow rays wf_shade left; an unoccluded one adds its term to L.
/// Whether it was is recorded in `seen` at `slot` (unless WF_NO_RECORD).
__kernel void wf_shadow(SCENE_ARGS RenderParams rp, __global float* state, __global uint* ustate,
                        uint n, __global const uint* live, uint count, uint two_state,
                        __global uint* seen, uint slot) {
    const SceneRefs s = SCENE_REFS(rp);
    WF_LIVE_PATH();
    if (!(WF_U(WF_FLAGS) & WF_SHADOW)) return;
    const int unoccluded = wf_shadow_unoccluded(&s, state, n, i);
    if (slot != WF_NO_RECORD) seen[slot * n + i] = (uint)unoccluded;
    if (!unoccluded) return;
    for (uint c = 0; c < 3u; ++c) WF_F(WF_L + c) = WF_F(WF_L + c) + WF_F(WF_CONTRIB + c);
    if (two_state)
        for (uint c = 0; c < 3u; ++c)
            WF_F(WF_L_OLD + c) = WF_F(WF_L_OLD + c) + WF_F(WF_CONTRIB_OLD + c);
}

/// Stage 4 of the PRB replay, every bounce: the vertex's shadow ray (or, for a bounce the first
/// pass recorded, `seen` at `slot`), then its derivatives into
/// the gradients, as path_replay pushes them (path/adjoint.h): the emission's; the light sample's
/// where it is unoccluded, whose term then leaves L_rem; the continuation's, through what remains
/// in L_rem; the albedo's (its parameter or texels) once for the vertex. Saturated contributions
/// count in guards[i]. The atomics of the gradient sums keep this stage one path per instruction,
/// as the traversal does; wf_shade_replay, vectorised, computed everything else.
__kernel void wf_replay_shadow(SCENE_ARGS RenderParams rp, __global const float* params,
                               __global float* state, __global uint* ustate, uint n,
                               __global const uint* live, uint count,
                               __global const uint* seen, uint slot,
                               __global const uint* active, __global uint* grad,
                               __global uint* guards) {
    const SceneRefs s = SCENE_REFS(rp);
    WF_LIVE_PATH();
    const uint flags = WF_U(WF_FLAGS);
    if (!(flags & (WF_SHADOW | WF_EMITTED | WF_SHADED))) return;
    Adjoint adj;
    adj.grad = grad;
    adj.active = active;
    adj.delta = make_float3(WF_F(WF_DELTA), WF_F(WF_DELTA + 1u), WF_F(WF_DELTA + 2u));
    adj.L_rem = make_float3(WF_F(WF_L), WF_F(WF_L + 1u), WF_F(WF_L + 2u));
    adj.saturated = 0u;
#if SHAPE_GRAD
    adj.shape = shape_vertex_none();
#endif
    if (flags & WF_EMITTED)
        grad_add_rgb(&adj, WF_U(WF_EMIT_PARAM),
                     make_float3(WF_F(WF_GRAD_EMIT), WF_F(WF_GRAD_EMIT + 1u),
                                 WF_F(WF_GRAD_EMIT + 2u)));
    BsdfGrad acc = bsdf_grad_zero();
    if (flags & WF_SHADOW) {
        if (slot != WF_NO_RECORD ? seen[slot * n + i] != 0u
                                 : wf_shadow_unoccluded(&s, state, n, i)) {
            if (WF_U(WF_LIGHT_PARAM) != NO_PARAM) // not an environment map's
                grad_add_rgb(&adj, WF_U(WF_LIGHT_PARAM),
                             make_float3(WF_F(WF_GRAD_LIGHT), WF_F(WF_GRAD_LIGHT + 1u),
                                         WF_F(WF_GRAD_LIGHT + 2u)));
            material_grad_add(&acc, diffuse_albedo_grad(WF_F(WF_NEE_G)),
                              make_float3(WF_F(WF_GRAD_NEE), WF_F(WF_GRAD_NEE + 1u),
                                          WF_F(WF_GRAD_NEE + 2u)));
            adj.L_rem -= make_float3(WF_F(WF_CONTRIB), WF_F(WF_CONTRIB + 1u),
                                     WF_F(WF_CONTRIB + 2u));
        }
    }
    if (flags & WF_CONTINUED) {
        const float3 f = make_float3(WF_F(WF_CONT_F), WF_F(WF_CONT_F + 1u), WF_F(WF_CONT_F + 2u));
        material_grad_add(&acc, diffuse_albedo_grad(WF_F(WF_CONT_G)),
                          adjoint_continuation_k3(adj.delta, adj.L_rem, f));
    }
    if (flags & WF_SHADED) { // interaction_albedo_source, grad_material
        Interaction it;
        it.mat = material_load(&s, params, WF_U(WF_MATERIAL));
#if HAS_TEXTURES
        it.tu = WF_F(WF_TU);
        it.tv = WF_F(WF_TV);
#endif
        AlbedoSource src;
        interaction_albedo_source(&s, &it, &src);
        grad_material(&adj, &it.mat, &src, &acc);
    }
    WF_SET3(WF_L, adj.L_rem.x, adj.L_rem.y, adj.L_rem.z);
    if (adj.saturated) guards[i] += adj.saturated;
}

/// Stage 5, once per wave: each path's radiance into its pixel's sums, as render_pass adds it.
__kernel void wf_accumulate(__global const float* state, __global float4* accum,
                            __global uint* guards, uint n) {
    const uint i = get_global_id(0);
    if (i >= n) return;
    const float3 L = make_float3(WF_F(WF_L), WF_F(WF_L + 1u), WF_F(WF_L + 2u));
    accum[i] = add_sample(accum[i], L);
    if (!all_finite(L)) ++guards[i];
}

/// Stage 5 of the two-state path: both radiances into their pixel's sums, as render_two_state
/// adds them (a sample non-finite in either state is dropped from both).
__kernel void wf_accumulate_two_state(__global const float* state, __global float4* accum,
                                      __global float4* accum_old, __global uint* guards, uint n) {
    const uint i = get_global_id(0);
    if (i >= n) return;
    const float3 L = make_float3(WF_F(WF_L), WF_F(WF_L + 1u), WF_F(WF_L + 2u));
    const float3 L_old = make_float3(WF_F(WF_L_OLD), WF_F(WF_L_OLD + 1u), WF_F(WF_L_OLD + 2u));
    float4 sum = accum[i], sum_old = accum_old[i];
    if (!add_sample_two_state(&sum, &sum_old, L, L_old)) ++guards[i];
    accum[i] = sum;
    accum_old[i] = sum_old;
}

/// Whether pixel i's delta is zero, where the adjoint's first pass has nothing to do (as
/// adjoint_primal tests it).
TANDEM_INLINE int wf_delta_zero(__global const float* delta, uint i) {
    return delta[3u * i] == 0.0f && delta[3u * i + 1u] == 0.0f && delta[3u * i + 2u] == 0.0f;
}

/// Stage 5 of the adjoint's first pass (adjoint_primal's result, kernels/adjoint.cl):
/// radiance[k n + i] = L of the wave's path i, where delta is not zero (adjoint_pass reads
/// nothing elsewhere).
__kernel void wf_store_radiance(__global const float* state, __global const float* delta,
                                __global float4* radiance, uint k, uint n) {
    const uint i = get_global_id(0);
    if (i >= n) return;
    if (wf_delta_zero(delta, i)) return;
    radiance[k * n + i] = (float4)(WF_F(WF_L), WF_F(WF_L + 1u), WF_F(WF_L + 2u), 0.0f);
}

/// After wf_generate, for the PRB replay of sample k of the launch (kernels/adjoint.cl:
/// adjoint_pass, whose arguments these are): each path's adjoint d = delta 2^s / spp and L_rem = its
/// primal radiance radiance[k n + i]. A pixel whose d is zero has nothing to propagate; a
/// non-finite radiance was dropped by the primal, so its gradient is too (one count in guards).
__kernel void wf_replay_begin(__global const float* delta, float inv_spp,
                              __global const int* exponent, __global const float4* radiance,
                              uint k, __global float* state, __global uint* ustate,
                              __global uint* guards, uint n) {
    const uint i = get_global_id(0);
    if (i >= n) return;
    const float scale = grad_pow2(exponent[0]);
    const float3 d = make_float3(delta[3u * i] * scale, delta[3u * i + 1u] * scale,
                                 delta[3u * i + 2u] * scale) *
                     inv_spp;
    if (d.x == 0.0f && d.y == 0.0f && d.z == 0.0f) {
        WF_U(WF_FLAGS) = 0u;
        return;
    }
    const float3 L = radiance[k * n + i].xyz;
    if (!all_finite(L)) {
        ++guards[i];
        WF_U(WF_FLAGS) = 0u;
        return;
    }
    WF_SET3(WF_DELTA, d.x, d.y, d.z);
    WF_SET3(WF_L, L.x, L.y, L.z);
}

/// After wf_generate, for the adjoint's first pass: the paths of pixels whose delta is zero end
/// before they start (adjoint_primal skips those pixels).
__kernel void wf_skip_zero_delta(__global const float* delta, __global uint* ustate, uint n) {
    const uint i = get_global_id(0);
    if (i >= n) return;
    if (wf_delta_zero(delta, i)) WF_U(WF_FLAGS) = 0u;
}

/// The live list, step 1: counts[j] = the paths of [j chunk, (j + 1) chunk) that are alive.
__kernel void wf_live_counts(__global const uint* ustate, __global uint* counts, uint chunk,
                             uint n) {
    const uint j = get_global_id(0);
    const uint begin = j * chunk;
    if (begin >= n) return;
    const uint end = min(begin + chunk, n);
    uint c = 0u;
    for (uint i = begin; i < end; ++i) c += ustate[WF_FLAGS * n + i] & WF_ALIVE;
    counts[j] = c;
}

/// Step 2, one work item: offsets[j] = counts[0] + ... + counts[j - 1], and total[0] = the sum of
/// all `chunks` (the host reads it: the bounce's launch size, 0 when the wave is done).
__kernel void wf_live_offsets(__global const uint* counts, uint chunks, __global uint* offsets,
                              __global uint* total) {
    if (get_global_id(0) != 0u) return;
    uint sum = 0u;
    for (uint j = 0; j < chunks; ++j) {
        offsets[j] = sum;
        sum += counts[j];
    }
    total[0] = sum;
}

/// Step 3: the live paths of chunk j into live[offsets[j]...], in increasing order. The list, and
/// so which work item takes which path, depends only on the flags: no atomics.
__kernel void wf_live_list(__global const uint* ustate, __global const uint* offsets,
                           __global uint* live, uint chunk, uint n) {
    const uint j = get_global_id(0);
    const uint begin = j * chunk;
    if (begin >= n) return;
    const uint end = min(begin + chunk, n);
    uint k = offsets[j];
    for (uint i = begin; i < end; ++i)
        if (ustate[WF_FLAGS * n + i] & WF_ALIVE) live[k++] = i;
}
