// The megakernels' lookups in scalars, for the wavefront's vectorised shading stage
// (path/wavefront.h): MIS weights and light densities, textures, triangle points, and the
// environment's evaluation and sampling. Each repeats, operation for operation, the function it
// names, with selects where that one branches or loops, so that PoCL's loop vectoriser can run the
// stage 8 paths per instruction and the bits stay the megakernels'. (Why a second copy: the
// originals take OpenCL vector types, structs by pointer and loops, each of which the vectoriser
// refuses; docs/wavefront.md.)
#ifndef TANDEM_KERNELS_PATH_WAVEFRONT_LOOKUP_H
#define TANDEM_KERNELS_PATH_WAVEFRONT_LOOKUP_H

#include "path/primal.h"

#if HAS_ENVMAP && !defined(ENVMAP_SEARCH_STEPS)
#error "ENVMAP_SEARCH_STEPS must be passed with HAS_ENVMAP (core/render/features.cpp)"
#endif

#if HAS_TEXTURES
/// i mod n in [0, n) (texture_wrap).
TANDEM_INLINE uint wf_wrap(int i, uint n) {
    const int m = i % (int)n;
    return (uint)(m < 0 ? m + (int)n : m);
}

/// Channel c of texel i of the bitmap at texel offset `offset` or parameter `param`
/// (texture_texel). A branch, not a select of two loads: the vectoriser makes it two masked
/// gathers, each touching only its lanes' memory.
TANDEM_INLINE float wf_texel(__global const float* params, __global const float4* texels,
                             uint param, uint offset, uint i, uint c) {
    float value;
    if (param != NO_PARAM)
        value = params[param + 3u * i + c];
    else
        value = ((__global const float*)texels)[4u * (offset + i) + c];
    return value;
}

/// Channel c of texture_eval of texture `index` at texture coordinates (u, v): checkerboard, or a
/// bitmap filtered bilinearly or by the nearest texel. (The three channels' calls share their
/// address arithmetic once inlined.)
TANDEM_INLINE float wf_texture(__global const TextureInfo* textures, __global const float4* texels,
                               __global const float* params, uint index, float u, float v, uint c) {
    __global const float* tf = (__global const float*)(textures + index);
    __global const uint* tw = (__global const uint*)(textures + index);
    const uint kind = tw[16], offset = tw[17], filter = tw[20], param = tw[21];
    // a checkerboard has no texels: its wrapping divides by 1
    const uint width = max(tw[18], 1u), height = max(tw[19], 1u);
    const float tu = tf[8] * u + tf[9] * v + tf[10];
    const float tv = tf[12] * u + tf[13] * v + tf[14];
    // checkerboard
    const int mu = tu - det_floor(tu) > 0.5f, mv = tv - det_floor(tv) > 0.5f;
    const float checker = tf[(mu == mv ? 0u : 4u) + c];
#if !HAS_BITMAPS
    // no bitmap in the scene: no texel gathers, which every lane would do (masked) below
    (void)texels;
    (void)params;
    (void)kind;
    (void)offset;
    (void)filter;
    (void)param;
    (void)width;
    (void)height;
    return checker;
#else
    // bitmap (texture_footprint), nearest
    const float x = tu * (float)width, y = tv * (float)height;
    const uint nearest = wf_wrap((int)det_floor(y), height) * width + wf_wrap((int)det_floor(x), width);
    // bitmap, bilinear between the four texel centres around (x, y)
    const float fx = x - 0.5f, fy = y - 0.5f;
    const float x0 = det_floor(fx), y0 = det_floor(fy);
    const float ax = fx - x0, ay = fy - y0;
    const int ix = (int)x0, iy = (int)y0;
    const uint i0 = wf_wrap(iy, height) * width + wf_wrap(ix, width);
    const uint i1 = wf_wrap(iy, height) * width + wf_wrap(ix + 1, width);
    const uint i2 = wf_wrap(iy + 1, height) * width + wf_wrap(ix, width);
    const uint i3 = wf_wrap(iy + 1, height) * width + wf_wrap(ix + 1, width);
    const float w0 = (1.0f - ax) * (1.0f - ay), w1 = ax * (1.0f - ay), w2 = (1.0f - ax) * ay,
                w3 = ax * ay;
    const float blend = wf_texel(params, texels, param, offset, i0, c) * w0 +
                        wf_texel(params, texels, param, offset, i1, c) * w1 +
                        wf_texel(params, texels, param, offset, i2, c) * w2 +
                        wf_texel(params, texels, param, offset, i3, c) * w3;
    // the nearest texel's weight is 1: texel * 1.0f is the texel
    const float bitmap = filter != TEXTURE_FILTER_NEAREST
                             ? blend
                             : wf_texel(params, texels, param, offset, nearest, c);
    return kind == TEXTURE_CHECKERBOARD ? checker : bitmap;
#endif
}
#endif

#if BVH_ANALYTIC
/// primitive_point (path/interaction.h) in scalars for the record at t (ShadingPrimitive): the
/// triangle's point and normal, the sphere's and the disk's are all computed, and the record's
/// kind picks one, so that the vectoriser keeps a single path of code. The operations are
/// primitive_point's, in its order, so the bits are the same.
TANDEM_INLINE void wf_primitive_point(__global const float* t, float u, float v, float* p,
                                      float* n) {
    float tp[3], tn[3];
    triangle_point(t, 1.0f - u - v, u, v, tp, tn);
    const uint kind = as_uint(t[7]);
    const float cx = t[0], cy = t[1], cz = t[2];
    // a sphere: centre + radius times the decoded direction; front = direction x orientation
    float sx, sy, sz;
    bvh_oct_decode(u, v, &sx, &sy, &sz);
    const float radius = t[4], orient_s = t[5];
    // a disk: centre + u x_axis + v y_axis; front = normalize(x_axis x y_axis) x orientation
    const float ax = t[4], ay = t[5], az = t[6], bx = t[8], by = t[9], bz = t[10];
    const float qx = ay * bz - az * by, qy = az * bx - ax * bz, qz = ax * by - ay * bx;
    const float inv_q = 1.0f / sqrt(qx * qx + qy * qy + qz * qz);
    const float orient_d = t[11];
    // bit tests, not comparisons: LLVM turned two comparisons of `kind` into a switch, which
    // the loop vectoriser refuses (BVH_PRIM_SPHERE and BVH_PRIM_DISK are single bits)
    const int sphere = (kind & BVH_PRIM_SPHERE) != 0u, disk = (kind & BVH_PRIM_DISK) != 0u;
    p[0] = sphere ? cx + sx * radius : (disk ? cx + ax * u + bx * v : tp[0]);
    p[1] = sphere ? cy + sy * radius : (disk ? cy + ay * u + by * v : tp[1]);
    p[2] = sphere ? cz + sz * radius : (disk ? cz + az * u + bz * v : tp[2]);
    n[0] = sphere ? sx * orient_s : (disk ? qx * inv_q * orient_d : tn[0]);
    n[1] = sphere ? sy * orient_s : (disk ? qy * inv_q * orient_d : tn[1]);
    n[2] = sphere ? sz * orient_s : (disk ? qz * inv_q * orient_d : tn[2]);
}

#if HAS_TEXTURES
/// primitive_uv in scalars, as wf_primitive_point: the triangle's interpolated uvs from its
/// record in uvs (TriangleUV) at `uv`, the sphere's or the disk's, picked by the kind of the
/// primitive record at t.
TANDEM_INLINE void wf_primitive_uv(__global const float* t, __global const float* uv, float u,
                                   float v, float* tu, float* tv) {
    const uint kind = as_uint(t[7]);
    float sx, sy, sz;
    bvh_oct_decode(u, v, &sx, &sy, &sz);
    bvh_quat_rotate(t[8], t[9], t[10], t[11], &sx, &sy, &sz); // into the sphere's own axes
    const int sphere = (kind & BVH_PRIM_SPHERE) != 0u, disk = (kind & BVH_PRIM_DISK) != 0u;
    // the angle: of the direction from a sphere's centre, or of a disk's local point (one
    // atan2 of selected arguments, not two selected results: every lane computes both)
    const float phi = det_atan2(sphere ? sy : v, sphere ? sx : u);
    const float phi_u = (phi < 0.0f ? phi + 2.0f * TANDEM_PI : phi) * (0.5f * TANDEM_INV_PI);
    const float theta_v = det_acos(fmin(fmax(sz, -1.0f), 1.0f)) * TANDEM_INV_PI;
    const float r = sqrt(u * u + v * v);
    float ttu, ttv;
    triangle_uv(uv, u, v, &ttu, &ttv);
    *tu = sphere ? phi_u : (disk ? r : ttu);
    *tv = sphere ? theta_v : (disk ? phi_u : ttv);
}
#endif
#endif

#if HAS_ENV_LIGHT
#if HAS_ENVMAP
/// envmap_find (shared/envmap.h) as ENVMAP_SEARCH_STEPS steps of selects, ceil(log2(n)) for the
/// largest n of the map's two searches (features.cpp): each step halves [lo, hi) as the loop does,
/// and a step after the interval is down to one cell keeps it. The same cell; no loop left inside
/// the work-item loop for the vectoriser to refuse.
TANDEM_INLINE uint wf_envmap_find(__global const float* c, uint n, float u) {
    uint lo = 0u, hi = n;
#pragma unroll
    for (uint k = 0u; k < ENVMAP_SEARCH_STEPS; ++k) {
        const uint mid = (lo + hi) / 2u; // lo where hi = lo + 1: a valid index still
        const int below = c[mid] <= u, open = hi - lo > 1u;
        lo = open && below ? mid : lo;
        hi = open && !below ? mid : hi;
    }
    return lo;
}

/// envmap_eval and envmap_pdf (shared/envmap.h) of world direction (dx, dy, dz) at once, from one
/// footprint: the radiance into Le[0..3); returns the solid-angle density.
TANDEM_INLINE float wf_envmap_lookup(const EnvMap* env, __global const float4* env_texels,
                                     float dx, float dy, float dz, float* Le) {
    // envmap_to_local
    const float lx = env->to_local0.x * dx + env->to_local0.y * dy + env->to_local0.z * dz;
    const float ly = env->to_local1.x * dx + env->to_local1.y * dy + env->to_local1.z * dz;
    const float lz = env->to_local2.x * dx + env->to_local2.y * dy + env->to_local2.z * dz;
    // envmap_footprint (det_floor is floor for finite values; x0f < 0 takes no conversion)
    const uint w = env->width, h = env->height;
    float u = det_atan2(lx, -lz) * (0.5f * TANDEM_INV_PI);
    u = u - det_floor(u);
    const float v = det_acos(fmin(fmax(ly, -1.0f), 1.0f)) * TANDEM_INV_PI;
    const float fx = u * (float)w - 0.5f;
    const float x0f = det_floor(fx);
    const float ax = fx - x0f;
    const uint x0 = x0f < 0.0f ? w - 1u : min((uint)fmax(x0f, 0.0f), w - 1u);
    const uint x1 = x0 + 1u < w ? x0 + 1u : 0u;
    const float fy = fmin(fmax(v, 0.0f) * (float)(h - 1u), (float)(h - 1u));
    const uint y0 = min((uint)fy, h - 2u);
    const float ay = fy - (float)y0;
    __global const float* t = (__global const float*)(env_texels + env->texel_offset);
    const uint i00 = 4u * (y0 * w + x0), i10 = 4u * (y0 * w + x1);
    const uint i01 = 4u * ((y0 + 1u) * w + x0), i11 = 4u * ((y0 + 1u) * w + x1);
    // envmap_eval: rgb; envmap_pdf: w. (Written out: a loop over the channels would be
    // vectorised on its own, 2 wide, before the loop over work items, which then is not.)
    Le[0] = envmap_lerp(envmap_lerp(t[i00], t[i10], ax), envmap_lerp(t[i01], t[i11], ax), ay);
    Le[1] = envmap_lerp(envmap_lerp(t[i00 + 1u], t[i10 + 1u], ax),
                        envmap_lerp(t[i01 + 1u], t[i11 + 1u], ax), ay);
    Le[2] = envmap_lerp(envmap_lerp(t[i00 + 2u], t[i10 + 2u], ax),
                        envmap_lerp(t[i01 + 2u], t[i11 + 2u], ax), ay);
    const float pdf_uv = envmap_lerp(envmap_lerp(t[i00 + 3u], t[i10 + 3u], ax),
                                     envmap_lerp(t[i01 + 3u], t[i11 + 3u], ax), ay);
    const float sin_theta = sqrt(fmax(0.0f, 1.0f - ly * ly));
    return sin_theta > 0.0f ? pdf_uv / (2.0f * TANDEM_PI * TANDEM_PI * sin_theta) : 0.0f;
}

/// envmap_sample_eval (shared/envmap.h): the world direction drawn from (u1, u2) into d[0..3), its
/// radiance into Le[0..3); returns its density.
TANDEM_INLINE float wf_envmap_sample(const EnvMap* env, __global const float4* env_texels,
                                     __global const float* env_cdf, float u1, float u2, float* d,
                                     float* Le) {
    const uint w = env->width, cells_y = env->height - 1u;
    __global const float* rows = env_cdf + env->cdf_offset;
    const uint y = wf_envmap_find(rows, cells_y, u1);
    __global const float* cols = rows + (cells_y + 1u) + y * (w + 1u);
    const uint x = wf_envmap_find(cols, w, u2);
    const float ry = fmin((u1 - rows[y]) / fmax(rows[y + 1u] - rows[y], 1e-30f), 1.0f);
    const float rx = fmin((u2 - cols[x]) / fmax(cols[x + 1u] - cols[x], 1e-30f), 1.0f);
    __global const float* t = (__global const float*)(env_texels + env->texel_offset);
    const uint x1 = x + 1u < w ? x + 1u : 0u;
    const uint i00 = 4u * (y * w + x), i10 = 4u * (y * w + x1);
    const uint i01 = 4u * ((y + 1u) * w + x), i11 = 4u * ((y + 1u) * w + x1);
    const float w00 = t[i00 + 3u], w10 = t[i10 + 3u], w01 = t[i01 + 3u], w11 = t[i11 + 3u];
    const float ty = envmap_invert_linear(w00 + w10, w01 + w11, ry);
    const float c0 = envmap_lerp(w00, w01, ty), c1 = envmap_lerp(w10, w11, ty);
    const float tx = envmap_invert_linear(c0, c1, rx);
    const float u = ((float)x + 0.5f + tx) / (float)w;
    const float v = ((float)y + ty) / (float)cells_y;
    const float theta = v * TANDEM_PI, phi = 2.0f * TANDEM_PI * u;
    float st, ct, sp, cp;
    det_sincos(theta, &st, &ct);
    det_sincos(phi, &sp, &cp);
    const float l0 = st * sp, l1 = ct, l2 = -st * cp;
    d[0] = env->to_local0.x * l0 + env->to_local1.x * l1 + env->to_local2.x * l2;
    d[1] = env->to_local0.y * l0 + env->to_local1.y * l1 + env->to_local2.y * l2;
    d[2] = env->to_local0.z * l0 + env->to_local1.z * l1 + env->to_local2.z * l2;
    Le[0] = envmap_lerp(envmap_lerp(t[i00], t[i10], tx), envmap_lerp(t[i01], t[i11], tx), ty);
    Le[1] = envmap_lerp(envmap_lerp(t[i00 + 1u], t[i10 + 1u], tx),
                        envmap_lerp(t[i01 + 1u], t[i11 + 1u], tx), ty);
    Le[2] = envmap_lerp(envmap_lerp(t[i00 + 2u], t[i10 + 2u], tx),
                        envmap_lerp(t[i01 + 2u], t[i11 + 2u], tx), ty);
    const float pdf_uv = envmap_lerp(c0, c1, tx);
    return st > 0.0f ? pdf_uv / (2.0f * TANDEM_PI * TANDEM_PI * st) : 0.0f;
}
#endif
#endif

#endif // TANDEM_KERNELS_PATH_WAVEFRONT_LOOKUP_H
