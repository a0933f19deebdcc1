// Path-tracing megakernel: unidirectional path tracing with next-event estimation and MIS (power
// heuristic), Russian roulette and a box pixel filter. One work item per pixel; each owns its
// accumulator, so there are no atomics and the sum order is fixed (deterministic).
#pragma OPENCL FP_CONTRACT OFF

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

#include "shared/bsdfs.h"
#include "shared/bvh4_traverse.h"
#include "shared/envmap.h"
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

static inline float path_rand(PathRng rng, uint dim) {
    return rng_uniform(rng.seed, rng.pixel, rng.sample, dim);
}

static inline Hit trace_closest(__global const float4* nodes, __global const BvhTriangle* tris,
                                Ray ray) {
#if BVH_WIDTH == 4
    return bvh4_intersect_closest((__global const Bvh4Node*)nodes, tris, ray);
#else
    return bvh_intersect_closest((__global const BvhNode*)nodes, tris, ray);
#endif
}

static inline int trace_any(__global const float4* nodes, __global const BvhTriangle* tris, Ray ray) {
#if BVH_WIDTH == 4
    return bvh4_intersect_any((__global const Bvh4Node*)nodes, tris, ray);
#else
    return bvh_intersect_any((__global const BvhNode*)nodes, tris, ray);
#endif
}

static inline Ray make_ray(float3 o, float3 d, float tmin, float tmax) {
    Ray r;
    r.org = make_float4(o.x, o.y, o.z, tmin);
    r.dir = make_float4(d.x, d.y, d.z, tmax);
    return r;
}

/// Density, in solid angle at x, of NEE choosing point p on emissive triangle e.
static inline float light_pdf_triangle(__global const EmissiveTriangle* e, float light_pmf_scale,
                                       float dist2, float cos_light) {
    const float area = e->p0.w, pmf = e->p1.w;
    return cos_light > 0.0f ? light_pmf_scale * pmf * dist2 / (cos_light * area) : 0.0f;
}

/// One path from pixel (px, py), sample `sample`: returns its radiance (linear RGB).
static float3 trace_path(__global const float4* nodes, __global const BvhTriangle* tris,
                         __global const BvhTriangle* prims, __global const TriangleInfo* infos,
                         __global const TriangleUV* uvs, __global const TextureInfo* textures,
                         __global const float4* texels,
                         __global const Material* materials, __global const EmissiveTriangle* emissive,
                         __global const DeltaLight* delta_lights, __global const AliasEntry* alias,
                         __global const float4* env_texels, __global const float* env_cdf,
                         const EnvMap* envmap, const DeviceCamera* cam,
                         const RenderParams* params, PathRng rng, uint px, uint py) {
    const float3 zero = make_float3(0.0f, 0.0f, 0.0f);
    const float3 env = xyz(params->env_radiance);
    const float tri_scale = 1.0f - params->light_env_prob; // probability NEE uses the alias table

    // Step 1: camera ray through a uniform point of the pixel (box filter).
    const float fx = ((float)px + path_rand(rng, 0)) / (float)cam->width;
    const float fy = ((float)py + path_rand(rng, 1)) / (float)cam->height;
    float3 dir = vnormalize(xyz(cam->dir_z) + xyz(cam->dir_x) * (1.0f - 2.0f * fx) +
                            xyz(cam->dir_y) * (1.0f - 2.0f * fy));
    const float cos_z = vdot(dir, xyz(cam->dir_z));
    Ray ray = make_ray(xyz(cam->origin), dir, cam->near_clip / cos_z, cam->far_clip / cos_z);

    float3 L = zero, beta = make_float3(1.0f, 1.0f, 1.0f);
    if (params->max_depth == 0u) return L; // Mitsuba: max_depth 0 renders black
    float prev_bsdf_pdf = 0.0f; // solid-angle density of the direction that led here; 0: camera
    for (uint depth = 0;; ++depth) {
        const uint dim = 2u + depth * RNG_DIMS_PER_BOUNCE;
        const Hit hit = trace_closest(nodes, tris, ray);

        // Step 2: escaped: environment light, MIS-weighted against NEE's choice of it.
        if (hit.prim == HIT_NONE) {
#if HAS_ENV_LIGHT
#if HAS_ENVMAP
            const float3 Le_env = envmap_eval(envmap, env_texels, dir);
            const float pdf_env = envmap_pdf(envmap, env_cdf, dir);
#else
            const float3 Le_env = env;
            const float pdf_env = PDF_UNIFORM_SPHERE;
#endif
            const float w = depth == 0 ? 1.0f
                                       : weight_bsdf_hit(prev_bsdf_pdf, params->light_env_prob * pdf_env);
            L += beta * Le_env * w;
#endif
            break;
        }

        // Step 3: the surface: position, geometric normal, material.
        const BvhTriangle tri = prims[hit.prim];
        const float3 p0 = xyz(tri.v0), p1 = xyz(tri.v1), p2 = xyz(tri.v2);
        const float3 x = p0 * (1.0f - hit.u - hit.v) + p1 * hit.u + p2 * hit.v;
        const float3 n_front = vnormalize(vcross(p1 - p0, p2 - p0));
        const float3 wi = -dir;
        const TriangleInfo info = infos[hit.prim];

#if HAS_AREA_LIGHTS
        // Step 4: emission seen by this ray (front side only), MIS-weighted against NEE.
        if (info.emitter != NO_EMITTER && vdot(wi, n_front) > 0.0f) {
            __global const EmissiveTriangle* e = &emissive[info.emitter];
            float w = 1.0f;
            if (depth > 0) {
                const float dist2 = hit.t * hit.t; // dir is unit length
                w = weight_bsdf_hit(prev_bsdf_pdf,
                                    light_pdf_triangle(e, tri_scale, dist2, vdot(wi, n_front)));
            }
            L += beta * xyz(e->radiance) * w;
        }
#endif
        if (!(depth + 1u < params->max_depth)) break;

        const Material mat = materials[info.material];
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
        float3 albedo = xyz(mat.reflectance);
#if HAS_TEXTURES
        if (mat.texture != NO_TEXTURE) {
            const TriangleUV tuv = uvs[hit.prim];
            const float b0 = 1.0f - hit.u - hit.v;
            const float tu = tuv.uv01.x * b0 + tuv.uv01.z * hit.u + tuv.uv2.x * hit.v;
            const float tv = tuv.uv01.y * b0 + tuv.uv01.w * hit.u + tuv.uv2.y * hit.v;
            albedo = texture_eval(&textures[mat.texture], texels, tu, tv);
        }
#endif
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
#if HAS_ENV_LIGHT
            if (u_choice < params->light_env_prob) {
#if HAS_ENVMAP
                float pdf_dir;
                wo = envmap_sample(envmap, env_cdf, u1, u2, &pdf_dir);
                // the density of the texel wo is looked up in, like Le and the BSDF-hit weight
                pdf_dir = envmap_pdf(envmap, env_cdf, wo);
                Le = envmap_eval(envmap, env_texels, wo);
#else
                const float pdf_dir = PDF_UNIFORM_SPHERE;
                wo = sample_uniform_sphere(u1, u2);
                Le = env;
#endif
                light_pdf = params->light_env_prob * pdf_dir;
                shadow_dir = wo;
                shadow_tmax = INFINITY;
                sampled = 1;
            }
#endif
#if HAS_ALIAS_LIGHTS
            if (!sampled) {
                // alias table: the remapped choice picks a slot, its fraction the slot or alias
                const float u = (u_choice - params->light_env_prob) / tri_scale;
                const uint count = params->emissive_count + params->delta_count;
                const float scaled = u * (float)count;
                uint slot = min((uint)scaled, count - 1u);
                // the slot-or-alias coin gets its own dimension: the fraction of `scaled` keeps
                // only 24 - log2(count) bits, which would round q for large emissive meshes
                if (path_rand(rng, dim + DIM_ALIAS) >= alias[slot].q) slot = alias[slot].alias;
#if HAS_AREA_LIGHTS
                if (slot < params->emissive_count) {
                    __global const EmissiveTriangle* e = &emissive[slot];
                    const float3 b = sample_uniform_triangle(u1, u2);
                    const float3 q0 = xyz(e->p0), q1 = xyz(e->p1), q2 = xyz(e->p2);
                    const float3 y = q0 * b.x + q1 * b.y + q2 * (1.0f - b.x - b.y);
                    const float3 n_light = vnormalize(vcross(q1 - q0, q2 - q0));
                    const float3 to_light = y - origin;
                    const float dist2 = vdot(to_light, to_light);
                    const float dist = sqrt(dist2);
                    wo = to_light * (1.0f / dist);
                    Le = xyz(e->radiance);
                    light_pdf = light_pdf_triangle(e, tri_scale, dist2, -vdot(wo, n_light));
                    // end just off the light's surface, on our side, so it cannot occlude itself
                    shadow_dir = offset_ray_origin(y, vdot(n_light, wo) < 0.0f ? n_light : -n_light) - origin;
                    shadow_tmax = 1.0f;
                }
#endif
#if HAS_DELTA_LIGHTS
                if (slot >= params->emissive_count) {
                    // A point or spot light: a discrete choice, not a density. The "radiance"
                    // is intensity * falloff / dist^2 and the "pdf" the selection probability;
                    // BSDF sampling cannot hit it, so its MIS weight is 1 (delta_light below).
                    __global const DeltaLight* d = &delta_lights[slot - params->emissive_count];
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
            if (light_pdf > 0.0f && max_component(f) > 0.0f &&
                !trace_any(nodes, tris, make_ray(origin, shadow_dir, 0.0f, shadow_tmax))) {
                const float w =
                    delta_light ? 1.0f : weight_nee(light_pdf, bsdf_pdf(&mat, albedo, wi_local, wo_local));
                L += beta * f * Le * (w / light_pdf);
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
        if (max_component(weight) <= 0.0f) break;
        beta = beta * weight;
        prev_bsdf_pdf = delta ? INFINITY : pdf;
        dir = frame_to_world(frame, wo_local);
        // leave from the side the new direction points to (refraction crosses the surface)
        const float3 origin_next = vdot(dir, n_out) >= 0.0f ? origin : offset_ray_origin(x, -n_out);
        ray = make_ray(origin_next, dir, 0.0f, INFINITY);

        // Step 7: Russian roulette on the throughput: Mitsuba's rule, without its eta^2 factor
        // (which refraction tracking would add; unbiased either way).
        if (depth + 1u >= params->rr_depth) {
            const float q = fmin(max_component(beta), 0.95f);
            if (path_rand(rng, dim + DIM_RR) >= q) break;
            beta = beta * (1.0f / q);
        }
    }
    return L;
}

/// Reads the scene; adds the radiance of samples [sample_begin, sample_begin + sample_count) of
/// every pixel to accum[pixel] (rgb, w = sample count), and counts non-finite samples, which are
/// dropped, in guards[pixel]. nodes: the BVH (BvhNode or Bvh4Node by BVH_WIDTH); tris: leaf-order
/// triangles; prims: the same triangles in primitive order; uvs, textures, texels: texturing.
__kernel void render_pass(__global const float4* nodes, __global const BvhTriangle* tris,
                          __global const BvhTriangle* prims, __global const TriangleInfo* infos,
                          __global const TriangleUV* uvs, __global const TextureInfo* textures,
                          __global const float4* texels, __global const Material* materials,
                          __global const EmissiveTriangle* emissive,
                          __global const DeltaLight* delta_lights, __global const AliasEntry* alias,
                          __global const float4* env_texels, __global const float* env_cdf,
                          EnvMap envmap, DeviceCamera cam, RenderParams params,
                          __global float4* accum, __global uint* guards) {
    const uint pixel = get_global_id(0);
    if (pixel >= cam.width * cam.height) return;
    const uint px = pixel % cam.width, py = pixel / cam.width;
    float4 sum = accum[pixel];
    uint caught = guards[pixel];
    for (uint s = 0; s < params.sample_count; ++s) {
        PathRng rng;
        rng.seed = params.seed;
        rng.pixel = pixel;
        rng.sample = params.sample_begin + s;
        const float3 L = trace_path(nodes, tris, prims, infos, uvs, textures, texels, materials,
                                    emissive, delta_lights, alias, env_texels, env_cdf, &envmap,
                                    &cam, &params, rng, px, py);
        if (all_finite(L)) {
            sum += make_float4(L.x, L.y, L.z, 0.0f);
        } else {
            ++caught;
        }
        sum.w += 1.0f;
    }
    accum[pixel] = sum;
    guards[pixel] = caught;
}
