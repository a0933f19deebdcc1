// The lights' emission: the environment's radiance and density, an emissive triangle's density,
// and the emission a ray finds (the environment on a miss, an area light on a hit) with the MIS
// weight of having found it by BSDF sampling (docs/method.md, "Primal path", steps 1 and 2).
#ifndef TANDEM_KERNELS_PATH_EMISSION_H
#define TANDEM_KERNELS_PATH_EMISSION_H

#include "path/interaction.h"
#include "shared/envmap.h"

/// Radiance (linear RGB) of the environment along world direction dir under `params` (zero for a
/// constant environment when the scene has none: HAS_ENV_LIGHT may be compiled in for a scene
/// without one).
static inline float3 light_env_radiance(const SceneRefs* s, __global const float* params,
                                        float3 dir) {
#if HAS_ENVMAP
    (void)params;
    return envmap_eval(s->envmap, s->env_texels, dir);
#else
    (void)dir;
    const uint param = s->rp->env_param;
    return param != NO_PARAM ? param_rgb(params, param) : make_float3(0.0f, 0.0f, 0.0f);
#endif
}

/// The parameter the environment's radiance is: a constant environment's, or NO_PARAM (an
/// environment map is not differentiable).
TANDEM_INLINE uint light_env_param(const SceneRefs* s) {
#if HAS_ENVMAP
    (void)s;
    return NO_PARAM;
#else
    return s->rp->env_param;
#endif
}

/// Solid-angle density with which NEE, having chosen the environment, samples direction dir.
TANDEM_INLINE float light_env_pdf(const SceneRefs* s, float3 dir) {
#if HAS_ENVMAP
    return envmap_pdf(s->envmap, s->env_texels, dir);
#else
    (void)s;
    (void)dir;
    return PDF_UNIFORM_SPHERE;
#endif
}

/// light_env_radiance along dir, and light_env_pdf of dir in *pdf, from one lookup of the map.
TANDEM_INLINE float3 light_env_radiance_pdf(const SceneRefs* s, __global const float* params,
                                            float3 dir, float* pdf) {
#if HAS_ENVMAP
    (void)params;
    return envmap_eval_pdf(s->envmap, s->env_texels, dir, pdf);
#else
    *pdf = light_env_pdf(s, dir);
    return light_env_radiance(s, params, dir);
#endif
}

/// Density, in solid angle at x, of NEE choosing point p on emissive triangle e (light_pmf_scale:
/// the probability that NEE uses the alias table; dist2: |p - x|^2; cos_light: at p, toward x).
static inline float light_pdf_triangle(__global const EmissiveTriangle* e, float light_pmf_scale,
                                       float dist2, float cos_light) {
    const float area = e->p0.w, pmf = e->p1.w;
    return cos_light > 0.0f ? light_pmf_scale * pmf * dist2 / (cos_light * area) : 0.0f;
}

/// prev_bsdf_pdf after a vertex whose reservoir took all of the direct light that NEE can sample
/// (ReSTIR, path/restir.h: restir_next_pdf): the emission its BSDF sample finds has weight 0
/// where NEE could have sampled it (pdf_light > 0) and 1 where not. No density is negative.
#define EMISSION_AFTER_NEE_ALL (-1.0f)

/// Weight of the BSDF-sampled estimate of emission found at depth > 0 (pdf_bsdf: its density,
/// pdf_light: NEE's density for the same direction). After a delta lobe (pdf_bsdf = +inf) NEE
/// could not have produced the direction, so the weight is 1 under every strategy.
static inline float emission_mis_weight(float pdf_bsdf, float pdf_light) {
    if (pdf_bsdf == INFINITY) return 1.0f;
#if RESTIR
    // (under NEE alone, emission after the camera ray never counts: 0 as below)
    if (pdf_bsdf == EMISSION_AFTER_NEE_ALL)
        return pdf_light > 0.0f || LIGHT_STRATEGY == STRATEGY_NEE_ONLY ? 0.0f : 1.0f;
#endif
#if LIGHT_STRATEGY == STRATEGY_MIS
    return mis_power(pdf_bsdf, pdf_light);
#elif LIGHT_STRATEGY == STRATEGY_BSDF_ONLY
    return 1.0f;
#else
    return 0.0f; // NEE alone accounts for lights after the camera ray
#endif
}

/// Emission found by a ray: the radiance Le under the path's parameters, the MIS weight w of
/// having found it by BSDF sampling, and the rgb parameter Le is (or NO_PARAM). The path adds
/// beta * Le * w.
typedef struct Emission {
    float3 Le;
    float w;
    uint param;
} Emission;

/// The emission's radiance under another parameter state (the two-state path's old one).
TANDEM_INLINE float3 emission_Le_in(__global const float* params, const Emission* e) {
    return param_rgb_or(params, e->param, e->Le);
}

/// The environment seen by a ray that escaped (direction xyz(ray.dir)), found at `depth` by a
/// BSDF sample of density prev_bsdf_pdf (depth 0: the camera ray, weight 1).
TANDEM_INLINE Emission emission_env(const SceneRefs* s, __global const float* params, Ray ray,
                                    uint depth, float prev_bsdf_pdf) {
    const float3 dir = xyz(ray.dir);
    Emission e;
    float pdf_dir; // NEE's density of the direction, once the environment is chosen
    e.Le = light_env_radiance_pdf(s, params, dir, &pdf_dir);
    e.w = 1.0f;
    if (depth > 0) // NEE's density: the environment's choice times its direction's
        e.w = emission_mis_weight(prev_bsdf_pdf, s->rp->light_env_prob * pdf_dir);
    e.param = light_env_param(s);
    return e;
}

/// The emission of the surface hit `it` toward the ray (area lights emit on their front side
/// only), found at `depth` as emission_env. Returns 0 where the surface emits nothing toward wi.
TANDEM_INLINE int emission_area(const SceneRefs* s, __global const float* params,
                                const Interaction* it, uint depth, float prev_bsdf_pdf,
                                Emission* out) {
    if (it->info.emitter == NO_EMITTER || !(vdot(it->wi, it->n_front) > 0.0f)) return 0;
    __global const EmissiveTriangle* e = &s->emissive[it->info.emitter];
    float w = 1.0f;
    if (depth > 0) {
        // tri_scale: NEE's probability of the alias table; dist2: the ray's direction is unit
        const float tri_scale = 1.0f - s->rp->light_env_prob;
        const float dist2 = it->hit.t * it->hit.t;
        w = emission_mis_weight(prev_bsdf_pdf,
                                light_pdf_triangle(e, tri_scale, dist2, vdot(it->wi, it->n_front)));
    }
    out->Le = param_rgb(params, e->radiance_param);
    out->w = w;
    out->param = e->radiance_param;
    return 1;
}

#endif // TANDEM_KERNELS_PATH_EMISSION_H
