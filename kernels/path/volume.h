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
#include "path/nee.h"

/// The transmittance (rgb) from `origin`, in `medium`, to the light of ls: through the media along
/// its shadow ray and the null surfaces it crosses; 0 where any other surface blocks it, not a
/// number where the walk gave up (media_gave_up). With an
/// adjoint `adj` (the replay), the same walk pushes instead the derivative of the transmittance of
/// every piece through a medium for a light-sample term whose adjoint is k (delta times the term,
/// which is not 0), drawing the points of grid pieces from r, and returns 1.
TANDEM_INLINE float3 media_shadow(const SceneRefs* s, __global const float* params, float3 origin,
                                  const LightSample* ls, uint medium, MediaRng* r, Adjoint* adj,
                                  float3 k) {
    float3 T = make_float3(1.0f, 1.0f, 1.0f);
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
            const Medium m = medium_load(s, params, medium);
            if (adj)
                medium_transmittance_adjoint(s, params, &m, o, d, 0.0f, open ? t_end : h.t, k, r,
                                             adj);
            else
                T = T * medium_transmittance(s, params, &m, o, d, 0.0f, open ? t_end : h.t, r);
        }
        if (open || !all_finite(T)) return T;
        const TriangleInfo info = s->infos[h.prim];
        if (!(max_component(T) > 0.0f) || s->materials[info.material].type != MATERIAL_NULL)
            return make_float3(0.0f, 0.0f, 0.0f);
        if (crossing + 1u == MEDIA_MAX_CROSSINGS) return media_gave_up();
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
/// transmittance *T from media_shadow (0 where the light is blocked). With an adjoint (the
/// replay), the derivative of the transmittance goes into the gradients and the term leaves
/// adj->L_rem; the caller pushes those of f and Le.
TANDEM_INLINE float3 media_nee(const SceneRefs* s, __global const float* params, PathRng rng,
                               uint depth, float3 origin, const LightSample* ls, uint medium,
                               float3 beta, float3 f, float w, Adjoint* adj, float3* T) {
    MediaRng shadow = media_rng(rng, depth, MEDIA_SHADOW);
    *T = media_shadow(s, params, origin, ls, medium, &shadow, 0, beta);
    if (!all_finite(*T)) return *T; // gave up: the sample is dropped
    if (!(max_component(*T) > 0.0f)) return make_float3(0.0f, 0.0f, 0.0f);
    const float3 term = media_nee_term(beta, *T, f, ls->Le, w);
    if (adj) {
        adj->L_rem -= term;
        MediaRng points = media_rng(rng, depth, MEDIA_SHADOW_GRAD);
        media_shadow(s, params, origin, ls, medium, &points, adj, adj->delta * term);
    }
    return term;
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
/// taken out of L_rem; the sampling is detached.
TANDEM_INLINE float3 path_volume_from(const SceneRefs* s, __global const float* params,
                                      PathRng rng, Ray ray, const Hit* first, Adjoint* adj) {
    const RenderParams* rp = s->rp;
    float3 L = make_float3(0.0f, 0.0f, 0.0f), beta = make_float3(1.0f, 1.0f, 1.0f);
    if (rp->max_depth == 0u) return L;
    float prev_pdf = 0.0f; // density of the direction that led here (0: the camera's)
    float dist = 0.0f;     // along it, from the last vertex to the origin of `ray`
    uint medium = s->cam->medium, crossings = 0u;
    MediaRng flights = media_rng(rng, 0u, MEDIA_FLIGHTS);
    MediaRng points = media_rng(rng, 0u, MEDIA_FLIGHTS_GRAD); // the replay's only
    for (uint depth = 0u;;) {
        const Hit hit = first && depth == 0u && crossings == 0u ? *first : trace_closest(s, ray);
        const float3 o = xyz(ray.org), d = xyz(ray.dir);
        if (medium != NO_MEDIUM) {
            const Medium m = medium_load(s, params, medium);
            float t_s;
            const float t_hit = hit.prim == HIT_NONE ? INFINITY : hit.t;
            // everything after this point comes through the flight's transmittance
            const float3 k = adj ? adj->delta * adj->L_rem : make_float3(0.0f, 0.0f, 0.0f);
            const int flight =
                medium_free_flight(s, params, &m, o, d, ray.org.w, t_hit, &flights, &beta, &t_s);
            if (flight == FLIGHT_ABSORBED) {
                if (flights.exhausted) L = media_gave_up();
                break;
            }
            if (adj)
                medium_transmittance_adjoint(s, params, &m, o, d, ray.org.w,
                                             flight == FLIGHT_SCATTERED ? t_s : t_hit, k, &points,
                                             adj);
            if (flight == FLIGHT_SCATTERED) {
                // A vertex in the medium: NEE through the media, then the phase function.
                const float3 x = o + d * t_s;
                if (adj) medium_scatter_adjoint(s, params, &m, x, k, adj);
                if (!path_continues(rp, depth)) break;
                const VertexRandom vr = vertex_random(rng, path_dim(depth));
                if (NEE_ENABLED) {
                    const LightSample ls = nee_sample(s, params, x, vr);
                    if (ls.pdf > 0.0f) {
                        const float cos_l = vdot(ls.wo, d);
                        const float ph = phase_eval(m.phase, m.g, cos_l);
                        const float w = (ls.delta ? 1.0f : nee_mis_weight(ls.pdf, ph)) / ls.pdf;
                        float3 T;
                        const float3 term = media_nee(s, params, rng, depth, x, &ls, medium, beta,
                                                      make_float3(ph, ph, ph), w, adj, &T);
                        L += term;
                        if (adj && max_component(term) > 0.0f) {
                            // d/d(Le) through the light, d/dg through the phase's value
                            const float3 bt = beta * T, dl = adj->delta;
                            if (ls.Le_param != NO_PARAM)
                                grad_add_rgb(
                                    adj, ls.Le_param,
                                    make_float3(adjoint_nee_light_channel(dl.x, bt.x, ph, w),
                                                adjoint_nee_light_channel(dl.y, bt.y, ph, w),
                                                adjoint_nee_light_channel(dl.z, bt.z, ph, w)));
                            if (m.g_param != NO_PARAM)
                                grad_add(adj, m.g_param,
                                         channel_sum(adj->delta * term) * phase_dlog_dg(m.phase, m.g, cos_l));
                        }
                    }
                }
                const float3 wo = phase_sample(m.phase, m.g, d, vertex_rand(vr, DIM_BSDF),
                                               vertex_rand(vr, DIM_BSDF + 1u));
                // the phase sample's weight (phase / its density, 1) holds the phase: d/dg of
                // what came through it
                if (adj && m.g_param != NO_PARAM)
                    grad_add(adj, m.g_param,
                             channel_sum(adj->delta * adj->L_rem) * phase_dlog_dg(m.phase, m.g, vdot(wo, d)));
                prev_pdf = phase_eval(m.phase, m.g, vdot(wo, d));
                ray = make_ray(x, wo, 0.0f, INFINITY);
                dist = 0.0f;
                crossings = 0u;
                if (roulette_applies(rp, depth)) {
                    const float q = roulette_q(beta);
                    if (roulette_ends(vr, q)) break;
                    beta = roulette_beta3(beta, q);
                }
                ++depth;
                flights = media_rng(rng, depth, MEDIA_FLIGHTS);
                points = media_rng(rng, depth, MEDIA_FLIGHTS_GRAD);
                continue;
            }
        }

        // No collision before the surface: the environment, or the surface.
        if (hit.prim == HIT_NONE) {
#if HAS_ENV_LIGHT
            const Emission env = emission_env(s, params, ray, depth, prev_pdf);
            L = path_term_add3(L, beta, env.Le, env.w);
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
            ray = make_ray(offset_ray_origin(it.x, vdot(d, it.n_front) > 0.0f ? it.n_front
                                                                              : -it.n_front),
                           d, 0.0f, INFINITY);
            continue;
        }
        if (!path_continues(rp, depth)) break;
        if (!interaction_shade(s, params, &it)) break;
        const VertexRandom vr = vertex_random(rng, path_dim(depth));
        const BsdfSample bs = continuation_sample(&it, vr);
        BsdfGrad acc = bsdf_grad_zero(); // the replay's d/d(material) of this vertex
        if (nee_applies(&it)) {
            const LightSample ls = nee_sample(s, params, it.origin, vr);
            const NeeEval ev = nee_eval(&it, &ls);
            if (ls.pdf > 0.0f && max_component(ev.f) > 0.0f) {
                const float w = nee_weight(&it, &ls, &ev);
                float3 T;
                const float3 term =
                    media_nee(s, params, rng, depth, it.origin, &ls,
                              medium_crossed(&it.info, ls.wo, it.n_front, medium), beta, ev.f, w,
                              adj, &T);
                L += term;
                // d/d(material) through f, d/d(Le) through the light (path/adjoint.h)
                if (adj && max_component(term) > 0.0f) adjoint_nee(adj, &acc, &it, &ls, &ev, beta * T, w);
            }
        }
        const int ends = continuation_failed(&bs) || max_component(bs.weight) <= 0.0f;
        if (adj) {
            if (!ends) adjoint_continuation(adj, &acc, &it, &bs);
            AlbedoSource src;
            interaction_albedo_source(s, &it, &src);
            grad_material(adj, &it.mat, &src, &acc);
        }
        if (ends) break;
        beta = continuation_beta3(beta, bs.weight);
        prev_pdf = continuation_pdf(&bs);
        ray = continuation_ray(&it, &bs);
        medium = medium_crossed(&it.info, xyz(ray.dir), it.n_front, medium);
        dist = 0.0f;
        crossings = 0u;
        if (roulette_applies(rp, depth)) {
            const float q = roulette_q(beta);
            if (roulette_ends(vr, q)) break;
            beta = roulette_beta3(beta, q);
        }
        ++depth;
        flights = media_rng(rng, depth, MEDIA_FLIGHTS);
        points = media_rng(rng, depth, MEDIA_FLIGHTS_GRAD);
    }
    return L;
}

#endif // TANDEM_KERNELS_PATH_VOLUME_H
