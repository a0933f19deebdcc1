// Reuse of the secondary boundary term's light vertices across iterations ("Amortizing Samples in
// Physics-Based Inverse Rendering using ReSTIR", Wang, Wyman, Wu, Zhao, SIGGRAPH Asia 2023,
// Sec. 5.2, Alg. 6; docs/restir.md, "Reuse for the boundary"). Where shadows of many lights make
// the secondary term's noise, a direction from an edge point x_B pays only if it aims at a light
// against which the edge is a silhouette, and which sees x_B: a light point that paid at a nearby
// x_B last iteration likely pays here too.
//
// With reuse the directions from x_B are split in two: (A) (kernels/boundary.cl) keeps those that
// aim at no emissive triangle, and (R) here integrates the others over the emissive triangles'
// points y, in area measure. Where the ray x_B + s w crosses several emissive triangles (a closed
// light's near and far sides), each crossing point takes the share of its density among them
// (the balance heuristic over the crossings), so that
//     integral over (R)'s directions of f(w) dw = integral over y of f(w_y) p_A(y) / p_L(w_y) dA(y),
// p_A(y) the area density of the lights' alias table (selection probability over area) and p_L
// the light-sampled direction density (path/boundary_secondary.h: secondary_light_density). y is
// resampled: fresh candidates from p_A by streaming RIS, then combined with the previous
// iteration's reservoirs whose x_B lay in the same grid cell under defensive pairwise MIS
// (shared/reservoir.h; a reservoir's own target is evaluated at its own x_B, on the edge table of
// its iteration, so a silhouette that turned is no longer counted as its support). The target is
// cheap and positive wherever f may not be 0: the luminance of the light along w (plus a floor,
// for the light a light's surface reflects) times |cos| / d^2 at y times |T x w|, zero where the
// edge is neither a silhouette nor a clear crease toward y; where SecondaryReuse::flags asks, the
// light along w is what either side of the edge sees first (at least SECONDARY_REUSE_HIDDEN of y's), and
// the whole is weighed by SECONDARY_REUSE_HIDDEN where the camera does not see the receiver
// directly. It is proportional to neither side's share of a closed light: y on its far side has
// the near side's light, which is what its direction sees. Every reservoir is written by the one work item of its
// sample; the previous ones are read only.
#ifndef TANDEM_KERNELS_PATH_BOUNDARY_REUSE_H
#define TANDEM_KERNELS_PATH_BOUNDARY_REUSE_H

#include "path/boundary_secondary.h"
#include "shared/boundary.h"
#include "shared/reservoir.h"

/// The target's factor for a light point neither side of the edge sees (positive: a hidden light
/// still lights what x_s sees through reflections, and the support must hold every direction the
/// integrand may use).
#define SECONDARY_REUSE_HIDDEN 0.05f
/// The sample counter of the resampling's random numbers (fresh candidates, neighbour picks,
/// coins), of (R)'s walk and of its sides' paths (path_rng's third key, after the secondary
/// term's BOUNDARY_COUNTER + 5).
#define SECONDARY_REUSE_COUNTER 0x80000006u
/// Dimensions of the resampling's stream per fresh candidate.
#define SECONDARY_REUSE_DIMS 5u

/// The buffers and settings of one pass's reuse (kernels/boundary.cl: boundary_secondary).
typedef struct SecondaryReuseRefs {
    SecondaryReuse p;
    __global const BoundaryReservoir* prev;  ///< the previous iteration's, one per sample
    __global const SecondaryEdge* prev_edges; ///< the previous iteration's edge table
    __global const uint* bucket_first;        ///< p.buckets + 1 starts into bucket_slots
    __global const uint* bucket_slots;        ///< previous reservoirs by bucket, in slot order
    __global BoundaryReservoir* out;          ///< this iteration's, one per sample
    __global const float4* chunks;            ///< the emissive chunks (EMISSIVE_CHUNK)
} SecondaryReuseRefs;

/// A boundary point x_B: at parameter t of an edge, and its tangent T.
typedef struct SecondaryPoint {
    SecondaryEdge edge;
    float3 xb, T;
    float eps;
    int creases; ///< whether clear creases count (max_depth 3 on: boundary_secondary_sample)
} SecondaryPoint;

TANDEM_INLINE SecondaryPoint secondary_point(const SecondaryEdge* e, float t, int creases) {
    SecondaryPoint p;
    p.edge = *e;
    const float3 a = xyz(e->p0), b = xyz(e->p1);
    p.T = (b - a) * (1.0f / vlength(b - a));
    p.xb = a + (b - a) * t;
    p.eps = SECONDARY_EPS * (1.0f + fmax(fabs(p.xb.x), fmax(fabs(p.xb.y), fabs(p.xb.z))));
    p.creases = creases;
    return p;
}

/// The luminance of the emission that the ray o + t w (t > 0) meets first: an emitter's front side
/// (0 where it meets anything else, or nothing).
TANDEM_INLINE float secondary_seen_emission(const SceneRefs* s, __global const float* params,
                                            float3 o, float3 w) {
    const Ray ray = make_ray(o, w, 0.0f, INFINITY);
    const Hit hit = trace_closest(s, ray);
    if (hit.prim == HIT_NONE) return 0.0f;
    const uint e = s->infos[hit.prim].emitter;
    if (e == NO_EMITTER) return 0.0f;
    __global const EmissiveTriangle* t = &s->emissive[e];
    if (!(vdot(make_float3(t->nx, t->ny, t->nz), w) < 0.0f)) return 0.0f;
    return fmax(luminance(param_rgb(params, t->radiance_param)), 0.0f);
}

/// The target of light point (light, u1, u2) at boundary point p (see the top of this file), and
/// in *w the unit direction from p to the point, in *density its direction density under the
/// alias table (p_A d^2 / |cos|). 0 where the point is not on (R)'s support.
TANDEM_INLINE float secondary_reuse_target(const SceneRefs* s, __global const float* params,
                                           const SecondaryReuse* rs, const SecondaryPoint* p,
                                           uint light, float u1, float u2, float3* w,
                                           float* density) {
    *w = make_float3(0.0f, 0.0f, 0.0f);
    *density = 0.0f;
    if (light >= s->rp->emissive_count) return 0.0f;
    __global const EmissiveTriangle* tri = &s->emissive[light];
    if (!(tri->p0.w > 0.0f) || secondary_in_light_plane(tri, p->xb, p->eps)) return 0.0f;
    const float o[3] = {p->xb.x, p->xb.y, p->xb.z};
    float wo[3], dist2, cos_l, shadow[3];
    nee_triangle_sample((__global const float*)tri, o, 1.0f, u1, u2, wo, &dist2, &cos_l, shadow);
    *w = make_float3(wo[0], wo[1], wo[2]);
    const float ac = fabs(cos_l);
    if (!(ac > 0.0f && dist2 > 0.0f)) return 0.0f;
    if (!(secondary_silhouette(&p->edge, *w) ||
          (p->creases && secondary_crease_clear(&p->edge, *w))))
        return 0.0f;
    *density = tri->p1.w / tri->p0.w * dist2 / ac;
    // the light along w: y's own luminance (either side: where y is a closed light's far side,
    // the ray meets the near side first, of the same radiance); with visibility, what either side
    // of the edge sees first along w, kept at least SECONDARY_REUSE_HIDDEN of y's
    const float lum_y = fmax(luminance(param_rgb(params, tri->radiance_param)), 0.0f);
    float L = lum_y;
    if ((rs->flags & SECONDARY_REUSE_LIGHT_VISIBLE) != 0u) {
        // the side away from the edge's faces first (their mean normal's side of the plane of
        // T and w): a silhouette's other side is the occluder itself, which sees no light, so
        // the second side is traced only where the first sees none
        float3 n_w = vnormalize(vcross(*w, p->T));
        if (vdot(n_w, xyz(p->edge.n0) + xyz(p->edge.n1)) < 0.0f) n_w = -n_w;
        L = secondary_seen_emission(s, params, p->xb + n_w * p->eps, *w);
        if (!(L > 0.0f)) L = secondary_seen_emission(s, params, p->xb - n_w * p->eps, *w);
        L = fmax(L, SECONDARY_REUSE_HIDDEN * lum_y);
    }
    float v = (L + rs->lum_floor) * ac / dist2 * vlength(vcross(p->T, *w));
    if ((rs->flags & SECONDARY_REUSE_RECEIVER_SEEN) != 0u && v > 0.0f) {
        // the receiver x_s, found from x_B along -w, seen by the camera (route 0 only: one seen
        // through bounces keeps the factor's floor)
        const Ray back = make_ray(p->xb, -*w, p->eps, INFINITY);
        const Hit hit = trace_closest(s, back);
        Receiver rc;
        int seen = 0;
        if (hit.prim != HIT_NONE) {
            interaction_at(s, back, hit, &rc.it);
            seen = secondary_to_camera(s, params, *w, &rc);
        }
        if (!seen) v *= SECONDARY_REUSE_HIDDEN;
    }
    return isfinite(v) ? v : 0.0f;
}

/// The target of reservoir r's light point at point p, with no direction wanted.
TANDEM_INLINE float secondary_reuse_target_of(const SceneRefs* s, __global const float* params,
                                              const SecondaryReuse* rs, const SecondaryPoint* p,
                                              const BoundaryReservoir* r) {
    float3 w;
    float density;
    return secondary_reuse_target(s, params, rs, p, r->light, r->u1, r->u2, &w, &density);
}

/// Resamples the light vertex of sample `sample`, boundary point p (edge `edge_index` at t):
/// rs.candidates fresh points from the lights' alias table by streaming RIS, then the combine with
/// up to rs.neighbours previous reservoirs of p's cell (those of its bucket with its hash, from a
/// random start in slot order). Writes the result to out[sample] and returns it, with the
/// direction toward its point in *w and that direction's density in *density
/// (secondary_reuse_target).
TANDEM_INLINE BoundaryReservoir secondary_reuse_resample(const SceneRefs* s,
                                                         __global const float* params,
                                                         const SecondaryReuseRefs* refs,
                                                         const SecondaryPoint* p, uint edge_index,
                                                         float t, uint sample, float3* w_out,
                                                         float* density_out) {
    const SecondaryReuse* rs = &refs->p;
    const RenderParams* rp = s->rp;
    const PathRng rng = path_rng(rp->seed, sample, SECONDARY_REUSE_COUNTER);
    BoundaryReservoir r;
    r.edge = edge_index;
    r.t = t;
    r.light = NO_EMISSIVE;
    r.u1 = 0.0f;
    r.u2 = 0.0f;
    r.W = 0.0f;
    r.M = 0.0f;
    r.cell = secondary_reuse_cell(p->xb, rs->cell);
    // fresh candidates: each from the alias table over every light (a point or spot light's slot
    // is a candidate of target 0)
    const uint lights = rp->emissive_count + rp->delta_count;
    float w_sum = 0.0f, P_c = 0.0f;
    float3 w_c = make_float3(0.0f, 0.0f, 0.0f);
    float density_c = 0.0f;
    for (uint m = 0u; m < rs->candidates && lights > 0u; ++m) {
        const uint d = SECONDARY_REUSE_DIMS * m;
        const uint slot = min((uint)(path_rand(rng, d) * (float)lights), lights - 1u);
        const uint e = path_rand(rng, d + 1u) >= s->alias[slot].q ? s->alias[slot].alias : slot;
        if (e >= rp->emissive_count) continue;
        const float u1 = path_rand(rng, d + 2u), u2 = path_rand(rng, d + 3u);
        float3 w;
        float density;
        const float P = secondary_reuse_target(s, params, rs, p, e, u1, u2, &w, &density);
        const float p_A = s->emissive[e].p1.w / s->emissive[e].p0.w;
        if (wrs_update(&w_sum, reservoir_ratio(P, p_A * (float)rs->candidates),
                       path_rand(rng, d + 4u))) {
            r.light = e;
            r.u1 = u1;
            r.u2 = u2;
            P_c = P;
            w_c = w;
            density_c = density;
        }
    }
    const float W_c = reservoir_ratio(w_sum, P_c);
    // the previous reservoirs of p's cell
    const uint base = SECONDARY_REUSE_DIMS * rs->candidates;
    uint nb[RESTIR_MAX_NEIGHBOURS];
    uint k = 0u;
    const float M_c = 1.0f;
    float M_sum = M_c;
    if (rs->buckets > 0u) {
        const uint bucket = r.cell & (rs->buckets - 1u);
        const uint first = refs->bucket_first[bucket];
        const uint n = refs->bucket_first[bucket + 1u] - first;
        const uint start = n > 0u ? min((uint)(path_rand(rng, base) * (float)n), n - 1u) : 0u;
        const uint wanted = min(rs->neighbours, (uint)RESTIR_MAX_NEIGHBOURS);
        for (uint j = 0u; j < n && k < wanted; ++j) {
            const uint i = refs->bucket_slots[first + (start + j) % n];
            const BoundaryReservoir q = refs->prev[i];
            // by the cell alone, never by the sample: an empty neighbour stays in M_sum and in
            // the canonical's terms, with a resampling weight of 0 (dropping it would keep only
            // the neighbours whose own random samples came out non-empty, and bias the chain:
            // tests/kernels/shared/test_reservoir.cpp, the 1-D models)
            if (q.cell != r.cell) continue;
            nb[k++] = i;
            M_sum += fmin(q.M, rs->m_cap);
        }
    }
    // the canonical sample's defensive pairwise MIS weight, then the combine. A neighbour's
    // domain enters the MIS weights (P_ic, P_ii) by its target without the rays it traces (flags
    // 0: the same support, as SECONDARY_REUSE_HIDDEN > 0): any functions that are the same for
    // every sample make the weights sum to one ("Generalized Resampled Importance Sampling", Lin
    // et al. 2022, Sec. 4), and the canonical's is its own target, so P_c and P_ci are the full
    // ones that the contribution weight needs. A neighbour then costs the rays of P_ci alone.
    SecondaryReuse mis = *rs;
    mis.flags = 0u;
    float m_c = pairwise_mis_canonical_start(M_sum, M_c, k);
    for (uint j = 0u; j < k; ++j) {
        const BoundaryReservoir q = refs->prev[nb[j]];
        const SecondaryEdge eq = refs->prev_edges[q.edge];
        const SecondaryPoint pq = secondary_point(&eq, q.t, p->creases);
        const float P_ic = r.light == NO_EMISSIVE
                               ? 0.0f
                               : secondary_reuse_target_of(s, params, &mis, &pq, &r);
        m_c += pairwise_mis_canonical_term(fmin(q.M, rs->m_cap), M_sum, M_c, P_c, P_ic);
    }
    BoundaryReservoir out = r;
    float sum = 0.0f, P_out = P_c;
    *w_out = w_c;
    *density_out = density_c;
    wrs_update(&sum, m_c * P_c * W_c, path_rand(rng, base + 1u));
    for (uint j = 0u; j < k; ++j) {
        const BoundaryReservoir q = refs->prev[nb[j]];
        if (q.light == NO_EMISSIVE) continue;
        const SecondaryEdge eq = refs->prev_edges[q.edge];
        const SecondaryPoint pq = secondary_point(&eq, q.t, p->creases);
        float3 w;
        float density;
        const float P_ci = secondary_reuse_target(s, params, rs, p, q.light, q.u1, q.u2, &w, &density);
        const float P_ii = secondary_reuse_target_of(s, params, &mis, &pq, &q);
        const float m_i =
            pairwise_mis_neighbour(fmin(q.M, rs->m_cap), M_sum, M_c, P_ii, P_ci);
        if (wrs_update(&sum, m_i * P_ci * q.W, path_rand(rng, base + 2u + j))) {
            out.light = q.light;
            out.u1 = q.u1;
            out.u2 = q.u2;
            P_out = P_ci;
            *w_out = w;
            *density_out = density;
        }
    }
    out.W = reservoir_ratio(sum, P_out);
    if (!(out.W > 0.0f) || !isfinite(out.W)) {
        out.light = NO_EMISSIVE;
        out.W = 0.0f;
    }
    out.M = M_sum;
    refs->out[sample] = out;
    return out;
}

/// (R) of a secondary sample at edge `edge_index`'s point t, of density p_point per unit length:
/// the resampled light point's direction into *w and its weight, |T x w| p_A(y) W / (p_L(w)
/// p_point) over the samples (see the top of this file); 0 where it has none. Its jump is
/// evaluated with the streams SECONDARY_REUSE_COUNTER + 1 (the walk) and + 2 (the side paths).
TANDEM_INLINE float secondary_reuse_direction(const SceneRefs* s, __global const float* params,
                                              const SecondaryReuseRefs* refs,
                                              const SecondaryEdge* edge, uint edge_index, float t,
                                              int creases, float p_point, float inv_samples,
                                              uint sample, float3* w) {
    const SecondaryPoint p = secondary_point(edge, t, creases);
    float density;
    const BoundaryReservoir r =
        secondary_reuse_resample(s, params, refs, &p, edge_index, t, sample, w, &density);
    if (r.light == NO_EMISSIVE || !(density > 0.0f)) return 0.0f;
    const float p_L = secondary_light_density(s, refs->chunks, p.xb, *w, p.eps, r.light, density);
    const float p_A = s->emissive[r.light].p1.w / s->emissive[r.light].p0.w;
    const float weight = vlength(vcross(p.T, *w)) * p_A * r.W / (p_L * p_point) * inv_samples;
    return weight > 0.0f && isfinite(weight) ? weight : 0.0f;
}

#endif // TANDEM_KERNELS_PATH_BOUNDARY_REUSE_H
