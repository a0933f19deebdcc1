// The secondary boundary term of shape gradients: shadows and other visibility edges seen from the
// surface points the camera sees (docs/method.md, "Shape gradients"). Multi-directional sampling
// ("Path-Space Differentiable Rendering", Zhang et al. 2020, Sec. 5.2; "Amortizing Samples in
// Physics-Based Inverse Rendering using ReSTIR", Wang et al. 2023, Sec. 5.2): a point x_B on a mesh
// edge and a direction w, the receiver x_s found by tracing from x_B along -w, connected to the
// camera. In the measure of (x_B, w), the camera's pixel integral over x_s becomes
//     d I_q (boundary) = W_q(x_s) f_r(x_s; camera, w) |T x w| [D (n_w . v_B) + s F_bg (r/R - 1) (n_w . v_s)]
// per unit of edge length and solid angle at x_B: W_q = d(pixel)/dA at x_s, f_r the BSDF without
// its cosine (that cosine and the 1/r^2 cancel the Jacobian from dA(x_s) to dw), T the unit edge,
// n_w = normalize(w x T), D = L(-n_w side) - L(+n_w side) the jump of the radiance arriving at
// x_s, v_B the edge point's velocity (it rides on the edge), and, where x_s itself moves (v_s: it
// slides along its camera ray), the background's part of the jump (F_bg, on side s = +1 for -n_w,
// -1 for +n_w, at distance R from x_s; the edge at r) moves at (r / R) v_B + (1 - r / R) v_s, since
// the interior term holds the far end of each light segment fixed (path/shape_adjoint.h).
// Every edge is a candidate, creases included: where both faces turn toward x_s, the radiance still
// jumps from one face's to the other's.
// The film sees x_s directly (route 0) or through k bounces (route k: x_s = y_0, y_1, ..., y_k, the
// camera seeing y_k). A walk from x_s samples those bounces as light tracing does (importance
// transport: "Robust Monte Carlo Methods for Light Transport Simulation", Veach 1997, Sec. 3.7.6
// and 5.3), and each route's connection to the camera takes the place of W_q(x_s) f_r: it
// estimates the importance reaching x_s from the film (secondary_connect, secondary_walk_route).
// With shading normals n_s, radiance arriving at y along w_in is weighed by the rendering
// equation's |w_in . n_s|, while the change of measure to the edge (at x_s) or to the walk's
// sampled direction (at y_j, j >= 1) divides by the geometric |w_in . n_g|; at y_k the film's
// d(pixel)/dA is geometric too.
#ifndef TANDEM_KERNELS_PATH_BOUNDARY_SECONDARY_H
#define TANDEM_KERNELS_PATH_BOUNDARY_SECONDARY_H

#include "path/adjoint.h"
#include "path/interaction.h"
#include "path/primal.h"
#include "shared/boundary.h"

/// World-space offset of the two sides of an edge and of rays leaving it, relative to the scene's
/// scale at the point (as Mitsuba's ShapeEpsilon-based offsets).
#define SECONDARY_EPS 1e-4f


/// Where radiance arriving at a point y along w_in reaches the film: y connected to the camera
/// (secondary_to_camera).
typedef struct Receiver {
    Interaction it;
    uint pixel;
    float3 f;      ///< f(camera, w_in) |w_in . n_s| at it.x, per channel
    float weight;  ///< d(pixel)/dA at it.x over |w_in . n_g|: f weight is f_r d(pixel)/dA
    float3 d_cam;  ///< unit, from the camera to it.x (its camera ray)
} Receiver;

/// Connects rc->it (a hit, not yet shaded) to the camera, for light arriving along w (toward
/// where it comes from). Returns 0 where it is not seen (outside the film, occluded, or facing
/// away), or reflects nothing toward the camera from w.
TANDEM_INLINE int secondary_to_camera(const SceneRefs* s, __global const float* params, float3 w,
                                      Receiver* rc) {
    const DeviceCamera* cam = s->cam;
    const float3 o = xyz(cam->origin);
    const float3 to_cam = o - rc->it.x;
    const float r_c = vlength(to_cam);
    rc->it.wi = to_cam * (1.0f / r_c);
    if (!interaction_shade(s, params, &rc->it)) return 0;
    float fx, fy, z;
    camera_project(cam, rc->it.x, &fx, &fy, &z);
    if (!(z > cam->near_clip && fx >= 0.0f && fy >= 0.0f && fx < (float)cam->width &&
          fy < (float)cam->height))
        return 0;
    rc->pixel = (uint)fy * cam->width + (uint)fx;
    // seen from the camera: nothing between (the shadow ray stops just short of the origin)
    if (trace_any(s, make_ray(rc->it.origin, to_cam, 0.0f, 1.0f - 1e-4f))) return 0;
    const float cos_g = fabs(vdot(rc->it.n_front, w));
    if (!(cos_g > 0.0f)) return 0;
    rc->f = bsdf_eval(rc->it.plastic_tables, &rc->it.mat, rc->it.albedo, rc->it.wi_local,
                      frame_to_local(rc->it.frame, w));
    // d(pixel)/dA: W H / (4 tan_x tan_y) pixels per unit of the image plane at distance 1, times
    // the geometric cos / r_c^2 per unit area, over cos^3 of the ray's angle to the view axis
    rc->d_cam = -rc->it.wi;
    const float cos_axis = vdot(rc->d_cam, xyz(cam->dir_z));
    const float per_area = (float)cam->width * (float)cam->height /
                           (4.0f * vlength(xyz(cam->dir_x)) * vlength(xyz(cam->dir_y))) *
                           fabs(vdot(rc->it.n_front, rc->it.wi)) /
                           (r_c * r_c * cos_axis * cos_axis * cos_axis);
    rc->weight = per_area / cos_g;
    return 1;
}

/// The importance the film gives radiance arriving at x_s along w, per channel, so that radiance
/// L there adds vdot(imp, L) to the loss's derivative: delta_q f_r d(pixel)/dA times the walk's
/// weight, summed over the routes, those through bounces apart (their receiver moves along
/// another ray: secondary_push_receiver).
typedef struct SecondaryImportance {
    float3 direct;  ///< route 0's
    float3 bounced; ///< routes 1 and on
    float3 d_cam;   ///< route 0: x_s's camera ray direction
} SecondaryImportance;

TANDEM_INLINE SecondaryImportance secondary_importance_none(void) {
    SecondaryImportance imp;
    imp.direct = make_float3(0.0f, 0.0f, 0.0f);
    imp.bounced = imp.direct;
    imp.d_cam = imp.direct;
    return imp;
}

TANDEM_INLINE int secondary_importance_any(const SecondaryImportance* imp) {
    return imp->direct.x != 0.0f || imp->direct.y != 0.0f || imp->direct.z != 0.0f ||
           imp->bounced.x != 0.0f || imp->bounced.y != 0.0f || imp->bounced.z != 0.0f;
}

/// The walk from the receiver x_s toward the film: route k's point y_k, and the product of the
/// bounces' adjoint weights from x_s to it.
typedef struct SecondaryWalk {
    Interaction xs;  ///< x_s (interaction_at: wi = w)
    Interaction at;  ///< y_k (interaction_at: wi toward y_{k-1}, or w at x_s)
    float3 x1;       ///< y_1, once the walk has reached it
    float3 thr;      ///< prod over j < k of f |cos| / p at y_j, in importance transport
    uint route;      ///< k
} SecondaryWalk;

/// Starts the walk at the receiver x_s, traced from x_B along -w. Returns 0 where the ray escapes.
TANDEM_INLINE int secondary_walk_start(const SceneRefs* s, float3 xb, float3 w, float eps,
                                       SecondaryWalk* wk) {
    const Ray back = make_ray(xb, -w, eps, INFINITY);
    const Hit hit = trace_closest(s, back);
    if (hit.prim == HIT_NONE) return 0;
    interaction_at(s, back, hit, &wk->xs);
    wk->at = wk->xs;
    wk->x1 = wk->xs.x;
    wk->thr = make_float3(1.0f, 1.0f, 1.0f);
    wk->route = 0u;
    return 1;
}

/// The adjoint weight of a bounce at shaded y from wi (toward the light) to wo = frame_to_world
/// (wo_local), given bsdf_sample's radiance weight T = f |wo . n_s| / p: a refraction's eta_ti^2
/// (radiance's solid-angle compression) is not importance's, which crosses the interface with
/// weight 1 (Veach 1997, Sec. 5.2); shading normals turn the cosines to
/// |wi . n_s| |wo . n_g| / (|wi . n_g| |wo . n_s|) (Sec. 5.3; exactly 1 where n_s = +-n_g).
TANDEM_INLINE float3 secondary_adjoint_weight(const Interaction* y, float3 T, float3 wo_local,
                                              float3 wo) {
    if (y->mat.type == MATERIAL_DIELECTRIC && wo_local.z * y->wi_local.z < 0.0f)
        T = make_float3(1.0f, 1.0f, 1.0f);
    const float den = fabs(vdot(y->wi, y->n_front)) * fabs(vdot(wo, y->frame.n));
    if (!(den > 0.0f)) return make_float3(0.0f, 0.0f, 0.0f);
    return T * (fabs(vdot(y->wi, y->frame.n)) * fabs(vdot(wo, y->n_front)) / den);
}

/// Route wk->route: connects y_k to the camera, adding its importance for radiance arriving at
/// x_s to *imp, then steps the walk to y_{k+1} by a BSDF sample (random numbers of `pick` from
/// dimension 9 + 4k; Russian roulette from rr_depth on, as the camera's paths). Returns whether
/// route k + 1 exists: below `routes`, and the step found a surface.
TANDEM_INLINE int secondary_walk_route(const SceneRefs* s, __global const float* params,
                                       PathRng pick, __global const float* delta, float scale,
                                       uint routes, SecondaryWalk* wk, SecondaryImportance* imp) {
    const uint k = wk->route;
    Receiver rc;
    rc.it = wk->at;
    if (secondary_to_camera(s, params, wk->at.wi, &rc)) {
        const float3 d = make_float3(delta[3u * rc.pixel], delta[3u * rc.pixel + 1u],
                                     delta[3u * rc.pixel + 2u]) * scale;
        const float3 v = d * (wk->thr * rc.f) * rc.weight;
        if (k == 0u) {
            imp->direct = v;
            imp->d_cam = rc.d_cam;
        } else {
            imp->bounced += v;
        }
    }
    if (k + 1u >= routes) return 0;
    Interaction y = wk->at;
    if (!interaction_shade(s, params, &y)) return 0;
    const uint dim = 9u + 4u * k;
    float3 wo_local;
    float pdf;
    int is_delta;
    const float3 T = bsdf_sample(y.plastic_tables, &y.mat, y.albedo, y.wi_local,
                                 path_rand(pick, dim), path_rand(pick, dim + 1u),
                                 path_rand(pick, dim + 2u), &wo_local, &pdf, &is_delta);
    if (!(max_component(T) > 0.0f)) return 0;
    const float3 wo = frame_to_world(y.frame, wo_local);
    float3 thr = wk->thr * secondary_adjoint_weight(&y, T, wo_local, wo);
    if (!(max_component(thr) > 0.0f)) return 0;
    if (roulette_applies(s->rp, k)) {
        const float q = roulette_q(thr);
        if (roulette_ends_at(path_rand(pick, dim + 3u), q)) return 0;
        thr = roulette_beta3(thr, q);
    }
    const Ray ray = make_ray(vdot(wo, y.n_out) >= 0.0f ? y.origin
                                                        : offset_ray_origin(y.x, -y.n_out),
                             wo, 0.0f, INFINITY);
    const Hit hit = trace_closest(s, ray);
    if (hit.prim == HIT_NONE) return 0;
    interaction_at(s, ray, hit, &wk->at);
    if (k == 0u) wk->x1 = wk->at.x;
    wk->thr = thr;
    wk->route = k + 1u;
    return 1;
}

/// Whether o lies in the plane of emissive triangle t, within eps (an edge point of an emissive
/// mesh, on its own faces' planes): the directions from o to its points lie on a great circle, of
/// zero solid angle and so of infinite density, which no estimate divided by a finite one may
/// use. secondary_direction voids them and secondary_direction_pdf leaves such triangles out.
TANDEM_INLINE int secondary_in_light_plane(__global const EmissiveTriangle* t, float3 o, float eps) {
    return fabs(vdot(make_float3(t->nx, t->ny, t->nz), o - xyz(t->p0))) <= eps;
}

/// The emissive triangles' chunk bounds and the point and spot lights' share of the light
/// sampling, as secondary_direction_pdf reads them.
typedef struct SecondaryLights {
    __global const float4* chunks;
    float p_delta;
} SecondaryLights;

/// Whether the ray o + t w (t > 0) crosses emissive triangle `t` (of positive area, its plane not
/// holding o: secondary_in_light_plane), at distance *dist, with |n . w| = *cos_light > 0: where
/// it does, a uniform point of the triangle has the direction density dist^2 / (cos_light area).
TANDEM_INLINE int secondary_ray_triangle(__global const EmissiveTriangle* t, float3 o, float3 w,
                                         float eps, float* dist, float* cos_light) {
    if (secondary_in_light_plane(t, o, eps)) return 0;
    const float3 a = xyz(t->p0), e1 = xyz(t->p1) - a, e2 = xyz(t->p2) - a;
    const float3 q = vcross(w, e2);
    const float det = vdot(e1, q);
    if (det == 0.0f) return 0;
    const float inv = 1.0f / det;
    const float3 sv = o - a;
    const float u = vdot(sv, q) * inv;
    const float3 r = vcross(sv, e1);
    const float v = vdot(w, r) * inv;
    *dist = vdot(e2, r) * inv;
    if (!(u >= 0.0f && v >= 0.0f && u + v <= 1.0f && *dist > 0.0f && t->p0.w > 0.0f)) return 0;
    *cos_light = fabs(vdot(make_float3(t->nx, t->ny, t->nz), w));
    return *cos_light > 0.0f;
}

/// The light-sampled share of secondary_direction_pdf: the density, per unit solid angle at o, of
/// the direction w toward a point of an emissive triangle drawn from the alias table, uniform on
/// it, summed over every triangle the ray o + t w crosses (each could have drawn it; `chunks`
/// bound them, EMISSIVE_CHUNK), except those whose plane holds o (secondary_in_light_plane).
/// Triangle `drawn` (NO_EMISSIVE: none), which w was drawn toward, counts `drawn_density` whatever
/// the intersection test says (its rounding may miss a point of the triangle's edge).
TANDEM_INLINE float secondary_light_density(const SceneRefs* s, __global const float4* chunks,
                                            float3 o, float3 w, float eps, uint drawn,
                                            float drawn_density) {
    const RenderParams* rp = s->rp;
    const uint count = rp->emissive_count;
    const uint n = (count + EMISSIVE_CHUNK - 1u) / EMISSIVE_CHUNK; // chunks; then the groups
    float p_triangles = 0.0f;
    // (a group or chunk the ray misses holds no triangle the intersection test would find: the
    // same terms are summed, in the same order, as by testing every triangle)
    uint c_end = 0u;
    for (uint k = n; c_end < n; k += 2u) {
        const float4 range = chunks[k + 1u];
        c_end = (uint)range.y;
        const uint g_first = (uint)range.x * EMISSIVE_CHUNK;
        const uint g_end = min(c_end * EMISSIVE_CHUNK, count);
        if (!emissive_chunk_near(o, w, chunks[k]) && !(drawn >= g_first && drawn < g_end))
            continue;
        for (uint first = g_first; first < g_end; first += EMISSIVE_CHUNK) {
            const uint end = min(first + EMISSIVE_CHUNK, count);
            const int near = emissive_chunk_near(o, w, chunks[first / EMISSIVE_CHUNK]);
            if (!near && !(drawn >= first && drawn < end)) continue;
            for (uint e = first; e < end; ++e) {
                __global const EmissiveTriangle* t = &s->emissive[e];
                float dist, cos_l;
                if (e == drawn)
                    p_triangles += drawn_density;
                else if (near && secondary_ray_triangle(t, o, w, eps, &dist, &cos_l))
                    p_triangles += t->p1.w / t->p0.w * dist * dist / cos_l;
            }
        }
    }
    return p_triangles;
}

/// The density, per unit solid angle at o, of the direction w of secondary_direction: with
/// probability p_light a light of the alias table (an emissive triangle's point, uniform on it; a
/// point or spot light's slot: a uniform direction), else uniform on the sphere. The triangles'
/// share sums over every emissive triangle the ray o + t w crosses (each could have drawn it),
/// except those whose plane holds o (secondary_in_light_plane); `chunks` bound them
/// (EMISSIVE_CHUNK), and p_delta, one less the triangles' selection probabilities summed in table
/// order, is the point and spot lights' share (the host's: secondary_delta_share).
TANDEM_INLINE float secondary_direction_pdf(const SceneRefs* s, __global const float4* chunks,
                                            float p_delta, float3 o, float3 w, float p_light,
                                            float eps) {
    const float p_triangles = secondary_light_density(s, chunks, o, w, eps, NO_EMISSIVE, 0.0f);
    const float uniform = 0.25f * TANDEM_INV_PI;
    return (1.0f - p_light) * uniform + p_light * (fmax(p_delta, 0.0f) * uniform + p_triangles);
}

/// The direction of a secondary sample from x_B (secondary_direction_pdf), from u[0..5); 0 where
/// it is void (a point of a triangle whose plane holds x_B).
TANDEM_INLINE float3 secondary_direction(const SceneRefs* s, float3 xb, float p_light, float eps,
                                         const float* u) {
    const RenderParams* rp = s->rp;
    const uint lights = rp->emissive_count + rp->delta_count;
    if (u[0] < p_light && lights > 0u) {
        const uint slot = min((uint)(u[1] * (float)lights), lights - 1u);
        const uint e = u[2] >= s->alias[slot].q ? s->alias[slot].alias : slot;
        if (e < rp->emissive_count) {
            if (secondary_in_light_plane(&s->emissive[e], xb, eps))
                return make_float3(0.0f, 0.0f, 0.0f);
            const float o[3] = {xb.x, xb.y, xb.z};
            float wo[3], dist2, cos_l, shadow[3];
            nee_triangle_sample((__global const float*)&s->emissive[e], o, 1.0f, u[3], u[4], wo,
                                &dist2, &cos_l, shadow);
            return make_float3(wo[0], wo[1], wo[2]);
        }
    }
    return sample_uniform_sphere(u[3], u[4]);
}

/// Whether w crosses the edge's silhouette: its faces on opposite sides (a border: always).
TANDEM_INLINE int secondary_silhouette(const SecondaryEdge* e, float3 w) {
    if (e->n1.w == 0.0f) return 1;
    return vdot(xyz(e->n0), w) * vdot(xyz(e->n1), w) < 0.0f;
}

/// Whether a crease (not a silhouette) is seen clear of edge-on: both faces at least
/// SECONDARY_CREASE_COS (about 3 degrees) from parallel to w. Nearer, one face's sliver may be
/// thinner than the side rays' offset, which then miss it and read a jump that is not there: a
/// bias of the offset's order that guided directions, crowding near silhouettes, make large (on
/// the glossy floor at max_depth 3, creases alone gave -0.0011 against a total of 0.0064; with
/// 1e-2 here -0.00012, with 5e-2 -0.000004 +- 0.000001). What is left out is the crease's own
/// jump over that band of directions: 0.5 % of the creases' part on a lit cube seen from a screen.
#define SECONDARY_CREASE_COS 5e-2f
TANDEM_INLINE int secondary_crease_clear(const SecondaryEdge* e, float3 w) {
    return fabs(vdot(xyz(e->n0), w)) >= SECONDARY_CREASE_COS &&
           fabs(vdot(xyz(e->n1), w)) >= SECONDARY_CREASE_COS;
}

/// Adds g n to both edge vertices, weighted by their share (1 - t, t) of the edge point's motion.
TANDEM_INLINE void secondary_push_edge(Adjoint* adj, const SecondaryEdge* e, float t, float3 gn) {
    const uint a = as_uint(e->p0.w), b = as_uint(e->p1.w);
    if (a != NO_PARAM) grad_add_rgb(adj, a, gn * (1.0f - t));
    if (b != NO_PARAM) grad_add_rgb(adj, b, gn * t);
}

/// Adds g (n_w . v_s) for a receiver x_s (`it`) on a moving triangle: v_s = d (n . dP) / (n . d)
/// at its barycentric weights (it slides along the ray that found it, of unit direction d: its
/// camera ray, or the bounce's from x_1).
TANDEM_INLINE void secondary_push_receiver(const SceneRefs* s, Adjoint* adj, const Interaction* it,
                                           float3 d, float3 n_w, float g) {
    const uint4 pp = s->prim_params[it->hit.prim];
    if (pp.x == NO_PARAM || g == 0.0f) return;
    const float3 n = it->n_front;
    const float nd = vdot(n, d);
    if (nd == 0.0f) return;
    const float3 gn = n * (g * vdot(d, n_w) / nd);
    const float u = it->hit.u, v = it->hit.v;
    grad_add_rgb(adj, pp.x, gn * (1.0f - u - v));
    grad_add_rgb(adj, pp.y, gn * u);
    grad_add_rgb(adj, pp.z, gn * v);
}

/// The radiance arriving at the receiver `it` along the ray from it toward `target` (s's
/// max_depth: the camera's, less the segments from the camera to it), and its first hit's
/// distance into *dist (INFINITY where it escapes).
TANDEM_INLINE float3 secondary_side(const SceneRefs* s, __global const float* params, PathRng rng,
                                    const Interaction* it, float3 target, float* dist) {
    const float3 to = target - it->x;
    const float3 dir = to * (1.0f / vlength(to));
    const float3 n = vdot(it->n_front, dir) >= 0.0f ? it->n_front : -it->n_front;
    const Ray ray = make_ray(offset_ray_origin(it->x, n), dir, 0.0f, INFINITY);
    const Hit hit = trace_closest(s, ray);
    *dist = hit.prim == HIT_NONE ? INFINITY : hit.t;
    return path_primal_from(s, params, rng, ray, &hit, no_reservoir(), 0);
}

/// Whether nothing lies on the segment from a to b (a: just off a surface of normal n, or in free
/// space where n is 0).
TANDEM_INLINE int secondary_clear(const SceneRefs* s, float3 a, float3 b) {
    return !trace_any(s, make_ray(a, b - a, 0.0f, 1.0f - 1e-4f));
}

/// Adds the jump of the radiance arriving at x_s (wk->xs) from L_minus (the -n_w side) to L_plus,
/// weighed by the film's importance imp and `common` (the sample's |T x w| / pdf / N), to the
/// edge's vertices, and the background's part of it to x_s's (the side bg_minus ? - : + sees
/// beyond the edge, at R from x_s; shift = r / R - 1, the edge at r), each route group along the
/// ray it finds x_s by (its camera ray, or the bounce's from y_1).
TANDEM_INLINE void secondary_push_jump(const SceneRefs* s, Adjoint* adj, const SecondaryEdge* edge,
                                       float t, const SecondaryWalk* wk,
                                       const SecondaryImportance* imp, float3 n_w, float common,
                                       float3 L_minus, float3 L_plus, int bg_minus, float shift) {
    const float3 I = imp->direct + imp->bounced;
    secondary_push_edge(adj, edge, t, n_w * (common * (vdot(I, L_minus) - vdot(I, L_plus))));
    const float3 F = bg_minus ? L_minus : -L_plus;
    const float3 xs = wk->xs.x;
    secondary_push_receiver(s, adj, &wk->xs, imp->d_cam, n_w,
                            common * vdot(imp->direct, F) * shift);
    secondary_push_receiver(s, adj, &wk->xs, vnormalize(xs - wk->x1), n_w,
                            common * vdot(imp->bounced, F) * shift);
}

/// (A)'s two sides for the routes of imp: the radiance arriving at x_s from just either side of
/// the edge point xb, by paths as long as `route`'s leave (route k: the camera's max_depth less
/// k + 1 segments). Returns the guards it trips.
TANDEM_INLINE uint secondary_sides(const SceneRefs* s, __global const float* params, PathRng rng,
                                   uint route, const SecondaryEdge* edge, float t, float3 xb,
                                   float3 n_w, float eps, float common, const SecondaryWalk* wk,
                                   const SecondaryImportance* imp, Adjoint* adj) {
    RenderParams rp1 = *s->rp;
    if (rp1.max_depth != 0xFFFFFFFFu) rp1.max_depth -= 1u + route;
    rp1.rr_depth = rp1.rr_depth > route ? rp1.rr_depth - 1u - route : 0u;
    SceneRefs s1 = *s;
    s1.rp = &rp1;
    float r_minus, r_plus;
    const float3 L_minus = secondary_side(&s1, params, rng, &wk->xs, xb - n_w * eps, &r_minus);
    const float3 L_plus = secondary_side(&s1, params, rng, &wk->xs, xb + n_w * eps, &r_plus);
    if (!all_finite(L_minus) || !all_finite(L_plus)) return 1u;
    // the background: the side whose first hit lies beyond the edge
    const int bg_minus = r_minus > r_plus;
    const float R = bg_minus ? r_minus : r_plus;
    secondary_push_jump(s, adj, edge, t, wk, imp, n_w, common, L_minus, L_plus, bg_minus,
                        vlength(xb - wk->xs.x) / R - 1.0f);
    return 0u;
}

/// The receiver x_s of direction w from x_B and the routes from it to the film (secondary_walk_route),
/// each route group with its two sides (secondary_sides): adds the sample's jump, weighed by
/// `common` (|T x w| over the density of (x_B, w), over the samples), to the gradient. `pick`: the
/// walk's random numbers, `rng`: the sides' paths'. Returns the guards it trips.
TANDEM_INLINE uint secondary_evaluate(const SceneRefs* s, __global const float* params, PathRng pick,
                                      PathRng rng, __global const float* delta, float scale,
                                      const SecondaryEdge* edge, float t, float3 xb, float3 T,
                                      float3 w, float eps, float common, Adjoint* adj) {
    // max_depth counts the segments of the camera's paths: route k reaches x_s in k + 1 of them,
    // which leaves its sides at least one (routes: max_depth - 1; the host skips max_depth < 2)
    const int bounded = s->rp->max_depth != 0xFFFFFFFFu;
    const uint routes = bounded ? s->rp->max_depth - 1u : 0xFFFFFFFFu;
    SecondaryWalk wk;
    if (!secondary_walk_start(s, xb, w, eps, &wk)) return 0u;
    const float3 n_w = vnormalize(vcross(w, T));
    uint caught = 0u;
    SecondaryImportance imp = secondary_importance_none();
    for (int more = 1; more;) {
        const uint route = wk.route;
        more = secondary_walk_route(s, params, pick, delta, scale, routes, &wk, &imp);
        if ((bounded || !more) && secondary_importance_any(&imp)) {
            caught += secondary_sides(s, params, rng, bounded ? route : 0u, edge, t, xb, n_w, eps,
                                      common, &wk, &imp, adj);
            imp = secondary_importance_none();
        }
    }
    return caught;
}

#endif // TANDEM_KERNELS_PATH_BOUNDARY_SECONDARY_H
