// Light-sample reuse at the primary vertex of the adjoint's paths ("Amortizing Samples in
// Physics-Based Inverse Rendering using ReSTIR", Wang, Wyman, Wu, Zhao, SIGGRAPH Asia 2023, Sec. 4;
// docs/restir.md): the NEE term a path takes from its slot's reservoir instead of drawing a light
// sample (the reservoirs themselves: kernels/restir.cl). Built with
// RESTIR=1 only; with RESTIR=0 every path samples NEE as before, bit for bit.
#ifndef TANDEM_KERNELS_PATH_RESTIR_H
#define TANDEM_KERNELS_PATH_RESTIR_H

#include "path/nee.h"

#ifndef RESTIR
#error "RESTIR must be passed as 0 or 1"
#endif

/// How a path reads its reservoir (PrimaryReservoir::mode).
#define RESERVOIR_MODE_VISIBLE 1u ///< W > 0 implies an unoccluded sample (resampled with rays)
#define RESERVOIR_MODE_TRACE 2u   ///< resampled without visibility: the path traces the shadow ray

/// The reservoir of a path's sample slot, or none (slot 0: the path samples NEE itself).
typedef struct PrimaryReservoir {
    __global const Reservoir* slot;
    uint mode;
} PrimaryReservoir;

TANDEM_INLINE PrimaryReservoir no_reservoir(void) {
    PrimaryReservoir pr;
    pr.slot = 0;
    pr.mode = 0u;
    return pr;
}

/// The reservoir of sample `sample` of `pixel` in `reservoirs` (spp slots per pixel, pixel-major;
/// kernels/restir.cl), read as `mode` (RESERVOIR_MODE_*); none where mode is 0 or the build has no
/// RESTIR.
TANDEM_INLINE PrimaryReservoir sample_reservoir(__global const Reservoir* reservoirs, uint mode,
                                                uint spp, uint pixel, uint sample) {
    PrimaryReservoir pr = no_reservoir();
#if RESTIR
    if (mode != 0u) {
        pr.slot = reservoirs + (pixel * spp + sample);
        pr.mode = mode;
    }
#else
    (void)reservoirs;
    (void)mode;
    (void)spp;
    (void)pixel;
    (void)sample;
#endif
    return pr;
}

/// The depth-0 NEE term of a path read from its reservoir: the sample (light, u1, u2) decoded at
/// the path's own shading point, weighted by the reservoir's contribution weight W. Returns 1 and
/// sets ls, ev and w (the term is beta f Le w, as nee_weight's) where it contributes. A shadow ray
/// it traces goes through `rec` (nee_visible).
TANDEM_INLINE int restir_nee_term(const SceneRefs* s, __global const float* params,
                                  const Interaction* it, PrimaryReservoir pr, LightSample* ls,
                                  NeeEval* ev, float* w, PathRecord* rec) {
    const Reservoir r = *pr.slot;
    // an empty slot estimates 0; a slot of another shading point cannot happen (the resampling
    // pass traces the same camera ray), and is read as empty should it
    if (reservoir_is_empty(&r) || !(r.W > 0.0f) || r.prim != it->hit.prim || r.b1 != it->hit.u ||
        r.b2 != it->hit.v)
        return 0;
    *ls = nee_decode_light(s, params, it->origin, r.light, r.u1, r.u2);
    *ev = nee_eval(it, ls);
    if (!(ls->pdf > 0.0f && ls->G > 0.0f && max_component(ev->f) > 0.0f)) return 0;
    if (pr.mode == RESERVOIR_MODE_TRACE && !nee_visible(s, it->origin, ls, 0u, rec)) return 0;
    *w = nee_light_weight(it, ls, ev) * ls->G * r.W;
    return 1;
}

/// The NEE term of the path vertex at `depth` (random numbers `vr`): from the reservoir at depth
/// 0 when there is one, else NEE's own light sample. Returns 1 and sets ls, ev and w (the term is
/// beta f Le w) where the term is not zero. Its shadow ray goes through `rec` (nee_visible; 0:
/// traced, nothing recorded).
TANDEM_INLINE int path_nee_term(const SceneRefs* s, __global const float* params,
                                const Interaction* it, VertexRandom vr, uint depth,
                                PrimaryReservoir pr, LightSample* ls, NeeEval* ev, float* w,
                                PathRecord* rec) {
#if RESTIR
    // a slot the pass left without a shading point (restir_serves) takes NEE's own sample
    if (depth == 0u && pr.slot && pr.slot->prim != HIT_NONE)
        return restir_nee_term(s, params, it, pr, ls, ev, w, rec);
#else
    (void)pr;
#endif
    *ls = nee_sample(s, params, it->origin, vr);
    *ev = nee_eval(it, ls);
    if (!(ls->pdf > 0.0f && max_component(ev->f) > 0.0f &&
          nee_visible(s, it->origin, ls, depth, rec)))
        return 0;
    *w = nee_weight(it, ls, ev);
    return 1;
}

#endif // TANDEM_KERNELS_PATH_RESTIR_H
