// The scene as the path kernels see it: the feature flags, SceneRefs (generated from the kernel
// arguments of shared/scene_args.h), ray queries, parameter access, materials and the camera ray.
#ifndef TANDEM_KERNELS_PATH_SCENE_H
#define TANDEM_KERNELS_PATH_SCENE_H

// Feature flags (core/render/features.h: render_features), always passed explicitly.
#if !defined(BVH_WIDTH) || (BVH_WIDTH != 2 && BVH_WIDTH != 4 && BVH_WIDTH != 8)
#error "BVH_WIDTH must be passed as 2, 4 or 8"
#endif
#if !defined(HAS_AREA_LIGHTS) || !defined(HAS_ENV_LIGHT) || !defined(LIGHT_STRATEGY) ||            \
    !defined(HAS_TEXTURES) || !defined(HAS_DELTA_LIGHTS) || !defined(HAS_ENVMAP) ||                \
    !defined(BSDF_CONDUCTOR) || !defined(BSDF_DIELECTRIC) || !defined(BSDF_PLASTIC) ||             \
    !defined(BVH_AXIS_LOOPS) || !defined(BVH_ANALYTIC) || !defined(BVH_TRI4) ||                    \
    !defined(BVH_PREFETCH) || !defined(HAS_BITMAPS) || !defined(CAMERA_PACKETS) ||             \
    !defined(HAS_MEDIA) || !defined(SHAPE_GRAD) || !defined(HAS_SHADING_NORMALS)
#error "every feature flag (HAS_*, BSDF_*, LIGHT_STRATEGY, BVH_*) must be passed"
#endif
#define HAS_ALIAS_LIGHTS (HAS_AREA_LIGHTS || HAS_DELTA_LIGHTS)

#define STRATEGY_MIS 0
#define STRATEGY_BSDF_ONLY 1
#define STRATEGY_NEE_ONLY 2
#define USE_NEE (LIGHT_STRATEGY != STRATEGY_BSDF_ONLY)

#if CAMERA_PACKETS && (BVH_WIDTH != 8 || !BVH_TRI4 || BVH_ANALYTIC)
#error "CAMERA_PACKETS needs the eight-wide tree of BvhTri4 blocks (BVH_WIDTH 8, BVH_TRI4 1)"
#endif

#include "path/random.h"
#include "shared/bsdfs.h"
#include "shared/bvh8_packet.h"
#include "shared/pixel_sample.h"
#include "shared/scene_args.h"
#include "shared/textures.h"

#define PATH_SCENE_REF_BUFFER(T, name) __global const T* name;
#define PATH_SCENE_REF_VALUE(T, name) const T* name;

/// The scene as the kernels see it: a member per scene argument (shared/scene_args.h), buffers as
/// they are and by-value records through a pointer to the kernel's argument, and the launch's
/// RenderParams.
typedef struct SceneRefs {
    TANDEM_SCENE_ARGS(PATH_SCENE_REF_BUFFER, PATH_SCENE_REF_VALUE)
    const RenderParams* rp;
} SceneRefs;

#define PATH_SCENE_INIT_BUFFER(T, name) name,
#define PATH_SCENE_INIT_VALUE(T, name) &name,

/// The initialiser of the SceneRefs of a kernel declared with SCENE_ARGS and its RenderParams
/// `rp`: `const SceneRefs s = SCENE_REFS(rp);`.
#define SCENE_REFS(rp)                                                                             \
    {                                                                                              \
        TANDEM_SCENE_ARGS(PATH_SCENE_INIT_BUFFER, PATH_SCENE_INIT_VALUE)                           \
        PATH_SCENE_INIT_VALUE(RenderParams, rp)                                                    \
    }

/// The closest hit along `ray`. Inlined wherever it is called (TANDEM_INLINE): a kernel that
/// calls it twice, as one that fuses the resampling pass into its paths does (path/resample.h),
/// got the traversal as a call otherwise, and ran slower on PoCL.
TANDEM_INLINE Hit trace_closest(const SceneRefs* s, Ray ray) {
    Hit hit; // written through a pointer, not returned on from the traversal: see compat.h
#if BVH_WIDTH == 8
    bvh8_intersect_closest_into((__global const Bvh8Node*)s->nodes, s->tris, ray, BVH_TRI4, &hit);
#elif BVH_WIDTH == 4
    bvh4_intersect_closest_into((__global const Bvh4Node*)s->nodes, s->tris, ray, BVH_TRI4, &hit);
#else
    bvh_intersect_closest_into((__global const BvhNode*)s->nodes, s->tris, ray, &hit);
#endif
    return hit;
}

static inline int trace_any(const SceneRefs* s, Ray ray) {
#if BVH_WIDTH == 8
    return bvh8_intersect_any((__global const Bvh8Node*)s->nodes, s->tris, ray, BVH_TRI4);
#elif BVH_WIDTH == 4
    return bvh4_intersect_any((__global const Bvh4Node*)s->nodes, s->tris, ray, BVH_TRI4);
#else
    return bvh_intersect_any((__global const BvhNode*)s->nodes, s->tris, ray);
#endif
}

/// The ray o + t d, t in [tmin, tmax). The direction is kept as given: xyz(ray.dir) is d.
static inline Ray make_ray(float3 o, float3 d, float tmin, float tmax) {
    Ray r;
    r.org = make_float4(o.x, o.y, o.z, tmin);
    r.dir = make_float4(d.x, d.y, d.z, tmax);
    return r;
}

static inline float3 param_rgb(__global const float* params, uint offset) {
    return make_float3(params[offset], params[offset + 1u], params[offset + 2u]);
}

/// Channel c of the rgb parameter at `offset` in `params`, or `fixed` where there is none
/// (NO_PARAM).
TANDEM_INLINE float param_or(__global const float* params, uint offset, uint c, float fixed) {
    return offset != NO_PARAM ? params[offset + c] : fixed;
}

/// Whether a path that found a surface at `depth` shades it (and goes on): max_depth counts the
/// path's segments, so the last one only collects the emission it finds.
TANDEM_INLINE int path_continues(const RenderParams* rp, uint depth) {
    return depth + 1u < rp->max_depth;
}

/// The rgb parameter at `offset` in `params`, or `fixed` where there is none (NO_PARAM): what a
/// value computed under one parameter state is under another.
TANDEM_INLINE float3 param_rgb_or(__global const float* params, uint offset, float3 fixed) {
    return offset != NO_PARAM ? param_rgb(params, offset) : fixed;
}

/// Material `index` with its differentiable values taken from params. eta and k are never
/// parameters: the two-state path's delta lobes rely on it (continuation_weight_old).
static inline Material material_load(const SceneRefs* s, __global const float* params, uint index) {
    Material m = s->materials[index];
    if (m.reflectance_param != NO_PARAM) { // param_or's values: reflectance is a parameter
        m.reflectance = make_float4(param_or(params, m.reflectance_param, 0u, m.reflectance.x),
                                    param_or(params, m.reflectance_param, 1u, m.reflectance.y),
                                    param_or(params, m.reflectance_param, 2u, m.reflectance.z),
                                    0.0f);
    }
    if (m.specular_param != NO_PARAM) {
        const float3 c = param_rgb(params, m.specular_param);
        m.specular = make_float4(c.x, c.y, c.z, 0.0f);
    }
    if (m.alpha_param != NO_PARAM) m.alpha = params[m.alpha_param];
    return m;
}

/// The albedo of material m at a surface point (texture coordinates tu, tv) under `params`.
/// Inlined wherever it is called, as trace_closest: the two-state kernel, which calls it twice,
/// runs faster on PoCL so.
TANDEM_INLINE float3 material_albedo(const SceneRefs* s, const Material* m,
                                     __global const float* params, float tu, float tv) {
#if HAS_TEXTURES
    if (m->texture != NO_TEXTURE)
        return texture_eval(&s->textures[m->texture], s->texels, params, tu, tv);
#endif
    (void)s;
    (void)params;
    (void)tu;
    (void)tv;
    return xyz(m->reflectance);
}

/// The camera ray through point (px + u0, py + u1) of the image: its unit direction into d[0..3)
/// and its extent, from the near to the far clip plane, into *tmin and *tmax (it starts at the
/// camera's origin). Scalars: path_camera_ray_at and the wavefront's wf_generate, which PoCL
/// vectorises, both call it.
TANDEM_INLINE void camera_ray(const DeviceCamera* cam, uint px, uint py, float u0, float u1,
                              float* d, float* tmin, float* tmax) {
    const float fx = ((float)px + u0) / (float)cam->width;
    const float fy = ((float)py + u1) / (float)cam->height;
    const float sx = 1.0f - 2.0f * fx, sy = 1.0f - 2.0f * fy;
    const float vx = (cam->dir_z.x + cam->dir_x.x * sx) + cam->dir_y.x * sy;
    const float vy = (cam->dir_z.y + cam->dir_x.y * sx) + cam->dir_y.y * sy;
    const float vz = (cam->dir_z.z + cam->dir_x.z * sx) + cam->dir_y.z * sy;
    const float inv_len = 1.0f / sqrt(dot3(vx, vy, vz, vx, vy, vz)); // vnormalize
    d[0] = vx * inv_len;
    d[1] = vy * inv_len;
    d[2] = vz * inv_len;
    const float cos_z = dot3(d[0], d[1], d[2], cam->dir_z.x, cam->dir_z.y, cam->dir_z.z);
    *tmin = cam->near_clip / cos_z;
    *tmax = cam->far_clip / cos_z;
}

/// The camera ray through point (px + u0, py + u1) of the image (camera_ray).
TANDEM_INLINE Ray path_camera_ray_at(const SceneRefs* s, uint px, uint py, float u0, float u1) {
    float d[3], tmin, tmax;
    camera_ray(s->cam, px, py, u0, u1, d, &tmin, &tmax);
    return make_ray(xyz(s->cam->origin), make_float3(d[0], d[1], d[2]), tmin, tmax);
}

/// The camera ray of sample `sample` of pixel (px, py) whose quadrant offset is `offset`
/// (shared/pixel_sample.h), at (u0, u1) inside its quadrant.
TANDEM_INLINE Ray path_camera_ray_sample(const SceneRefs* s, uint px, uint py, uint sample,
                                         uint offset, float u0, float u1) {
    const uint q = pixel_quadrant(sample, offset);
    return path_camera_ray_at(s, px, py, pixel_stratified(u0, q & 1u),
                              pixel_stratified(u1, q >> 1u));
}

/// The camera ray of a path (a box filter over its pixel, stratified: shared/pixel_sample.h):
/// random dimensions 0 and 1 of the path (on x86 CPUs from one eight-lane hash, cheaper than two:
/// path/random.h).
TANDEM_INLINE Ray path_camera_ray(const SceneRefs* s, PathRng rng, uint px, uint py) {
    const uint offset = pixel_quadrant_offset(rng.seed, rng.pixel);
#if PATH_RNG_LANES
    const float8 u = rng_uniform8(rng.seed, rng.pixel, rng.sample, 0u);
    return path_camera_ray_sample(s, px, py, rng.sample, offset, u.s0, u.s1);
#else
    return path_camera_ray_sample(s, px, py, rng.sample, offset, path_rand(rng, 0),
                                  path_rand(rng, 1));
#endif
}

#endif // TANDEM_KERNELS_PATH_SCENE_H
