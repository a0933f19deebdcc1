// The lights' emission: the environment's radiance and density, an emissive triangle's density,
// and the emission a ray finds (the environment on a miss, an area light on a hit) with the MIS
// weight of having found it by BSDF sampling (docs/method.md, "Primal path", steps 1 and 2).
#ifndef TANDEM_KERNELS_PATH_EMISSION_H
#define TANDEM_KERNELS_PATH_EMISSION_H

#include "path/interaction.h"
#include "shared/envmap.h"

#if !HAS_ENVMAP
/// Channel c of a constant environment's radiance, parameter `param` of `params`, or black where
/// the scene has none (HAS_ENV_LIGHT may be compiled in for a scene without one). A branch, not a
/// select of a load: PoCL's loop vectoriser makes it a masked load.
TANDEM_INLINE float light_env_constant(__global const float* params, uint param, uint c) {
    float value = 0.0f;
    if (param != NO_PARAM) value = params[param + c];
    return value;
}
#endif

/// Radiance (linear RGB) of the environment along world direction dir under `params`.
static inline float3 light_env_radiance(const SceneRefs* s, __global const float* params,
                                        float3 dir) {
#if HAS_ENVMAP
    (void)params;
    return envmap_eval(s->envmap, s->env_texels, dir);
#else
    (void)dir;
    const uint param = s->rp->env_param;
    return make_float3(light_env_constant(params, param, 0u), light_env_constant(params, param, 1u),
                       light_env_constant(params, param, 2u));
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

/// Density, in solid angle at x, of NEE choosing a point p on an emissive triangle of area `area`
/// whose alias-table probability is `pmf` (light_pmf_scale: the probability that NEE uses the
/// alias table; dist2: |p - x|^2; cos_light: at p, toward x).
TANDEM_INLINE float light_pdf_area(float area, float pmf, float light_pmf_scale, float dist2,
                                   float cos_light) {
    return cos_light > 0.0f ? light_pmf_scale * pmf * dist2 / (cos_light * area) : 0.0f;
}

/// The probability that NEE draws from the alias table (emissive triangles, point and spot
/// lights) rather than the environment.
TANDEM_INLINE float light_alias_prob(const RenderParams* rp) { return 1.0f - rp->light_env_prob; }

/// NEE's density, in solid angle at the ray's origin, of the point a ray of unit direction found
/// at distance t on an emissive triangle of area `area` and alias-table probability `pmf`, seen
/// at cosine cos_light (light_pdf_area).
TANDEM_INLINE float emission_area_pdf(const RenderParams* rp, float area, float pmf, float t,
                                      float cos_light) {
    return light_pdf_area(area, pmf, light_alias_prob(rp), t * t, cos_light);
}

/// NEE's density of a direction of the environment whose density, once NEE has chosen the
/// environment, is pdf_dir: the choice's probability times it.
TANDEM_INLINE float light_env_choice_pdf(const RenderParams* rp, float pdf_dir) {
    return rp->light_env_prob * pdf_dir;
}

/// light_pdf_area of emissive triangle e.
static inline float light_pdf_triangle(__global const EmissiveTriangle* e, float light_pmf_scale,
                                       float dist2, float cos_light) {
    return light_pdf_area(e->p0.w, e->p1.w, light_pmf_scale, dist2, cos_light);
}

/// prev_bsdf_pdf after a vertex whose reservoir took all of the direct light that NEE can sample
/// (ReSTIR, path/restir.h: restir_next_pdf): the emission its BSDF sample finds has weight 0
/// where NEE could have sampled it (pdf_light > 0) and 1 where not. No density is negative.
#define EMISSION_AFTER_NEE_ALL (-1.0f)

/// Weight of the BSDF-sampled estimate of emission found at depth > 0 (pdf_bsdf: its density,
/// pdf_light: NEE's density for the same direction). After a delta lobe (pdf_bsdf = +inf) NEE
/// could not have produced the direction, so the weight is 1 under every strategy.
/// Written with selects, as mis_power, so that the wavefront's vectorised stage can inline it.
TANDEM_INLINE float emission_mis_weight(float pdf_bsdf, float pdf_light) {
#if LIGHT_STRATEGY == STRATEGY_MIS
    const float w = mis_power(pdf_bsdf, pdf_light);
#elif LIGHT_STRATEGY == STRATEGY_BSDF_ONLY
    const float w = 1.0f;
#else
    const float w = 0.0f; // NEE alone accounts for lights after the camera ray
#endif
#if RESTIR
    // (under NEE alone, emission after the camera ray never counts: 0 as below)
    const float w_nee_all =
        pdf_light > 0.0f || LIGHT_STRATEGY == STRATEGY_NEE_ONLY ? 0.0f : 1.0f;
    return pdf_bsdf == INFINITY ? 1.0f : (pdf_bsdf == EMISSION_AFTER_NEE_ALL ? w_nee_all : w);
#else
    return pdf_bsdf == INFINITY ? 1.0f : w;
#endif
}

/// The MIS weight of emission found at `depth` by a ray whose direction had density
/// prev_bsdf_pdf, NEE's density for it being pdf_light: 1 for the camera ray (depth 0), else
/// emission_mis_weight.
TANDEM_INLINE float emission_weight(uint depth, float prev_bsdf_pdf, float pdf_light) {
    return depth > 0u ? emission_mis_weight(prev_bsdf_pdf, pdf_light) : 1.0f;
}

/// The emission term beta Le w of one channel added to the radiance L so far (the replay
/// subtracts it from L_rem: path_term_sub). Every estimator adds its terms through these, channel
/// by channel, in one order.
TANDEM_INLINE float path_term_add(float L, float beta, float Le, float w) {
    return L + beta * Le * w;
}
TANDEM_INLINE float path_term_sub(float L, float beta, float Le, float w) {
    return L - beta * Le * w;
}
TANDEM_INLINE float3 path_term_add3(float3 L, float3 beta, float3 Le, float w) {
    return make_float3(path_term_add(L.x, beta.x, Le.x, w), path_term_add(L.y, beta.y, Le.y, w),
                       path_term_add(L.z, beta.z, Le.z, w));
}
TANDEM_INLINE float3 path_term_sub3(float3 L, float3 beta, float3 Le, float w) {
    return make_float3(path_term_sub(L.x, beta.x, Le.x, w), path_term_sub(L.y, beta.y, Le.y, w),
                       path_term_sub(L.z, beta.z, Le.z, w));
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
    // NEE's density: the environment's choice times its direction's
    e.w = emission_weight(depth, prev_bsdf_pdf, light_env_choice_pdf(s->rp, pdf_dir));
    e.param = light_env_param(s);
    return e;
}

/// The emission of the surface hit `it` toward the ray (area lights emit on their front side
/// only), found at `depth` at distance `dist` from the vertex whose sample (of density
/// prev_bsdf_pdf) led there, as emission_env. Returns 0 where the surface emits nothing toward wi.
/// (dist is it->hit.t except after null surfaces, which a volumetric path crosses without
/// scattering: kernels/path/volume.h.)
TANDEM_INLINE int emission_area_at(const SceneRefs* s, __global const float* params,
                                   const Interaction* it, uint depth, float prev_bsdf_pdf,
                                   float dist, Emission* out) {
    if (it->info.emitter == NO_EMITTER || !(vdot(it->wi, it->n_front) > 0.0f)) return 0;
    __global const EmissiveTriangle* e = &s->emissive[it->info.emitter];
    const float w = emission_weight(
        depth, prev_bsdf_pdf,
        emission_area_pdf(s->rp, e->p0.w, e->p1.w, dist, vdot(it->wi, it->n_front)));
    out->Le = param_rgb(params, e->radiance_param);
    out->w = w;
    out->param = e->radiance_param;
    return 1;
}

/// emission_area_at for a hit the previous vertex's sample found directly (at it->hit.t).
TANDEM_INLINE int emission_area(const SceneRefs* s, __global const float* params,
                                const Interaction* it, uint depth, float prev_bsdf_pdf,
                                Emission* out) {
    return emission_area_at(s, params, it, depth, prev_bsdf_pdf, it->hit.t, out);
}

#endif // TANDEM_KERNELS_PATH_EMISSION_H
