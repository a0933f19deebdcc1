// The volumetric path (HAS_MEDIA builds): shadow rays through media and null surfaces, and the
// path that scatters in media and on surfaces, with its replay (docs/method.md, "Participating
// media" and "Gradients of media").
#ifndef TANDEM_KERNELS_PATH_VOLUME_H
#define TANDEM_KERNELS_PATH_VOLUME_H

#include "path/adjoint.h"
#include "path/continuation.h"
#include "path/emission.h"
#include "path/media.h"
#include "path/media_adjoint.h"
#include "path/media_drt.h"
#include "path/nee.h"

/// The transmittance (rgb) from `origin`, in `medium`, to the light of ls: through the media along
/// its shadow ray and the null surfaces it crosses; 0 where any other surface blocks it, not a
/// number where the walk gave up (media_gave_up). For a two-state path (old not 0), *T_old is the
/// old state's, by the same walk: ratio tracking under the majorant of both states
/// (medium_load_states), on the same collisions. With an adjoint `adj` (the replay, one state),
/// the same walk pushes instead the derivative of the transmittance of every piece through a
/// medium for a light-sample term whose adjoint is k (delta times the term, which is not 0),
/// drawing the points of grid pieces from r, and returns 1.
TANDEM_INLINE float3 media_shadow(const SceneRefs* s, __global const float* params, float3 origin,
                                  const LightSample* ls, uint medium, MediaRng* r, Adjoint* adj,
                                  float3 k, const OldState* old, float3* T_old) {
    const float3 zero = make_float3(0.0f, 0.0f, 0.0f), one = make_float3(1.0f, 1.0f, 1.0f);
    float3 T = one;
    MediaRng r_old; // the old state's copy of r: the same numbers, as long as both walk
    if (old) {
        *T_old = one;
        r_old = *r;
    }
    const float len = vlength(ls->shadow_dir);
    const float3 d = ls->shadow_dir * (1.0f / len);
    const int bounded = ls->shadow_tmax < INFINITY;
    const float3 target = origin + ls->shadow_dir * (bounded ? ls->shadow_tmax : 0.0f);
    float3 o = origin;
    float t_end = bounded ? len * ls->shadow_tmax : INFINITY;
    for (uint crossing = 0u;; ++crossing) {
        const Hit h = trace_closest(s, make_ray(o, d, 0.0f, t_end));
        const int open = h.prim == HIT_NONE;
        if (medium != NO_MEDIUM) {
            Medium m, m_old;
            medium_load_states(s, params, old, medium, &m, &m_old);
            const float t1 = open ? t_end : h.t;
            if (adj) {
                medium_transmittance_adjoint(s, params, &m, o, d, 0.0f, t1, k, r, adj);
            } else {
                T = T * medium_transmittance(s, params, &m, o, d, 0.0f, t1, r);
                if (old)
                    *T_old = *T_old *
                             medium_transmittance(s, old->params, &m_old, o, d, 0.0f, t1, &r_old);
            }
        }
        if (open || !all_finite(T) || (old && !all_finite(*T_old))) return T;
        const TriangleInfo info = s->infos[h.prim];
        const int lit = max_component(T) > 0.0f || (old && max_component(*T_old) > 0.0f);
        if (!lit || s->materials[info.material].type != MATERIAL_NULL) {
            if (old) *T_old = zero;
            return zero;
        }
        if (crossing + 1u == MEDIA_MAX_CROSSINGS) {
            if (old) *T_old = media_gave_up();
            return media_gave_up();
        }
        float3 x, n;
        primitive_point(s, h.prim, h.u, h.v, &x, &n);
        medium = medium_crossed(&info, d, n, medium);
        o = offset_ray_origin(x, vdot(d, n) > 0.0f ? n : -n);
        t_end = bounded ? vdot(target - o, d) : INFINITY;
        if (!(t_end > 0.0f)) return T;
    }
}

/// The contribution of a light sample whose transmittance is T and f (the BSDF's f cos, or the
/// phase function's value), MIS weight over density w: beta T f Le w.
TANDEM_INLINE float3 media_nee_term(float3 beta, float3 T, float3 f, float3 Le, float w) {
    return nee_term3(beta * T, f, Le, w);
}

/// A light sample's term through the media from `origin` in `medium`: beta T f Le w, with the
/// transmittance *T from media_shadow (0 where the light is blocked). A two-state path (old not
/// 0) adds the old state's term, with its own throughput, transmittance, f_old and radiance and
/// the new state's MIS weight, to old->L. With an adjoint (the replay), the derivative of the
/// transmittance goes into the gradients and the term leaves adj->L_rem; the caller pushes those
/// of f and Le.
TANDEM_INLINE float3 media_nee(const SceneRefs* s, __global const float* params, PathRng rng,
                               uint depth, float3 origin, const LightSample* ls, uint medium,
                               float3 beta, float3 f, float w, Adjoint* adj, float3* T,
                               OldState* old, float3 f_old) {
    MediaRng shadow = media_rng(rng, depth, MEDIA_SHADOW);
    float3 T_old;
    *T = media_shadow(s, params, origin, ls, medium, &shadow, 0, beta, old, &T_old);
    if (old) old->L += media_nee_term(old->beta, T_old, f_old, nee_Le_in(old->params, ls), w);
    if (!all_finite(*T)) return *T; // gave up: the sample is dropped
    if (!(max_component(*T) > 0.0f)) return make_float3(0.0f, 0.0f, 0.0f);
    const float3 term = media_nee_term(beta, *T, f, ls->Le, w);
    if (adj) {
        adj->L_rem -= term;
        MediaRng points = media_rng(rng, depth, MEDIA_SHADOW_GRAD);
        media_shadow(s, params, origin, ls, medium, &points, adj, adj->delta * term, 0, 0);
    }
    return term;
}

/// The end of a scattering vertex, in a medium or on a surface: Russian roulette on the
/// throughput (a two-state path's on both, with roulette_q_two_state, both divided by the same
/// q). Returns whether the path goes on.
TANDEM_INLINE int volume_roulette(const RenderParams* rp, uint depth, VertexRandom vr,
                                  float3* beta, OldState* old) {
    if (!roulette_applies(rp, depth)) return 1;
    const float q = old ? roulette_q_two_state(*beta, old->beta) : roulette_q(*beta);
    if (roulette_ends(vr, q)) return 0;
    *beta = roulette_beta3(*beta, q);
    if (old) old->beta = roulette_beta3(old->beta, q);
    return 1;
}

/// The scattering vertex at x in medium m (m_old: the old state's, for a two-state path) that a
/// free flight along d reached: NEE through the media, the phase function's next direction
/// (*ray, *prev_pdf), and for the replay their derivatives (k: the adjoint of everything after
/// the collision). The old state weighs the new state's direction with its own phase function
/// over the new one's (the phase sample's weight, 1, in the new state).
TANDEM_INLINE void volume_medium_vertex(const SceneRefs* s, __global const float* params,
                                        PathRng rng, uint depth, VertexRandom vr, uint medium,
                                        const Medium* m, const Medium* m_old, float3 x, float3 d,
                                        float3 beta, float3* L, Ray* ray, float* prev_pdf,
                                        Adjoint* adj, OldState* old) {
    if (NEE_ENABLED) {
        const LightSample ls = nee_sample(s, params, x, vr);
        if (ls.pdf > 0.0f) {
            const float cos_l = vdot(ls.wo, d);
            const float ph = phase_eval(m->phase, m->g, cos_l);
            const float ph_old = old ? phase_eval(m_old->phase, m_old->g, cos_l) : 0.0f;
            const float w = (ls.delta ? 1.0f : nee_mis_weight(ls.pdf, ph)) / ls.pdf;
            float3 T;
            const float3 term =
                media_nee(s, params, rng, depth, x, &ls, medium, beta, make_float3(ph, ph, ph), w,
                          adj, &T, old, make_float3(ph_old, ph_old, ph_old));
            *L += term;
            if (adj && max_component(term) > 0.0f) {
                // d/d(Le) through the light, d/dg through the phase's value
                const float3 bt = beta * T, dl = adj->delta;
                if (ls.Le_param != NO_PARAM)
                    grad_add_rgb(adj, ls.Le_param,
                                 make_float3(adjoint_nee_light_channel(dl.x, bt.x, ph, w),
                                             adjoint_nee_light_channel(dl.y, bt.y, ph, w),
                                             adjoint_nee_light_channel(dl.z, bt.z, ph, w)));
                if (m->g_param != NO_PARAM)
                    grad_add(adj, m->g_param,
                             channel_sum(adj->delta * term) * phase_dlog_dg(m->phase, m->g, cos_l));
            }
        }
    }
    const float3 wo = phase_sample(m->phase, m->g, d, vertex_rand(vr, DIM_BSDF),
                                   vertex_rand(vr, DIM_BSDF + 1u));
    const float cos_o = vdot(wo, d);
    // the phase sample's weight (phase / its density, 1) holds the phase: d/dg of what came
    // through it
    if (adj && m->g_param != NO_PARAM)
        grad_add(adj, m->g_param,
                 channel_sum(adj->delta * adj->L_rem) * phase_dlog_dg(m->phase, m->g, cos_o));
    *prev_pdf = phase_eval(m->phase, m->g, cos_o);
    if (old) old->beta = old->beta * (phase_eval(m_old->phase, m_old->g, cos_o) / *prev_pdf);
    *ray = make_ray(x, wo, 0.0f, INFINITY);
}

/// The scattering vertex on the surface `it` (not null) in `medium`, as path_primal's: NEE through
/// the media, the BSDF's next direction (*ray, *prev_pdf, *medium), and for the replay their
/// derivatives; a two-state path's old state with its own material along the same directions
/// (path/two_state.h). Returns whether the path goes on.
TANDEM_INLINE int volume_surface_vertex(const SceneRefs* s, __global const float* params,
                                        PathRng rng, uint depth, VertexRandom vr, Interaction* it,
                                        uint* medium, float3* beta, float3* L, Ray* ray,
                                        float* prev_pdf, Adjoint* adj, OldState* old) {
    const float3 zero = make_float3(0.0f, 0.0f, 0.0f);
    const BsdfSample bs = continuation_sample(it, vr);
    BsdfGrad acc = bsdf_grad_zero(); // the replay's d/d(material) of this vertex
    Material mat_old;
    float3 albedo_old = zero;
    if (old) {
        mat_old = material_load(s, old->params, it->info.material);
        albedo_old = material_albedo(s, &mat_old, old->params, it->tu, it->tv);
    }
    if (nee_applies(it)) {
        const LightSample ls = nee_sample(s, params, it->origin, vr);
        const NeeEval ev = nee_eval(it, &ls);
        const float3 f_old =
            old ? bsdf_eval(it->plastic_tables, &mat_old, albedo_old, it->wi_local, ev.wo_local)
                : zero;
        if (ls.pdf > 0.0f && (max_component(ev.f) > 0.0f || max_component(f_old) > 0.0f)) {
            const float w = nee_weight(it, &ls, &ev);
            float3 T;
            const float3 term =
                media_nee(s, params, rng, depth, it->origin, &ls,
                          medium_crossed(&it->info, ls.wo, it->n_front, *medium), *beta, ev.f, w,
                          adj, &T, old, f_old);
            *L += term;
            // d/d(material) through f, d/d(Le) through the light (path/adjoint.h)
            if (adj && max_component(term) > 0.0f)
                adjoint_nee(adj, &acc, it, &ls, &ev, *beta * T, w);
        }
    }
    const float3 weight_old = old && !continuation_failed(&bs)
                                  ? continuation_weight_old(it, &mat_old, albedo_old, &bs)
                                  : zero;
    const int ends = continuation_failed(&bs) ||
                     (max_component(bs.weight) <= 0.0f && max_component(weight_old) <= 0.0f);
    if (adj) {
        if (!ends) adjoint_continuation(adj, &acc, it, &bs);
        AlbedoSource src;
        interaction_albedo_source(s, it, &src);
        grad_material(adj, &it->mat, &src, &acc);
    }
    if (ends) return 0;
    *beta = continuation_beta3(*beta, bs.weight);
    if (old) old->beta = continuation_beta3(old->beta, weight_old);
    *prev_pdf = continuation_pdf(&bs);
    *ray = continuation_ray(it, &bs);
    *medium = medium_crossed(&it->info, xyz(ray->dir), it->n_front, *medium);
    return 1;
}

/// The radiance (linear RGB) of the volumetric path that leaves the camera along `ray` (its
/// first hit `first` where given, as path_primal_from), in the parameter state `params`. Media
/// scatter (free flights), null surfaces are crossed without a vertex, and every other surface is
/// shaded as path_primal's are; NEE from either kind of vertex goes through media_shadow. depth
/// counts scattering vertices, in the media and on surfaces alike (Mitsuba's volpath).
///
/// With an adjoint `adj` (adj->L_rem: the primal's radiance of this path), this is the path's
/// replay (path/replay.h, for media): the same path, term by term, each term's derivative pushed
/// into the gradients (the adjoint of media above; surfaces as path_replay_vertex) and the term
/// taken out of L_rem; the sampling is detached. Its segments in grid media are offered to a
/// reservoir, and the one kept takes differential ratio tracking's term (path/media_drt.h): the
/// path that estimates the in-scattered radiance at its point runs through this same loop
/// afterwards, from that point, with the adjoint off (a second copy of the loop would double the
/// kernel, and its compile time).
///
/// With an old state `old` (old->beta 1, old->L 0 on entry; no adjoint), this is the two-state
/// path through media (CV-PS: "Recursive Control Variates for Inverse Rendering", section 5 and
/// Appendix B): the path is sampled from the new state, free flights under a majorant of both
/// states (medium_free_flight), and old->L receives the old state's estimate along it: its own
/// media, materials and radiances, the new state's MIS weights, and one roulette for both. With
/// equal states both estimates are this path's primal radiance, bit for bit.
TANDEM_INLINE float3 path_volume_from(const SceneRefs* s, __global const float* params,
                                      PathRng rng, Ray ray, const Hit* first, Adjoint* adj,
                                      OldState* old) {
    const RenderParams* rp = s->rp;
    float3 L = make_float3(0.0f, 0.0f, 0.0f), beta = make_float3(1.0f, 1.0f, 1.0f);
    if (rp->max_depth == 0u) return L;
    float prev_pdf = 0.0f; // density of the direction that led here (0: the camera's)
    float dist = 0.0f;     // along it, from the last vertex to the origin of `ray`
    uint medium = s->cam->medium, crossings = 0u, depth = 0u;
    MediaRng flights = media_rng(rng, 0u, MEDIA_FLIGHTS);
    MediaRng points = flights, pick = flights; // the replay's
    if (adj) {
        points = media_rng(rng, 0u, MEDIA_FLIGHTS_GRAD);
        pick = media_rng(rng, 0u, MEDIA_DRT_PICK);
    }
    DrtReservoir drt; // the replay's differential ratio tracking
    drt_reset(&drt);
    Adjoint* replay = adj; // (adj is 0 while the loop runs DRT's path)
    float3 L_path = L, drt_x = L, drt_k = L;
    Medium drt_m;
    int drt_vertex = 0; // the loop's next vertex is DRT's point
    for (;;) {
        for (;;) {
            Hit hit;
            float3 d;
            int scattered = 0;
            VertexRandom vr;
            if (drt_vertex) {
                // DRT's point: a vertex in its medium, where its path starts
                drt_vertex = 0;
                d = drt.d;
                vr = vertex_random(rng, path_dim(depth));
                volume_medium_vertex(s, params, rng, depth, vr, medium, &drt_m, &drt_m, drt_x, d,
                                     beta, &L, &ray, &prev_pdf, 0, 0);
                scattered = 1;
            } else {
                hit = first ? *first : trace_closest(s, ray);
                first = 0;
                const float3 o = xyz(ray.org);
                d = xyz(ray.dir);
                if (medium != NO_MEDIUM) {
                    Medium m, m_old;
                    medium_load_states(s, params, old, medium, &m, &m_old);
                    float t_s;
                    const float t_hit = hit.prim == HIT_NONE ? INFINITY : hit.t;
                    // everything after this point comes through the flight's transmittance
                    const float3 k =
                        adj ? adj->delta * adj->L_rem : make_float3(0.0f, 0.0f, 0.0f);
                    if (adj && m.kind == MEDIUM_GRID && path_continues(rp, depth))
                        drt_offer(&drt, &pick, o, d, ray.org.w, t_hit, medium, depth,
                                  adj->delta * beta);
                    const int flight = medium_free_flight(s, params, &m, o, d, ray.org.w, t_hit,
                                                          &flights, &beta, &t_s, old, &m_old);
                    if (flight == FLIGHT_ABSORBED) {
                        if (flights.exhausted) L = media_gave_up();
                        break;
                    }
                    if (adj)
                        medium_transmittance_adjoint(s, params, &m, o, d, ray.org.w,
                                                     flight == FLIGHT_SCATTERED ? t_s : t_hit, k,
                                                     &points, adj);
                    if (flight == FLIGHT_SCATTERED) {
                        // A vertex in the medium.
                        const float3 x = o + d * t_s;
                        if (adj) medium_scatter_adjoint(s, params, &m, x, k, adj);
                        if (!path_continues(rp, depth)) break;
                        vr = vertex_random(rng, path_dim(depth));
                        volume_medium_vertex(s, params, rng, depth, vr, medium, &m, &m_old, x, d,
                                             beta, &L, &ray, &prev_pdf, adj, old);
                        scattered = 1;
                    }
                }
            }
            if (!scattered) {
                // No collision before the surface: the environment, or the surface.
                if (hit.prim == HIT_NONE) {
#if HAS_ENV_LIGHT
                    const Emission env = emission_env(s, params, ray, depth, prev_pdf);
                    L = path_term_add3(L, beta, env.Le, env.w);
                    if (old)
                        old->L = path_term_add3(old->L, old->beta,
                                                emission_Le_in(old->params, &env), env.w);
                    if (adj) {
                        adjoint_emission(adj, &env, beta);
                        adj->L_rem = path_term_sub3(adj->L_rem, beta, env.Le, env.w);
                    }
#endif
                    break;
                }
                Interaction it;
                interaction_at(s, ray, hit, &it);
                dist += hit.t;
#if HAS_AREA_LIGHTS
                Emission em;
                if (emission_area_at(s, params, &it, depth, prev_pdf, dist, &em)) {
                    L = path_term_add3(L, beta, em.Le, em.w);
                    if (old)
                        old->L = path_term_add3(old->L, old->beta,
                                                emission_Le_in(old->params, &em), em.w);
                    if (adj) {
                        adjoint_emission(adj, &em, beta);
                        adj->L_rem = path_term_sub3(adj->L_rem, beta, em.Le, em.w);
                    }
                }
#endif
                if (s->materials[it.info.material].type == MATERIAL_NULL) {
                    // A null surface: the ray goes on, into the medium on its other side.
                    if (++crossings == MEDIA_MAX_CROSSINGS) {
                        L = media_gave_up();
                        break;
                    }
                    medium = medium_crossed(&it.info, d, it.n_front, medium);
                    ray = make_ray(offset_ray_origin(it.x, vdot(d, it.n_front) > 0.0f
                                                               ? it.n_front
                                                               : -it.n_front),
                                   d, 0.0f, INFINITY);
                    continue;
                }
                if (!path_continues(rp, depth)) break;
                if (!interaction_shade(s, params, &it)) break;
                vr = vertex_random(rng, path_dim(depth));
                if (!volume_surface_vertex(s, params, rng, depth, vr, &it, &medium, &beta, &L,
                                           &ray, &prev_pdf, adj, old))
                    break;
            }
            // Both kinds of scattering vertex: the next segment starts here.
            dist = 0.0f;
            crossings = 0u;
            if (!volume_roulette(rp, depth, vr, &beta, old)) break;
            ++depth;
            flights = media_rng(rng, depth, MEDIA_FLIGHTS);
            if (adj) points = media_rng(rng, depth, MEDIA_FLIGHTS_GRAD);
        }
        if (!adj || !(drt.w > 0.0f)) break; // the path is done (and DRT's, if it ran)
        // The replay is done: DRT's point on the kept segment, and its path from there.
        L_path = L;
        MediaRng r = media_rng(rng, 0u, MEDIA_DRT_POINT);
        if (!drt_point(s, params, &drt, &r, &drt_m, &drt_x, &drt_k)) break;
        rng = media_rng(rng, 0u, MEDIA_DRT_PATH).rng;
        adj = 0;
        L = make_float3(0.0f, 0.0f, 0.0f);
        beta = make_float3(1.0f, 1.0f, 1.0f);
        medium = drt.medium;
        depth = drt.depth;
        dist = 0.0f;
        crossings = 0u;
        flights = media_rng(rng, depth, MEDIA_FLIGHTS);
        drt_vertex = 1;
    }
    if (!replay || adj) return L; // not the replay, or DRT did not run
    // L: the in-scattered radiance at DRT's point
    if (all_finite(L)) medium_grid_sigma_t_adjoint(s, params, &drt_m, drt_x, drt_k * L, replay);
    return L_path;
}

#endif // TANDEM_KERNELS_PATH_VOLUME_H
