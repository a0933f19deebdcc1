// The adjoint of one path for Path Replay Backpropagation ("Path Replay Backpropagation:
// Differentiating Light Paths using Constant Memory and Linear Time", Vicini, Speierer, Jakob,
// SIGGRAPH 2021, Sec. 4; docs/method.md, "Path Replay Backpropagation"): the derivative each term
// of the path pushes into the parameter gradients, accumulated in fixed point. Every contribution
// is linear in delta, so scaling delta by 2^s scales them all exactly (shared/fixed_point.h).
#ifndef TANDEM_KERNELS_PATH_ADJOINT_H
#define TANDEM_KERNELS_PATH_ADJOINT_H

#include "path/continuation.h"
#include "path/nee.h"
#include "shared/bsdf_grad.h"
#include "shared/fixed_point.h"

#if SHAPE_GRAD
/// The moving vertex of a path whose shape derivatives are being gathered (path/shape_adjoint.h).
typedef struct ShapeVertex {
    uint prim;   ///< its triangle, or NO_PARAM: no moving vertex pending
    float u, v;  ///< its hit coordinates (barycentric weights 1 - u - v, u, v)
    float3 x;    ///< its position
    float3 n;    ///< the normal on its shading side (frame.n)
    float3 n_g;  ///< its triangle's own unit normal (n_front: the plane it slides in)
    float3 d;    ///< the unit direction of the ray that found it
    float3 g_x;  ///< delta . d(terms)/dx gathered so far
    float3 g_n;  ///< delta . d(terms)/dn gathered so far
    float3 g_wo; ///< delta . d(continuation term)/d(its direction) through a glossy BSDF
    float g_tu, g_tv; ///< delta . d(terms)/d(texture coordinates) through its albedo
} ShapeVertex;
#endif

/// What the replay of one path carries: the adjoint of its radiance, the radiance not yet
/// accounted for, and where gradients go (fixed-point sums, shared/fixed_point.h).
typedef struct Adjoint {
    __global uint* grad; ///< GRAD_WORDS words per parameter element
    /// one bit per element: only those set are differentiated (0: all of them)
    __global const uint* active;
    float3 delta;        ///< dloss / d(this sample's radiance), per channel, times 2^s
    float3 L_rem;        ///< the primal radiance minus the terms replayed so far
    uint saturated;      ///< contributions clamped or dropped (shared/fixed_point.h)
#if SHAPE_GRAD
    ShapeVertex shape;   ///< the moving vertex whose continuation term is pending
#endif
} Adjoint;

/// Adds v, a contribution already scaled by 2^s (delta carries the scale), to element `index`.
static inline void grad_add(Adjoint* a, uint index, float v) {
    if (v == 0.0f) return;
    if (a->active && ((a->active[index >> 5u] >> (index & 31u)) & 1u) == 0u) return;
    if (!(fabs(v) <= GRAD_MAX_CONTRIBUTION)) {
        ++a->saturated;
        if (!isfinite(v)) return;
        v = v > 0.0f ? GRAD_MAX_CONTRIBUTION : -GRAD_MAX_CONTRIBUTION;
    }
    fixed_add(a->grad + GRAD_WORDS * index, fixed_encode(v));
}

static inline void grad_add_rgb(Adjoint* a, uint offset, float3 v) {
    grad_add(a, offset, v.x);
    grad_add(a, offset + 1u, v.y);
    grad_add(a, offset + 2u, v.z);
}

/// Adds k * d(f cos)/d(theta) to acc, the derivatives a vertex gathers for its material's
/// parameters, per channel (k = delta times the term's radiance over f cos).
TANDEM_INLINE void material_grad_add(BsdfGrad* acc, BsdfGrad g, float3 k) {
    acc->d_albedo += k * g.d_albedo;
    acc->d_specular += k * g.d_specular;
    acc->d_alpha += k * g.d_alpha;
}

/// Pushes a vertex's gathered material derivatives (material_grad_add) into the gradients, once
/// per vertex: its NEE and BSDF-sampled terms read the same texels with the same weights, and one
/// atomic add per element instead of two halves the adds that contend for the same texels.
static inline void grad_material(Adjoint* a, const Material* m, const AlbedoSource* src,
                                 const BsdfGrad* acc) {
    if (src->param != NO_PARAM) grad_add_rgb(a, src->param, acc->d_albedo);
    if (src->texel_param != NO_PARAM)
        for (uint i = 0; i < src->count; ++i)
            grad_add_rgb(a, src->texel_param + 3u * src->index[i], acc->d_albedo * src->weight[i]);
    if (m->specular_param != NO_PARAM) grad_add_rgb(a, m->specular_param, acc->d_specular);
    if (m->alpha_param != NO_PARAM)
        grad_add(a, m->alpha_param, acc->d_alpha.x + acc->d_alpha.y + acc->d_alpha.z);
}

// The replay's terms, one channel each (the one definition: the megakernels' adjoint_* below
// apply them to float3 channels, the wavefront to its scalars). delta: the adjoint of the path's
// radiance; every derivative is linear in it.

/// d(beta Le w)/d(Le) of the emission term, times delta.
TANDEM_INLINE float adjoint_emission_channel(float delta, float beta, float w) {
    return delta * beta * w;
}

/// d(beta f Le w)/d(Le) of a light sample's term, times delta.
TANDEM_INLINE float adjoint_nee_light_channel(float delta, float beta, float f, float w) {
    return delta * beta * f * w;
}

/// delta beta Le w: what d(f cos)/d(theta) is multiplied by in the derivative of a light sample's
/// term (material_grad_add).
TANDEM_INLINE float adjoint_nee_k(float delta, float beta, float Le, float w) {
    return delta * beta * Le * w;
}

/// delta L_rem / f: what d(f cos)/d(theta) of the BSDF sample's direction is multiplied by, with
/// L_rem the radiance that arrived through it (0 where f is: safe_div).
TANDEM_INLINE float adjoint_continuation_k(float delta, float L_rem, float f) {
    return safe_div(delta * L_rem, f);
}

/// Emission term beta * Le * w: d/d(Le) into Le's parameter, if it is one.
TANDEM_INLINE void adjoint_emission(Adjoint* a, const Emission* e, float3 beta) {
    if (e->param != NO_PARAM)
        grad_add_rgb(a, e->param,
                     make_float3(adjoint_emission_channel(a->delta.x, beta.x, e->w),
                                 adjoint_emission_channel(a->delta.y, beta.y, e->w),
                                 adjoint_emission_channel(a->delta.z, beta.z, e->w)));
}

/// NEE term beta * f * Le * w_over_pdf (ls evaluated at `it` as ev): d/d(material) through f into
/// the vertex's acc, d/d(Le) through the light's parameter.
TANDEM_INLINE void adjoint_nee(Adjoint* a, BsdfGrad* acc, const Interaction* it,
                               const LightSample* ls, const NeeEval* ev, float3 beta,
                               float w_over_pdf) {
    const float3 d = a->delta;
    const float3 k = make_float3(adjoint_nee_k(d.x, beta.x, ls->Le.x, w_over_pdf),
                                 adjoint_nee_k(d.y, beta.y, ls->Le.y, w_over_pdf),
                                 adjoint_nee_k(d.z, beta.z, ls->Le.z, w_over_pdf));
    material_grad_add(
        acc, bsdf_eval_grad(it->plastic_tables, &it->mat, it->albedo, it->wi_local, ev->wo_local), k);
    if (ls->Le_param != NO_PARAM)
        grad_add_rgb(a, ls->Le_param,
                     make_float3(adjoint_nee_light_channel(d.x, beta.x, ev->f.x, w_over_pdf),
                                 adjoint_nee_light_channel(d.y, beta.y, ev->f.y, w_over_pdf),
                                 adjoint_nee_light_channel(d.z, beta.z, ev->f.z, w_over_pdf)));
}

/// delta L_rem / f per channel (adjoint_continuation_k).
TANDEM_INLINE float3 adjoint_continuation_k3(float3 delta, float3 L_rem, float3 f) {
    return make_float3(adjoint_continuation_k(delta.x, L_rem.x, f.x),
                       adjoint_continuation_k(delta.y, L_rem.y, f.y),
                       adjoint_continuation_k(delta.z, L_rem.z, f.z));
}

/// The BSDF sample's factor f / p: everything still in L_rem arrived through its direction, so
/// d/d(theta) of beta f/p Li is L_rem (d f/d theta) / f, with p detached; into the vertex's acc.
TANDEM_INLINE void adjoint_continuation(Adjoint* a, BsdfGrad* acc, const Interaction* it,
                                        const BsdfSample* bs) {
    BsdfGrad g;
    float3 f;
    if (bs->delta) {
        g = bsdf_delta_weight_grad(&it->mat, it->wi_local, bs->wo_local);
        f = bs->weight;
    } else {
        g = bsdf_eval_grad(it->plastic_tables, &it->mat, it->albedo, it->wi_local, bs->wo_local);
        f = bsdf_eval(it->plastic_tables, &it->mat, it->albedo, it->wi_local, bs->wo_local);
    }
    material_grad_add(acc, g, adjoint_continuation_k3(a->delta, a->L_rem, f));
}

/// d(f cos)/d(albedo) of a diffuse vertex, the same in every channel, as a BsdfGrad (the
/// wavefront keeps only the scalar: bsdf_diffuse_eval_grad's value).
TANDEM_INLINE BsdfGrad diffuse_albedo_grad(float g) {
    BsdfGrad grad = bsdf_grad_zero();
    grad.d_albedo = make_float3(g, g, g);
    return grad;
}

#endif // TANDEM_KERNELS_PATH_ADJOINT_H
