// The interior term of shape gradients in the PRB replay (SHAPE_GRAD builds; docs/method.md,
// "Shape gradients"). Each hit point slides along its incoming ray, which stays fixed, as the
// surface under it moves: at barycentric coordinates b of a triangle whose vertices move by dP_k,
// the point on the surface at fixed b moves by sum_k b_k dP_k, and the ray's hit by
//     dx = d (n . sum_k b_k dP_k) / (n . d)                       (d the ray's unit direction),
// while the triangle's normal n turns with its vertices. The terms a vertex adds to the path
// depend on x and n through the geometry of their light, with the far end fixed in the world
// (Mitsuba 3's prb_projective, since 3.7; "Projective Sampling for Differentiable Rendering of
// Geometry", Zhang, Roussel, Vicini, Jakob, SIGGRAPH Asia 2023, Sec. 3):
//   - a light sample at y: its term is proportional to (n . wo) cos_y / r^2 on a triangle light,
//     (n . wo) / r^2 for a point light, (n . wo) for the environment (wo = (y - x) / r);
//   - the BSDF sample: everything still in L_rem arrived through its direction, in proportion to
//     (n . wo) times the Jacobian |n' . wo| / r^2 to the next hit x' (fixed), or (n . wo) where
//     the path escaped.
// The derivative of a term T through such a factor F is T d(log F). A glossy BSDF (roughconductor,
// roughplastic) depends on its directions besides: f(n . wi, n . wo, wi . wo) (shared/
// bsdf_dir_grad.h), so its terms change as n turns, as wo turns toward the fixed far end, and as
// wi turns when the vertex before it moves (ShapeDirs). A vertex gathers delta . dT/dx and /dn
// from its light sample and, once the next hit is known, from its continuation; its push into its
// triangle's three vertices (shape_vertex_push) waits until the vertex after it has added what its
// own BSDF owes to the turn of wi (shape_vertex_incoming). An albedo read from a bitmap depends on
// the hit's texture coordinates too, which slide with its barycentrics (shape_vertex_texture).
// Mirrors and glass (delta BSDFs) move their next vertex with them: the host refuses them on a
// moving shape.
#ifndef TANDEM_KERNELS_PATH_SHAPE_ADJOINT_H
#define TANDEM_KERNELS_PATH_SHAPE_ADJOINT_H

#include "path/adjoint.h"
#include "shared/bsdf_dir_grad.h"

#if SHAPE_GRAD
TANDEM_INLINE ShapeVertex shape_vertex_none(void) {
    ShapeVertex sv;
    sv.prim = NO_PARAM;
    sv.u = sv.v = sv.g_tu = sv.g_tv = 0.0f;
    sv.x = sv.n = sv.n_g = sv.d = sv.g_x = sv.g_n = sv.g_wo = make_float3(0.0f, 0.0f, 0.0f);
    return sv;
}

/// The vertex at `it` (shaded, found along unit direction d) as pending, if its triangle moves
/// (its vertices are parameters: prim_params); else none.
TANDEM_INLINE ShapeVertex shape_vertex_at(const SceneRefs* s, const Interaction* it, float3 d) {
    ShapeVertex sv = shape_vertex_none();
    if (s->prim_params[it->hit.prim].x == NO_PARAM) return sv;
    sv.prim = it->hit.prim;
    sv.u = it->hit.u;
    sv.v = it->hit.v;
    sv.x = it->x;
    sv.n = it->frame.n;
    sv.n_g = it->n_front;
    sv.d = d;
    return sv;
}

/// What a glossy vertex's BSDF adds to the derivative of a term through its directions, for the
/// term's weights k per channel (its derivative is k . d(f cos_o), the explicit cos_o left to the
/// geometry): in world space, d/dn, d/dwo and d/dwi (shared/bsdf_dir_grad.h).
typedef struct ShapeDirs {
    float3 n, wo, wi;
} ShapeDirs;

TANDEM_INLINE ShapeDirs shape_bsdf_dirs(const Interaction* it, float3 k, float3 wo_local,
                                        float3 wo) {
    const BsdfDirGrad g =
        bsdf_eval_dir_grad(it->plastic_tables, &it->mat, it->albedo, it->wi_local, wo_local);
    const float a = vdot(k, g.d_cos_i), b = vdot(k, g.d_cos_o), c = vdot(k, g.d_mu);
    const float3 n = it->frame.n;
    ShapeDirs d;
    d.n = it->wi * a + wo * b;
    d.wo = n * b + it->wi * c;
    d.wi = n * a + wo * c;
    return d;
}

/// Whether the vertex at `it` needs its BSDF's direction derivatives: a glossy BSDF at a moving
/// vertex (`here`) or after one (`before`).
TANDEM_INLINE int shape_dirs_needed(const Interaction* it, const ShapeVertex* here,
                                    const ShapeVertex* before) {
    return bsdf_has_dir_grad(&it->mat) && (here->prim != NO_PARAM || before->prim != NO_PARAM);
}

/// Adds k d(log F)/dx and k d(log F)/dn for a term of weight k (delta . term) whose factor is
/// F = (n . wo) (n_far . wo)^a / r^(2 b) p(x) toward a point at distance r along wo: a = 1 with
/// the far end's normal n_far (a triangle light, or the Jacobian to the next hit), b = 1 for a
/// point at a finite distance; a = b = 0 for a direction (the environment, wo fixed as x moves);
/// p the light's emission profile toward x (a spot's falloff), d(log p)/dx = profile_dx. `dirs`
/// (0 for a BSDF that has none): the term's derivatives through its BSDF's directions, of which
/// d/dwo reaches x through d(wo)/dx = -(I - wo wo^T) / r.
TANDEM_INLINE void shape_vertex_add(ShapeVertex* sv, float k, const ShapeDirs* dirs, float3 wo,
                                    float r, int far_point, int has_far_normal, float3 n_far,
                                    float3 profile_dx) {
    const float cos_x = vdot(sv->n, wo);
    if (!(cos_x > 0.0f) || k == 0.0f) return;
    sv->g_n += wo * (k / cos_x);
    if (dirs) sv->g_n += dirs->n;
    if (!far_point) return;
    // d(wo)/dx = -(I - wo wo^T) / r: d(log(n . wo))/dx = -(n - (n . wo) wo) / (r (n . wo))
    float3 g = (sv->n - wo * cos_x) * (-1.0f / (r * cos_x));
    if (has_far_normal) {
        const float cos_far = vdot(n_far, wo);
        if (cos_far != 0.0f) g += (n_far - wo * cos_far) * (-1.0f / (r * cos_far));
    }
    g += wo * (2.0f / r); // d(log 1/r^2)/dx = 2 wo / r
    sv->g_x += (g + profile_dx) * k;
    if (dirs) sv->g_x += (dirs->wo - wo * vdot(wo, dirs->wo)) * (-1.0f / r);
}

/// The pending vertex's derivatives through its albedo's texture coordinates, from what its terms
/// gathered for the albedo itself (acc_albedo = delta . d(terms)/d(albedo), per channel): as it
/// slides, the texture under it moves (a bitmap's bilinear lookup; texture_eval_duv).
TANDEM_INLINE void shape_vertex_texture(const SceneRefs* s, __global const float* params,
                                        ShapeVertex* sv, const Interaction* it,
                                        float3 acc_albedo) {
#if HAS_TEXTURES
    if (sv->prim == NO_PARAM || it->mat.texture == NO_TEXTURE) return;
    float3 du, dv;
    texture_eval_duv(&s->textures[it->mat.texture], s->texels, params, it->tu, it->tv, &du, &dv);
    sv->g_tu = vdot(acc_albedo, du);
    sv->g_tv = vdot(acc_albedo, dv);
#else
    (void)s;
    (void)params;
    (void)sv;
    (void)it;
    (void)acc_albedo;
#endif
}

/// The vector q_t with q_t . delta the change of the pending vertex's terms through its texture
/// coordinates when its barycentrics slide by du = c_u . delta, dv = c_v . delta (delta = dx -
/// sum_k w_k dP_k; c_u = (e2 x N) / |N|^2, c_v = (N x e1) / |N|^2): its texture coordinates move
/// by du (t1 - t0) + dv (t2 - t0), t_k those of its triangle's corners.
TANDEM_INLINE float3 shape_vertex_texture_slide(const SceneRefs* s, const ShapeVertex* sv,
                                                float3 e1, float3 e2, float3 N) {
    const float len2 = vdot(N, N);
    if ((sv->g_tu == 0.0f && sv->g_tv == 0.0f) || !(len2 > 0.0f))
        return make_float3(0.0f, 0.0f, 0.0f);
#if HAS_TEXTURES
    __global const float* t = (__global const float*)(s->uvs + sv->prim);
    const float a1 = sv->g_tu * (t[2] - t[0]) + sv->g_tv * (t[3] - t[1]);
    const float a2 = sv->g_tu * (t[4] - t[0]) + sv->g_tv * (t[5] - t[1]);
    return (vcross(e2, N) * a1 + vcross(N, e1) * a2) * (1.0f / len2);
#else
    (void)s;
    (void)e1;
    (void)e2;
    return make_float3(0.0f, 0.0f, 0.0f);
#endif
}

#if HAS_SHADING_NORMALS
/// shape_vertex_push for a vertex shaded with its triangle's vertex normals N_k, whose normal is
/// n = +-M / |M|, M = sum_k w_k N_k at its barycentric weights w (interpolated_normal), with
/// g_M = +-(I - n n^T) g_n / |M|. As it slides along its ray (dx as in shape_vertex_push, in the
/// plane of its triangle's own normal n_g) its barycentrics move by du = c_u . delta,
/// dv = c_v . delta, delta = dx - sum_k w_k dP_k, c_u = (e2 x N) / |N|^2, c_v = (N x e1) / |N|^2,
/// which turns M by du (N1 - N0) + dv (N2 - N0); so with q = (g_M . (N1 - N0)) c_u +
/// (g_M . (N2 - N0)) c_v, dP_k gets w_k (n_g ((g_x + q) . d) / (n_g . d) - q). M turns with the
/// vertex normals too, w_k g_M for N_k: a normal derived from the positions passes it on to the
/// vertices around it through its blocks of normal_jac (core/scene/vertex_normals.h); a normal
/// of the file's stays.
TANDEM_INLINE void shape_vertex_push_smooth(const SceneRefs* s, Adjoint* adj,
                                            const ShapeVertex* sv, const uint offset[3],
                                            const float w[3], float3 e1, float3 e2, float3 N) {
    float3 m;
    const float3 n_m = interpolated_normal(s, sv->prim, sv->u, sv->v, &m);
    const float nd = vdot(sv->n_g, sv->d), len2 = vdot(N, N);
    if (nd == 0.0f || !(len2 > 0.0f)) return;
    const float sign = vdot(sv->n, n_m) >= 0.0f ? 1.0f : -1.0f;
    const float3 g_m = (sv->g_n - sv->n * vdot(sv->g_n, sv->n)) * (sign / vlength(m));
    __global const TriangleNormals* tn = s->normals + sv->prim;
    const float3 n0 = xyz(tn->n0), n1 = xyz(tn->n1), n2 = xyz(tn->n2);
    const float3 q = (vcross(e2, N) * vdot(g_m, n1 - n0) + vcross(N, e1) * vdot(g_m, n2 - n0)) *
                         (1.0f / len2) +
                     shape_vertex_texture_slide(s, sv, e1, e2, N);
    const float slide = vdot(sv->g_x + q, sv->d) / nd;
    const uint link[3] = {tn->link.y, tn->link.z, tn->link.w};
    for (uint k = 0; k < 3u; ++k) {
        grad_add_rgb(adj, offset[k], (sv->n_g * slide - q) * w[k]);
        if (link[k] == NO_PARAM) continue;
        const float3 h = g_m * w[k];
        const uint count = as_uint(s->normal_jac[link[k]].c1.w);
        for (uint b = link[k]; b < link[k] + count; ++b) {
            __global const NormalJacobian* j = s->normal_jac + b;
            grad_add_rgb(adj, as_uint(j->c0.w),
                         make_float3(vdot(xyz(j->c0), h), vdot(xyz(j->c1), h), vdot(xyz(j->c2), h)));
        }
    }
}
#endif

/// Pushes the pending vertex's gathered derivatives into its triangle's vertex parameters:
/// through its position, dx/dP_k = d n^T b_k / (n . d) (it slides along its ray), and through its
/// normal n = +-normalize(N), N = e1 x e2 (e1 = P1 - P0, e2 = P2 - P0): with b = the part of
/// d/dn across n, over |N|, d/dP1 = e2 x b, d/dP2 = b x e1, d/dP0 = -(both); and through its
/// texture coordinates (q = shape_vertex_texture_slide), w_k (n (q . d) / (n . d) - q). A vertex
/// shaded with vertex normals: shape_vertex_push_smooth.
TANDEM_INLINE void shape_vertex_push(const SceneRefs* s, Adjoint* adj, ShapeVertex* sv) {
    if (sv->prim == NO_PARAM) return;
    const uint4 pp = s->prim_params[sv->prim];
    __global const ShadingPrimitive* t = s->prims + sv->prim;
    const float3 e1 = xyz(t->v1) - xyz(t->v0), e2 = xyz(t->v2) - xyz(t->v0);
    const float3 N = vcross(e1, e2);
    const float len = vlength(N);
    const float nd = vdot(sv->n, sv->d);
    const float w[3] = {1.0f - sv->u - sv->v, sv->u, sv->v};
    const uint offset[3] = {pp.x, pp.y, pp.z};
#if HAS_SHADING_NORMALS
    if (primitive_smooth(s, sv->prim)) {
        shape_vertex_push_smooth(s, adj, sv, offset, w, e1, e2, N);
        sv->prim = NO_PARAM;
        return;
    }
#endif
    if (len > 0.0f && nd != 0.0f) {
        const float3 q = shape_vertex_texture_slide(s, sv, e1, e2, N);
        const float slide = vdot(sv->g_x + q, sv->d) / nd;
        const float3 b = (sv->g_n - sv->n * vdot(sv->g_n, sv->n)) * (1.0f / len);
        const float3 d1 = vcross(e2, b), d2 = vcross(b, e1);
        for (uint k = 0; k < 3u; ++k) {
            const float3 normal_part = k == 0u ? -(d1 + d2) : (k == 1u ? d1 : d2);
            grad_add_rgb(adj, offset[k], (sv->n * slide - q) * w[k] + normal_part);
        }
    }
    sv->prim = NO_PARAM;
}

/// The pending vertex's continuation term, now that its BSDF sample found `next` (at x_next with
/// normal n_next; escaped: the environment, along `dir`): L_rem is what arrived through it. Its
/// push waits for shape_vertex_incoming.
TANDEM_INLINE void shape_vertex_continue(ShapeVertex* sv, float3 delta, float3 L_rem, int escaped,
                                         float3 dir, float3 x_next, float3 n_next) {
    if (sv->prim == NO_PARAM) return;
    const float k = vdot(delta, L_rem);
    const float3 zero = make_float3(0.0f, 0.0f, 0.0f);
    ShapeDirs dirs;
    dirs.n = dirs.wi = zero; // d/dn of the continuation's BSDF went in when it was sampled
    dirs.wo = sv->g_wo;
    if (escaped) {
        shape_vertex_add(sv, k, 0, dir, 0.0f, 0, 0, n_next, zero);
    } else {
        const float3 to = x_next - sv->x;
        const float r = vlength(to);
        if (r > 0.0f) shape_vertex_add(sv, k, &dirs, to * (1.0f / r), r, 1, 1, n_next, zero);
    }
}

/// The continuation's BSDF sample at a glossy vertex `it` (its direction wo, weights k =
/// delta L_rem / f per channel): d/dn into `here`, d/dwo kept in it until the next point is known
/// (shape_vertex_continue), d/dwi into *g_wi.
TANDEM_INLINE void shape_vertex_sampled(ShapeVertex* here, float3* g_wi, const Interaction* it,
                                        float3 k, float3 wo_local, float3 wo) {
    const ShapeDirs dirs = shape_bsdf_dirs(it, k, wo_local, wo);
    *g_wi += dirs.wi;
    if (here->prim == NO_PARAM) return;
    if (vdot(here->n, wo) > 0.0f) here->g_n += dirs.n;
    here->g_wo = dirs.wo;
}

/// Pushes the vertex before `x` (the pending one), once the vertex at x has gathered g_wi = delta
/// . d(its terms)/d(wi) through its BSDF: wi = (x_before - x) / r turns as x_before moves,
/// d(wi)/d(x_before) = (I - wi wi^T) / r.
TANDEM_INLINE void shape_vertex_incoming(const SceneRefs* s, Adjoint* adj, ShapeVertex* before,
                                         float3 g_wi, float3 x) {
    if (before->prim == NO_PARAM) return;
    const float3 to = before->x - x;
    const float r = vlength(to);
    if (r > 0.0f) {
        const float3 wi = to * (1.0f / r);
        before->g_x += (g_wi - wi * vdot(wi, g_wi)) * (1.0f / r);
    }
    shape_vertex_push(s, adj, before);
}

#endif // SHAPE_GRAD

#endif // TANDEM_KERNELS_PATH_SHAPE_ADJOINT_H
