// The primary boundary term of shape gradients: edge sampling on the image plane ("Differentiable
// Monte Carlo Ray Tracing through Edge Sampling", Li et al. 2018, Sec. 4.1; docs/method.md,
// "Shape gradients"). Where an edge of a moving mesh is visible, the image jumps from the radiance
// on one side of it to the radiance on the other; moving the edge sweeps that jump across the
// film:
//   d I_q / d theta  (boundary part) = integral over the edges inside pixel q of
//                                      (L(s - eps n) - L(s + eps n)) (v(s) . n) dl(s),
// n the edge's unit film normal, v the film velocity of the edge point (which rides on the edge:
// the point at parameter t moves as (1 - t) dv0 + t dv1) and l film length in pixels (the box
// filter of a pixel of area one). Each sample picks an edge piece in proportion to its length
// (core/render/boundary.h builds them), a point uniformly on it, and estimates both radiances
// with one path each, sharing their random numbers.
#pragma OPENCL FP_CONTRACT OFF

#include "path/boundary_guide.h"
#include "path/boundary_pairs.h"
#include "path/boundary_reuse.h"
#include "path/boundary_secondary.h"
#include "path/primal.h"
#include "path/shape_adjoint.h"
#include "shared/boundary.h"
#include "shared/fixed_point.h"

/// Film offset of the two side rays from the edge, in pixels: small against a pixel, large against
/// float rounding of a direction (about 1e-7 of the field of view).
#define BOUNDARY_SIDE_EPS 1e-3f
/// The sample counter of the primary boundary's random numbers (path_rng's third key).
#define BOUNDARY_COUNTER 0x80000000u

/// Adds v (already scaled by 2^s) to element `index` of grad, as the adjoint's grad_add
/// (kernels/path/adjoint.h) does; counts clamped and dropped contributions in *saturated.
TANDEM_INLINE void boundary_grad_add(__global uint* grad, __global const uint* active, uint index,
                                     float v, uint* saturated) {
    if (v == 0.0f || index == NO_PARAM) return;
    if (((active[index >> 5u] >> (index & 31u)) & 1u) == 0u) return;
    if (!(fabs(v) <= GRAD_MAX_CONTRIBUTION)) {
        ++*saturated;
        if (!isfinite(v)) return;
        v = v > 0.0f ? GRAD_MAX_CONTRIBUTION : -GRAD_MAX_CONTRIBUTION;
    }
    fixed_add(grad + GRAD_WORDS * index, fixed_encode(v));
}

/// One boundary sample: sample `sample` of rp.seed. Returns the number of guards it trips
/// (non-finite radiance, saturated contributions).
TANDEM_INLINE uint boundary_primary_sample(const SceneRefs* s, __global const float* params,
                                           __global const float* delta, float scale,
                                           __global const BoundaryEdge* edges,
                                           __global const AliasEntry* edge_alias, uint edge_count,
                                           float inv_samples, uint sample,
                                           __global const uint* active, __global uint* grad) {
    const DeviceCamera* cam = s->cam;
    // the side paths' random numbers (from dimension 2, path_dim(0)) and the edge's, counters
    // that the interior's paths (seed, pixel, sample < 2^31) never reach
    const PathRng rng = path_rng(s->rp->seed, sample, BOUNDARY_COUNTER);
    const PathRng pick = path_rng(s->rp->seed, sample, BOUNDARY_COUNTER + 1u);
    // the edge piece, by the alias table over lengths, and a uniform point on its film image
    const uint slot = min((uint)(path_rand(pick, 0u) * (float)edge_count), edge_count - 1u);
    const uint e = path_rand(pick, 1u) >= edge_alias[slot].q ? edge_alias[slot].alias : slot;
    const BoundaryEdge edge = edges[e];
    float ax, ay, az, bx, by, bz;
    camera_project(cam, xyz(edge.a), &ax, &ay, &az);
    camera_project(cam, xyz(edge.b), &bx, &by, &bz);
    const float u = path_rand(pick, 2u);
    const float fx = ax + (bx - ax) * u, fy = ay + (by - ay) * u;
    if (!(fx >= 0.0f && fy >= 0.0f && fx < (float)cam->width && fy < (float)cam->height)) return 0u;
    const uint pixel = (uint)fy * cam->width + (uint)fx;
    const float3 d = make_float3(delta[3u * pixel], delta[3u * pixel + 1u],
                                 delta[3u * pixel + 2u]) * scale;
    if (d.x == 0.0f && d.y == 0.0f && d.z == 0.0f) return 0u;
    // the edge point, perspective-correct, and its parameter on the whole edge
    const float tau = edge_perspective_tau(u, az, bz);
    const float3 p = xyz(edge.a) + (xyz(edge.b) - xyz(edge.a)) * tau;
    const float t = edge.a.w + (edge.b.w - edge.a.w) * tau;
    // visible from the camera? An occluded edge point adds nothing: both sides see the occluder.
    float dir[3], tmin, tmax;
    camera_ray(cam, 0u, 0u, fx, fy, dir, &tmin, &tmax);
    const float3 o = xyz(cam->origin);
    const float dist = vlength(p - o);
    if (dist <= tmin || dist >= tmax) return 0u;
    const Hit centre = trace_closest(s, make_ray(o, make_float3(dir[0], dir[1], dir[2]), tmin, tmax));
    if (centre.prim != HIT_NONE && centre.t < dist * (1.0f - 1e-4f)) return 0u;
    // the film normal, and the radiance just on either side of the edge
    const float ex = bx - ax, ey = by - ay;
    const float inv_len = 1.0f / sqrt(ex * ex + ey * ey);
    const float nx = -ey * inv_len, ny = ex * inv_len;
    float3 L[2];
    for (uint side = 0; side < 2u; ++side) {
        const float sign = side == 0u ? -1.0f : 1.0f;
        camera_ray(cam, 0u, 0u, fx + sign * BOUNDARY_SIDE_EPS * nx,
                   fy + sign * BOUNDARY_SIDE_EPS * ny, dir, &tmin, &tmax);
        L[side] = path_primal_from(s, params, rng, make_ray(o, make_float3(dir[0], dir[1], dir[2]),
                                                            tmin, tmax),
                                   0, no_reservoir(), 0);
    }
    if (!all_finite(L[0]) || !all_finite(L[1])) return 1u;
    const float3 jump = L[0] - L[1];
    // delta . (L- - L+) / pdf, the pdf of the point per pixel of film length being pmf / length
    const float c = (d.x * jump.x + d.y * jump.y + d.z * jump.z) * edge.length / edge.pmf *
                    inv_samples;
    const float3 g = camera_project_gradient(cam, p, nx, ny) * c;
    uint saturated = 0u;
    const float w0 = 1.0f - t, w1 = t;
    boundary_grad_add(grad, active, edge.param0, g.x * w0, &saturated);
    boundary_grad_add(grad, active, edge.param0 + 1u, g.y * w0, &saturated);
    boundary_grad_add(grad, active, edge.param0 + 2u, g.z * w0, &saturated);
    boundary_grad_add(grad, active, edge.param1, g.x * w1, &saturated);
    boundary_grad_add(grad, active, edge.param1 + 1u, g.y * w1, &saturated);
    boundary_grad_add(grad, active, edge.param1 + 2u, g.z * w1, &saturated);
    return saturated;
}

/// Reads the scene, rp (its seed: the boundary stream's), scene_params, delta (dloss/dimage, rgb
/// per pixel) and the edge pieces with their alias table (core/render/boundary.h). Work item
/// `pixel` takes samples pixel + k * pixels for k < per_pixel, each weighing inv_samples (1 / the
/// total), and adds its contributions, scaled by 2^exponent[0], to grad (fixed point) for the
/// elements set in active; guards[pixel] counts non-finite radiance and saturated contributions.
__kernel void boundary_primary(SCENE_ARGS RenderParams rp, __global const float* scene_params,
                               __global const float* delta, __global const int* exponent,
                               __global const BoundaryEdge* edges,
                               __global const AliasEntry* edge_alias, uint edge_count,
                               uint per_pixel, float inv_samples, __global const uint* active,
                               __global uint* grad, __global uint* guards) {
    const SceneRefs s = SCENE_REFS(rp);
    const uint pixel = get_global_id(0);
    const uint pixels = cam.width * cam.height;
    if (pixel >= pixels) return;
    const float scale = grad_pow2(exponent[0]);
    uint caught = guards[pixel];
    for (uint k = 0; k < per_pixel; ++k)
        caught += boundary_primary_sample(&s, scene_params, delta, scale, edges, edge_alias,
                                          edge_count, inv_samples, pixel + k * pixels, active,
                                          grad);
    guards[pixel] = caught;
}

/// One secondary boundary sample (path/boundary_secondary.h): an edge point x_B, then (A) a
/// direction from the mixture of secondary_direction, whose two sides' radiance comes from paths,
/// and (B), where the scene has point or spot lights, the direction to one of them, whose two
/// sides' light is a visibility test each (a point light is a direction of zero measure that (A)
/// never draws: its part of the jump is integrated exactly). `guide`: the share of (A)'s directions
/// drawn from the guide (path/boundary_guide.h). Each direction's receiver x_s reaches the film by
/// the routes of a walk (secondary_walk_route): directly, and through 1, 2, ... bounces, as far as
/// max_depth leaves room. Under a bounded max_depth each route's sides are paths of its own length;
/// unbounded, one pair serves every route. Returns the guards it trips.
TANDEM_INLINE uint boundary_secondary_sample(const SceneRefs* s, __global const float* params,
                                             __global const float* delta, float scale,
                                             __global const SecondaryEdge* edges,
                                             __global const AliasEntry* edge_alias,
                                             uint edge_count, const GuideRefs* guide,
                                             const SecondaryLights* lights,
                                             const SecondaryPairs* pairs,
                                             const SecondaryReuseRefs* reuse, float inv_samples,
                                             uint sample, Adjoint* adj) {
    const RenderParams* rp = s->rp;
    const PathRng pick = path_rng(rp->seed, sample, BOUNDARY_COUNTER + 2u);
    const PathRng rng = path_rng(rp->seed, sample, BOUNDARY_COUNTER + 3u);
    // the edge point: from the edges' pmf or, with probability pairs->share, from a light pair
    // (an edge with a light it may be a silhouette against, which (A) then aims at), uniform
    // along the edge either way
    const PathRng paired = path_rng(rp->seed, sample, BOUNDARY_COUNTER + 5u);
    const int from_pair = pairs->count > 0u && path_rand(paired, 0u) < pairs->share;
    uint edge_index, pair_light = 0u;
    float t;
    if (from_pair) {
        const uint slot = min((uint)(path_rand(paired, 1u) * (float)pairs->count), pairs->count - 1u);
        const uint k = path_rand(paired, 6u) >= pairs->alias[slot].q ? pairs->alias[slot].alias : slot;
        edge_index = pairs->list[k].x;
        pair_light = pairs->list[k].y;
        t = path_rand(paired, 2u);
    } else {
        const uint slot = min((uint)(path_rand(pick, 0u) * (float)edge_count), edge_count - 1u);
        edge_index = path_rand(pick, 1u) >= edge_alias[slot].q ? edge_alias[slot].alias : slot;
        t = path_rand(pick, 2u);
    }
    const SecondaryEdge edge = edges[edge_index];
    const float3 a = xyz(edge.p0), b = xyz(edge.p1);
    const float len = vlength(b - a);
    const float3 T = (b - a) * (1.0f / len), xb = a + (b - a) * t;
    const float eps =
        SECONDARY_EPS * (1.0f + fmax(fabs(xb.x), fmax(fabs(xb.y), fabs(xb.z))));
    // the density of the edge point per unit length: the pmf's share and the pairs' (what (B)
    // divides by; (A)'s direction density comes with its own: secondary_pair_density)
    const float p_edge = edge.n0.w / len;
    float p_point = p_edge;
    if (pairs->count > 0u) {
        float here = 0.0f;
        for (uint k = pairs->first[edge_index]; k < pairs->first[edge_index + 1u]; ++k)
            here += pairs->pmf[k];
        p_point = (1.0f - pairs->share) * p_edge + pairs->share * here / len;
    }
    const int bounded = rp->max_depth != 0xFFFFFFFFu;
    const uint routes = bounded ? rp->max_depth - 1u : 0xFFFFFFFFu;
    // (A) a direction from the mixture (the guide's share c where x_B has one). With reuse, (A)
    // draws no light point and keeps only the directions that aim at no emissive triangle: (R)
    // below integrates the others (path/boundary_reuse.h)
    const int reused = reuse->p.enabled != 0u;
    const float p_light = rp->emissive_count > 0u && !reused ? 0.5f : 0.0f;
    float u[5] = {path_rand(pick, 3u), path_rand(pick, 4u), path_rand(pick, 5u),
                  path_rand(pick, 6u), path_rand(pick, 7u)};
    const uint gslot = guide_slot(guide, edge_index, t);
    const float c = gslot == GUIDE_NO_SLOT ? 0.0f : guide->g.fraction;
    float3 w_a;
    uint drawn = NO_EMISSIVE;
    float drawn_density = 0.0f;
    if (from_pair) {
        w_a = secondary_toward_light(s, pairs->lights[pair_light], xb, eps, path_rand(paired, 3u),
                                     path_rand(paired, 4u), path_rand(paired, 5u), &drawn,
                                     &drawn_density);
    } else if (u[0] < c) {
        w_a = guide_sample(guide, gslot, u[1], u[3], u[4]);
    } else {
        if (c > 0.0f) u[0] = (u[0] - c) / (1.0f - c);
        w_a = secondary_direction(s, xb, p_light, eps, u);
    }
    // not only silhouettes: where both of an edge's faces turn toward x_s (a crease), the surface
    // seen along w jumps from one face to the other as w crosses it, and with it the radiance (a
    // lit face beside an unlit one), a jump that moves with the edge. Paths of one segment see
    // only emission, the same on both faces of a mesh: creases count from max_depth 3 on.
    const int creases = !bounded || rp->max_depth >= 3u;
    const int has_a = (w_a.x != 0.0f || w_a.y != 0.0f || w_a.z != 0.0f) &&
                      (secondary_silhouette(&edge, w_a) ||
                       (creases && secondary_crease_clear(&edge, w_a)));
    uint caught = 0u;
    // the directions whose jumps are evaluated, each with its weight (|T x w| over the density of
    // (x_B, w), over the samples) and its streams' counters: (A)'s, and with reuse (R)'s. One
    // call of secondary_evaluate serves both: the walk and the side paths are inlined once.
    float3 dirs[2];
    float weights[2];
    uint keys[2];
    uint count = 0u;
    if (has_a && !(reused && secondary_light_density(s, lights->chunks, xb, w_a, eps, NO_EMISSIVE,
                                                      0.0f) > 0.0f)) {
        float pdf_a = secondary_direction_pdf(s, lights->chunks, lights->p_delta, xb, w_a,
                                              p_light, eps);
        if (c > 0.0f) pdf_a = (1.0f - c) * pdf_a + c * guide_pdf(guide, gslot, w_a);
        // the density of (x_B, w): the edges' pmf with (A)'s mixture, and the pairs' share
        float p_a = p_edge * pdf_a;
        if (pairs->count > 0u)
            p_a = (1.0f - pairs->share) * p_a +
                  pairs->share * secondary_pair_density(s, pairs, edge_index, len, xb, w_a, eps,
                                                        drawn, drawn_density);
        if (p_a > 0.0f) {
            dirs[count] = w_a;
            weights[count] = vlength(vcross(T, w_a)) / p_a * inv_samples;
            keys[count++] = BOUNDARY_COUNTER + 2u;
        }
    }
#if RESTIR
    // (R) with reuse (compiled where the scene is built for reuse: RESTIR=1): a light point by
    // resampling, fresh and from the previous iteration's
    // reservoirs near x_B (the host gives pairs none then: p_point = p_edge)
    if (reused) {
        float3 w_r;
        const float weight = secondary_reuse_direction(s, params, reuse, &edge, edge_index, t,
                                                       creases, p_point, inv_samples, sample, &w_r);
        if (weight > 0.0f) {
            dirs[count] = w_r;
            weights[count] = weight;
            keys[count++] = SECONDARY_REUSE_COUNTER + 1u;
        }
    }
#endif
    for (uint k = 0u; k < count; ++k)
        caught += secondary_evaluate(s, params, path_rng(rp->seed, sample, keys[k]),
                                     path_rng(rp->seed, sample, keys[k] + 1u), delta, scale, &edge,
                                     t, xb, T, dirs[k], eps, weights[k], adj);
    SecondaryWalk wk;

#if HAS_DELTA_LIGHTS
    // (B) a point or spot light, uniformly: its light on each side by two visibility tests from
    // x_s, which every route shares
    if (rp->delta_count > 0u) {
        const uint k =
            min((uint)(path_rand(pick, 8u) * (float)rp->delta_count), rp->delta_count - 1u);
        const LightSample ls = nee_sample_delta(s, xb, k); // Le: intensity / |y - x_B|^2
        const float3 w = ls.wo;
        if (secondary_silhouette(&edge, w) && secondary_walk_start(s, xb, w, eps, &wk)) {
            const float3 y = xyz(s->delta_lights[k].position);
            const float3 n_w = vnormalize(vcross(w, T));
            const float3 p_minus = xb - n_w * eps, p_plus = xb + n_w * eps;
            const float3 n_out = vdot(wk.xs.n_front, w) >= 0.0f ? wk.xs.n_front : -wk.xs.n_front;
            const float3 origin = offset_ray_origin(wk.xs.x, n_out);
            const int lit_minus =
                secondary_clear(s, origin, p_minus) && secondary_clear(s, p_minus, y);
            const int lit_plus =
                secondary_clear(s, origin, p_plus) && secondary_clear(s, p_plus, y);
            if (lit_minus != lit_plus) {
                SecondaryImportance imp = secondary_importance_none();
                while (secondary_walk_route(s, params, pick, delta, scale, routes, &wk, &imp)) {
                }
                const float common =
                    vlength(vcross(T, w)) * (float)rp->delta_count / p_point * inv_samples;
                const float3 zero = make_float3(0.0f, 0.0f, 0.0f);
                // the lit side sees the light beyond the edge, at R from x_s
                secondary_push_jump(s, adj, &edge, t, &wk, &imp, n_w, common,
                                    lit_minus ? ls.Le : zero, lit_plus ? ls.Le : zero, lit_minus,
                                    vlength(xb - wk.xs.x) / vlength(y - wk.xs.x) - 1.0f);
            }
        }
    }
#endif
    return caught;
}

/// The secondary boundary term: as boundary_primary, over the mesh edges `edges` with their alias
/// table (core/render/boundary.h: secondary_edges), per_pixel samples per pixel of the film;
/// `guide` with its edges' slots and CDFs (core/render/boundary_guide.h; fraction 0: none);
/// emissive_chunks and p_delta as secondary_direction_pdf reads them (core/render/boundary.h:
/// emissive_chunks, delta_light_share); the light pairs (SecondaryPairs; pair_count 0: none) with
/// their pmf, alias table, starts per edge and lights (core/render/boundary.h:
/// secondary_light_pairs), drawn with probability pair_share; the reuse of light vertices across
/// iterations (path/boundary_reuse.h; reuse.enabled 0: none): the previous iteration's reservoirs,
/// one per sample, its edge table, its reservoirs by hash bucket (reuse_first: reuse.buckets + 1
/// starts into reuse_slots), and this iteration's reservoirs, one per sample, written here.
__kernel void boundary_secondary(SCENE_ARGS RenderParams rp, __global const float* scene_params,
                                 __global const float* delta, __global const int* exponent,
                                 __global const SecondaryEdge* edges,
                                 __global const AliasEntry* edge_alias, uint edge_count,
                                 SecondaryGuide guide, __global const uint* guide_edges,
                                 __global const float* guide_cdf,
                                 __global const float4* emissive_chunks, float p_delta,
                                 __global const uint2* pair_list, __global const float* pair_pmf,
                                 __global const AliasEntry* pair_alias,
                                 __global const uint* pair_first,
                                 __global const uint2* pair_lights, uint pair_count,
                                 float pair_share, SecondaryReuse reuse,
                                 __global const BoundaryReservoir* reuse_prev,
                                 __global const SecondaryEdge* reuse_prev_edges,
                                 __global const uint* reuse_first, __global const uint* reuse_slots,
                                 __global BoundaryReservoir* reuse_out, uint per_pixel,
                                 float inv_samples,
                                 __global const uint* active, __global uint* grad,
                                 __global uint* guards) {
    const SceneRefs s = SCENE_REFS(rp);
    const uint pixel = get_global_id(0);
    const uint pixels = cam.width * cam.height;
    if (pixel >= pixels) return;
    SecondaryLights lights;
    lights.chunks = emissive_chunks;
    lights.p_delta = p_delta;
    GuideRefs g;
    g.g = guide;
    g.edge_slot = guide_edges;
    g.cdf = guide_cdf;
    Adjoint adj;
    adj.grad = grad;
    adj.active = active;
    adj.delta = make_float3(0.0f, 0.0f, 0.0f);
    adj.L_rem = make_float3(0.0f, 0.0f, 0.0f);
    adj.saturated = 0u;
#if SHAPE_GRAD
    adj.shape = shape_vertex_none();
#endif
    const float scale = grad_pow2(exponent[0]);
    uint caught = guards[pixel];
    SecondaryPairs pairs;
    pairs.list = pair_list;
    pairs.pmf = pair_pmf;
    pairs.alias = pair_alias;
    pairs.first = pair_first;
    pairs.lights = pair_lights;
    pairs.chunks = emissive_chunks;
    pairs.count = pair_count;
    pairs.share = pair_share;
    SecondaryReuseRefs reused;
    reused.p = reuse;
    reused.prev = reuse_prev;
    reused.prev_edges = reuse_prev_edges;
    reused.bucket_first = reuse_first;
    reused.bucket_slots = reuse_slots;
    reused.out = reuse_out;
    reused.chunks = emissive_chunks;
    for (uint k = 0; k < per_pixel; ++k)
        caught += boundary_secondary_sample(&s, scene_params, delta, scale, edges, edge_alias,
                                            edge_count, &g, &lights, &pairs, &reused, inv_samples,
                                            pixel + k * pixels, &adj);
    guards[pixel] = caught + adj.saturated;
}

/// The angle-nearest point to the ray o + s d (d unit, s > 0) of the edge from a to b, as its
/// parameter into *t and the point into *p, and the tangent of its angle off the ray (INFINITY:
/// behind o): the closest points of the edge's line and the ray's, the edge's parameter clamped.
TANDEM_INLINE float guide_edge_nearest(float3 a, float3 b, float3 o, float3 d, float* t,
                                       float3* p) {
    const float3 e = b - a, r = a - o;
    const float A = vdot(e, e), B = vdot(e, d), C = vdot(e, r), F = vdot(d, r);
    const float den = A - B * B;
    *t = den > 0.0f ? fmin(fmax((B * F - C) / den, 0.0f), 1.0f) : 0.0f;
    *p = a + e * *t;
    const float3 v = *p - o;
    const float along = vdot(v, d);
    if (!(along > 0.0f)) return INFINITY;
    return vlength(v - d * along) / along;
}

/// The guide's training samples (core/render/boundary_guide.h). Sample j's camera ray through
/// pixel j mod pixels (random numbers of its own) finds a receiver x_s, whose BSDF draws a
/// direction d; the point x_B of a silhouette edge nearest to that ray in angle (the edge's faces
/// on opposite sides of the direction from x_s: secondary_silhouette), where x_s sees it, is where
/// the guide should send directions from. points[j] = (x_B's parameter on its edge, weight), the
/// weight f(w_B) |cos| / p(d) for w_B = normalize(x_B - x_s): near 1 where w_B lies in the lobe
/// that drew d, small outside it (0: no sample); cells[j] = w_B's cell among dir_res^2
/// (secondary_guide_cell), edge_of[j] its edge.
__kernel void boundary_guide_train(SCENE_ARGS RenderParams rp, __global const float* scene_params,
                                   __global const SecondaryEdge* edges, uint edge_count,
                                   uint dir_res, uint count, __global float4* points,
                                   __global uint* cells, __global uint* edge_of) {
    const SceneRefs s = SCENE_REFS(rp);
    const uint j = get_global_id(0);
    if (j >= count) return;
    points[j] = make_float4(0.0f, 0.0f, 0.0f, 0.0f);
    cells[j] = 0u;
    edge_of[j] = 0u;
    const uint pixel = j % (cam.width * cam.height);
    const PathRng rng = path_rng(rp.seed, j, BOUNDARY_COUNTER + 4u);
    const Ray ray = path_camera_ray(&s, rng, pixel % cam.width, pixel / cam.width);
    const Hit hit = trace_closest(&s, ray);
    if (hit.prim == HIT_NONE) return;
    Interaction it;
    interaction_at(&s, ray, hit, &it);
    if (!interaction_shade(&s, scene_params, &it)) return;
    const BsdfSample bs = continuation_sample(&it, vertex_random(rng, path_dim(0)));
    if (continuation_failed(&bs) || bs.delta || !(bs.pdf > 0.0f)) return;
    const float3 d = frame_to_world(it.frame, bs.wo_local);
    float best = INFINITY;
    float3 xb = it.x;
    uint nearest = 0u;
    float t_best = 0.0f;
    for (uint k = 0; k < edge_count; ++k) {
        const SecondaryEdge edge = edges[k];
        float3 p;
        float t;
        const float angle = guide_edge_nearest(xyz(edge.p0), xyz(edge.p1), it.x, d, &t, &p);
        if (!(angle < best)) continue;
        const float3 to = p - it.x;
        if (!secondary_silhouette(&edge, to * (1.0f / vlength(to)))) continue;
        best = angle;
        xb = p;
        nearest = k;
        t_best = t;
    }
    if (!(best < INFINITY)) return;
    const float3 to = xb - it.x;
    const float3 wb = to * (1.0f / vlength(to));
    const float3 wb_local = frame_to_local(it.frame, wb);
    const float weight =
        luminance(bsdf_eval(it.plastic_tables, &it.mat, it.albedo, it.wi_local, wb_local)) / bs.pdf;
    if (!(weight > 0.0f) || !finite_value(weight)) return;
    const float3 n = vdot(it.n_front, wb) >= 0.0f ? it.n_front : -it.n_front;
    if (!secondary_clear(&s, offset_ray_origin(it.x, n), xb)) return;
    points[j] = make_float4(t_best, weight, 0.0f, 0.0f);
    cells[j] = secondary_guide_cell(wb, dir_res);
    edge_of[j] = nearest;
}
