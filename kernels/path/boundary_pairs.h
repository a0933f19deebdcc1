// The secondary boundary term's light pairs (core/render/boundary.h: secondary_light_pairs;
// docs/method.md, "Light pairs"): an edge drawn with a light it may be a silhouette against, and a
// direction toward a point of that light, with the density of that technique.
#ifndef TANDEM_KERNELS_PATH_BOUNDARY_PAIRS_H
#define TANDEM_KERNELS_PATH_BOUNDARY_PAIRS_H

#include "path/boundary_secondary.h"

/// The secondary term's light pairs (core/render/boundary.h): `count` pairs (edge, light) in
/// `list`, sorted by edge, those of edge e at first[e] .. first[e + 1] - 1; a light is a range
/// (first triangle, count) of the emissive table in `lights`. A sample draws a pair with
/// probability `share`, by pmf, then a point uniform along the edge, a triangle of the light
/// uniformly and a point uniform on it to aim at.
typedef struct SecondaryPairs {
    __global const uint2* list;
    __global const float* pmf;        ///< each pair's probability
    __global const AliasEntry* alias; ///< over the pairs, by pmf
    __global const uint* first;
    __global const uint2* lights;
    __global const float4* chunks; ///< the emissive chunks (EMISSIVE_CHUNK)
    uint count;
    float share;
} SecondaryPairs;

/// The direction from xb toward a point uniform on a triangle of light `light` (u0 the triangle,
/// (u1, u2) the point, on either side of it), and in *density the density of that triangle's
/// points' directions at it (0 and a zero direction where the triangle's plane holds xb or it is
/// seen edge-on); *tri the triangle.
TANDEM_INLINE float3 secondary_toward_light(const SceneRefs* s, uint2 light, float3 xb, float eps,
                                            float u0, float u1, float u2, uint* tri,
                                            float* density) {
    *tri = light.x + min((uint)(u0 * (float)light.y), light.y - 1u);
    *density = 0.0f;
    __global const EmissiveTriangle* t = &s->emissive[*tri];
    if (secondary_in_light_plane(t, xb, eps)) return make_float3(0.0f, 0.0f, 0.0f);
    const float o[3] = {xb.x, xb.y, xb.z};
    float wo[3], dist2, cos_l, shadow[3];
    nee_triangle_sample((__global const float*)t, o, 1.0f, u1, u2, wo, &dist2, &cos_l, shadow);
    // either side, as the plain sampler's light directions and as secondary_pair_density counts
    // every triangle the ray crosses (a closed light's far side too)
    cos_l = fabs(cos_l);
    if (!(cos_l > 0.0f) || !(t->p0.w > 0.0f)) return make_float3(0.0f, 0.0f, 0.0f);
    *density = dist2 / (cos_l * t->p0.w);
    return make_float3(wo[0], wo[1], wo[2]);
}

/// The density of the pairs' technique at the edge point xb (uniform along edge `edge`, of length
/// len) and direction w, per unit length and solid angle: each pair of the edge drawn with its
/// pmf, then each triangle of its light the ray crosses with 1 / its triangles.
/// Triangle `drawn`, which w was drawn toward, counts `drawn_density` whatever the intersection
/// test says (its rounding may miss a point of the triangle's edge).
TANDEM_INLINE float secondary_pair_density(const SceneRefs* s, const SecondaryPairs* pairs,
                                           uint edge, float len, float3 xb, float3 w, float eps,
                                           uint drawn, float drawn_density) {
    float sum = 0.0f;
    for (uint k = pairs->first[edge]; k < pairs->first[edge + 1u]; ++k) {
        const uint2 light = pairs->lights[pairs->list[k].y];
        const uint end = light.x + light.y;
        float part = 0.0f;
        for (uint c = light.x / EMISSIVE_CHUNK; c * EMISSIVE_CHUNK < end; ++c) {
            const uint lo = max(light.x, c * EMISSIVE_CHUNK);
            const uint hi = min(end, (c + 1u) * EMISSIVE_CHUNK);
            const int near = emissive_chunk_near(xb, w, pairs->chunks[c]);
            if (!near && !(drawn >= lo && drawn < hi)) continue;
            for (uint e = lo; e < hi; ++e) {
                float dist, cos_l;
                if (e == drawn)
                    part += drawn_density;
                else if (near && secondary_ray_triangle(&s->emissive[e], xb, w, eps, &dist, &cos_l))
                    part += dist * dist / (cos_l * s->emissive[e].p0.w);
            }
        }
        sum += pairs->pmf[k] * part / (float)light.y;
    }
    return sum / len;
}

#endif // TANDEM_KERNELS_PATH_BOUNDARY_PAIRS_H
