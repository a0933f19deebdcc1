// Participating media in the path tracer (HAS_MEDIA builds): free flights by spectral tracking
// against a majorant, transmittance by ratio tracking (closed form in a homogeneous medium), shadow
// rays through null surfaces, and the volumetric path that uses them (docs/method.md,
// "Participating media").
//
// RGB extinction: one distance for all three channels, drawn from the majorant of the largest
// channel, then spectral tracking (Kutz et al. 2017, "Spectral and Decomposition Tracking for
// Rendering Heterogeneous Volumes", section 5.2, with its history-aware probabilities and
// absorption folded into the weights): at a tentative collision the path scatters with
// probability P_s = avg(|beta sigma_s|) / (avg(|beta sigma_s|) + avg(|beta sigma_n|)) and weight
// sigma_s / (mu P_s), or goes on with weight sigma_n / (mu (1 - P_s)). One distance for every
// channel is what the gradients need: the two-state path and the replay walk the same collisions
// for every channel and both parameter states, under one majorant. (Mitsuba's volpath picks a hero
// channel per path instead; both are unbiased.)
#ifndef TANDEM_KERNELS_PATH_MEDIA_H
#define TANDEM_KERNELS_PATH_MEDIA_H

#include "path/adjoint.h"
#include "path/continuation.h"
#include "path/emission.h"
#include "path/nee.h"
#include "shared/medium.h"

// The random numbers of free flights and ratio tracking: a stream of their own per path vertex and
// purpose (the free flights that lead from the vertex, or its shadow ray's ratio tracking), keyed
// by a hash of (seed, depth, purpose) in place of the seed, its dimensions counted from 0. (Not
// dimensions with a high bit set beside the path's own: pcg4d mixes inputs that differ only in
// their high bits poorly, and such streams came out correlated with the vertex's light sample,
// which biased single scattering by about 1 % where null collisions occur.) A walk that would draw
// more than MEDIA_MAX_DRAWS ends (a free flight absorbs the path, a shadow ray is taken as
// blocked): 2^18 collisions, far beyond any medium a majorant bounds sensibly.
#define MEDIA_MAX_DRAWS 0x80000u
#define MEDIA_STREAM_TAG 0x6D656469u /* "medi" */
/// Null surfaces a path or shadow ray crosses between two scattering vertices, at most.
#define MEDIA_MAX_CROSSINGS 64u

#define FLIGHT_ESCAPED 0
#define FLIGHT_SCATTERED 1
#define FLIGHT_ABSORBED 2

/// A stream of random numbers for one walk: dimensions `dim` up to `end` of the stream's key.
typedef struct MediaRng {
    PathRng rng;
    uint dim, end;
    int exhausted;
} MediaRng;

#define MEDIA_FLIGHTS 0u      /* the free flights that lead from a vertex */
#define MEDIA_SHADOW 1u       /* its shadow ray's ratio tracking */
#define MEDIA_FLIGHTS_GRAD 2u /* the replay's points on the free flights' segments */
#define MEDIA_SHADOW_GRAD 3u  /* the replay's points on the shadow ray's segments */

/// The stream of `purpose` (MEDIA_*) of the vertex at `depth` of the path of `rng`.
TANDEM_INLINE MediaRng media_rng(PathRng rng, uint depth, uint purpose) {
    uint key[4];
    rng_pcg4d(rng.seed, depth, purpose, MEDIA_STREAM_TAG, key);
    MediaRng r;
    r.rng = path_rng(key[0], rng.pixel, rng.sample);
    r.dim = 0u;
    r.end = MEDIA_MAX_DRAWS;
    r.exhausted = 0;
    return r;
}

TANDEM_INLINE float media_rand(MediaRng* r) {
    if (r->dim == r->end) {
        r->exhausted = 1;
        return 0.0f;
    }
    return path_rand(r->rng, r->dim++);
}

/// The medium a ray of direction d is in after crossing the surface of record `info` whose front
/// normal is n_front, coming from `current`: the shape's interior (d against the normal) or
/// exterior, where the shape is a medium transition; `current` where it is not (Mitsuba's rule).
TANDEM_INLINE uint medium_crossed(const TriangleInfo* info, float3 d, float3 n_front,
                                  uint current) {
    if (info->interior == NO_MEDIUM && info->exterior == NO_MEDIUM) return current;
    return vdot(d, n_front) < 0.0f ? info->interior : info->exterior;
}

/// Medium `index` with its differentiable values taken from params (Medium's *_param), ready for
/// the functions below: sigma_t.w is the scale; a homogeneous medium's sigma_t.xyz is its
/// extinction times the scale, and `majorant` the largest channel of that.
TANDEM_INLINE Medium medium_load(const SceneRefs* s, __global const float* params, uint index) {
    Medium m = s->media[index];
    if (m.scale_param != NO_PARAM) m.sigma_t.w = params[m.scale_param];
    if (m.g_param != NO_PARAM) m.g = params[m.g_param];
    if (m.albedo_grid == NO_GRID && m.albedo_param != NO_PARAM) {
        const float3 a = param_rgb(params, m.albedo_param);
        m.albedo = make_float4(a.x, a.y, a.z, 0.0f);
    }
    if (m.kind == MEDIUM_HOMOGENEOUS) {
        const float3 st = param_rgb_or(params, m.sigma_t_param, xyz(m.sigma_t)) * m.sigma_t.w;
        m.sigma_t = make_float4(st.x, st.y, st.z, m.sigma_t.w);
        m.majorant = fmax(st.x, fmax(st.y, st.z));
    }
    return m;
}

/// Extinction and scattering coefficients (rgb) of medium m (medium_load) at world point x. Grids
/// are parameters: their voxels are read from params.
TANDEM_INLINE void medium_coefficients(const SceneRefs* s, __global const float* params,
                                       const Medium* m, float3 x, float3* sigma_t,
                                       float3* sigma_s) {
    float3 st = xyz(m->sigma_t), albedo = xyz(m->albedo);
    if (m->kind == MEDIUM_GRID) {
        const DeviceGrid g = s->grids[m->sigma_t_grid];
        st = grid_eval3(params, &g, grid_local(&g, x)) * m->sigma_t.w;
    }
    if (m->albedo_grid != NO_GRID) {
        const DeviceGrid g = s->grids[m->albedo_grid];
        albedo = grid_eval3(params, &g, grid_local(&g, x));
    }
    *sigma_t = st;
    *sigma_s = st * albedo;
}

/// A walk along a ray through a medium's majorant: pieces [a, b) of the ray, in order, each with
/// one majorant mu. A homogeneous medium is one piece; a grid medium's are the cells of its
/// majorant grid that the ray crosses inside the grid's unit cube (a 3D DDA: Amanatides and Woo
/// 1987), outside of which the medium is empty.
typedef struct MajorantWalk {
    float t, t_end; ///< the walk's position and its end
    float mu;       ///< homogeneous: the majorant
    int grid;       ///< walks the cells of a majorant grid
    int cx, cy, cz, sx, sy, sz;
    float next_x, next_y, next_z, dx, dy, dz;
    uint nx, ny, nz, offset;
    float scale;
    float piece_t, piece_end, piece_mu; ///< majorant_collision's place in the current piece
} MajorantWalk;

/// The DDA's setup on one axis: ray origin o and direction d in cell units, the start cell c;
/// the ray parameter of the next cell face, the step between faces, and the cell step.
TANDEM_INLINE void walk_axis(float o, float d, int c, float* next, float* delta, int* step) {
    if (d > 0.0f) {
        *next = ((float)(c + 1) - o) / d;
        *delta = 1.0f / d;
        *step = 1;
    } else if (d < 0.0f) {
        *next = ((float)c - o) / d;
        *delta = -1.0f / d;
        *step = -1;
    } else {
        *next = INFINITY;
        *delta = INFINITY;
        *step = 0;
    }
}

/// The slab [0, n] on one axis of a ray o + t d (cell units), intersected into [*t0, *t1).
TANDEM_INLINE void walk_clip(float o, float d, float n, float* t0, float* t1) {
    if (d == 0.0f) {
        if (!(o >= 0.0f && o <= n)) *t1 = *t0; // parallel and outside: empty
        return;
    }
    const float a = (0.0f - o) / d, b = (n - o) / d;
    *t0 = fmax(*t0, fmin(a, b));
    *t1 = fmin(*t1, fmax(a, b));
}

/// Cell c of an axis of n cells at coordinate p (clamped: p is in [0, n] up to rounding).
TANDEM_INLINE int walk_cell(float p, uint n) {
    const int c = (int)det_floor(p), last = (int)n - 1;
    return c < 0 ? 0 : (c > last ? last : c);
}

/// Starts the walk through medium m along o + t d (d unit, world space) over [t0, t1).
TANDEM_INLINE void majorant_walk_begin(const SceneRefs* s, const Medium* m, float3 o, float3 d,
                                       float t0, float t1, MajorantWalk* w) {
    w->t = t0;
    w->t_end = t1;
    w->piece_t = w->piece_end = w->piece_mu = 0.0f; // no piece yet
    w->mu = m->majorant;
    w->grid = m->kind == MEDIUM_GRID;
    if (!w->grid) return;
    const DeviceGrid g = s->grids[m->majorant_grid];
    w->nx = g.nx;
    w->ny = g.ny;
    w->nz = g.nz;
    w->offset = g.offset;
    w->scale = m->sigma_t.w;
    const float3 res = make_float3((float)g.nx, (float)g.ny, (float)g.nz);
    const float3 ol = grid_local(&g, o) * res, dl = grid_local_dir(&g, d) * res;
    walk_clip(ol.x, dl.x, res.x, &w->t, &w->t_end);
    walk_clip(ol.y, dl.y, res.y, &w->t, &w->t_end);
    walk_clip(ol.z, dl.z, res.z, &w->t, &w->t_end);
    if (!(w->t < w->t_end)) return;
    const float3 p = ol + dl * w->t;
    w->cx = walk_cell(p.x, g.nx);
    w->cy = walk_cell(p.y, g.ny);
    w->cz = walk_cell(p.z, g.nz);
    walk_axis(ol.x, dl.x, w->cx, &w->next_x, &w->dx, &w->sx);
    walk_axis(ol.y, dl.y, w->cy, &w->next_y, &w->dy, &w->sy);
    walk_axis(ol.z, dl.z, w->cz, &w->next_z, &w->dz, &w->sz);
}

/// The walk's next piece [*a, *b) and its majorant *mu; 0 when the walk is over.
TANDEM_INLINE int majorant_walk_next(const SceneRefs* s, MajorantWalk* w, float* a, float* b,
                                     float* mu) {
    if (!(w->t < w->t_end)) return 0;
    *a = w->t;
    if (!w->grid) {
        *b = w->t_end;
        *mu = w->mu;
        w->t = w->t_end;
        return 1;
    }
    if (w->cx < 0 || w->cy < 0 || w->cz < 0 || w->cx >= (int)w->nx || w->cy >= (int)w->ny ||
        w->cz >= (int)w->nz)
        return 0;
    const uint cell = ((uint)w->cz * w->ny + (uint)w->cy) * w->nx + (uint)w->cx;
    *mu = w->scale * s->medium_data[w->offset + cell];
    const float tn = fmin(w->next_x, fmin(w->next_y, w->next_z));
    *b = fmin(tn, w->t_end);
    if (w->next_x == tn) {
        w->cx += w->sx;
        w->next_x += w->dx;
    } else if (w->next_y == tn) {
        w->cy += w->sy;
        w->next_y += w->dy;
    } else {
        w->cz += w->sz;
        w->next_z += w->dz;
    }
    w->t = *b;
    return 1;
}

/// The walk's next tentative collision: its distance *t and the majorant *mu it was drawn against
/// (exponential steps against each piece's majorant, from the piece's start: free flights and
/// ratio tracking alike). Returns 0 when the walk is over, or when r ran out (r->exhausted).
TANDEM_INLINE int majorant_collision(const SceneRefs* s, MajorantWalk* w, MediaRng* r, float* t,
                                     float* mu) {
    for (;;) {
        if (w->piece_mu > 0.0f) {
            w->piece_t -= det_log(1.0f - media_rand(r)) / w->piece_mu;
            if (r->exhausted) return 0;
            if (w->piece_t < w->piece_end) {
                *t = w->piece_t;
                *mu = w->piece_mu;
                return 1;
            }
        }
        if (!majorant_walk_next(s, w, &w->piece_t, &w->piece_end, &w->piece_mu)) return 0;
    }
}

/// The sum of a channel triple (the adjoint of a value that is the same in every channel).
TANDEM_INLINE float channel_sum(float3 v) { return v.x + v.y + v.z; }

/// The mean of a channel triple's magnitudes (spectral tracking's probabilities).
TANDEM_INLINE float media_mean(float3 v) {
    return (fabs(v.x) + fabs(v.y) + fabs(v.z)) * (1.0f / 3.0f);
}

/// A free flight through `medium` along o + t d over [t0, t1) (t1: the surface the ray found, or
/// +inf), by spectral tracking (see the top of this file) with random numbers from r. Returns
/// FLIGHT_SCATTERED with the collision's distance in *t_out, FLIGHT_ESCAPED at t1, or
/// FLIGHT_ABSORBED (nothing of the throughput is left, or r ran out); *beta is weighted either way.
TANDEM_INLINE int medium_free_flight(const SceneRefs* s, __global const float* params,
                                     const Medium* m, float3 o, float3 d, float t0, float t1,
                                     MediaRng* r, float3* beta, float* t_out) {
    MajorantWalk w;
    majorant_walk_begin(s, m, o, d, t0, t1, &w);
    float t, mu;
    while (majorant_collision(s, &w, r, &t, &mu)) {
        float3 st, ss;
        medium_coefficients(s, params, m, o + d * t, &st, &ss);
        const float3 sn = make_float3(fmax(mu - st.x, 0.0f), fmax(mu - st.y, 0.0f),
                                      fmax(mu - st.z, 0.0f));
        const float ps = media_mean(*beta * ss), pn = media_mean(*beta * sn);
        if (!(ps + pn > 0.0f)) return FLIGHT_ABSORBED;
        const float p_scatter = ps / (ps + pn);
        if (pn == 0.0f || media_rand(r) < p_scatter) {
            *beta = *beta * ss * (1.0f / (mu * p_scatter));
            *t_out = t;
            return FLIGHT_SCATTERED;
        }
        *beta = *beta * sn * (1.0f / (mu * (1.0f - p_scatter)));
    }
    return r->exhausted ? FLIGHT_ABSORBED : FLIGHT_ESCAPED;
}

/// exp(-sigma t) of one channel: 1 where sigma is 0, whatever t (even +inf).
TANDEM_INLINE float media_beer(float sigma, float t) {
    return sigma > 0.0f ? det_exp(-sigma * t) : 1.0f;
}

/// The transmittance (rgb) of `medium` along o + t d over [t0, t1): in closed form in a
/// homogeneous medium, by ratio tracking (Novak et al. 2014, "Residual Ratio Tracking for
/// Estimating Attenuation in Participating Media", section 3) against the majorant walk in a grid
/// one, with random numbers from r (0 where r runs out).
TANDEM_INLINE float3 medium_transmittance(const SceneRefs* s, __global const float* params,
                                          const Medium* m, float3 o, float3 d, float t0, float t1,
                                          MediaRng* r) {
    if (m->kind == MEDIUM_HOMOGENEOUS) {
        const float len = t1 - t0;
        return make_float3(media_beer(m->sigma_t.x, len), media_beer(m->sigma_t.y, len),
                           media_beer(m->sigma_t.z, len));
    }
    float3 T = make_float3(1.0f, 1.0f, 1.0f);
    MajorantWalk w;
    majorant_walk_begin(s, m, o, d, t0, t1, &w);
    float t, mu;
    while (majorant_collision(s, &w, r, &t, &mu)) {
        float3 st, ss;
        medium_coefficients(s, params, m, o + d * t, &st, &ss);
        T = T * make_float3(fmax(mu - st.x, 0.0f), fmax(mu - st.y, 0.0f), fmax(mu - st.z, 0.0f)) *
            (1.0f / mu);
        if (!(max_component(T) > 0.0f)) return T;
    }
    return r->exhausted ? make_float3(0.0f, 0.0f, 0.0f) : T;
}

// The adjoint of media (path replay: docs/method.md, "Gradients of media"). The sampling is
// detached, as on surfaces: the majorants, the collision distances and spectral tracking's
// probabilities are constants. What depends on the parameters is
// - the transmittance of every piece of ray through a medium, T = exp(-int sigma_t): its
//   estimate (the product of the null-collision weights of free flights, or ratio tracking) has
//   the expectation T, so a term that arrived through it has the derivative
//   -(int d sigma_t / d theta) times itself. The line integral is exact in a homogeneous medium
//   (length times d sigma_t) and, in a grid, estimated with one point drawn uniformly on the piece
//   inside the grid (unbiased, independent of the tracking). This is the transmittance's own
//   derivative, not that of each null-collision weight (sigma_n / mu): those vanish where the
//   majorant is tight (a homogeneous medium has no null collisions in its densest channel), and
//   differentiating them would then miss d T / d sigma_t entirely.
// - sigma_s(x) = sigma_t(x) albedo(x), a factor of everything after a scattering collision at x;
// - the phase function's value, in its light sample's term and its sampled direction's weight.

/// Adds k_c times d sigma_t_c / d theta of homogeneous medium m (medium_load), per channel c: into
/// its sigma_t (times scale) and its scale (times sigma_t before the scale).
TANDEM_INLINE void medium_sigma_t_adjoint(Adjoint* adj, __global const float* params,
                                          const Medium* m, float3 k) {
    const float scale = m->sigma_t.w;
    if (m->sigma_t_param != NO_PARAM) grad_add_rgb(adj, m->sigma_t_param, k * scale);
    if (m->scale_param != NO_PARAM) {
        const float3 raw = param_rgb(params, m->sigma_t_param);
        grad_add(adj, m->scale_param, k.x * raw.x + k.y * raw.y + k.z * raw.z);
    }
}

/// Adds k_c times d v_c(l) / d(voxel) to the voxels of grid g (a parameter: g->offset is in the
/// parameter buffer) that the lookup at local point l blends; a one-channel grid gets the sum over
/// the channels.
TANDEM_INLINE void grid_adjoint(Adjoint* adj, const DeviceGrid* g, float3 l, float3 k) {
    uint index[8];
    float weight[8];
    grid_corners(g, l, index, weight);
    for (uint i = 0; i < 8u; ++i) {
        const uint e = g->offset + index[i];
        if (g->channels == 1u)
            grad_add(adj, e, weight[i] * (k.x + k.y + k.z));
        else
            grad_add_rgb(adj, e, k * weight[i]);
    }
}

/// The part [*a, *b) of [t0, t1) of o + t d inside grid g's unit cube (empty: *a >= *b).
TANDEM_INLINE void grid_clip(const DeviceGrid* g, float3 o, float3 d, float t0, float t1, float* a,
                             float* b) {
    const float3 ol = grid_local(g, o), dl = grid_local_dir(g, d);
    *a = t0;
    *b = t1;
    walk_clip(ol.x, dl.x, 1.0f, a, b);
    walk_clip(ol.y, dl.y, 1.0f, a, b);
    walk_clip(ol.z, dl.z, 1.0f, a, b);
}

/// The adjoint of the transmittance of medium m (medium_load) along o + t d over [t0, t1), which
/// multiplies radiance whose adjoint is k (delta times that radiance, per channel): -k times the
/// line integral of d sigma_t (see above), in a grid at one point drawn with r.
TANDEM_INLINE void medium_transmittance_adjoint(const SceneRefs* s, __global const float* params,
                                                const Medium* m, float3 o, float3 d, float t0,
                                                float t1, float3 k, MediaRng* r, Adjoint* adj) {
    if (max_component(fabs(k)) == 0.0f) return;
    if (m->kind == MEDIUM_HOMOGENEOUS) {
        // an unbounded piece transmits only channels of sigma_t 0, where d T / d sigma_t is
        // -infinity: left out
        const float len = t1 - t0;
        if (len < INFINITY) medium_sigma_t_adjoint(adj, params, m, k * -len);
        return;
    }
    const DeviceGrid g = s->grids[m->sigma_t_grid];
    float a, b;
    grid_clip(&g, o, d, t0, t1, &a, &b);
    if (!(a < b)) return;
    const float t = a + (b - a) * media_rand(r);
    const float3 l = grid_local(&g, o + d * t);
    const float len = b - a;
    grid_adjoint(adj, &g, l, k * (-len * m->sigma_t.w));
    if (m->scale_param != NO_PARAM) {
        const float3 v = grid_eval3(params, &g, l);
        grad_add(adj, m->scale_param, -len * (k.x * v.x + k.y * v.y + k.z * v.z));
    }
}

/// The adjoint of the factor sigma_s(x) = sigma_t(x) albedo(x) of a scattering collision at x in
/// medium m (medium_load), which multiplies radiance whose adjoint is k: k / sigma_s times its
/// derivative, into sigma_t (and scale) and albedo.
TANDEM_INLINE void medium_scatter_adjoint(const SceneRefs* s, __global const float* params,
                                          const Medium* m, float3 x, float3 k, Adjoint* adj) {
    if (max_component(fabs(k)) == 0.0f) return;
    float3 albedo = xyz(m->albedo);
    DeviceGrid ga;
    float3 la;
    if (m->albedo_grid != NO_GRID) {
        ga = s->grids[m->albedo_grid];
        la = grid_local(&ga, x);
        albedo = grid_eval3(params, &ga, la);
    }
    if (m->kind == MEDIUM_HOMOGENEOUS) {
        medium_sigma_t_adjoint(adj, params, m, safe_ratio(k, xyz(m->sigma_t)));
    } else {
        const DeviceGrid g = s->grids[m->sigma_t_grid];
        const float3 l = grid_local(&g, x);
        grid_adjoint(adj, &g, l, safe_ratio(k, grid_eval3(params, &g, l)));
        if (m->scale_param != NO_PARAM)
            grad_add(adj, m->scale_param, safe_div(k.x + k.y + k.z, m->sigma_t.w));
    }
    if (m->albedo_grid != NO_GRID)
        grid_adjoint(adj, &ga, la, safe_ratio(k, albedo));
    else if (m->albedo_param != NO_PARAM)
        grad_add_rgb(adj, m->albedo_param, safe_ratio(k, albedo));
}

/// The transmittance (rgb) from `origin`, in `medium`, to the light of ls: through the media along
/// its shadow ray and the null surfaces it crosses; 0 where any other surface blocks it. With an
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
        if (open) return T;
        const TriangleInfo info = s->infos[h.prim];
        if (crossing + 1u == MEDIA_MAX_CROSSINGS || !(max_component(T) > 0.0f) ||
            s->materials[info.material].type != MATERIAL_NULL)
            return make_float3(0.0f, 0.0f, 0.0f);
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
            if (flight == FLIGHT_ABSORBED) break;
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
            if (++crossings == MEDIA_MAX_CROSSINGS) break;
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

#endif // TANDEM_KERNELS_PATH_MEDIA_H
