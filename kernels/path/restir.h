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

/// How a path reads its reservoir (PrimaryReservoir::mode). The adjoint kernels take the mode and
/// the reservoirs' share of direct light (RESTIR_DIRECT_*, shared/reservoir.h) in one word:
/// mode | direct << RESERVOIR_DIRECT_SHIFT.
#define RESERVOIR_MODE_VISIBLE 1u ///< W > 0 implies an unoccluded sample (resampled with rays)
#define RESERVOIR_MODE_TRACE 2u   ///< resampled without visibility: the path traces the shadow ray
#define RESERVOIR_MODE_MASK 3u
#define RESERVOIR_DIRECT_SHIFT 2u

/// The reservoir of a path's sample slot, or none (slot 0: the path samples NEE itself).
typedef struct PrimaryReservoir {
    __global const Reservoir* slot;
    uint mode;
    uint direct; ///< RESTIR_DIRECT_*: the share of direct light the reservoir estimates
} PrimaryReservoir;

TANDEM_INLINE PrimaryReservoir no_reservoir(void) {
    PrimaryReservoir pr;
    pr.slot = 0;
    pr.mode = 0u;
    pr.direct = RESTIR_DIRECT_MIS;
    return pr;
}

/// The reservoir of sample `sample` of `pixel` in `reservoirs` (spp slots per pixel, pixel-major;
/// kernels/restir.cl), read as `mode` (RESERVOIR_MODE_* | RESTIR_DIRECT_* <<
/// RESERVOIR_DIRECT_SHIFT); none where mode is 0 or the build has no RESTIR.
TANDEM_INLINE PrimaryReservoir sample_reservoir(__global const Reservoir* reservoirs, uint mode,
                                                uint spp, uint pixel, uint sample) {
    PrimaryReservoir pr = no_reservoir();
#if RESTIR
    if (mode != 0u) {
        pr.slot = reservoirs + (pixel * spp + sample);
        pr.mode = mode & RESERVOIR_MODE_MASK;
        pr.direct = mode >> RESERVOIR_DIRECT_SHIFT;
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

/// Whether a reservoir at the shaded point `it` estimates all of its direct light that NEE can
/// sample, rather than NEE's MIS share (`direct`: RESTIR_DIRECT_*). A function of the point alone,
/// so that the resampling pass (its targets, at every domain's own point) and the path (its term
/// and the next vertex's emission weight, restir_next_pdf) split direct light the same way.
TANDEM_INLINE int restir_takes_all(uint direct, const Interaction* it) {
    return direct == RESTIR_DIRECT_ALL ||
           (direct == RESTIR_DIRECT_AUTO && it->mat.type == MATERIAL_DIFFUSE);
}

/// The weight w_L of light sample ls at `it` in a reservoir's integrand: NEE's MIS weight, or 1
/// where the reservoir takes all of the direct light (restir_takes_all).
TANDEM_INLINE float restir_light_weight(uint direct, const Interaction* it, const LightSample* ls,
                                        const NeeEval* ev) {
    return restir_takes_all(direct, it) ? 1.0f : nee_light_weight(it, ls, ev);
}

/// Whether the vertex at `depth` takes its NEE term from a reservoir (path_nee_term).
TANDEM_INLINE int path_served(PrimaryReservoir pr, uint depth) {
#if RESTIR
    return depth == 0u && pr.slot && pr.slot->prim != HIT_NONE;
#else
    (void)pr;
    (void)depth;
    return 0;
#endif
}

/// Whether reservoir r was resampled at the path's own shading point `it` (the pass traces the
/// same camera ray, so always; a slot of another point is read as empty should it not be).
TANDEM_INLINE int reservoir_is_at(const Reservoir* r, const Interaction* it) {
    return r->prim == it->hit.prim && r->b1 == it->hit.u && r->b2 == it->hit.v;
}

/// The density the next vertex's emission weight reads (prev_bsdf_pdf) after the vertex at
/// `depth`, shaded as `it`, sampled its continuation with density `pdf`. Where that vertex's
/// reservoir took all of its direct light, emission found by the BSDF sample is NEE's already
/// (EMISSION_AFTER_NEE_ALL, path/emission.h); a delta lobe's (pdf inf) never is.
TANDEM_INLINE float restir_next_pdf(PrimaryReservoir pr, uint depth, const Interaction* it,
                                    float pdf) {
#if RESTIR
    // a slot of another shading point estimates its NEE term as 0 (restir_nee_term), and the
    // BSDF keeps its share
    if (path_served(pr, depth) && restir_takes_all(pr.direct, it) && pdf != INFINITY) {
        const Reservoir r = *pr.slot;
        if (reservoir_is_at(&r, it)) return EMISSION_AFTER_NEE_ALL;
    }
#else
    (void)pr;
    (void)depth;
    (void)it;
#endif
    return pdf;
}

/// The depth-0 NEE term of a path read from its reservoir: the sample (light, u1, u2) decoded at
/// the path's own shading point, weighted by the reservoir's contribution weight W. Returns 1 and
/// sets ls, ev and w (the term is beta f Le w, as nee_weight's) where it contributes. A shadow ray
/// it traces goes through `rec` (nee_visible).
TANDEM_INLINE int restir_nee_term(const SceneRefs* s, __global const float* params,
                                  const Interaction* it, PrimaryReservoir pr, LightSample* ls,
                                  NeeEval* ev, float* w, PathRecord* rec) {
    const Reservoir r = *pr.slot;
    // an empty slot estimates 0, and so does one of another shading point (reservoir_is_at)
    if (reservoir_is_empty(&r) || !(r.W > 0.0f) || !reservoir_is_at(&r, it)) return 0;
    *ls = nee_decode_light(s, params, it->origin, r.light, r.u1, r.u2);
    *ev = nee_eval(it, ls);
    if (!(ls->pdf > 0.0f && ls->G > 0.0f && max_component(ev->f) > 0.0f)) return 0;
    if (pr.mode == RESERVOIR_MODE_TRACE && !nee_visible(s, it->origin, ls, 0u, rec)) return 0;
    *w = restir_light_weight(pr.direct, it, ls, ev) * ls->G * r.W;
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
    if (path_served(pr, depth)) return restir_nee_term(s, params, it, pr, ls, ev, w, rec);
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
