// One path of the path tracer (../shared/METHOD.md sections 1 and 2), shared by the primal render
// (kernels/render.cl) and the PRB adjoint (kernels/adjoint.cl): unidirectional path tracing with
// next-event estimation and MIS (power heuristic), Russian roulette and a box pixel filter. Every
// differentiable value (reflectance, bitmap texels, specular_reflectance, alpha, emitted
// radiance) is read from the flat parameter buffer. trace_path with an Adjoint replays a path and
// pushes the adjoint into the parameter gradients; with a TwoState it also estimates the previous
// parameter state along the same path (CV-PS, METHOD.md section 3); with neither it is the plain
// primal estimate.
#ifndef TANDEM_KERNELS_PATH_H
#define TANDEM_KERNELS_PATH_H

// Feature flags (core/renderer.h: render_features), always passed explicitly.
#if !defined(BVH_WIDTH) || (BVH_WIDTH != 2 && BVH_WIDTH != 4)
#error "BVH_WIDTH must be passed as 2 or 4"
#endif
#if !defined(HAS_AREA_LIGHTS) || !defined(HAS_ENV_LIGHT) || !defined(LIGHT_STRATEGY) ||          \
    !defined(HAS_TEXTURES) || !defined(HAS_DELTA_LIGHTS) || !defined(HAS_ENVMAP) ||               \
    !defined(BSDF_CONDUCTOR) || !defined(BSDF_DIELECTRIC) || !defined(BSDF_PLASTIC)
#error "every feature flag (HAS_*, BSDF_*, LIGHT_STRATEGY) must be passed"
#endif
#define HAS_ALIAS_LIGHTS (HAS_AREA_LIGHTS || HAS_DELTA_LIGHTS)

#include "shared/bsdf_grad.h"
#include "shared/bsdfs.h"
#include "shared/bvh4_traverse.h"
#include "shared/envmap.h"
#include "shared/fixed_point.h"
#include "shared/rng.h"
#include "shared/textures.h"

#define STRATEGY_MIS 0
#define STRATEGY_BSDF_ONLY 1
#define STRATEGY_NEE_ONLY 2
#define USE_NEE (LIGHT_STRATEGY != STRATEGY_BSDF_ONLY)

/// Weight of the BSDF-sampled estimate of emission found at depth > 0 (pdf_bsdf: its density,
/// pdf_light: NEE's density for the same direction). After a delta lobe (pdf_bsdf = +inf) NEE
/// could not have produced the direction, so the weight is 1 under every strategy.
static inline float weight_bsdf_hit(float pdf_bsdf, float pdf_light) {
    if (pdf_bsdf == INFINITY) return 1.0f;
#if LIGHT_STRATEGY == STRATEGY_MIS
    return mis_power(pdf_bsdf, pdf_light);
#elif LIGHT_STRATEGY == STRATEGY_BSDF_ONLY
    return 1.0f;
#else
    return 0.0f; // NEE alone accounts for lights after the camera ray
#endif
}

/// Weight of the NEE estimate (pdf_light: its density, pdf_bsdf: the BSDF's for the direction).
static inline float weight_nee(float pdf_light, float pdf_bsdf) {
#if LIGHT_STRATEGY == STRATEGY_MIS
    return mis_power(pdf_light, pdf_bsdf);
#else
    return 1.0f;
#endif
}

// Random dimensions: two for the pixel position, then RNG_DIMS_PER_BOUNCE per path vertex.
#define RNG_DIMS_PER_BOUNCE 8u
#define DIM_LIGHT_CHOICE 0u
#define DIM_LIGHT_POINT 1u
#define DIM_BSDF 3u
#define DIM_RR 5u
#define DIM_LOBE 6u
#define DIM_ALIAS 7u

typedef struct PathRng {
    uint seed, pixel, sample;
} PathRng;

static inline PathRng path_rng(uint seed, uint pixel, uint sample) {
    PathRng r;
    r.seed = seed;
    r.pixel = pixel;
    r.sample = sample;
    return r;
}

static inline float path_rand(PathRng rng, uint dim) {
    return rng_uniform(rng.seed, rng.pixel, rng.sample, dim);
}

/// The scene as the kernels see it: device buffers and the per-launch records.
typedef struct SceneRefs {
    __global const float4* nodes;       ///< BvhNode or Bvh4Node, by BVH_WIDTH
    __global const BvhTriangle* tris;   ///< leaf order
    __global const BvhTriangle* prims;  ///< primitive order
    __global const TriangleInfo* infos;
    __global const TriangleUV* uvs;
    __global const TextureInfo* textures;
    __global const float4* texels;      ///< bitmaps that are not parameters
    __global const Material* materials;
    __global const EmissiveTriangle* emissive;
    __global const DeltaLight* delta_lights;
    __global const AliasEntry* alias;
    __global const float4* env_texels;
    __global const float* env_cdf;
    const EnvMap* envmap;
    const DeviceCamera* cam;
    const RenderParams* rp;
} SceneRefs;

static inline Hit trace_closest(const SceneRefs* s, Ray ray) {
#if BVH_WIDTH == 4
    return bvh4_intersect_closest((__global const Bvh4Node*)s->nodes, s->tris, ray);
#else
    return bvh_intersect_closest((__global const BvhNode*)s->nodes, s->tris, ray);
#endif
}

static inline int trace_any(const SceneRefs* s, Ray ray) {
#if BVH_WIDTH == 4
    return bvh4_intersect_any((__global const Bvh4Node*)s->nodes, s->tris, ray);
#else
    return bvh_intersect_any((__global const BvhNode*)s->nodes, s->tris, ray);
#endif
}

static inline Ray make_ray(float3 o, float3 d, float tmin, float tmax) {
    Ray r;
    r.org = make_float4(o.x, o.y, o.z, tmin);
    r.dir = make_float4(d.x, d.y, d.z, tmax);
    return r;
}

static inline float3 param_rgb(__global const float* params, uint offset) {
    return make_float3(params[offset], params[offset + 1u], params[offset + 2u]);
}

/// Radiance of the constant environment (zero when the scene has none: HAS_ENV_LIGHT may be
/// compiled in for a scene without an environment).
static inline float3 constant_env(__global const float* params, const RenderParams* rp) {
    return rp->env_param != NO_PARAM ? param_rgb(params, rp->env_param) : make_float3(0.0f, 0.0f, 0.0f);
}

/// Density, in solid angle at x, of NEE choosing point p on emissive triangle e.
static inline float light_pdf_triangle(__global const EmissiveTriangle* e, float light_pmf_scale,
                                       float dist2, float cos_light) {
    const float area = e->p0.w, pmf = e->p1.w;
    return cos_light > 0.0f ? light_pmf_scale * pmf * dist2 / (cos_light * area) : 0.0f;
}

/// Material `index` with its differentiable values taken from params.
static inline Material material_load(const SceneRefs* s, __global const float* params, uint index) {
    Material m = s->materials[index];
    if (m.reflectance_param != NO_PARAM) {
        const float3 c = param_rgb(params, m.reflectance_param);
        m.reflectance = make_float4(c.x, c.y, c.z, 0.0f);
    }
    if (m.specular_param != NO_PARAM) {
        const float3 c = param_rgb(params, m.specular_param);
        m.specular = make_float4(c.x, c.y, c.z, 0.0f);
    }
    if (m.alpha_param != NO_PARAM) m.alpha = params[m.alpha_param];
    return m;
}

// ---- the adjoint (PRB) ----

/// What the replay of one path carries: the adjoint of its radiance, the radiance not yet
/// accounted for, and where gradients go (fixed-point pairs, shared/fixed_point.h).
typedef struct Adjoint {
    __global uint* grad; ///< 2 words per parameter element
    float3 delta;        ///< dloss / d(this sample's radiance), per channel
    float3 L_rem;        ///< the primal radiance minus the terms replayed so far
    uint saturated;      ///< contributions clamped or dropped (shared/fixed_point.h)
} Adjoint;

static inline void grad_add(Adjoint* a, uint index, float v) {
    if (v == 0.0f) return;
    if (!(fabs(v) <= GRAD_MAX_CONTRIBUTION)) {
        ++a->saturated;
        if (!isfinite(v)) return;
        v = v > 0.0f ? GRAD_MAX_CONTRIBUTION : -GRAD_MAX_CONTRIBUTION;
    }
    fixed_add(a->grad + 2u * index, fixed_encode(v));
}

static inline void grad_add_rgb(Adjoint* a, uint offset, float3 v) {
    grad_add(a, offset, v.x);
    grad_add(a, offset + 1u, v.y);
    grad_add(a, offset + 2u, v.z);
}

/// Where the albedo of a surface point comes from: an rgb parameter, or up to four texels of a
/// bitmap parameter with their bilinear weights.
typedef struct AlbedoSource {
    uint param;       ///< rgb parameter, or NO_PARAM
    uint texel_param; ///< first texel of a bitmap parameter, or NO_PARAM
    uint count;
    uint index[4];
    float weight[4];
} AlbedoSource;

/// Pushes k * d(f cos)/d(theta) into the gradients of the material's parameters, per channel
/// (k = delta times the term's radiance over f cos, as METHOD.md section 2 prescribes).
static inline void grad_material(Adjoint* a, const Material* m, const AlbedoSource* src,
                                 BsdfGrad g, float3 k) {
    const float3 d_albedo = k * g.d_albedo;
    if (src->param != NO_PARAM) grad_add_rgb(a, src->param, d_albedo);
    if (src->texel_param != NO_PARAM)
        for (uint i = 0; i < src->count; ++i)
            grad_add_rgb(a, src->texel_param + 3u * src->index[i], d_albedo * src->weight[i]);
    if (m->specular_param != NO_PARAM) grad_add_rgb(a, m->specular_param, k * g.d_specular);
    if (m->alpha_param != NO_PARAM) {
        const float3 d = k * g.d_alpha;
        grad_add(a, m->alpha_param, d.x + d.y + d.z);
    }
}

/// Per channel num / den, 0 where den is 0 (a channel the BSDF does not transmit carries no
/// radiance through it and gets no gradient, METHOD.md section 2).
static inline float3 safe_ratio(float3 num, float3 den) {
    return make_float3(den.x != 0.0f ? num.x / den.x : 0.0f, den.y != 0.0f ? num.y / den.y : 0.0f,
                       den.z != 0.0f ? num.z / den.z : 0.0f);
}

// ---- the two-state path (CV-PS) ----

/// The previous parameter state carried along a path sampled from the new one: its parameters,
/// throughput and radiance. Geometry, textures' uvs, light sampling and MIS weights are shared.
typedef struct TwoState {
    __global const float* params_old;
    float3 beta_old;
    float3 L_old;
} TwoState;

/// The albedo of material m at a surface point (texture coordinates tu, tv) under `params`.
static inline float3 material_albedo(const SceneRefs* s, const Material* m, __global const float* params,
                                     float tu, float tv) {
#if HAS_TEXTURES
    if (m->texture != NO_TEXTURE) return texture_eval(&s->textures[m->texture], s->texels, params, tu, tv);
#endif
    (void)s;
    (void)params;
    (void)tu;
    (void)tv;
    return xyz(m->reflectance);
}

/// One path from pixel (px, py): returns its radiance (linear RGB). With adj != 0 the path is a
/// replay: adj->L_rem must hold the primal radiance of the same path (same rng), and every term
/// pushes its derivative into adj->grad. The replay reproduces the primal bit for bit: the
/// gradient code only reads what the primal computes. With two != 0 (and adj = 0) the path is
/// sampled from `params` and two->L_old receives the estimate for two->params_old.
TANDEM_INLINE float3 trace_path(const SceneRefs* s, __global const float* params, PathRng rng, uint px,
                         uint py, Adjoint* adj, TwoState* two) {
    const float3 zero = make_float3(0.0f, 0.0f, 0.0f);
    const DeviceCamera* cam = s->cam;
    const RenderParams* rp = s->rp;
    const float tri_scale = 1.0f - rp->light_env_prob; // probability NEE uses the alias table

    // Step 1: camera ray through a uniform point of the pixel (box filter).
    const float fx = ((float)px + path_rand(rng, 0)) / (float)cam->width;
    const float fy = ((float)py + path_rand(rng, 1)) / (float)cam->height;
    float3 dir = vnormalize(xyz(cam->dir_z) + xyz(cam->dir_x) * (1.0f - 2.0f * fx) +
                            xyz(cam->dir_y) * (1.0f - 2.0f * fy));
    const float cos_z = vdot(dir, xyz(cam->dir_z));
    Ray ray = make_ray(xyz(cam->origin), dir, cam->near_clip / cos_z, cam->far_clip / cos_z);

    float3 L = zero, beta = make_float3(1.0f, 1.0f, 1.0f);
    if (rp->max_depth == 0u) return L; // Mitsuba: max_depth 0 renders black
    float prev_bsdf_pdf = 0.0f; // solid-angle density of the direction that led here; 0: camera
    for (uint depth = 0;; ++depth) {
        const uint dim = 2u + depth * RNG_DIMS_PER_BOUNCE;
        const Hit hit = trace_closest(s, ray);

        // Step 2: escaped: environment light, MIS-weighted against NEE's choice of it.
        if (hit.prim == HIT_NONE) {
#if HAS_ENV_LIGHT
#if HAS_ENVMAP
            const float3 Le_env = envmap_eval(s->envmap, s->env_texels, dir);
            const float pdf_env = envmap_pdf(s->envmap, s->env_cdf, dir);
#else
            const float3 Le_env = constant_env(params, rp);
            const float pdf_env = PDF_UNIFORM_SPHERE;
#endif
            const float w = depth == 0 ? 1.0f
                                       : weight_bsdf_hit(prev_bsdf_pdf, rp->light_env_prob * pdf_env);
            const float3 E = beta * Le_env * w;
            L += E;
#if !HAS_ENVMAP
            if (two) two->L_old += two->beta_old * constant_env(two->params_old, rp) * w;
#else
            if (two) two->L_old += two->beta_old * Le_env * w;
#endif
            if (adj) {
#if !HAS_ENVMAP
                if (rp->env_param != NO_PARAM) grad_add_rgb(adj, rp->env_param, adj->delta * beta * w);
#endif
                adj->L_rem -= E;
            }
#endif
            break;
        }

        // Step 3: the surface: position, geometric normal, material.
        const BvhTriangle tri = s->prims[hit.prim];
        const float3 p0 = xyz(tri.v0), p1 = xyz(tri.v1), p2 = xyz(tri.v2);
        const float3 x = p0 * (1.0f - hit.u - hit.v) + p1 * hit.u + p2 * hit.v;
        const float3 n_front = vnormalize(vcross(p1 - p0, p2 - p0));
        const float3 wi = -dir;
        const TriangleInfo info = s->infos[hit.prim];

#if HAS_AREA_LIGHTS
        // Step 4: emission seen by this ray (front side only), MIS-weighted against NEE.
        if (info.emitter != NO_EMITTER && vdot(wi, n_front) > 0.0f) {
            __global const EmissiveTriangle* e = &s->emissive[info.emitter];
            float w = 1.0f;
            if (depth > 0) {
                const float dist2 = hit.t * hit.t; // dir is unit length
                w = weight_bsdf_hit(prev_bsdf_pdf,
                                    light_pdf_triangle(e, tri_scale, dist2, vdot(wi, n_front)));
            }
            const float3 E = beta * param_rgb(params, e->radiance_param) * w;
            L += E;
            if (two) two->L_old += two->beta_old * param_rgb(two->params_old, e->radiance_param) * w;
            if (adj) {
                grad_add_rgb(adj, e->radiance_param, adj->delta * beta * w);
                adj->L_rem -= E;
            }
        }
#endif
        if (!(depth + 1u < rp->max_depth)) break;

        const Material mat = material_load(s, params, info.material);
        float3 n = n_front;
        // A dielectric is two-sided by nature (wi_local.z < 0: inside); other BSDFs are one-sided
        // unless wrapped in twosided, and black from behind.
        const int dielectric = mat.type == MATERIAL_DIELECTRIC;
        if (!dielectric) {
            if ((mat.flags & MATERIAL_FLAG_TWOSIDED) && vdot(wi, n) < 0.0f) n = -n;
            if (vdot(wi, n) <= 0.0f) break;
        }
        const Frame frame = frame_from_normal(n);
        const float3 wi_local = frame_to_local(frame, wi);
        AlbedoSource src;
        src.param = mat.reflectance_param;
        src.texel_param = NO_PARAM;
        src.count = 0u;
        float tu = 0.0f, tv = 0.0f;
#if HAS_TEXTURES
        if (mat.texture != NO_TEXTURE) {
            const TriangleUV tuv = s->uvs[hit.prim];
            const float b0 = 1.0f - hit.u - hit.v;
            tu = tuv.uv01.x * b0 + tuv.uv01.z * hit.u + tuv.uv2.x * hit.v;
            tv = tuv.uv01.y * b0 + tuv.uv01.w * hit.u + tuv.uv2.y * hit.v;
            __global const TextureInfo* t = &s->textures[mat.texture];
            src.param = NO_PARAM;
            if (adj && t->param != NO_PARAM) {
                src.texel_param = t->param;
                src.count = texture_footprint(t, tu, tv, src.index, src.weight);
            }
        }
#endif
        const float3 albedo = material_albedo(s, &mat, params, tu, tv);
        // the previous state's material (two-state paths only)
        Material mat_old = mat;
        float3 albedo_old = albedo;
        if (two) {
            mat_old = material_load(s, two->params_old, info.material);
            albedo_old = material_albedo(s, &mat_old, two->params_old, tu, tv);
        }
        const float3 n_out = vdot(wi, n) >= 0.0f ? n : -n; // the side wi leaves from
        const float3 origin = offset_ray_origin(x, n_out);
        // purely specular materials have nothing for NEE to evaluate
        const int smooth = mat.type == MATERIAL_CONDUCTOR || dielectric;

        // Step 5: next-event estimation: one point on a light, MIS-weighted against the BSDF.
        if (USE_NEE && (HAS_ALIAS_LIGHTS || HAS_ENV_LIGHT) && !smooth) {
            const float u_choice = path_rand(rng, dim + DIM_LIGHT_CHOICE);
            const float u1 = path_rand(rng, dim + DIM_LIGHT_POINT);
            const float u2 = path_rand(rng, dim + DIM_LIGHT_POINT + 1u);
            float3 wo = zero, Le = zero;
            float light_pdf = 0.0f;
            float3 shadow_dir = zero; // the shadow ray is origin + t shadow_dir, t in [0, shadow_tmax)
            float shadow_tmax = 0.0f;
            int sampled = 0, delta_light = 0;
            uint Le_param = NO_PARAM; // the parameter Le is, if any
            float3 Le_old = zero;     // Le in the previous state (two-state paths)
#if HAS_ENV_LIGHT
            if (u_choice < rp->light_env_prob) {
#if HAS_ENVMAP
                float pdf_dir;
                wo = envmap_sample(s->envmap, s->env_cdf, u1, u2, &pdf_dir);
                // the density of the texel wo is looked up in, like Le and the BSDF-hit weight
                pdf_dir = envmap_pdf(s->envmap, s->env_cdf, wo);
                Le = envmap_eval(s->envmap, s->env_texels, wo);
                Le_old = Le;
#else
                const float pdf_dir = PDF_UNIFORM_SPHERE;
                wo = sample_uniform_sphere(u1, u2);
                Le = constant_env(params, rp);
                Le_param = rp->env_param;
                if (two) Le_old = constant_env(two->params_old, rp);
#endif
                light_pdf = rp->light_env_prob * pdf_dir;
                shadow_dir = wo;
                shadow_tmax = INFINITY;
                sampled = 1;
            }
#endif
#if HAS_ALIAS_LIGHTS
            if (!sampled) {
                // alias table: the remapped choice picks a slot, its fraction the slot or alias
                const float u = (u_choice - rp->light_env_prob) / tri_scale;
                const uint count = rp->emissive_count + rp->delta_count;
                const float scaled = u * (float)count;
                uint slot = min((uint)scaled, count - 1u);
                // the slot-or-alias coin gets its own dimension: the fraction of `scaled` keeps
                // only 24 - log2(count) bits, which would round q for large emissive meshes
                if (path_rand(rng, dim + DIM_ALIAS) >= s->alias[slot].q) slot = s->alias[slot].alias;
#if HAS_AREA_LIGHTS
                if (slot < rp->emissive_count) {
                    __global const EmissiveTriangle* e = &s->emissive[slot];
                    const float3 b = sample_uniform_triangle(u1, u2);
                    const float3 q0 = xyz(e->p0), q1 = xyz(e->p1), q2 = xyz(e->p2);
                    const float3 y = q0 * b.x + q1 * b.y + q2 * (1.0f - b.x - b.y);
                    const float3 n_light = vnormalize(vcross(q1 - q0, q2 - q0));
                    const float3 to_light = y - origin;
                    const float dist2 = vdot(to_light, to_light);
                    const float dist = sqrt(dist2);
                    wo = to_light * (1.0f / dist);
                    Le = param_rgb(params, e->radiance_param);
                    Le_param = e->radiance_param;
                    if (two) Le_old = param_rgb(two->params_old, e->radiance_param);
                    light_pdf = light_pdf_triangle(e, tri_scale, dist2, -vdot(wo, n_light));
                    // end just off the light's surface, on our side, so it cannot occlude itself
                    shadow_dir = offset_ray_origin(y, vdot(n_light, wo) < 0.0f ? n_light : -n_light) - origin;
                    shadow_tmax = 1.0f;
                }
#endif
#if HAS_DELTA_LIGHTS
                if (slot >= rp->emissive_count) {
                    // A point or spot light: a discrete choice, not a density. The "radiance"
                    // is intensity * falloff / dist^2 and the "pdf" the selection probability;
                    // BSDF sampling cannot hit it, so its MIS weight is 1 (delta_light below).
                    __global const DeltaLight* d = &s->delta_lights[slot - rp->emissive_count];
                    const float3 to_light = xyz(d->position) - origin;
                    const float dist2 = vdot(to_light, to_light);
                    const float dist = sqrt(dist2);
                    wo = to_light * (1.0f / dist);
                    float falloff = 1.0f;
                    if (d->type == DELTA_SPOT) {
                        const float c = -vdot(wo, xyz(d->axis));
                        falloff = c >= d->cos_beam
                                      ? 1.0f
                                      : (c > d->axis.w ? (d->cutoff - acos(c)) * d->inv_transition : 0.0f);
                    }
                    Le = xyz(d->intensity) * (falloff / dist2);
                    Le_old = Le;
                    light_pdf = tri_scale * d->position.w;
                    shadow_dir = to_light;
                    shadow_tmax = 1.0f;
                    delta_light = 1;
                }
#endif
            }
#endif
            (void)sampled;
            const float3 wo_local = frame_to_local(frame, wo);
            const float3 f = bsdf_eval(&mat, albedo, wi_local, wo_local);
            const float3 f_old = two ? bsdf_eval(&mat_old, albedo_old, wi_local, wo_local) : zero;
            if (light_pdf > 0.0f && (max_component(f) > 0.0f || max_component(f_old) > 0.0f) &&
                !trace_any(s, make_ray(origin, shadow_dir, 0.0f, shadow_tmax))) {
                // one MIS weight, the new state's, for both states
                const float w =
                    delta_light ? 1.0f : weight_nee(light_pdf, bsdf_pdf(&mat, albedo, wi_local, wo_local));
                const float3 N = beta * f * Le * (w / light_pdf);
                L += N;
                if (two) two->L_old += two->beta_old * f_old * Le_old * (w / light_pdf);
                if (adj) {
                    // N = beta f Le w / p: d/d(material) through f, d/d(Le) through the light
                    const float3 k = adj->delta * beta * Le * (w / light_pdf);
                    grad_material(adj, &mat, &src, bsdf_eval_grad(&mat, albedo, wi_local, wo_local), k);
                    if (Le_param != NO_PARAM)
                        grad_add_rgb(adj, Le_param, adj->delta * beta * f * (w / light_pdf));
                    adj->L_rem -= N;
                }
            }
        }

        // Step 6: continue the path by sampling the BSDF. After a delta lobe the next emission
        // found gets full weight (prev_bsdf_pdf = +inf), as NEE cannot sample that direction.
        float3 wo_local;
        float pdf;
        int delta;
        const float3 weight = bsdf_sample(&mat, albedo, wi_local, path_rand(rng, dim + DIM_LOBE),
                                          path_rand(rng, dim + DIM_BSDF),
                                          path_rand(rng, dim + DIM_BSDF + 1u), &wo_local, &pdf, &delta);
        if (!delta && pdf <= 0.0f) break;
        // The old state's throughput through the same direction: f_old / p_new, or for a delta
        // lobe the old state's weight of the same lobe (METHOD.md section 3).
        float3 weight_old = zero;
        if (two) {
            if (delta) {
                weight_old = bsdf_delta_weight(&mat_old, wi_local, wo_local);
            } else {
                // f_old / p as weight * (f_old / f_new) where f_new > 0: the same value, and
                // exactly `weight` when the two states agree (so H == F bit for bit on an
                // unchanging scene, the steady state of papers/000 Fig. 3)
                const float3 f_new = bsdf_eval(&mat, albedo, wi_local, wo_local);
                const float3 f_old = bsdf_eval(&mat_old, albedo_old, wi_local, wo_local);
                const float3 direct = f_old * (1.0f / pdf), ratio = weight * safe_ratio(f_old, f_new);
                weight_old = make_float3(f_new.x > 0.0f && isfinite(ratio.x) ? ratio.x : direct.x,
                                         f_new.y > 0.0f && isfinite(ratio.y) ? ratio.y : direct.y,
                                         f_new.z > 0.0f && isfinite(ratio.z) ? ratio.z : direct.z);
            }
        }
        if (max_component(weight) <= 0.0f && max_component(weight_old) <= 0.0f) break;
        if (adj) {
            // Everything still in L_rem arrived through wo: d/d(theta) of beta f/p Li is
            // L_rem (d f/d theta) / f, with p detached (METHOD.md section 2, step 3).
            BsdfGrad g;
            float3 f;
            if (delta) {
                g = bsdf_delta_weight_grad(&mat, wi_local, wo_local);
                f = weight;
            } else {
                g = bsdf_eval_grad(&mat, albedo, wi_local, wo_local);
                f = bsdf_eval(&mat, albedo, wi_local, wo_local);
            }
            grad_material(adj, &mat, &src, g, safe_ratio(adj->delta * adj->L_rem, f));
        }
        beta = beta * weight;
        if (two) two->beta_old = two->beta_old * weight_old;
        prev_bsdf_pdf = delta ? INFINITY : pdf;
        dir = frame_to_world(frame, wo_local);
        // leave from the side the new direction points to (refraction crosses the surface)
        const float3 origin_next = vdot(dir, n_out) >= 0.0f ? origin : offset_ray_origin(x, -n_out);
        ray = make_ray(origin_next, dir, 0.0f, INFINITY);

        // Step 7: Russian roulette on the throughput: Mitsuba's rule, without its eta^2 factor
        // (which refraction tracking would add; unbiased either way).
        if (depth + 1u >= rp->rr_depth) {
            // decided on the new throughput; both states divide by the same q. When the new
            // throughput is zero (a clamped albedo, say) the new path carries nothing, and the
            // old one decides instead, so the old state's estimate is not cut short.
            float q = fmin(max_component(beta), 0.95f);
            if (two && !(q > 0.0f)) q = fmin(max_component(two->beta_old), 0.95f);
            if (path_rand(rng, dim + DIM_RR) >= q) break;
            beta = beta * (1.0f / q);
            if (two) two->beta_old = two->beta_old * (1.0f / q);
        }
    }
    return L;
}

/// The SceneRefs of a kernel's scene arguments (SCENE_ARGS below).
#define SCENE_ARGS                                                                                 \
    __global const float4 *nodes, __global const BvhTriangle *tris,                                \
        __global const BvhTriangle *prims, __global const TriangleInfo *infos,                     \
        __global const TriangleUV *uvs, __global const TextureInfo *textures,                      \
        __global const float4 *texels, __global const Material *materials,                         \
        __global const EmissiveTriangle *emissive, __global const DeltaLight *delta_lights,        \
        __global const AliasEntry *alias, __global const float4 *env_texels,                       \
        __global const float *env_cdf, EnvMap envmap, DeviceCamera cam, RenderParams params
#define SCENE_REFS(s)                                                                              \
    SceneRefs s;                                                                                   \
    s.nodes = nodes;                                                                               \
    s.tris = tris;                                                                                 \
    s.prims = prims;                                                                               \
    s.infos = infos;                                                                               \
    s.uvs = uvs;                                                                                   \
    s.textures = textures;                                                                         \
    s.texels = texels;                                                                             \
    s.materials = materials;                                                                       \
    s.emissive = emissive;                                                                         \
    s.delta_lights = delta_lights;                                                                 \
    s.alias = alias;                                                                               \
    s.env_texels = env_texels;                                                                     \
    s.env_cdf = env_cdf;                                                                           \
    s.envmap = &envmap;                                                                            \
    s.cam = &cam;                                                                                  \
    s.rp = &params

#endif // TANDEM_KERNELS_PATH_H
