// Next-event estimation: a light sample (the choice of a light and its decoding into direction,
// radiance, density and shadow ray; nee_sample_light) and its evaluation at a surface point (the
// BSDF toward it, visibility, MIS weight) (docs/method.md, "Primal path", step 3).
#ifndef TANDEM_KERNELS_PATH_NEE_H
#define TANDEM_KERNELS_PATH_NEE_H

#include "path/emission.h"
#include "path/record.h"
#include "shared/det_math.h"
#include "shared/reservoir.h"

/// Whether this build samples lights at all: a strategy with NEE and a light to sample.
#define NEE_ENABLED (USE_NEE && (HAS_ALIAS_LIGHTS || HAS_ENV_LIGHT))

/// Weight of the NEE estimate (pdf_light: its density, pdf_bsdf: the BSDF's for the direction).
static inline float nee_mis_weight(float pdf_light, float pdf_bsdf) {
#if LIGHT_STRATEGY == STRATEGY_MIS
    return mis_power(pdf_light, pdf_bsdf);
#else
    (void)pdf_light;
    (void)pdf_bsdf;
    return 1.0f;
#endif
}

/// One light sample seen from a point: pdf = 0 where none was drawn.
typedef struct LightSample {
    float3 wo;         ///< unit direction from the point to the light, world space
    float3 Le;         ///< radiance arriving along -wo (linear RGB) under the sampling parameters
    float pdf;         ///< solid-angle density (a delta light: its selection probability)
    float3 shadow_dir; ///< the shadow ray is origin + t shadow_dir, t in [0, shadow_tmax)
    float shadow_tmax;
    uint Le_param; ///< the rgb parameter Le is, or NO_PARAM
    int delta;     ///< a point or spot light: BSDF sampling cannot hit it (MIS weight 1)
    /// The light's own measure mu_L (area on an emissive triangle, solid angle for the
    /// environment, counting for a point or spot light), which does not depend on the point the
    /// light is seen from: G converts it to solid angle at that point (cos_light / dist^2 on a
    /// triangle, else 1) and pdf_light is the sample's density in it (pdf = pdf_light / G where
    /// G > 0). Light-sample reuse (ReSTIR, path/restir.h) estimates in mu_L.
    float G;
    float pdf_light;
#if SHAPE_GRAD
    /// Where the light is, for the interior term of shape gradients (path/shape_adjoint.h): its
    /// distance (INFINITY for the environment) and, on a triangle, its unit normal (else 0); and
    /// for a spot light, d(log falloff)/dx at the point it is seen from (else 0).
    float dist;
    float3 light_normal;
    float3 falloff_dx;
#endif
} LightSample;

/// The sample's radiance under another parameter state (the two-state path's old one).
TANDEM_INLINE float3 nee_Le_in(__global const float* params, const LightSample* ls) {
    return param_rgb_or(params, ls->Le_param, ls->Le);
}

TANDEM_INLINE LightSample nee_no_sample(void) {
    const float3 zero = make_float3(0.0f, 0.0f, 0.0f);
    LightSample ls;
    ls.wo = zero;
    ls.Le = zero;
    ls.pdf = 0.0f;
    ls.shadow_dir = zero;
    ls.shadow_tmax = 0.0f;
    ls.Le_param = NO_PARAM;
    ls.delta = 0;
    ls.G = 0.0f;
    ls.pdf_light = 0.0f;
#if SHAPE_GRAD
    ls.dist = INFINITY;
    ls.light_normal = zero;
    ls.falloff_dx = zero;
#endif
    return ls;
}

/// The environment along a direction drawn from (u1, u2).
TANDEM_INLINE LightSample nee_sample_env(const SceneRefs* s, __global const float* params, float u1,
                                         float u2) {
    LightSample ls = nee_no_sample();
    float pdf_wo;
#if HAS_ENVMAP
    // radiance and density of the point the sampler drew (envmap_sample_eval), not looked up again
    (void)params;
    ls.wo = envmap_sample_eval(s->envmap, s->env_texels, s->env_cdf, u1, u2, &ls.Le, &pdf_wo);
#else
    ls.wo = sample_uniform_sphere(u1, u2);
    ls.Le = light_env_radiance_pdf(s, params, ls.wo, &pdf_wo);
#endif
    ls.pdf = light_env_choice_pdf(s->rp, pdf_wo);
    ls.Le_param = light_env_param(s);
    ls.G = 1.0f;
    ls.pdf_light = ls.pdf;
    ls.shadow_dir = ls.wo;
    ls.shadow_tmax = INFINITY;
    return ls;
}

/// A point on an emissive triangle, drawn from (u1, u2), seen from origin o[0..3): the one
/// definition of the triangle light sample, in scalars (nee_sample_triangle; the wavefront's
/// shading stage). e: the triangle's record (EmissiveTriangle, as floats: triangle_point; its
/// area at 3, its alias-table probability at 7); tri_scale: NEE's probability of the alias table.
/// Writes the unit direction wo[0..3), |y - o|^2, the cosine at the light toward o, the shadow
/// ray's direction shadow[0..3) (from o to just off the light's surface, on o's side, so that the
/// light cannot occlude itself; t in [0, 1)), and returns the solid-angle density.
TANDEM_INLINE float nee_triangle_sample(__global const float* e, const float* o, float tri_scale,
                                        float u1, float u2, float* wo, float* dist2,
                                        float* cos_light, float* shadow) {
    // sample_uniform_triangle: the weights of p0 and p1; p2 gets the rest
    const float su = sqrt(u1);
    const float b0 = 1.0f - su, b1 = u2 * su;
    float y[3], n[3];
    triangle_point(e, b0, b1, 1.0f - b0 - b1, y, n);
    const float tx = y[0] - o[0], ty = y[1] - o[1], tz = y[2] - o[2];
    *dist2 = tx * tx + ty * ty + tz * tz;
    const float inv_dist = 1.0f / sqrt(*dist2);
    wo[0] = tx * inv_dist;
    wo[1] = ty * inv_dist;
    wo[2] = tz * inv_dist;
    *cos_light = -(wo[0] * n[0] + wo[1] * n[1] + wo[2] * n[2]);
    const int behind = n[0] * wo[0] + n[1] * wo[1] + n[2] * wo[2] < 0.0f; // the side facing o
    shadow[0] = offset_component(y[0], behind ? n[0] : -n[0]) - o[0];
    shadow[1] = offset_component(y[1], behind ? n[1] : -n[1]) - o[1];
    shadow[2] = offset_component(y[2], behind ? n[2] : -n[2]) - o[2];
    return light_pdf_area(e[3], e[7], tri_scale, *dist2, *cos_light);
}

/// A point on emissive triangle `index`, drawn from (u1, u2), seen from `origin`
/// (nee_triangle_sample).
TANDEM_INLINE LightSample nee_sample_triangle(const SceneRefs* s, __global const float* params,
                                              float3 origin, uint index, float u1, float u2) {
    LightSample ls = nee_no_sample();
    __global const EmissiveTriangle* e = &s->emissive[index];
    const float tri_scale = light_alias_prob(s->rp);
    const float o[3] = {origin.x, origin.y, origin.z};
    float wo[3], dist2, cos_light, shadow[3];
    ls.pdf = nee_triangle_sample((__global const float*)e, o, tri_scale, u1, u2, wo, &dist2,
                                 &cos_light, shadow);
    ls.wo = make_float3(wo[0], wo[1], wo[2]);
    ls.Le = param_rgb(params, e->radiance_param);
    ls.Le_param = e->radiance_param;
    ls.G = cos_light > 0.0f ? cos_light / dist2 : 0.0f;
    ls.pdf_light = cos_light > 0.0f ? tri_scale * e->p1.w / e->p0.w : 0.0f; // pmf / area
    ls.shadow_dir = make_float3(shadow[0], shadow[1], shadow[2]);
    ls.shadow_tmax = 1.0f;
#if SHAPE_GRAD
    ls.dist = sqrt(dist2);
    ls.light_normal = make_float3(e->nx, e->ny, e->nz);
#endif
    return ls;
}

/// Point or spot light `index` seen from `origin`. A discrete choice, not a density: the "radiance"
/// is intensity * falloff / dist^2 and the "pdf" the selection probability.
TANDEM_INLINE LightSample nee_sample_delta(const SceneRefs* s, float3 origin, uint index) {
    LightSample ls = nee_no_sample();
    __global const DeltaLight* d = &s->delta_lights[index];
    const float3 to_light = xyz(d->position) - origin;
    const float dist2 = vdot(to_light, to_light);
    const float dist = sqrt(dist2);
    ls.wo = to_light * (1.0f / dist);
    float falloff = 1.0f;
#if SHAPE_GRAD
    ls.falloff_dx = make_float3(0.0f, 0.0f, 0.0f);
#endif
    if (d->type == DELTA_SPOT) {
        const float c = -vdot(ls.wo, xyz(d->axis));
        falloff = c >= d->cos_beam
                      ? 1.0f
                      : (c > d->axis.w ? (d->cutoff - det_acos(c)) * d->inv_transition : 0.0f);
#if SHAPE_GRAD
        // in the transition, falloff = (cutoff - acos c) / (cutoff - beam), c = -wo . axis, so
        // d(log falloff)/dc = 1 / (sqrt(1 - c^2) (cutoff - acos c)), and with
        // d(wo)/dx = -(I - wo wo^T) / dist, dc/dx = (axis - (axis . wo) wo) / dist
        if (falloff > 0.0f && falloff < 1.0f && c < 1.0f) {
            const float3 a = xyz(d->axis);
            const float dlog_dc = 1.0f / (sqrt(1.0f - c * c) * (d->cutoff - det_acos(c)));
            ls.falloff_dx = (a + ls.wo * c) * (dlog_dc / dist);
        }
#endif
    }
    ls.Le = xyz(d->intensity) * (falloff / dist2);
    ls.pdf = light_alias_prob(s->rp) * d->position.w;
    ls.G = 1.0f;
    ls.pdf_light = ls.pdf;
    ls.shadow_dir = to_light;
    ls.shadow_tmax = 1.0f;
    ls.delta = 1;
#if SHAPE_GRAD
    ls.dist = dist;
#endif
    return ls;
}

#if HAS_ALIAS_LIGHTS
/// u_choice remapped to [0, 1) for the alias table, where NEE has not chosen the environment.
TANDEM_INLINE float nee_alias_choice(const RenderParams* rp, float u_choice) {
    return (u_choice - rp->light_env_prob) / light_alias_prob(rp);
}

/// The light of the alias table of `count` slots that the remapped choice u (nee_alias_choice)
/// and u_alias pick: u picks a slot, u_alias the slot or its alias. (The fraction of u * count
/// would keep only 24 - log2(count) bits, which would round q for large emissive meshes, hence a
/// dimension of its own.)
TANDEM_INLINE uint nee_alias_pick(__global const AliasEntry* alias, uint count, float u,
                                  float u_alias) {
    const uint slot = min((uint)(u * (float)count), count - 1u);
    return u_alias >= alias[slot].q ? alias[slot].alias : slot;
}
#endif

/// The light NEE's random numbers pick: u_choice chooses the environment or the alias table and
/// then the table's slot, u_alias the slot or its alias. Returns RESERVOIR_LIGHT_ENV, an
/// emissive triangle i < E, a point or spot light E + j, or RESERVOIR_NO_LIGHT (none to sample).
TANDEM_INLINE uint nee_choose_light(const SceneRefs* s, float u_choice, float u_alias) {
    const RenderParams* rp = s->rp;
#if HAS_ENV_LIGHT
    if (u_choice < rp->light_env_prob) return RESERVOIR_LIGHT_ENV;
#endif
#if HAS_ALIAS_LIGHTS
    return nee_alias_pick(s->alias, rp->emissive_count + rp->delta_count,
                          nee_alias_choice(rp, u_choice), u_alias);
#else
    (void)s;
    (void)rp;
    (void)u_choice;
    (void)u_alias;
    return RESERVOIR_NO_LIGHT;
#endif
}

/// The sample (u1, u2) of `light` (nee_choose_light) seen from `origin`. A function of its
/// arguments alone: a light sample stored as (light, u1, u2) decodes to the same point from any
/// shading point, bit for bit.
TANDEM_INLINE LightSample nee_decode_light(const SceneRefs* s, __global const float* params,
                                           float3 origin, uint light, float u1, float u2) {
#if HAS_ENV_LIGHT
    if (light == RESERVOIR_LIGHT_ENV) return nee_sample_env(s, params, u1, u2);
#endif
#if HAS_AREA_LIGHTS
    if (light < s->rp->emissive_count) return nee_sample_triangle(s, params, origin, light, u1, u2);
#endif
#if HAS_DELTA_LIGHTS
    if (light != RESERVOIR_LIGHT_ENV && light != RESERVOIR_NO_LIGHT &&
        light >= s->rp->emissive_count)
        return nee_sample_delta(s, origin, light - s->rp->emissive_count);
#endif
    (void)s;
    (void)params;
    (void)origin;
    (void)light;
    (void)u1;
    (void)u2;
    return nee_no_sample();
}

/// The light sample NEE draws from `origin` with random numbers u_choice, u_alias
/// (nee_choose_light) and (u1, u2) (the point: nee_decode_light).
TANDEM_INLINE LightSample nee_sample_light(const SceneRefs* s, __global const float* params,
                                           float3 origin, float u_choice, float u_alias, float u1,
                                           float u2) {
    return nee_decode_light(s, params, origin, nee_choose_light(s, u_choice, u_alias), u1, u2);
}

/// The light sample of the path vertex with random numbers `vr`.
TANDEM_INLINE LightSample nee_sample(const SceneRefs* s, __global const float* params,
                                     float3 origin, VertexRandom vr) {
    return nee_sample_light(s, params, origin, vertex_rand(vr, DIM_LIGHT_CHOICE),
                            vertex_rand(vr, DIM_ALIAS), vertex_rand(vr, DIM_LIGHT_POINT),
                            vertex_rand(vr, DIM_LIGHT_POINT + 1u));
}

/// Whether NEE samples a light at `it`: purely specular materials have nothing to evaluate.
TANDEM_INLINE int nee_applies(const Interaction* it) {
    const int smooth = it->mat.type == MATERIAL_CONDUCTOR || it->mat.type == MATERIAL_DIELECTRIC;
    return NEE_ENABLED && !smooth;
}

/// A light sample seen from a shaded surface point: the direction to the light in the shading
/// frame and f (the BSDF times the cosine) of the interaction's material toward it.
typedef struct NeeEval {
    float3 wo_local;
    float3 f;
} NeeEval;

TANDEM_INLINE NeeEval nee_eval(const Interaction* it, const LightSample* ls) {
    NeeEval ev;
    ev.wo_local = frame_to_local(it->frame, ls->wo);
    ev.f = bsdf_eval(it->plastic_tables, &it->mat, it->albedo, it->wi_local, ev.wo_local);
    return ev;
}

/// Whether nothing lies between `origin` and the light of ls.
TANDEM_INLINE int nee_unoccluded(const SceneRefs* s, float3 origin, const LightSample* ls) {
    return !trace_any(s, make_ray(origin, ls->shadow_dir, 0.0f, ls->shadow_tmax));
}

/// nee_unoccluded for the vertex at `depth` of a path with record `rec` (path/record.h; 0: none,
/// traced). Built with SHADOW_RECORD=0, every call traces (to measure what the record saves).
TANDEM_INLINE int nee_visible(const SceneRefs* s, float3 origin, const LightSample* ls, uint depth,
                              PathRecord* rec) {
#if SHADOW_RECORD
    if (rec && depth < SHADOW_RECORD_DEPTHS) {
        if (rec->replay) return (int)((rec->shadow >> depth) & 1u);
        const int v = nee_unoccluded(s, origin, ls);
        rec->shadow |= (uint)v << depth;
        return v;
    }
#else
    (void)depth;
    (void)rec;
#endif
    return nee_unoccluded(s, origin, ls);
}

/// The MIS weight of a light sample against BSDF sampling at `it` (1 for a point or spot light).
TANDEM_INLINE float nee_light_weight(const Interaction* it, const LightSample* ls,
                                     const NeeEval* ev) {
    return ls->delta ? 1.0f
                     : nee_mis_weight(ls->pdf, bsdf_pdf(it->plastic_tables, &it->mat, it->albedo,
                                                        it->wi_local, ev->wo_local));
}

/// The factor w / pdf of a light sample of density pdf_light whose direction the BSDF samples
/// with density pdf_bsdf: its MIS weight against BSDF sampling over its density.
TANDEM_INLINE float nee_weight_of(float pdf_light, float pdf_bsdf) {
    return nee_mis_weight(pdf_light, pdf_bsdf) / pdf_light;
}

/// The factor w / pdf of an unoccluded sample: its MIS weight against BSDF sampling at `it` over
/// its density. The term is beta * f * Le * nee_weight (nee_term).
TANDEM_INLINE float nee_weight(const Interaction* it, const LightSample* ls, const NeeEval* ev) {
    return nee_light_weight(it, ls, ev) / ls->pdf;
}

/// One channel of a light sample's term beta f Le w (w: nee_weight), which the path adds to L.
TANDEM_INLINE float nee_term(float beta, float f, float Le, float w) { return beta * f * Le * w; }
TANDEM_INLINE float3 nee_term3(float3 beta, float3 f, float3 Le, float w) {
    return make_float3(nee_term(beta.x, f.x, Le.x, w), nee_term(beta.y, f.y, Le.y, w),
                       nee_term(beta.z, f.z, Le.z, w));
}

#endif // TANDEM_KERNELS_PATH_NEE_H
